// Embree 3 (Debian's libembree-dev) wrapped as the reference a user would pick instead of dynbvh:
// the same triangles, the same thread count, rebuilt or refitted per frame, traced one ray at a time
// (rtcIntersect1) or in packets of 8 or 16 (rtcIntersect8/16).
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <cstring>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>

#include <dynbvh/ray.hpp>
#include <dynbvh/triangle.hpp>

namespace dynbvh::bench {

enum class EmbreeMode { low, medium, high, refit };

inline const char* to_string(EmbreeMode m) {
    switch (m) {
        case EmbreeMode::low: return "embree-low";
        case EmbreeMode::medium: return "embree-medium";
        case EmbreeMode::high: return "embree-high";
        case EmbreeMode::refit: return "embree-refit";
    }
    return "embree";
}

/// One Embree device + scene + triangle geometry. `update(tris)` copies the frame's vertices
/// into Embree's buffer (not timed by callers); `commit()` is the build (or refit) to time.
class EmbreeBvh {
public:
    EmbreeBvh(int threads, EmbreeMode mode) : mode_(mode) {
        const std::string cfg = "threads=" + std::to_string(threads > 0 ? threads : 0) + ",set_affinity=0";
        device_ = rtcNewDevice(cfg.c_str());
        if (!device_) throw std::runtime_error("embree: rtcNewDevice failed");
    }
    EmbreeBvh(const EmbreeBvh&) = delete;
    EmbreeBvh& operator=(const EmbreeBvh&) = delete;
    ~EmbreeBvh() {
        release_scene();
        rtcReleaseDevice(device_);
    }

    /// Copies triangles into Embree's vertex buffer (recreating the geometry when the count changes).
    void update(std::span<const Trianglef> tris) {
        if (!scene_ || tris.size() != count_) create(tris.size());
        auto* v = static_cast<float*>(rtcGetGeometryBufferData(geom_, RTC_BUFFER_TYPE_VERTEX, 0));
        std::memcpy(v, tris.data(), tris.size() * sizeof(Trianglef));
        rtcUpdateGeometryBuffer(geom_, RTC_BUFFER_TYPE_VERTEX, 0);
        rtcCommitGeometry(geom_);
    }
    /// Builds (or refits, in refit mode after the first build) the acceleration structure.
    void commit() { rtcCommitScene(scene_); }

    Hitf intersect(const Rayf& r) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh;
        fill(rh.ray, r);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene_, &ctx, &rh);
        Hitf h;
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
            h.t = rh.ray.tfar;
            h.u = rh.hit.u;
            h.v = rh.hit.v;
            h.prim = rh.hit.primID;
        }
        return h;
    }
    /// rtcIntersect8 / rtcIntersect16 on N rays (N = 8 or 16); lanes with valid[k] == 0 are inactive.
    /// Writes each active lane's hit (or a miss) to out[k].
    template <int N>
    void intersect_packet(const Rayf* rays, const int* valid, Hitf* out) const {
        intersect_lanes<N>(scene_, rays, valid, out);
    }
    /// rtcOccluded8 / rtcOccluded16 on N rays: blocked[k] = whether active lane k hits anything (0 for
    /// inactive lanes).
    template <int N>
    void occluded_packet(const Rayf* rays, const int* valid, std::uint8_t* blocked) const {
        occluded_lanes<N>(scene_, rays, valid, blocked);
    }

    /// rtcIntersect8 / rtcIntersect16 of N rays in `scene` (coherent context): out[k] = lane k's hit
    /// (prim = Embree's primID) or a miss; instance[k] (when given) = the hit's instID[0] (two-level
    /// scenes), RTC_INVALID_GEOMETRY_ID for a miss.
    template <int N>
    static void intersect_lanes(RTCScene scene, const Rayf* rays, const int* valid, Hitf* out, std::uint32_t* instance = nullptr) {
        static_assert(N == 8 || N == 16, "Embree packets of 8 or 16 rays");
        using RH = std::conditional_t<N == 8, RTCRayHit8, RTCRayHit16>;
        alignas(64) RH rh;
        alignas(64) int v[N];
        fill_lanes<N>(rh.ray, rays, valid, v);
        for (int k = 0; k < N; ++k) {
            rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
        RTCIntersectContext ctx = coherent_context();
        if constexpr (N == 8) rtcIntersect8(v, scene, &ctx, &rh);
        else rtcIntersect16(v, scene, &ctx, &rh);
        for (int k = 0; k < N; ++k) {
            Hitf h;
            const bool hit = valid[k] && rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
            if (hit) {
                h.t = rh.ray.tfar[k];
                h.u = rh.hit.u[k];
                h.v = rh.hit.v[k];
                h.prim = rh.hit.primID[k];
            }
            out[k] = h;
            if (instance) instance[k] = hit ? rh.hit.instID[0][k] : RTC_INVALID_GEOMETRY_ID;
        }
    }
    /// rtcOccluded8 / rtcOccluded16 of N rays in `scene`: blocked[k] as occluded_packet.
    template <int N>
    static void occluded_lanes(RTCScene scene, const Rayf* rays, const int* valid, std::uint8_t* blocked) {
        static_assert(N == 8 || N == 16, "Embree packets of 8 or 16 rays");
        using R = std::conditional_t<N == 8, RTCRay8, RTCRay16>;
        alignas(64) R ray;
        alignas(64) int v[N];
        fill_lanes<N>(ray, rays, valid, v);
        RTCIntersectContext ctx = coherent_context();
        if constexpr (N == 8) rtcOccluded8(v, scene, &ctx, &ray);
        else rtcOccluded16(v, scene, &ctx, &ray);
        for (int k = 0; k < N; ++k) blocked[k] = valid[k] && ray.tfar[k] < 0 ? 1 : 0;
    }
    /// Up to 16 rays (rays.size() <= 16) as one call on 16 lanes: `f(r, valid, res)` traces lanes r[]
    /// (valid[k] = 1 for the given rays, the rest inactive default rays) into res[], whose first
    /// rays.size() entries go to out.
    template <class Out, class F>
    static void with_lanes16(std::span<const Rayf> rays, std::span<Out> out, const F& f) {
        Rayf r[16];
        int valid[16];
        Out res[16];
        for (std::size_t k = 0; k < 16; ++k) {
            valid[k] = k < rays.size();
            r[k] = valid[k] ? rays[k] : Rayf{};
        }
        f(static_cast<const Rayf*>(r), static_cast<const int*>(valid), res);
        std::copy_n(res, std::min<std::size_t>(16, rays.size()), out.begin());
    }
    bool occluded(const Rayf& r) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRay ray;
        fill(ray, r);
        rtcOccluded1(scene_, &ctx, &ray);
        return ray.tfar < 0;
    }
    EmbreeMode mode() const { return mode_; }

