// The `two-level` strategy's Accel (see auto_accel.hpp), on every executor.
#include "auto_accel.hpp"

#include <algorithm>
#include <stdexcept>
#include <vector>

#include <dynbvh/affine.hpp>
#include <dynbvh/builder.hpp>
#include <dynbvh/two_level.hpp>

#include <render/whitted.hpp>
#include "dyn_accel.hpp"

namespace dynbvh::study {

namespace {

/// io::Transform (column-major 4x4) as the library's row-major 3x4 Affine.
Affine<float> affine_of(const io::Transform& t) {
    Affine<float> a;
    for (std::size_t r = 0; r < 3; ++r)
        for (std::size_t c = 0; c < 4; ++c) a.m[4 * r + c] = t.m[c * 4 + r];
    return a;
}

bool is_identity(const io::Transform& t) { return t.m == io::Transform{}.m; }

/// The objects' (and, with one instance per leaf, the top level's) builder knobs: the objects are traced
/// through SIMD triangle blocks, so their leaves are collapsed with block_leaves' costs (TwoLevelConfig's
/// default), up to the spec's largest leaf.
template <class B> typename B::config tree_config(const BuilderSpec& spec);
template <> builder::ploc::config tree_config<builder::ploc>(const BuilderSpec& spec) {
    return {.radius = spec.radius, .morton_bits = spec.morton_bits, .leaves = {.max_leaf_size = spec.max_leaf, .cost = block_leaves.cost}};
}
template <> builder::lbvh::config tree_config<builder::lbvh>(const BuilderSpec& spec) {
    return {.morton_bits = spec.morton_bits, .leaves = {.max_leaf_size = spec.max_leaf, .cost = block_leaves.cost}};
}

template <class Exec, class B>
class TwoLevelAccel final : public Accel {
    using Scene = TwoLevel<B, Node<>, prim::indexed, Exec>;

    /// One object of the frame layout the scene was set up for.
    struct Slot {
        std::uint32_t first = 0, count = 0;   ///< its run of the frame's triangles
        bool deforming = false;               ///< given anew every frame (update_object), identity transform
        std::uint32_t id = 0;                 ///< TwoLevel object id (when count > 0)
    };

public:
    TwoLevelAccel(const BuilderSpec& spec, const Exec& ex, const Backend& backend) : spec_(spec), ex_(ex), backend_(backend) {
        cfg_.objects.rebuild_threshold = spec.threshold;
        cfg_.objects.builder = tree_config<B>(spec);
        auto top = tree_config<B>(spec);
        top.leaves.max_leaf_size = 1;   // one instance per top-level leaf (TwoLevelConfig's default)
        cfg_.top = top;
    }

    void frame_objects(std::span<const io::ObjectInstance> objects) override { objects_ = objects; }

    void build(std::span<const Trianglef> tris) override {
        if (!same_layout(tris)) {
            set_up(tris);
            return;
        }
        // Step: rigid objects move by their transforms, deforming ones are refitted or rebuilt.
        transforms_.resize(slots_.size());
        std::size_t k = 0;
        for (std::size_t i = 0; i < slots_.size(); ++i) {
            const Slot& s = slots_[i];
            if (s.count == 0) continue;
            transforms_[k++] = s.deforming || objects_.empty() ? Affine<float>{} : affine_of(objects_[i].transform);
            if (s.deforming) scene_->update_object(s.id, tris.subspan(s.first, s.count));
        }
        transforms_.resize(k);
        scene_->set_transforms(transforms_);
        scene_->commit();
    }

    void trace(std::span<const Trianglef>, const RayGen& gen, std::span<std::uint32_t> out) override {
        const Scene& sc = *scene_;
        if (spec_.packets) {   // packets of primary_packet_rays through both levels (TwoLevel::intersect of a RayPacket)
            constexpr int N = primary_packet_rays;
            trace_tiles_ray_packets<N>(backend_, gen, out, [&](const RayPacket<float, N>& p, std::uint32_t active, std::uint32_t* prims) {
                const InstanceHitPacket<float, N> h = sc.intersect(p, active);
                for (int k = 0; k < N; ++k) prims[k] = frame_prim(h.hit(k)).prim;
            });
            return;
        }
        trace_tiles(backend_, gen, out, [&](const Rayf& r) { return frame_prim(sc.intersect(r)).prim; });
    }
    std::optional<double> sah() const override { return std::nullopt; }
    std::optional<std::size_t> memory_bytes() const override {
        std::size_t bytes = scene_->top().memory_bytes();
        for (std::uint32_t o = 0; o < scene_->object_count(); ++o) bytes += scene_->object_bvh(o).memory_bytes();
        return bytes;
    }
    Hitf intersect(std::span<const Trianglef>, const Rayf& r) const override { return frame_prim(scene_->intersect(r)); }
    bool occluded(std::span<const Trianglef>, const Rayf& r) const override { return scene_->occluded(r); }
    void intersect_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<Hitf> out) const override {
        if (!spec_.packets) return Accel::intersect_packet(tris, rays, out);
        RayPacket<float, 16> p;
        const InstanceHitPacket<float, 16> h = scene_->intersect(p, render::ray_packet16(rays, p));
        for (std::size_t k = 0; k < std::min<std::size_t>(16, rays.size()); ++k) out[k] = frame_prim(h.hit(int(k)));
    }
    void occluded_packet(std::span<const Trianglef> tris, std::span<const Rayf> rays, std::span<std::uint8_t> out) const override {
        if (!spec_.packets) return Accel::occluded_packet(tris, rays, out);
        RayPacket<float, 16> p;
        const std::uint32_t m = scene_->occluded(p, render::ray_packet16(rays, p));
        for (std::size_t k = 0; k < std::min<std::size_t>(16, rays.size()); ++k) out[k] = (m >> k) & 1u;
    }

private:
    /// The hit with prim = the frame's triangle index (object's first triangle + the object's triangle).
    Hitf frame_prim(const InstanceHit<float>& h) const {
        Hitf out = h;
        if (h.instance != invalid_prim) out.prim = slots_[instance_slot_[h.instance]].first + h.prim;
        return out;
    }

