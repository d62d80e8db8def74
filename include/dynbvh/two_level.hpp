// SPDX-License-Identifier: MIT
/// @file two_level.hpp
/// Two-level scenes: objects, each with its own tree, placed by instances (an object and an affine
/// transform each), under a top-level tree over the instances' world boxes.
/// @code
///   dynbvh::TwoLevel<> scene;                           // PLOC for the objects and the top level
///   const auto ball = scene.add_object(ball_tris);      // built once
///   scene.set_instances(instances);                     // {object, transform} per instance
///   scene.commit();                                     // world boxes + top-level rebuild
///   for (frame...) {
///       scene.set_transforms(transforms);               // rigid motion: no object tree is touched
///       scene.update_object(cloth, cloth_tris);         // a deformed object: refit or rebuild (dynamic.hpp)
///       scene.commit();
///       auto hit = scene.intersect(ray);                // hit.instance, hit.prim (the object's triangle), t
///   }
/// @endcode
/// Objects: each is a Dynamic policy (dynamic.hpp) over the user's triangle array for that object, so
/// a rigid object's tree is built once and reused, and a deformed one is refitted or rebuilt by the
/// policy's SAH rule. The scene keeps a span of each object's triangles, or its MeshView (mesh.hpp:
/// an indexed mesh read in place, 16- or 32-bit indices); the user keeps the array alive and
/// unchanged until the next update_object, like every prim::indexed tree.
///
/// Top level: rebuilt by commit() with the same builder policy, over one reference per instance whose
/// box is the instance's (padded, see below) world box: the builders' `build_tree` over prepared
/// references and the shared emission (detail/emit.hpp), the same code path every builder ends with.
/// Feeding the builders degenerate triangles instead would break under presplitting (fragments would
/// be clipped smaller than the box) and waste the triangle reading; the reference path is the builders'
/// own input format, so no new tree code was needed. Default top leaves hold one instance (a leaf
/// test is a whole object traversal, far dearer than a box test).
///
/// Traversal: the top-level tree is walked near-first in double (reciprocals of the widened direction
/// computed once per ray); at a leaf each instance's ray is `object_ray(inverse, ray)` (affine.hpp: origin
/// and direction by the inverse transform, same t) and the object's traversal runs with the closest t
/// found so far as tmax, through the object's tree made 8-wide with SIMD triangle-block leaves for float
/// (`object_traced_type`; wide_blocks.hpp: the same answers as the object's binary tree, bit for bit). A hit
/// reports t (the same parameter in world and object space), u, v, the object's triangle (`prim`) and
/// the instance (`instance`). An exact tie between instances goes to the larger instance index (as brute
/// force's order gives it), so the answer does not depend on the order instances are visited in.
/// Packets (`intersect(RayPacket)`, `occluded(RayPacket)`; packet.hpp): the top level is traversed by
/// packet.hpp's packet traversal with a leaf step of its own: at each instance, the lanes that reach
/// its box go into object space together (object_ray's fma chains on all lanes at once where FMA is in
/// hardware: the same bits) and through the object's tree as one object-space packet (an affine map
/// keeps coherent rays coherent); every lane gets the single-ray answer, bit for bit.
///
/// Exactness contract: `intersect` returns what `brute_force_intersect` returns, which tests every
/// instance in order with the same object ray (object_ray) and the watertight triangle test against
/// every triangle of its object: the same t to the bit, and the same (instance, triangle) or another
/// one hit at exactly that t. Inside each object this is the object traversal's own contract
/// (watertight, traverse.hpp). For the top level to never cull an instance brute force hits, each
/// world box is padded and the ray's reach widened to cover the rounding of the transformation: with
/// u the unit roundoff of T, k = 256 u, kappa = ||L|| ||L^-1|| (infinity norms), B the largest
/// coordinate and D the largest extent of the exact world box, c the inverse's translation:
///   padding  p = k (||L|| (||L^-1|| B + |c|) + kappa D + B)   (absolute, per instance),
///   reach    the ray at parameter t may pass up to alpha |t| |dir| beside a box, alpha = k (kappa + 1).
/// These bound the object ray's rounding (fma chains, an inverse rounded from double) mapped back to
/// world space, with a wide safety factor (the derivation gives about 8 u). The triangle test's own t
/// error on grazing hits is not covered by a proof; tests/test_instances.cpp checks the contract
/// empirically (rotations, mirrors, scales, translations far from the origin), as for traverse.hpp.
/// Costs: commit() O(instances) plus a top-level build; a ray visits O(log instances) top nodes plus
/// the object traversals of the instances it reaches.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "affine.hpp"
#include "builder.hpp"
#include "bvh.hpp"
#include "detail/emit.hpp"
#include "detail/references.hpp"
#include "dynamic.hpp"
#include "mesh.hpp"
#include "executor.hpp"
#include "packet.hpp"
#include "traverse.hpp"
#include "traverse_wide.hpp"
#include "wide.hpp"
#include "wide_blocks.hpp"

