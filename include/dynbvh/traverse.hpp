// SPDX-License-Identifier: MIT
/// @file traverse.hpp
/// Closest-hit and any-hit queries of one ray against any `Bvh`, with the box and triangle tests
/// chosen at compile time:
/// @code
///   auto hit = dynbvh::intersect(bvh, tris, ray);                      // closest hit, robust tests
///   bool occ = dynbvh::occluded<dynbvh::trace::fast>(bvh, tris, ray);  // any hit, fast tests
///   using mixed = dynbvh::trace::policy<dynbvh::box::fast, dynbvh::tri::watertight>;
/// @endcode
/// Traversal is single-ray, near child first: at an inner node both children's boxes are tested, the
/// ray descends into the nearer and pushes the farther (with its entry distance, so it is skipped once
/// a closer hit is known) on a fixed stack of `max_depth` entries. The builders guarantee
/// `bvh.depth <= max_depth`; a deeper tree, or one whose `depth` is wrong, is traced with a heap stack
/// as large as the tree: never an overflow. The loop is compiled once per direction octant (the box
/// test's near/far planes are chosen at compile time). No allocation for valid trees, no virtual
/// calls. Rays that are not `traceable` (NaN or infinite origin or direction, zero direction, NaN or
/// empty [tmin, tmax]) hit nothing.
///
/// Exactness: trace::robust is built so that `intersect` returns what `brute_force_intersect` returns
/// (same t, u, v to the bit and the same triangle): the box test is conservative by a margin larger
/// than the error of the triangle test's t, and exact ties (two triangles hit at exactly the same t)
/// go to the larger triangle index whatever the visit order (detail::replaces_hit; boxes entered at
/// exactly the current tmax are still visited). tests/test_traverse.cpp
/// checks this on rays through vertices and edges, axis-parallel rays with +-0 components and grazing
/// rays over overlapping coplanar triangles far from the origin (an empirical check, not a proof).
/// box::fast may lose hits that only graze a box.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "bvh.hpp"
#include "detail/check_triangles.hpp"
#include "detail/triangle_source.hpp"
#include "intersect.hpp"
#include "mesh.hpp"

