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
#include "object_groups.hpp"

namespace dynbvh::study {

namespace {

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

    /// One object of the scene: a group of the frame's objects (object_groups.hpp).
    struct Slot {
        std::uint32_t id = 0;                   ///< TwoLevel object id
        std::vector<std::uint32_t> frame_index; ///< the frame's triangle of each of the object's triangles
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
        if (!groups_ || !groups_->holds(objects_, tris.size())) {
            set_up(tris);
            return;
        }
        // Step: rigid groups move by their transforms, deforming ones are refitted or rebuilt.
        const auto& groups = groups_->groups();
        transforms_.resize(groups.size());
        for (std::size_t g = 0; g < groups.size(); ++g) {
            transforms_[g] = groups_->transform(g, objects_);
            if (groups[g].deforming) {
                const auto [first, count] = groups_->run(g);
                scene_->update_object(slots_[g].id, tris.subspan(first, count));
            }
        }
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
    /// The hit with prim = the frame's triangle index (instance i is slot i).
    Hitf frame_prim(const InstanceHit<float>& h) const {
        Hitf out = h;
        if (h.instance != invalid_prim) out.prim = slots_[h.instance].frame_index[h.prim];
        return out;
    }

    /// A new scene for this frame's layout (object_groups.hpp): each group of the frame's objects one object,
    /// its triangles in object space (through the inverse of this frame's placement; deforming groups as
    /// they are, and refitted or rebuilt every frame), and one instance.
    void set_up(std::span<const Trianglef> tris) {
        groups_ = std::make_unique<GroupedObjects>(objects_, tris.size());
        scene_ = std::make_unique<Scene>(cfg_, ex_);
        const auto& groups = groups_->groups();
        slots_.assign(groups.size(), Slot{});
        object_space_.resize(groups.size());
        std::vector<Instance<float>> instances;
        for (std::size_t g = 0; g < groups.size(); ++g) {
            Slot& s = slots_[g];
            groups_->object_space(g, objects_, tris, object_space_[g], s.frame_index);
            if (groups[g].deforming) {
                const auto [first, count] = groups_->run(g);
                s.id = scene_->add_object(tris.subspan(first, count));   // the frame's own triangles, given anew each frame
            } else {
                s.id = scene_->add_object(object_space_[g]);
            }
            instances.push_back({s.id, groups_->transform(g, objects_)});
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
    std::unique_ptr<GroupedObjects> groups_;             // the layout the scene was set up for
    std::vector<Slot> slots_;                            // one per group = object = instance
    std::vector<std::vector<Trianglef>> object_space_;   // rigid groups' triangles in object space
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