namespace dynbvh {

/// One placement of an object: world = transform(object space).
template <class T>
struct Instance {
    std::uint32_t object = 0;   ///< id returned by TwoLevel::add_object
    Affine<T> transform{};      ///< object-to-world transform
};

/// Closest hit in a two-level scene: the object traversal's Hit (t, u, v, prim = the object's triangle)
/// and the instance it belongs to (`invalid_prim` when nothing is hit).
template <class T>
struct InstanceHit : Hit<T> {
    std::uint32_t instance = invalid_prim;   ///< index of the instance hit (into TwoLevel::instances())
};

/// The closest hits of a ray packet in a two-level scene: HitPacket's lanes (prim = the object's
/// triangle) and the instance of each lane's hit (`invalid_prim` for a miss or an inactive lane).
template <class T, int N>
struct alignas(64) InstanceHitPacket : HitPacket<T, N> {
    /// The hit instance per lane, or invalid_prim.
    alignas(64) std::uint32_t instance[std::size_t(N)];
    /// All misses.
    InstanceHitPacket() noexcept {
        for (int k = 0; k < N; ++k) instance[k] = invalid_prim;
    }
    /// Stores `h` in lane k.
    void set(int k, const InstanceHit<T>& h) noexcept {
        HitPacket<T, N>::set(k, h);
        instance[k] = h.instance;
    }
    /// Lane k's hit.
    InstanceHit<T> hit(int k) const noexcept {
        InstanceHit<T> h;
        static_cast<Hit<T>&>(h) = HitPacket<T, N>::hit(k);
        h.instance = instance[k];
        return h;
    }
};

namespace detail {
/// A builder config whose leaf collapse keeps one instance per leaf.
template <class BuilderConfig>
BuilderConfig one_instance_per_leaf() {
    BuilderConfig c{};
    c.leaves.max_leaf_size = 1;
    return c;
}
/// An object policy config whose builder collapses leaves for SIMD triangle blocks (block_leaves).
template <class BuilderConfig>
DynamicConfig<BuilderConfig> block_leaf_objects() {
    DynamicConfig<BuilderConfig> c{};
    c.builder.leaves = block_leaves;
    return c;
}
} // namespace detail

/// Knobs of TwoLevel.
template <class Builder>
struct TwoLevelConfig {
    /// Each object's refit-or-rebuild policy (default: DynamicConfig's defaults, with the builder's
    /// leaves collapsed for the SIMD triangle blocks the objects are traced through: block_leaves,
    /// wide_blocks.hpp). The builder's default leaves trace slower through blocks: n-body 146k,
    /// 1920x1080 packets, 1 thread, 44 -> 36 ms.
    DynamicConfig<typename Builder::config> objects = detail::block_leaf_objects<typename Builder::config>();
    /// The top-level build's knobs (default: the builder's defaults with one instance per leaf).
    typename Builder::config top = detail::one_instance_per_leaf<typename Builder::config>();
};

/// A two-level scene (see the file comment).
/// @tparam Builder builder policy for the objects and the top level (builder.hpp), default builder::ploc
/// @tparam NodeT, Prim the object trees' node layout and primitive policy; the top level uses NodeT
/// @tparam Exec threading backend for every build
template <class Builder = builder::ploc, class NodeT = Node<>, class Prim = prim::indexed,
          class Exec = exec::default_executor>
class TwoLevel {
public:
    using scalar_type = typename NodeT::scalar_type;              ///< the trees' scalar (float by default)
    using triangle_type = Triangle<scalar_type>;                  ///< an object's triangle
    using object_policy = Dynamic<Builder, NodeT, Prim, Exec>;    ///< each object's refit-or-rebuild policy
    using object_bvh_type = Bvh<NodeT, Prim>;                     ///< an object's tree
    /// The tree each object is traced through: its tree made 8-wide, with leaves in SIMD triangle blocks
    /// for float (wide_blocks.hpp), else with the same leaves (wide.hpp); the same answers, bit for bit.
    using object_traced_type = std::conditional_t<std::is_same_v<typename NodeT::scalar_type, float>,
                                                  wide_blocks_bvh_of<Bvh<NodeT, Prim>, 8>, wide_bvh_of<Bvh<NodeT, Prim>, 8>>;
    using top_bvh_type = Bvh<NodeT, prim::indexed>;   ///< its prim_ids are instance indices
    using config_type = TwoLevelConfig<Builder>;                  ///< the scene's knobs

    /// An empty scene. Throws std::invalid_argument for a bad cfg.objects (see DynamicConfig).
    explicit TwoLevel(const config_type& cfg = {}, const Exec& ex = {}) : cfg_(cfg), ex_(ex) {
        object_policy probe(cfg_.objects, ex_);   // validates the object policy's knobs
    }

    /// Adds an object over the user's triangles `tris` (kept as a span, see the file comment) and builds
    /// its tree. Returns its id (0, 1, ...). O(build).
    std::uint32_t add_object(std::span<const triangle_type> tris) { return add(tris); }
    /// The same over an indexed mesh read in place (kept as a view; no copy of its triangles): the
    /// tree and answers the span of make_triangles(vertices, indices) would give, bit for bit.
    template <class Index>
    std::uint32_t add_object(const MeshView<scalar_type, Index>& mesh) { return add(mesh); }

    /// Object `object` deformed: its triangles are now `tris` (any count; a new count rebuilds). The
    /// object's policy refits or rebuilds (dynamic.hpp) and says which. Call commit() before tracing.
    /// Throws std::invalid_argument when `object` is not an object id.
    FrameReport update_object(std::uint32_t object, std::span<const triangle_type> tris) { return update(object, tris); }
    /// The same over an indexed mesh read in place (typically the object's view after its vertices
    /// moved); an object may switch between spans and views.
    template <class Index>
    FrameReport update_object(std::uint32_t object, const MeshView<scalar_type, Index>& mesh) { return update(object, mesh); }

    /// Replaces the instances. Each must name an object (instances[i].object < object_count()) and have
    /// a finite, invertible transform (see dynbvh::inverse); otherwise std::invalid_argument naming
    /// instances[i] and the scene is unchanged. Inverses are computed here (in double). O(instances).
    void set_instances(std::span<const Instance<scalar_type>> instances) {
        std::vector<Affine<scalar_type>> inv(instances.size());
        for (std::size_t i = 0; i < instances.size(); ++i) {
            const std::string name = "instances[" + std::to_string(i) + "]";
            if (instances[i].object >= objects_.size())
                throw std::invalid_argument("dynbvh::TwoLevel::set_instances: " + name + ".object is " +
                                            std::to_string(instances[i].object) + " but the scene has " +
                                            std::to_string(objects_.size()) + " objects");
            inv[i] = inverse(instances[i].transform, name + ".transform");
        }
        instances_.assign(instances.begin(), instances.end());
        inverses_ = std::move(inv);
        dirty_ = true;
    }