    bool same_layout(std::span<const Trianglef> tris) const {
        if (!scene_) return false;
        if (objects_.empty() || !two_level_unsupported_layout(tris).empty()) return slots_.size() == 1 && slots_[0].count == tris.size();
        if (objects_.size() != slots_.size()) return false;
        for (std::size_t i = 0; i < slots_.size(); ++i)
            if (objects_[i].first_triangle != slots_[i].first || objects_[i].triangle_count != slots_[i].count) return false;
        return true;
    }
    std::string two_level_unsupported_layout(std::span<const Trianglef> tris) const {
        std::size_t at = 0;
        for (const auto& o : objects_) {
            if (o.first_triangle != at) return "gap";
            at += o.triangle_count;
        }
        return at == tris.size() ? std::string() : std::string("short");
    }

    /// A new scene for this frame's layout: rigid objects' triangles taken into object space (inverse of
    /// this frame's transform), deforming ones used as they are. Without usable objects the whole frame
    /// is one deforming object.
    void set_up(std::span<const Trianglef> tris) {
        scene_ = std::make_unique<Scene>(cfg_, ex_);
        slots_.clear();
        object_space_.clear();
        instance_slot_.clear();
        const bool usable = !objects_.empty() && two_level_unsupported_layout(tris).empty();
        if (!usable) slots_.push_back({0, std::uint32_t(tris.size()), true, 0});
        else
            for (const auto& o : objects_)
                slots_.push_back({o.first_triangle, o.triangle_count, o.animated && is_identity(o.transform), 0});
        object_space_.resize(slots_.size());
        std::vector<Instance<float>> instances;
        for (std::size_t i = 0; i < slots_.size(); ++i) {
            Slot& s = slots_[i];
            if (s.count == 0) continue;
            const auto run = tris.subspan(s.first, s.count);
            Affine<float> place{};
            if (s.deforming) {
                s.id = scene_->add_object(run);
            } else {
                place = affine_of(objects_[i].transform);
                const Affine<float> inv = inverse(place, "object " + objects_[i].name + "'s transform");
                auto& local = object_space_[i];
                local.resize(run.size());
                for (std::size_t t = 0; t < run.size(); ++t)
                    local[t] = {inv.point(run[t].p0), inv.point(run[t].p1), inv.point(run[t].p2)};
                s.id = scene_->add_object(local);
            }
            instances.push_back({s.id, place});
            instance_slot_.push_back(std::uint32_t(i));
        }
        scene_->set_instances(instances);
        scene_->commit();
    }

    BuilderSpec spec_;
    Exec ex_;
    const Backend& backend_;
    typename Scene::config_type cfg_;
    std::span<const io::ObjectInstance> objects_;
    std::unique_ptr<Scene> scene_;
    std::vector<Slot> slots_;
    std::vector<std::vector<Trianglef>> object_space_;   // rigid objects' triangles in object space
    std::vector<std::uint32_t> instance_slot_;           // instance -> slot
    std::vector<Affine<float>> transforms_;
};

} // namespace

template <class Exec>
std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec& spec, const Exec& ex, const Backend& backend) {
    if (spec.kind != Kind::two_level) throw std::logic_error("make_two_level_accel: " + spec.name() + " is not two-level");
    if (spec.over == Kind::lbvh) return std::make_unique<TwoLevelAccel<Exec, builder::lbvh>>(spec, ex, backend);
    return std::make_unique<TwoLevelAccel<Exec, builder::ploc>>(spec, ex, backend);
}

template std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec&, const exec::serial&, const Backend&);
#if defined(_OPENMP)
template std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec&, const exec::omp&, const Backend&);
#endif
#if defined(DYNBVH_WITH_TBB)
template std::unique_ptr<Accel> make_two_level_accel(const BuilderSpec&, const exec::tbb&, const Backend&);
#endif

} // namespace dynbvh::study
