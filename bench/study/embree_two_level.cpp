// embree-two-level: Embree 3's instancing over the frame's objects, the counterpart of our two-level
// (see embree_two_level.hpp).
#include "embree_two_level.hpp"

#include <stdexcept>

#if defined(DYNBVH_STUDY_EMBREE)
#include <embree3/rtcore.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include <dynbvh/affine.hpp>

#include "../embree_bvh.hpp"
#include "dyn_accel.hpp"
#include "object_groups.hpp"
#endif

namespace dynbvh::study {

#if defined(DYNBVH_STUDY_EMBREE)
namespace {

void fill(RTCRay& ray, const Rayf& r) {
    ray.org_x = r.org.x;
    ray.org_y = r.org.y;
    ray.org_z = r.org.z;
    ray.dir_x = r.dir.x;
    ray.dir_y = r.dir.y;
    ray.dir_z = r.dir.z;
    ray.tnear = r.tmin;
    ray.tfar = r.tmax;
    ray.time = 0;
    ray.mask = ~0u;
    ray.id = 0;
    ray.flags = 0;
}

class EmbreeTwoLevelAccel final : public Accel {
    /// One object: a group of the frame's objects (object_groups.hpp), as our two-level makes them.
    struct Slot {
        std::vector<std::uint32_t> frame_index;   // the frame's triangle of each of the object's triangles
        bool deforming = false;
        RTCScene scene = nullptr;      // the object's own scene
        RTCGeometry mesh = nullptr;    // its triangles
        RTCGeometry inst = nullptr;    // its instance in the top scene (geomID = slot index)
    };

public:
    EmbreeTwoLevelAccel(const BuilderSpec& spec, const Backend& backend) : backend_(backend), packets_(spec.packets) {
        const std::string cfg = "threads=" + std::to_string(backend.threads() > 0 ? backend.threads() : 0) + ",set_affinity=0";
        device_ = rtcNewDevice(cfg.c_str());
        if (!device_) throw std::runtime_error("embree-two-level: rtcNewDevice failed");
    }
    EmbreeTwoLevelAccel(const EmbreeTwoLevelAccel&) = delete;
    EmbreeTwoLevelAccel& operator=(const EmbreeTwoLevelAccel&) = delete;
    ~EmbreeTwoLevelAccel() override {
        release();
        rtcReleaseDevice(device_);
    }

    void frame_objects(std::span<const io::ObjectInstance> objects) override { objects_ = objects; }

    /// Untimed, like every Embree variant's buffer copy: a new layout gets its object scenes (rigid objects'
    /// triangles taken into object space through the inverse of this frame's transform); deforming objects
    /// get this frame's triangles.
    void prepare(std::span<const Trianglef> tris) override {
        if (!groups_ || !groups_->holds(objects_, tris.size())) set_up(tris);
        for (std::size_t g = 0; g < slots_.size(); ++g) {
            Slot& s = slots_[g];
            if (!s.deforming) continue;
            const auto [first, count] = groups_->run(g);
            auto* v = static_cast<float*>(rtcGetGeometryBufferData(s.mesh, RTC_BUFFER_TYPE_VERTEX, 0));
            std::memcpy(v, tris.data() + first, std::size_t(count) * sizeof(Trianglef));
            rtcUpdateGeometryBuffer(s.mesh, RTC_BUFFER_TYPE_VERTEX, 0);
            rtcCommitGeometry(s.mesh);
        }
    }
    /// Timed: deforming objects refitted (first frame: built), rigid ones' transforms set, the top scene rebuilt.
    void build(std::span<const Trianglef>) override {
        for (std::size_t g = 0; g < slots_.size(); ++g) {
            Slot& s = slots_[g];
            if (s.deforming || fresh_) rtcCommitScene(s.scene);
            if (!s.deforming) {
                const Affine<float> a = groups_->transform(g, objects_);
                rtcSetGeometryTransform(s.inst, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, a.m.data());
            }
            rtcCommitGeometry(s.inst);
        }
        rtcCommitScene(top_);
        fresh_ = false;
    }
    void trace(std::span<const Trianglef>, const RayGen& gen, std::span<std::uint32_t> out) override {
        if (packets_) {   // rtcIntersect16 on 4x4 pixels, as our two-level's packets
            trace_tiles_packets<16>(backend_, gen, out, [&](const Rayf* rays, const int* valid, std::uint32_t* prims) {
                Hitf h[16];
                hits16(rays, valid, h);
                for (int k = 0; k < 16; ++k) prims[k] = h[k].prim;
            });
            return;
        }
        trace_tiles(backend_, gen, out, [&](const Rayf& r) { return hit(r).prim; });
    }
    std::optional<double> sah() const override { return std::nullopt; }
    std::optional<std::size_t> memory_bytes() const override { return std::nullopt; }
    Hitf intersect(std::span<const Trianglef>, const Rayf& r) const override { return hit(r); }
    bool occluded(std::span<const Trianglef>, const Rayf& r) const override {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRay ray;
        fill(ray, r);
        rtcOccluded1(top_, &ctx, &ray);
        return ray.tfar < 0;
    }
    /// rtcIntersect16 / rtcOccluded16 when the study traces packets, else ray by ray.
    void intersect_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<Hitf> out) const override {
        if (!packets_) return Accel::intersect_packet(tris, rays, out);
        bench::EmbreeBvh::with_lanes16(rays, out, [&](const Rayf* r, const int* v, Hitf* h) { hits16(r, v, h); });
    }
    void occluded_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<std::uint8_t> out) const override {
        if (!packets_) return Accel::occluded_packet(tris, rays, out);
        bench::EmbreeBvh::with_lanes16(rays, out, [&](const Rayf* r, const int* v, std::uint8_t* b) {
            bench::EmbreeBvh::occluded_lanes<16>(top_, r, v, b);
        });
    }

private:
    /// rtcIntersect16 on the top scene; prim = the frame's triangle index (the slot's first + primID).
    void hits16(const Rayf* rays, const int* valid, Hitf* out) const {
        std::uint32_t inst[16];
        bench::EmbreeBvh::intersect_lanes<16>(top_, rays, valid, out, inst);
        for (int k = 0; k < 16; ++k)
            if (out[k].prim != invalid_prim) {
                if (inst[k] < slots_.size()) out[k].prim = slots_[inst[k]].frame_index[out[k].prim];
                else out[k] = Hitf{};
            }
    }