    /// Rigid motion: new transforms for the same instances (transforms[i] for instance i). No object
    /// tree is touched. Throws std::invalid_argument when the count differs from instance_count() or a
    /// transform is not invertible (scene unchanged). O(instances).
    void set_transforms(std::span<const Affine<scalar_type>> transforms) {
        if (transforms.size() != instances_.size())
            throw std::invalid_argument("dynbvh::TwoLevel::set_transforms: transforms has " + std::to_string(transforms.size()) +
                                        " entries but the scene has " + std::to_string(instances_.size()) + " instances");
        std::vector<Affine<scalar_type>> inv(transforms.size());
        for (std::size_t i = 0; i < transforms.size(); ++i) inv[i] = inverse(transforms[i], "transforms[" + std::to_string(i) + "]");
        for (std::size_t i = 0; i < transforms.size(); ++i) instances_[i].transform = transforms[i];
        inverses_ = std::move(inv);
        dirty_ = true;
    }

    /// Computes every instance's padded world box and rebuilds the top-level tree. Instances of empty
    /// objects get no box (nothing to hit). Throws std::invalid_argument when a world box overflows T.
    /// O(instances) plus the top-level build.
    void commit() {
        using T = scalar_type;
        const std::size_t n = instances_.size();
        References<T> refs;
        refs.primitive_count = n;
        refs.box.resize(n);
        refs.prim.resize(n);
        double alpha = 0;
        std::size_t live = 0;
        std::vector<double> alphas(n);
        for (std::size_t i = 0; i < n; ++i) {
            const object_bvh_type& ob = objects_[instances_[i].object].policy.bvh();
            if (ob.empty()) continue;
            double a = 0;
            refs.box[live] = world_box(ob.bounds(), instances_[i].transform, inverses_[i], a, i);
            alphas[live] = a;
            refs.prim[live++] = static_cast<std::uint32_t>(i);
            alpha = std::max(alpha, a);
        }
        refs.box.resize(live);
        refs.prim.resize(live);
        // The reach widening folded into the boxes, for the float top level (see the file comment):
        // a ray from an origin with |o| <= S comes within a|t|D <= a (B_i + S) / (1 - a) of box i where
        // it reaches it (B_i the box's largest coordinate), so box i grown by that much lets the plain
        // robust slab test stand in for the widened one. S = 8 times the largest coordinate of any box: the
        // cameras of a scene are rarely farther out; rays from farther take the double top level.
        double S = 0;
        for (std::size_t j = 0; j < live; ++j) S = std::max(S, largest_coordinate(refs.box[j]));
        S *= 8;
        for (std::size_t j = 0; j < live; ++j)
            refs.box[j] = grown(refs.box[j], alphas[j] * (largest_coordinate(refs.box[j]) + S) * (1.0 + 1.0 / 64), j);
        origin_bound_ = S;
        origin_bound_f_ = float(S);   // its float floor (the packets' comparison, see trace_top_packet)
        if (double(origin_bound_f_) > S) origin_bound_f_ = std::nextafter(origin_bound_f_, 0.0f);
        refs.excluded = n - live;
        update_reference_bounds(refs, ex_);
        const BinaryTree tree = Builder::build_tree(refs, cfg_.top, ex_);
        // No triangles: the top level is prim::indexed over instance ids, and emission reads none.
        top_ = emit_bvh<NodeT, prim::indexed>(tree, refs, std::span<const triangle_type>(), cfg_.top.leaves, ex_);
        if constexpr (std::is_same_v<T, float>) top8_ = make_wide<8>(top_, ex_);
        alpha_ = alpha;
        dirty_ = false;
    }

    /// Closest hit of the world ray `ray` (see the file comment); no hit for rays that are not
    /// `traceable`. Throws std::logic_error when the scene changed since the last commit().
    template <class Policy = trace::robust>
    InstanceHit<scalar_type> intersect(const Ray<scalar_type>& ray) const {
        return trace<Policy, false>(ray, "intersect");
    }
    /// Whether anything blocks `ray` within [tmin, tmax] (stops at the first hit). Throws
    /// std::logic_error when the scene changed since the last commit().
    template <class Policy = trace::robust>
    bool occluded(const Ray<scalar_type>& ray) const {
        return bool(trace<Policy, true>(ray, "occluded"));
    }

    /// Closest hits of the active lanes of `packet` (bit k of `active`; bits from N on are ignored): lane
    /// k is, bit for bit, `intersect<Policy>(packet.ray(k))`; inactive lanes get the miss value. Float
    /// scenes with box::robust trace the top level as a packet (packet.hpp's traversal) and, at each
    /// instance, the lanes that reach it as one object-space packet through the object's tree; other
    /// cases trace ray by ray. Throws std::logic_error when the scene changed since the last commit().
    template <class Policy = trace::robust, int N>
    InstanceHitPacket<scalar_type, N> intersect(const RayPacket<scalar_type, N>& packet, std::uint32_t active = all_lanes<N>,
                                                const PacketConfig& cfg = {}) const {
        InstanceHitPacket<scalar_type, N> out;
        trace_packet<Policy, false>(packet, active & all_lanes<N>, cfg, out, "intersect");
        return out;
    }
    /// Any-hit query of the active lanes of `packet`: bit k is set when lane k is active and
    /// `occluded<Policy>(packet.ray(k))` is true. Throws std::logic_error when the scene changed since
    /// the last commit().
    template <class Policy = trace::robust, int N>
    std::uint32_t occluded(const RayPacket<scalar_type, N>& packet, std::uint32_t active = all_lanes<N>,
                           const PacketConfig& cfg = {}) const {
        InstanceHitPacket<scalar_type, N> out;
        trace_packet<Policy, true>(packet, active & all_lanes<N>, cfg, out, "occluded");
        return out.hit_mask();
    }