namespace dynbvh {

namespace trace {
/// A traversal policy: one box test (namespace box) and one triangle test (namespace tri).
template <class Box, class Tri>
struct policy {
    /// The box test (namespace box).
    using box_test = Box;
    /// The triangle test (namespace tri).
    using triangle_test = Tri;
};
/// Default: no hit lost to rounding, watertight triangles (Ize 2013 + Woop et al. 2013).
using robust = policy<box::robust, tri::watertight>;
/// Fastest: plain slab test + Möller–Trumbore.
using fast = policy<box::fast, tri::moller_trumbore>;
} // namespace trace

namespace detail {

template <class Index, class T>
struct StackEntry {
    Index node;
    T tentry;  ///< entry distance of the node's box, to skip it once a closer hit is known
};

/// Tests the triangles of leaf slots [first, end) (slot i is triangle leaf_tris[ids[i]], or leaf_tris[i]
/// for prim::copied trees; leaf_tris is what leaf_triangles_of gives: a pointer, or a MeshView). Each
/// hit that replaces the closest so far (replaces_hit) narrows tmax and tbox = tmax * t_scale (the box
/// tests' units) and is kept in `hit` and `best_prim`; with AnyHit the first hit sets hit.prim and
/// returns true (stop). Shared by the binary and the wide traversal (wide.hpp).
template <class Tri, bool AnyHit, bool Precomputed, class T, class Index, class LeafTris>
DYNBVH_ALWAYS_INLINE bool test_leaf(const typename Tri::template prepared<T>& pt, const LeafTris leaf_tris,
                                    const Index* ids, std::size_t first, std::size_t end, T t_scale, T& tmax, T& tbox,
                                    std::uint32_t& best_prim, Hit<T>& hit) {
    for (std::size_t slot = first; slot < end; ++slot) {
        const Triangle<T>& tri = Precomputed ? leaf_tris[slot] : leaf_tris[ids[slot]];
        T t, u, v;
        if (Tri::test(pt, tri, tmax, t, u, v) &&
            record_hit<AnyHit>(t, u, v, static_cast<std::uint32_t>(ids[slot]), t_scale, tmax, tbox, best_prim, hit))
            return true;
    }
    return false;
}

/// Pops stack entries until one whose box can still hold a hit at or before `tbox` (box units: an
/// entry is skipped only when it starts strictly farther, so a tie at exactly tmax is still found) and
/// stores it in `next`; false when the stack is empty (the traversal is done). Shared by the binary
/// and the wide traversal loop.
template <class Box, class Entry, class T>
DYNBVH_ALWAYS_INLINE bool pop_closer(const Entry* stack, std::size_t& sp, T tbox, Entry& next) noexcept {
    while (sp != 0) {
        next = stack[--sp];
        if (Box::before(next.tentry, tbox)) return true;
    }
    return false;
}

/// Runs `run(stack, cap, hit)`, a traversal that returns false when its stack of `cap` entries would
/// overflow: on a fixed stack of FixedCap entries when `fits`; else, or after an overflow (a tree whose
/// `depth` field is wrong), on a heap stack of `heap_entries`, which the caller sizes so that no
/// traversal can overflow it. Shared by the binary and the wide traversal.
template <class Entry, std::size_t FixedCap, class T, class Run>
DYNBVH_ALWAYS_INLINE Hit<T> run_with_stack(bool fits, std::size_t heap_entries, Run&& run) {
    if (fits) {
        Entry stack[FixedCap];
        Hit<T> hit;
        if (run(stack, FixedCap, hit)) [[likely]] return hit;
    }
    std::vector<Entry> heap(heap_entries);
    Hit<T> hit;
    run(heap.data(), heap.size(), hit);
    return hit;
}

/// The one traversal loop, for one ray direction octant `Oct` (box tests without run-time sign
/// selects). `AnyHit` stops at the first hit. Returns false when the stack of `cap` entries would
/// overflow (only possible for a tree whose `depth` field understates its depth); `hit` is then
/// meaningless and the caller retries with a stack that cannot overflow.
template <class Policy, bool AnyHit, int Oct, class NodeT, class Prim, class Source>
bool traverse_octant(const Bvh<NodeT, Prim>& bvh, const Source tris,
                     // by value: local copies the compiler can keep in registers (stores to the stack
                     // could alias a reference)
                     const typename Policy::box_test::template prepared<typename NodeT::scalar_type> pb,
                     const typename Policy::triangle_test::template prepared<typename NodeT::scalar_type> pt,
                     typename NodeT::scalar_type tmax, Hit<typename NodeT::scalar_type>& hit,
                     StackEntry<typename NodeT::index_type, typename NodeT::scalar_type>* const stack, const std::size_t cap) {
    using T = typename NodeT::scalar_type;
    using Index = typename NodeT::index_type;
    using Box = typename Policy::box_test;
    using Tri = typename Policy::triangle_test;

    const NodeT* const nodes = bvh.nodes.data();
    const Index* const ids = bvh.prim_ids.data();
    const auto leaf_tris = leaf_triangles_of(bvh, tris);

    std::size_t sp = 0;
    std::uint32_t best_prim = invalid_prim;
    Index cur = 0;
    T tbox = tmax * pb.t_scale;  // tmax in the box test's units (see box::robust)
    for (;;) {
        const NodeT& n = nodes[cur];
        if (!n.is_leaf()) {
            const Index c0 = n.index, c1 = n.index + 1;
            const NodeT& n0 = nodes[c0];
            const NodeT& n1 = nodes[c1];
            T d0, d1;
            const bool h0 = Box::template test_octant<Oct>(pb, n0.min, n0.max, tbox, d0);
            const bool h1 = Box::template test_octant<Oct>(pb, n1.min, n1.max, tbox, d1);
            if (h0 && h1) {
                if (sp == cap) [[unlikely]] return false;
                const bool second = d1 < d0;
                stack[sp++] = second ? StackEntry<Index, T>{c0, d0} : StackEntry<Index, T>{c1, d1};
                cur = second ? c1 : c0;
                continue;
            }
            if (h0 || h1) {
                cur = h0 ? c0 : c1;
                continue;
            }
        } else {
            if (test_leaf<Tri, AnyHit, Bvh<NodeT, Prim>::precomputed>(pt, leaf_tris, ids, n.index, std::size_t(n.index) + n.count,
                                                                    T(pb.t_scale), tmax, tbox, best_prim, hit))
                return true;
        }
        // Pop the next subtree that can still hold a closer hit.
        StackEntry<Index, T> next;
        if (!pop_closer<Box>(stack, sp, tbox, next)) {
            hit.prim = best_prim;
            return true;
        }
        cur = next.node;
    }
}

template <class Policy, bool AnyHit, class NodeT, class Prim, class Source>
Hit<typename NodeT::scalar_type> traverse(const Bvh<NodeT, Prim>& bvh, const Source tris, const Ray<typename NodeT::scalar_type>& ray) {
    using T = typename NodeT::scalar_type;
    using Index = typename NodeT::index_type;
    using Box = typename Policy::box_test;
    using Tri = typename Policy::triangle_test;
    using Entry = StackEntry<Index, T>;

    if (bvh.nodes.empty() || !traceable(ray)) return {};
    const typename Box::template prepared<T> pb(ray);
    const typename Tri::template prepared<T> pt(ray);
    T troot;
    if (!Box::test(pb, bvh.nodes[0].min, bvh.nodes[0].max, ray.tmax, troot)) return {};

    auto run = [&](Entry* stack, std::size_t cap, Hit<T>& hit) {
        return dispatch_octant(pb.octant, [&](auto oct) {
            return traverse_octant<Policy, AnyHit, decltype(oct)::value>(bvh, tris, pb, pt, ray.tmax, hit, stack, cap);
        });
    };
    // One entry per level; a deeper tree gets a heap stack as large as the tree (each node is pushed
    // at most once).
    return run_with_stack<Entry, max_depth, T>(bvh.depth <= max_depth, bvh.nodes.size(), run);
}

} // namespace detail

/// Closest hit of `ray` in `bvh` with t in [ray.tmin, ray.tmax]: t, barycentrics (u, v) and the user's
/// triangle index (`Hit::prim`, never a leaf slot or fragment); no hit when `prim == invalid_prim`
/// (`if (hit)`). `tris` is the array the BVH was built over (unused for prim::copied; for
/// prim::indexed a span whose size is not `bvh.primitive_count` throws std::invalid_argument).
/// Cost: O(visited nodes); no allocation unless `bvh.depth > max_depth`.
template <class Policy = trace::robust, class NodeT, class Prim>
Hit<typename NodeT::scalar_type> intersect(const Bvh<NodeT, Prim>& bvh,
                                           std::span<const Triangle<typename NodeT::scalar_type>> tris,
                                           const Ray<typename NodeT::scalar_type>& ray) {
    detail::check_triangles(bvh, tris.size(), "intersect", !Bvh<NodeT, Prim>::precomputed);
    return detail::traverse<Policy, false>(bvh, tris, ray);
}

/// Closest hit over an indexed mesh read in place (mesh.hpp), the tree built over it (or over
/// make_triangles' array of it): the same hit as intersect over that array, bit for bit.
template <class Policy = trace::robust, class NodeT, class Prim, class Index>
Hit<typename NodeT::scalar_type> intersect(const Bvh<NodeT, Prim>& bvh, const MeshView<typename NodeT::scalar_type, Index>& mesh,
                                           const Ray<typename NodeT::scalar_type>& ray) {
    detail::check_triangles(bvh, mesh.size(), "intersect", !Bvh<NodeT, Prim>::precomputed);
    return detail::traverse<Policy, false>(bvh, mesh, ray);
}

/// Whether anything blocks `ray` within [ray.tmin, ray.tmax] (shadow rays): stops at the first hit.
template <class Policy = trace::robust, class NodeT, class Prim>
bool occluded(const Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris,
              const Ray<typename NodeT::scalar_type>& ray) {
    detail::check_triangles(bvh, tris.size(), "occluded", !Bvh<NodeT, Prim>::precomputed);
    return static_cast<bool>(detail::traverse<Policy, true>(bvh, tris, ray));
}

/// Any hit over an indexed mesh read in place (mesh.hpp); the same answer as occluded over make_triangles' array.
template <class Policy = trace::robust, class NodeT, class Prim, class Index>
bool occluded(const Bvh<NodeT, Prim>& bvh, const MeshView<typename NodeT::scalar_type, Index>& mesh,
              const Ray<typename NodeT::scalar_type>& ray) {
    detail::check_triangles(bvh, mesh.size(), "occluded", !Bvh<NodeT, Prim>::precomputed);
    return static_cast<bool>(detail::traverse<Policy, true>(bvh, mesh, ray));
}

namespace detail {
/// Brute force over any triangle source (a span or a MeshView): one code path.
template <class Policy, class T, class Source>
Hit<T> brute_force_intersect_over(const Source tris, const Ray<T>& ray) {
    using Tri = typename Policy::triangle_test;
    Hit<T> hit;
    if (!traceable(ray)) return hit;
    const typename Tri::template prepared<T> pt(ray);
    T tmax = ray.tmax;
    for (std::size_t i = 0; i < tris.size(); ++i) {
        const Triangle<T> tri = tris[i];
        if (!tri.is_finite()) continue;
        T t, u, v;
        if (Tri::test(pt, tri, tmax, t, u, v)) {   // (t == tmax: i is larger, so it wins the tie)
            tmax = t;
            hit = {t, u, v, static_cast<std::uint32_t>(i)};
        }
    }
    return hit;
}
template <class Policy, class T, class Source>
bool brute_force_occluded_over(const Source tris, const Ray<T>& ray) {
    using Tri = typename Policy::triangle_test;
    if (!traceable(ray)) return false;
    const typename Tri::template prepared<T> pt(ray);
    for (std::size_t i = 0; i < tris.size(); ++i) {
        const Triangle<T> tri = tris[i];
        if (!tri.is_finite()) continue;
        T t, u, v;
        if (Tri::test(pt, tri, ray.tmax, t, u, v)) return true;
    }
    return false;
}
} // namespace detail

/// Reference closest hit: every finite triangle is tested with `Policy`'s triangle test (O(n) per ray).
/// Same interval and tie rule as `intersect` (at exactly the same t the larger triangle index wins:
/// here a later triangle replaces the earlier).
/// Triangles with a NaN or infinite vertex are skipped, as the builders exclude them.
template <class Policy = trace::robust, class T>
Hit<T> brute_force_intersect(std::type_identity_t<std::span<const Triangle<T>>> tris, const Ray<T>& ray) {
    return detail::brute_force_intersect_over<Policy>(tris, ray);
}

/// Reference any hit: whether some finite triangle is hit within [tmin, tmax] (O(n) per ray).
template <class Policy = trace::robust, class T>
bool brute_force_occluded(std::type_identity_t<std::span<const Triangle<T>>> tris, const Ray<T>& ray) {
    return detail::brute_force_occluded_over<Policy>(tris, ray);
}

/// Reference closest hit over an indexed mesh read in place (mesh.hpp): what the span of
/// make_triangles(vertices, indices) gives, bit for bit (O(n) per ray).
template <class Policy = trace::robust, class T, class Index>
Hit<T> brute_force_intersect(const MeshView<T, Index>& mesh, const std::type_identity_t<Ray<T>>& ray) {
    return detail::brute_force_intersect_over<Policy>(mesh, ray);
}

/// Reference any hit over an indexed mesh read in place (O(n) per ray).
template <class Policy = trace::robust, class T, class Index>
bool brute_force_occluded(const MeshView<T, Index>& mesh, const std::type_identity_t<Ray<T>>& ray) {
    return detail::brute_force_occluded_over<Policy>(mesh, ray);
}

} // namespace dynbvh