    Hitf hit(const Rayf& r) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh;
        fill(rh.ray, r);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(top_, &ctx, &rh);
        Hitf h;
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID && rh.hit.instID[0] < slots_.size()) {
            h.t = rh.ray.tfar;
            h.u = rh.hit.u;
            h.v = rh.hit.v;
            h.prim = slots_[rh.hit.instID[0]].frame_index[rh.hit.primID];
        }
        return h;
    }

    void set_up(std::span<const Trianglef> tris) {
        release();
        fresh_ = true;
        top_ = rtcNewScene(device_);
        rtcSetSceneFlags(top_, RTC_SCENE_FLAG_DYNAMIC);
        rtcSetSceneBuildQuality(top_, RTC_BUILD_QUALITY_LOW);
        groups_ = std::make_unique<GroupedObjects>(objects_, tris.size());
        const auto& groups = groups_->groups();
        slots_.resize(groups.size());
        std::vector<Trianglef> local;
        for (std::size_t g = 0; g < groups.size(); ++g) {
            Slot& s = slots_[g];
            s.deforming = groups[g].deforming;
            // object space: the inverse of this frame's placement, as our two-level does
            groups_->object_space(g, objects_, tris, local, s.frame_index);
            const std::size_t n = groups[g].triangles;
            s.scene = rtcNewScene(device_);
            if (s.deforming) {
                rtcSetSceneFlags(s.scene, RTC_SCENE_FLAG_DYNAMIC);
                rtcSetSceneBuildQuality(s.scene, RTC_BUILD_QUALITY_LOW);
            }
            s.mesh = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
            // deforming objects are refitted after their first build (as embree-refit), rigid ones built once (medium)
            rtcSetGeometryBuildQuality(s.mesh, s.deforming ? RTC_BUILD_QUALITY_REFIT : RTC_BUILD_QUALITY_MEDIUM);
            auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(s.mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                                  sizeof(float) * 3, 3 * n + 1));
            auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(s.mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                        sizeof(unsigned) * 3, n));
            for (std::size_t k = 0; k < 3 * n; ++k) idx[k] = unsigned(k);
            if (!s.deforming) {   // (deforming ones get their triangles in prepare)
                std::memcpy(v, local.data(), n * sizeof(Trianglef));
                rtcCommitGeometry(s.mesh);
            }
            rtcAttachGeometry(s.scene, s.mesh);
            s.inst = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(s.inst, s.scene);
            const Affine<float> id{};
            rtcSetGeometryTransform(s.inst, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, id.m.data());
            rtcAttachGeometryByID(top_, s.inst, unsigned(g));
        }
    }

    void release() {
        for (Slot& s : slots_) {
            if (s.inst) rtcReleaseGeometry(s.inst);
            if (s.mesh) rtcReleaseGeometry(s.mesh);
            if (s.scene) rtcReleaseScene(s.scene);
        }
        slots_.clear();
        if (top_) rtcReleaseScene(top_);
        top_ = nullptr;
    }

    const Backend& backend_;
    bool packets_;   // primary rays in packets of 16 (the run's --rays)
    RTCDevice device_ = nullptr;
    RTCScene top_ = nullptr;
    std::unique_ptr<GroupedObjects> groups_;   // the layout the scene was set up for
    std::vector<Slot> slots_;                  // one per group = instance (geomID in the top scene)
    std::span<const io::ObjectInstance> objects_;
    bool fresh_ = true;
};

} // namespace
#endif

std::unique_ptr<Accel> make_embree_two_level_accel(const BuilderSpec& spec, const Backend& backend) {
#if defined(DYNBVH_STUDY_EMBREE)
    return std::make_unique<EmbreeTwoLevelAccel>(spec, backend);
#else
    (void)backend;
    throw std::runtime_error("builder " + spec.name() + ": this dynbvh-study was built without Embree 3 (install libembree-dev)");
#endif
}

} // namespace dynbvh::study