    /// Reference closest hit: every instance in order, its object ray (object_ray), every triangle of
    /// its object with Policy's triangle test, tmax narrowing to the best t (O(all instanced triangles)).
    template <class Policy = trace::robust>
    InstanceHit<scalar_type> brute_force_intersect(const Ray<scalar_type>& ray) const {
        InstanceHit<scalar_type> best;
        if (!traceable(ray)) return best;
        scalar_type tmax = ray.tmax;
        for (std::size_t k = 0; k < instances_.size(); ++k) {
            const Ray<scalar_type> r = object_ray(inverses_[k], Ray<scalar_type>{ray.org, ray.dir, ray.tmin, tmax});
            const Hit<scalar_type> h = objects_[instances_[k].object].visit(
                [&](const auto& tris) { return dynbvh::brute_force_intersect<Policy>(tris, r); });
            if (h) {
                static_cast<Hit<scalar_type>&>(best) = h;
                best.instance = static_cast<std::uint32_t>(k);
                tmax = h.t;
            }
        }
        return best;
    }
    /// Reference any hit (O(all instanced triangles)).
    template <class Policy = trace::robust>
    bool brute_force_occluded(const Ray<scalar_type>& ray) const {
        if (!traceable(ray)) return false;
        for (std::size_t k = 0; k < instances_.size(); ++k)
            if (objects_[instances_[k].object].visit(
                    [&](const auto& tris) { return dynbvh::brute_force_occluded<Policy>(tris, object_ray(inverses_[k], ray)); }))
                return true;
        return false;
    }

    /// Number of objects added.
    std::size_t object_count() const noexcept { return objects_.size(); }
    /// Number of instances (as last set).
    std::size_t instance_count() const noexcept { return instances_.size(); }
    /// Object `object`'s tree (throws std::invalid_argument for a bad id).
    const object_bvh_type& object_bvh(std::uint32_t object) const {
        check_object(object, "object_bvh", "object");
        return objects_[object].policy.bvh();
    }
    /// Object `object`'s triangles as last given as a span. Throws std::invalid_argument for a bad id,
    /// std::logic_error for an object last given as a MeshView (see object_triangle).
    std::span<const triangle_type> object_triangles(std::uint32_t object) const {
        check_object(object, "object_triangles", "object");
        const Object& o = objects_[object];
        if (o.view_index_bits != 0)
            throw std::logic_error("dynbvh::TwoLevel::object_triangles: object " + std::to_string(object) +
                                   " was given as a MeshView; read it with object_triangle_count / object_triangle");
        return o.tris;
    }
    /// Number of triangles of object `object` as last given (span or view).
    std::size_t object_triangle_count(std::uint32_t object) const {
        check_object(object, "object_triangle_count", "object");
        return objects_[object].visit([](const auto& tris) { return tris.size(); });
    }
    /// Triangle i of object `object` as last given (span or view), by value. Throws std::invalid_argument
    /// for a bad id or i.
    triangle_type object_triangle(std::uint32_t object, std::size_t i) const {
        check_object(object, "object_triangle", "object");
        return objects_[object].visit([&](const auto& tris) -> triangle_type {
            if (i >= tris.size())
                throw std::invalid_argument("dynbvh::TwoLevel::object_triangle: i is " + std::to_string(i) + " but object " +
                                            std::to_string(object) + " has " + std::to_string(tris.size()) + " triangles");
            return tris[i];
        });
    }
    /// The instances as last given (with the latest transforms).
    std::span<const Instance<scalar_type>> instances() const noexcept { return instances_; }
    /// Instance i's world-to-object transform, as object_ray uses it.
    const Affine<scalar_type>& inverse_transform(std::size_t i) const { return inverses_.at(i); }
    /// The top-level tree of the last commit().
    const top_bvh_type& top() const noexcept { return top_; }
    /// Whether commit() has seen every change.
    bool committed() const noexcept { return !dirty_; }

private:
    /// An object: its policy, its triangles as a span or a view (view_index_bits 16 or 32; 0: span), and
    /// its traced tree.
    struct Object {
        object_policy policy;
        std::span<const triangle_type> tris;
        MeshView<scalar_type, std::uint16_t> view16;
        MeshView<scalar_type, std::uint32_t> view32;
        int view_index_bits = 0;
        object_traced_type traced;   ///< policy.bvh() in the traced layout, remade after every update

        /// f(the object's triangle source): the span or the view.
        template <class F>
        decltype(auto) visit(const F& f) const {
            if (view_index_bits == 16) return f(view16);
            if (view_index_bits == 32) return f(view32);
            return f(tris);
        }
        void set(std::span<const triangle_type> t) {
            tris = t;
            view_index_bits = 0;
        }
        void set(const MeshView<scalar_type, std::uint16_t>& m) {
            view16 = m;
            tris = {};
            view_index_bits = 16;
        }
        void set(const MeshView<scalar_type, std::uint32_t>& m) {
            view32 = m;
            tris = {};
            view_index_bits = 32;
        }
    };
    /// Remakes o.traced from the object's tree (once for a rigid object; per update for a deformed one).
    void retrace(Object& o) {
        if constexpr (std::is_same_v<typename NodeT::scalar_type, float>)
            o.traced = o.visit([&](const auto& tris) { return make_wide_blocks<8>(o.policy.bvh(), tris, ex_); });
        else o.traced = make_wide<8>(o.policy.bvh(), ex_);
    }
    /// add_object over a span or a view.
    template <class Source>
    std::uint32_t add(const Source& tris) {
        if (objects_.size() >= std::size_t(invalid_prim))
            throw std::length_error("dynbvh::TwoLevel::add_object: too many objects");
        Object o{object_policy(cfg_.objects, ex_), {}, {}, {}, 0, {}};
        o.policy.update(tris);
        o.set(tris);
        retrace(o);
        objects_.push_back(std::move(o));
        dirty_ = true;
        return static_cast<std::uint32_t>(objects_.size() - 1);
    }
    /// update_object over a span or a view.
    template <class Source>
    FrameReport update(std::uint32_t object, const Source& tris) {
        check_object(object, "update_object", "object");
        Object& o = objects_[object];
        FrameReport r = o.policy.update(tris);
        o.set(tris);
        retrace(o);
        dirty_ = true;
        return r;
    }
    struct Entry {
        typename NodeT::index_type node;
        double enter;
    };

    void check_object(std::uint32_t object, const char* fn, const char* arg) const {
        if (object >= objects_.size())
            throw std::invalid_argument(std::string("dynbvh::TwoLevel::") + fn + ": " + arg + " is " + std::to_string(object) +
                                        " but the scene has " + std::to_string(objects_.size()) + " objects");
    }