private:
    /// The N lanes of an RTCRay8 / RTCRay16 from rays[], and Embree's lane mask v[] from valid[].
    template <int N, class RayN>
    static void fill_lanes(RayN& ray, const Rayf* rays, const int* valid, int* v) {
        for (int k = 0; k < N; ++k) {
            const Rayf& r = rays[k];
            v[k] = valid[k] ? -1 : 0;
            ray.org_x[k] = r.org.x; ray.org_y[k] = r.org.y; ray.org_z[k] = r.org.z;
            ray.dir_x[k] = r.dir.x; ray.dir_y[k] = r.dir.y; ray.dir_z[k] = r.dir.z;
            ray.tnear[k] = r.tmin;
            ray.tfar[k] = r.tmax;
            ray.time[k] = 0;
            ray.mask[k] = ~0u;
            ray.id[k] = 0;
            ray.flags[k] = 0;
        }
    }
    /// A context for coherent packets (primary rays of a tile).
    static RTCIntersectContext coherent_context() {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        return ctx;
    }
    static void fill(RTCRay& ray, const Rayf& r) {
        ray.org_x = r.org.x; ray.org_y = r.org.y; ray.org_z = r.org.z;
        ray.dir_x = r.dir.x; ray.dir_y = r.dir.y; ray.dir_z = r.dir.z;
        ray.tnear = r.tmin;
        ray.tfar = r.tmax;
        ray.time = 0;
        ray.mask = ~0u;
        ray.id = 0;
        ray.flags = 0;
    }
    void create(std::size_t n) {
        release_scene();
        scene_ = rtcNewScene(device_);
        const bool refit = mode_ == EmbreeMode::refit;
        const RTCBuildQuality q = mode_ == EmbreeMode::low ? RTC_BUILD_QUALITY_LOW
                                  : mode_ == EmbreeMode::high ? RTC_BUILD_QUALITY_HIGH
                                  : refit ? RTC_BUILD_QUALITY_REFIT : RTC_BUILD_QUALITY_MEDIUM;
        rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_DYNAMIC);
        rtcSetSceneBuildQuality(scene_, refit ? RTC_BUILD_QUALITY_LOW : q);
        geom_ = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        rtcSetGeometryBuildQuality(geom_, q);
        // Vertices in our triangle layout (3 consecutive points per triangle), plus padding Embree reads past the end.
        rtcSetNewGeometryBuffer(geom_, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, sizeof(float) * 3, 3 * n + 1);
        auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom_, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                    sizeof(unsigned) * 3, n));
        for (std::size_t i = 0; i < 3 * n; ++i) idx[i] = unsigned(i);
        rtcAttachGeometry(scene_, geom_);
        count_ = n;
    }
    void release_scene() {
        if (geom_) rtcReleaseGeometry(geom_);
        if (scene_) rtcReleaseScene(scene_);
        geom_ = nullptr;
        scene_ = nullptr;
    }

    EmbreeMode mode_;
    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    RTCGeometry geom_ = nullptr;
    std::size_t count_ = 0;
};

} // namespace dynbvh::bench