    /// The padded world box of object box `b` under `m` (inverse `inv`), rounded outward to T; `alpha`
    /// receives the instance's reach widening (see the file comment).
    static AABB<scalar_type> world_box(const AABB<scalar_type>& b, const Affine<scalar_type>& m,
                                       const Affine<scalar_type>& inv, double& alpha, std::size_t i) {
        using T = scalar_type;
        double lo[3] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                        std::numeric_limits<double>::infinity()};
        double hi[3] = {-lo[0], -lo[0], -lo[0]};
        for (unsigned corner = 0; corner < 8; ++corner) {
            const double p[3] = {double(corner & 1 ? b.max.x : b.min.x), double(corner & 2 ? b.max.y : b.min.y),
                                 double(corner & 4 ? b.max.z : b.min.z)};
            for (std::size_t r = 0; r < 3; ++r) {
                const auto e = [&](std::size_t c) { return double(m.m[4 * r + c]); };
                const double w = e(0) * p[0] + e(1) * p[1] + e(2) * p[2] + e(3);
                lo[r] = std::min(lo[r], w);
                hi[r] = std::max(hi[r], w);
            }
        }
        double big = 0, extent = 0;
        for (std::size_t r = 0; r < 3; ++r) {
            big = std::max({big, std::abs(lo[r]), std::abs(hi[r])});
            extent = std::max(extent, hi[r] - lo[r]);
        }
        const double nl = detail::linear_norm(m), na = detail::linear_norm(inv);
        const double c = std::max({std::abs(double(inv.m[3])), std::abs(double(inv.m[7])), std::abs(double(inv.m[11]))});
        const double k = 256.0 * double(std::numeric_limits<T>::epsilon()) * 0.5;
        const double kappa = nl * na;
        const double pad = k * (nl * (na * big + c) + kappa * extent + big) + 16.0 * double(std::numeric_limits<T>::min());
        alpha = k * (kappa + 1);
        return outward(lo, hi, pad, i);
    }
    /// The box [lo - e, hi + e] (double corners) rounded outward to T; std::invalid_argument naming instance
    /// `i` when it overflows T.
    static AABB<scalar_type> outward(const double* lo, const double* hi, double e, std::size_t i) {
        using T = scalar_type;
        AABB<T> out;
        constexpr T tinf = std::numeric_limits<T>::infinity();
        for (std::size_t r = 0; r < 3; ++r) {
            const double l = lo[r] - e, h = hi[r] + e;
            T lt = T(l), ht = T(h);
            if (double(lt) > l) lt = std::nextafter(lt, -tinf);
            if (double(ht) < h) ht = std::nextafter(ht, tinf);
            if (!std::isfinite(lt) || !std::isfinite(ht))
                throw std::invalid_argument("dynbvh::TwoLevel::commit: the world box of instance " + std::to_string(i) +
                                            " overflows the scalar type");
            out.min[r] = lt;
            out.max[r] = ht;
        }
        return out;
    }

    /// The largest |coordinate| of box `b`.
    static double largest_coordinate(const AABB<scalar_type>& b) noexcept {
        double m = 0;
        for (std::size_t r = 0; r < 3; ++r) m = std::max({m, std::abs(double(b.min[r])), std::abs(double(b.max[r]))});
        return m;
    }
    /// Box `b` grown by `e` on every side, rounded outward to T (std::invalid_argument for instance `i` on overflow).
    static AABB<scalar_type> grown(const AABB<scalar_type>& b, double e, std::size_t i) {
        const double lo[3] = {double(b.min.x), double(b.min.y), double(b.min.z)}, hi[3] = {double(b.max.x), double(b.max.y), double(b.max.z)};
        return outward(lo, hi, e, i);
    }

    /// Instance k at a top-level leaf: the object ray (object_ray) against the object's traced tree with
    /// the closest t so far; a closest hit narrows `tmax` and goes to `best`. AnyHit: true once one is found.
    template <class Policy, bool AnyHit>
    DYNBVH_ALWAYS_INLINE bool test_instance(std::uint32_t k, const Ray<scalar_type>& ray, scalar_type& tmax,
                                            InstanceHit<scalar_type>& best) const {
        const Object& obj = objects_[instances_[k].object];
        const Ray<scalar_type> r = object_ray(inverses_[k], Ray<scalar_type>{ray.org, ray.dir, ray.tmin, tmax});
        if constexpr (AnyHit) {
            if (!obj.visit([&](const auto& tris) { return dynbvh::occluded<Policy>(obj.traced, tris, r); })) return false;
            best.prim = 0;
            best.instance = k;
            return true;
        } else {
            const Hit<scalar_type> h = obj.visit([&](const auto& tris) { return dynbvh::intersect<Policy>(obj.traced, tris, r); });
            if (h && takes(h.t, tmax, k, best.instance)) {
                static_cast<Hit<scalar_type>&>(best) = h;
                best.instance = k;
                tmax = h.t;
            }
            return false;
        }
    }

    /// Whether a hit at t (<= tmax, the closest so far) in instance k replaces the closest so far, in
    /// instance `best` (invalid_prim: none): a closer one, or at the same t a larger instance index, as
    /// brute force's order gives; so the answer does not depend on the order instances are visited in.
    static DYNBVH_ALWAYS_INLINE bool takes(scalar_type t, scalar_type tmax, std::uint32_t k, std::uint32_t best) noexcept {
        return t < tmax || best == invalid_prim || k > best;
    }

    /// The float top level (top8_, boxes grown by the reach widening, see commit()): 8-wide near-first
    /// traversal with the robust slab test (traverse_wide.hpp's box test), one octant.
    template <class Policy, bool AnyHit, int Oct>
    void trace_top8(const Ray<float>& ray, const detail::WideBoxTest<box::robust, float, 8>& wb, float t_scale,
                    InstanceHit<float>& best) const {
        using Index = typename NodeT::index_type;
        using WideEntry = detail::WideStackEntry<Index, float>;
        WideEntry stack[7 * (max_depth + 1)];   // depth < max_depth checked by the caller
        std::size_t sp = 0;
        float tmax = ray.tmax, tbox = tmax * t_scale;
        Index cur = 0, cur_count = 0;
        for (;;) {
            if (cur_count == 0) {
                const auto& n = top8_.nodes[cur];
                alignas(32) float t[8];
                const unsigned mask = wb.template test<Oct>(n, tbox, t);
                if (mask != 0) {   // the stack holds 7 entries per level: always room
                    detail::descend_nearest(n, mask, t, stack, sp, sizeof stack / sizeof stack[0], cur, cur_count);
                    continue;
                }
            } else {
                for (std::size_t s = cur; s < std::size_t(cur) + cur_count; ++s)
                    if (test_instance<Policy, AnyHit>(static_cast<std::uint32_t>(top8_.prim_ids[s]), ray, tmax, best)) return;
                tbox = tmax * t_scale;
            }
            WideEntry next;
            if (!detail::pop_closer<box::robust>(stack, sp, tbox, next)) return;
            cur = next.child;
            cur_count = next.count;
        }
    }

    /// One ray's constants for the widened slab test on t of one sign (a = alpha for t >= 0, -alpha for
    /// t <= 0): per axis the reciprocals of d + a|d| and d - a|d| (0 where that is 0) and their signs,
    /// computed once per ray so that a box costs multiplications, not divisions.
    struct Reach {
        double inv_lo[3] = {0, 0, 0}, inv_hi[3] = {0, 0, 0};
        signed char s_lo[3] = {0, 0, 0}, s_hi[3] = {0, 0, 0};
        Reach() = default;
        Reach(const double* d, double aD) noexcept {
            for (std::size_t ax = 0; ax < 3; ++ax) {
                const double c1 = d[ax] + aD, c2 = d[ax] - aD;
                s_lo[ax] = c1 > 0 ? 1 : c1 < 0 ? -1 : 0;
                s_hi[ax] = c2 > 0 ? 1 : c2 < 0 ? -1 : 0;
                inv_lo[ax] = s_lo[ax] != 0 ? 1.0 / c1 : 0.0;
                inv_hi[ax] = s_hi[ax] != 0 ? 1.0 / c2 : 0.0;
            }
        }
    };
    /// The widened slab test over t in [t0, t1] (all t of one sign): whether the ray comes within a |t| D
    /// of box `b` for some t there; `enter` = the first such t. The bounds are widened by 2^-48 of
    /// themselves, more than the rounding of a product by a rounded reciprocal, so this never rejects what
    /// the exact slab test accepts (the world boxes are padded far more, see the file comment).
    static DYNBVH_ALWAYS_INLINE bool reach(const AABB<scalar_type>& b, const double* o, const Reach& R, double t0, double t1,
                                           double& enter) noexcept {
        constexpr double widen = 0x1p-48;
        for (std::size_t ax = 0; ax < 3; ++ax) {
            // lo - a|t|D <= o + t d   <=>   t (d + aD) >= lo - o
            const double r1 = double(b.min[ax]) - o[ax];
            if (R.s_lo[ax] > 0) {
                const double t = r1 * R.inv_lo[ax];
                t0 = std::max(t0, t - std::abs(t) * widen);
            } else if (R.s_lo[ax] < 0) {
                const double t = r1 * R.inv_lo[ax];
                t1 = std::min(t1, t + std::abs(t) * widen);
            } else if (r1 > 0) {
                return false;
            }
            // o + t d <= hi + a|t|D   <=>   t (d - aD) <= hi - o
            const double r2 = double(b.max[ax]) - o[ax];
            if (R.s_hi[ax] > 0) {
                const double t = r2 * R.inv_hi[ax];
                t1 = std::min(t1, t + std::abs(t) * widen);
            } else if (R.s_hi[ax] < 0) {
                const double t = r2 * R.inv_hi[ax];
                t0 = std::max(t0, t - std::abs(t) * widen);
            } else if (r2 < 0) {
                return false;
            }
        }
        enter = t0;
        return t0 <= t1;
    }
    /// Whether the ray may reach box `b` within [tmin, tmax] (conservative; see the file comment).
    /// `neg` / `pos`: the ray's Reach for t <= 0 and t >= 0.
    static DYNBVH_ALWAYS_INLINE bool visit(const AABB<scalar_type>& b, const double* o, const Reach& neg, const Reach& pos,
                                           double tmin, double tmax, double& enter) noexcept {
        bool hit = false;
        enter = std::numeric_limits<double>::infinity();
        double e;
        if (tmin < 0 && reach(b, o, neg, tmin, std::min(tmax, 0.0), e)) {
            hit = true;
            enter = e;
        }
        if (tmax >= 0 && reach(b, o, pos, std::max(tmin, 0.0), tmax, e)) {
            if (!hit) enter = e;
            hit = true;
        }
        return hit;
    }

    template <class Policy, bool AnyHit>
    InstanceHit<scalar_type> trace(const Ray<scalar_type>& ray, const char* fn) const {
        using T = scalar_type;
        using Index = typename NodeT::index_type;
        if (dirty_)
            throw std::logic_error(std::string("dynbvh::TwoLevel::") + fn +
                                   ": the scene changed since the last commit(); call commit() first");
        InstanceHit<T> best;
        if (top_.empty() || !traceable(ray)) return best;
        if constexpr (std::is_same_v<T, float>) {
            // The float top level, for origins within the boxes' reach bound (the common case).
            const double og = std::max({std::abs(double(ray.org.x)), std::abs(double(ray.org.y)), std::abs(double(ray.org.z))});
            if (og <= origin_bound_ && top8_.depth < max_depth) {
                auto run = [&](const detail::WideBoxTest<box::robust, float, 8>& wb, float t_scale, int octant) {
                    detail::dispatch_octant(octant, [&](auto oct) {
                        trace_top8<Policy, AnyHit, decltype(oct)::value>(ray, wb, t_scale, best);
                        return 0;
                    });
                };
#if defined(DYNBVH_SSE)
                bool ok;
                int octant;
                const detail::WideBoxTest<box::robust, float, 8> fast(ray, ok, octant);   // the common ray's setup
                if (ok) [[likely]] {
                    run(fast, 1.0f, octant);
                    return best;
                }
#endif
                const box::robust::prepared<float> pb(ray);
                run(detail::WideBoxTest<box::robust, float, 8>(pb), pb.t_scale, pb.octant);
                return best;
            }
        }
        const double o[3] = {double(ray.org.x), double(ray.org.y), double(ray.org.z)};
        const double d[3] = {double(ray.dir.x), double(ray.dir.y), double(ray.dir.z)};
        const double D = std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])});
        const double tmin = double(ray.tmin);
        const Reach pos(d, alpha_ * D);
        const Reach neg = tmin < 0 ? Reach(d, -alpha_ * D) : Reach{};   // only used for t < 0
        T tmax = ray.tmax;
        double enter;
        if (!visit(top_.nodes[0].bounds(), o, neg, pos, tmin, double(tmax), enter)) return best;

        Entry fixed[max_depth + 1];
        std::vector<Entry> heap;
        Entry* stack = fixed;
        if (top_.depth > max_depth) {   // never for our builders; a heap stack as large as the tree otherwise
            heap.resize(top_.nodes.size());
            stack = heap.data();
        }
        std::size_t sp = 0;
        Index cur = 0;
        for (;;) {
            const NodeT& n = top_.nodes[cur];
            bool descend = false;
            if (!n.is_leaf()) {
                double e0, e1;
                const bool h0 = visit(top_.nodes[n.left()].bounds(), o, neg, pos, tmin, double(tmax), e0);
                const bool h1 = visit(top_.nodes[n.right()].bounds(), o, neg, pos, tmin, double(tmax), e1);
                if (h0 && h1) {
                    const bool second = e1 < e0;
                    stack[sp++] = second ? Entry{n.left(), e0} : Entry{n.right(), e1};
                    cur = second ? n.right() : n.left();
                    descend = true;
                } else if (h0 || h1) {
                    cur = h0 ? n.left() : n.right();
                    descend = true;
                }
            } else {
                for (std::size_t s = n.index; s < std::size_t(n.index) + n.count; ++s)
                    if (test_instance<Policy, AnyHit>(static_cast<std::uint32_t>(top_.prim_ids[s]), ray, tmax, best)) return best;
            }
            if (descend) continue;
            // Pop the next subtree the ray may still reach before the best hit.
            bool found = false;
            while (sp != 0) {
                const Entry e = stack[--sp];
                if (e.enter <= double(tmax)) {
                    cur = e.node;
                    found = true;
                    break;
                }
            }
            if (!found) return best;
        }
    }

    /// The packet query (see intersect(packet)): out (all misses on entry) gets every active lane's answer.
    template <class Policy, bool AnyHit, int N>
    void trace_packet(const RayPacket<scalar_type, N>& packet, std::uint32_t active, const PacketConfig& cfg,
                      InstanceHitPacket<scalar_type, N>& out, const char* fn) const {
        if (dirty_)
            throw std::logic_error(std::string("dynbvh::TwoLevel::") + fn +
                                   ": the scene changed since the last commit(); call commit() first");
        if (top_.empty()) return;
        std::uint32_t alone = active;   // the lanes traced ray by ray
#if defined(DYNBVH_SSE)
        if constexpr (std::is_same_v<scalar_type, float> && std::is_same_v<typename Policy::box_test, box::robust>)
            alone = trace_top_packet<Policy, AnyHit>(packet, active, cfg, out);
#endif
        (void)cfg;
        for (std::uint32_t c = alone; c != 0; c &= c - 1) {
            const int k = std::countr_zero(c);
            out.set(k, trace<Policy, AnyHit>(packet.ray(k), fn));
        }
    }

#if defined(DYNBVH_SSE)
    /// The lanes of `m` of the world packet `p`, with the closest t so far `tmax` per lane, in object space
    /// by `inv`, into `op`: object_ray's operations lane for lane, so the same bits. With FMA in hardware
    /// every lane is transformed at once (a vector fma rounds as std::fma does), the lanes outside m too
    /// (they hold the packet's own rays, so op stays defined); without, lane by lane.
    template <int N>
    static DYNBVH_ALWAYS_INLINE void object_packet(const Affine<float>& inv, const RayPacket<float, N>& p, const float* tmax,
                                                   std::uint32_t m, RayPacket<float, N>& op) noexcept {
#if defined(__FMA__)
        using V = detail::packet_lanes<N>;   // (AVX-512: 16 lanes a step for packets of 16 and 32)
        using R = typename V::reg;
        const R m0 = V::set1(inv.m[0]), m1 = V::set1(inv.m[1]), m2 = V::set1(inv.m[2]), m3 = V::set1(inv.m[3]);
        const R m4 = V::set1(inv.m[4]), m5 = V::set1(inv.m[5]), m6 = V::set1(inv.m[6]), m7 = V::set1(inv.m[7]);
        const R m8 = V::set1(inv.m[8]), m9 = V::set1(inv.m[9]), m10 = V::set1(inv.m[10]), m11 = V::set1(inv.m[11]);
        const R zero = V::set1(0.0f);
        for (int o = 0; o < N; o += V::n) {
            // Affine::point and Affine::vector: fma(m0, x, fma(m1, y, fma(m2, z, m3 or 0))) per row
            const R x = V::load(p.org_x + o), y = V::load(p.org_y + o), z = V::load(p.org_z + o);
            V::store(op.org_x + o, V::madd(m0, x, V::madd(m1, y, V::madd(m2, z, m3))));
            V::store(op.org_y + o, V::madd(m4, x, V::madd(m5, y, V::madd(m6, z, m7))));
            V::store(op.org_z + o, V::madd(m8, x, V::madd(m9, y, V::madd(m10, z, m11))));
            const R dx = V::load(p.dir_x + o), dy = V::load(p.dir_y + o), dz = V::load(p.dir_z + o);
            V::store(op.dir_x + o, V::madd(m0, dx, V::madd(m1, dy, V::madd(m2, dz, zero))));
            V::store(op.dir_y + o, V::madd(m4, dx, V::madd(m5, dy, V::madd(m6, dz, zero))));
            V::store(op.dir_z + o, V::madd(m8, dx, V::madd(m9, dy, V::madd(m10, dz, zero))));
            V::store(op.tmin + o, V::load(p.tmin + o));
            V::store(op.tmax + o, V::load(tmax + o));
        }
        (void)m;
#else
        for (std::uint32_t c = m; c != 0; c &= c - 1) {
            const int j = std::countr_zero(c);
            op.set(j, object_ray(inv, Ray<float>{{p.org_x[j], p.org_y[j], p.org_z[j]}, {p.dir_x[j], p.dir_y[j], p.dir_z[j]},
                                                 p.tmin[j], tmax[j]}));
        }
#endif
    }

    /// The top level as a packet: packet.hpp's traversal of top8_ (by octant groups; a coherent group tests
    /// inner nodes by one interval test, leaf boxes ray by ray with box::robust's operations, as
    /// trace_top8; other groups every box ray by ray) down to every leaf it reaches; at a leaf, the lanes
    /// that reach its instance go into the object's space together (object_ray, lane by lane) and through
    /// the object's traced tree as one packet with their closest t so far. Returns the lanes left to the
    /// single-ray path: rays the packet set-up does not take (packet.hpp's classify), origins beyond the
    /// float top level's reach bound, groups of fewer than max(cfg.min_rays, 2) rays, and every ray when
    /// the top level is deeper than the packet's fixed stack.
    template <class Policy, bool AnyHit, int N>
    std::uint32_t trace_top_packet(const RayPacket<float, N>& packet, std::uint32_t active, const PacketConfig& cfg,
                                   InstanceHitPacket<float, N>& out) const {
        using TopNode = WideNode<float, typename NodeT::index_type, 8>;
        using I = typename NodeT::index_type;
        // The top level tests no triangle: moller_trumbore only makes the groups by octant alone.
        using PT = detail::PacketTraversal<tri::moller_trumbore, AnyHit, TopNode, prim::indexed, N>;
        static_assert(object_traced_type::block_lanes > 0, "float objects are traced through block trees");
        if (top8_.depth >= PT::fixed_levels) return active;   // (never for our builders: 8-wide levels of instances)
        // The top level's state per lane (closest t, u, v, triangle so far) is `out` itself (all misses on
        // entry), and out.instance the instance of each lane's closest hit.
        PT st(top8_, {}, packet, cfg, out);
        std::uint32_t packable = st.classify(active);
        {   // the float top level's origin bound: |org| <= origin_bound_ in double is |org| <= its float floor
            using V = typename PT::V;
            const typename PT::R bound = V::set1(origin_bound_f_);
            std::uint32_t near = 0;
            for (int o = 0; o < N; o += V::n) {
                const auto big = V::max(V::abs(V::load(packet.org_x + o)), V::max(V::abs(V::load(packet.org_y + o)), V::abs(V::load(packet.org_z + o))));
                near |= V::bits(V::le(big, bound)) << o;
            }
            packable &= near;
        }
        std::uint32_t alone = active & ~packable;
        std::uint32_t* const inst = out.instance;
        // The object-space packet, reused at every instance: only the lanes of m are set and read there
        // (the others hold default or earlier rays, so the packet set-up's SIMD reads stay defined).
        RayPacket<float, N> op;
        // A leaf slot: each instance against the lanes of m that reach it, as one object-space packet.
        const auto leaf = [&](I first, I count, std::uint32_t m) {
            for (std::size_t s = first; s < std::size_t(first) + count; ++s) {
                if constexpr (AnyHit) {
                    m &= st.alive;
                    if (m == 0) return;
                }
                const auto k = static_cast<std::uint32_t>(top8_.prim_ids[s]);
                object_packet(inverses_[k], packet, st.tmax, m, op);
                HitPacket<float, N> h;
                detail::packet_query<Policy, AnyHit>(objects_[instances_[k].object].traced, std::span<const Triangle<float>>(), op, m,
                                                     cfg, h);
                for (std::uint32_t c = h.hit_mask() & m; c != 0; c &= c - 1) {
                    const int j = std::countr_zero(c);
                    if constexpr (!AnyHit)
                        if (!takes(h.t[j], st.tmax[j], k, inst[j])) continue;
                    st.take(j, h.t[j], h.u[j], h.v[j], AnyHit ? 0u : h.prim[j]);
                    inst[j] = k;
                }
            }
        };
        // (the fixed stacks hold top8_.depth < PT::fixed_levels, checked above; one of them is used)
        union Stacks {
            Stacks() noexcept {}
            typename PT::Entry rays[PT::fixed_cap];                  // run: per-ray entry distances
            detail::IntervalEntry<typename PT::I> group[PT::fixed_cap];   // run_interval: one bound per entry
        } stack;
        return alone | st.for_each_group(packable, cfg.min_rays, [&](std::uint32_t g, auto o) {
            constexpr int Oct = decltype(o)::value;
            // A coherent group: inner nodes by one interval test for the whole group (packet.hpp); else ray by ray.
            const bool ok = st.coherent && cfg.interval ? st.template run_interval<Oct>(g, stack.group, PT::fixed_cap, leaf)
                                                        : st.template run<Oct, false>(g, stack.rays, PT::fixed_cap, leaf);
            return ok;   // false: a top level deeper than its depth field; these rays go alone (out.set)
        });
    }
#endif

    config_type cfg_;
    Exec ex_;
    std::vector<Object> objects_;
    std::vector<Instance<scalar_type>> instances_;
    std::vector<Affine<scalar_type>> inverses_;
    top_bvh_type top_;
    WideBvh<WideNode<scalar_type, typename NodeT::index_type, 8>, prim::indexed> top8_;   // float: top_ 8-wide
    double alpha_ = 0;        // largest reach widening over the instances (see the file comment)
    double origin_bound_ = 0; // rays with |org| up to this take the float top level (top8_)
    float origin_bound_f_ = 0; // the largest float <= origin_bound_
    bool dirty_ = false;
};

} // namespace dynbvh
