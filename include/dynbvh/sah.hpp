// SPDX-License-Identifier: MIT
/// @file sah.hpp
/// Tree quality metrics, for comparing builders on the same scene:
///  - `sah_cost`: the surface area heuristic cost of a finished tree (the study's definition),
///  - `epo`: end-point overlap (Aila, Karras, Laine 2013, "On quality metrics of bounding volume
///    hierarchies"), which also sees the overlap between sibling subtrees that SAH ignores.
/// Both are predictors; measured trace time is the truth.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "bvh.hpp"
#include "cost.hpp"
#include "detail/polygon.hpp"
#include "detail/check_triangles.hpp"
#include "executor.hpp"

namespace dynbvh {

template <class WideNodeT, class PrimPolicy>
struct WideBvh;   // wide.hpp

namespace detail {
struct SahSums {
    double inner = 0, leaf = 0;   // sum SA(n) over inner nodes; sum SA(l) * count(l) over leaves
    double inner_n = 0, refs = 0; // number of inner nodes; number of references
    static SahSums combine(const SahSums& a, const SahSums& b) noexcept {
        return {a.inner + b.inner, a.leaf + b.leaf, a.inner_n + b.inner_n, a.refs + b.refs};
    }
};

/// The SAH formula from a tree's sums and its root's area `root` (for a degenerate root, the
/// formula's limit, see sah_cost(Bvh)).
inline double sah_from_sums(const SahSums& s, double root, const SahCost& cfg) noexcept {
    if (!(root > 0)) return cfg.ct * s.inner_n + cfg.ci * s.refs;
    return (cfg.ct * s.inner + cfg.ci * s.leaf) / root;
}

/// The SAH formula over `nodes` (binary or wide): per_node(node)'s sums added up in parallel, divided
/// by the root's area (or its limit for a degenerate root, see sah_cost(Bvh)). 0 for no nodes.
template <class Nodes, class Exec, class PerNode>
double sah_of(const Nodes& nodes, const SahCost& cfg, const Exec& ex, const PerNode& per_node) {
    if (nodes.empty()) return 0.0;
    const SahSums s = ex.reduce(
        std::size_t(0), nodes.size(), SahSums{}, [&](std::size_t i) { return per_node(nodes[i]); },
        [](const SahSums& a, const SahSums& b) { return SahSums::combine(a, b); });
    return sah_from_sums(s, area(nodes[0].bounds()), cfg);
}
} // namespace detail

/// SAH cost = (1 / SA(root)) * (Ct * sum over inner nodes SA(n) + Ci * sum over leaves SA(l) * count(l)),
/// count(l) = references in leaf l, SA = box surface area (computed in double). Every node in
/// `bvh.nodes` counts (a valid tree has no unreachable nodes). An empty tree costs 0. When the root's
/// area is 0 (all geometry on one line or at one point) every box is the root's degenerate box and
/// the limit of the formula is used: Ct * inner nodes + Ci * references. O(nodes), parallel over `ex`.
template <class NodeT, class Prim, class Exec = exec::default_executor>
double sah_cost(const Bvh<NodeT, Prim>& bvh, const SahCost& cfg = {}, const Exec& ex = {}) {
    return detail::sah_of(bvh.nodes, cfg, ex, [](const NodeT& n) {
        const double a = detail::area(n.bounds());
        detail::SahSums r;
        if (n.is_leaf()) {
            r.leaf = a * double(n.count);
            r.refs = double(n.count);
        } else {
            r.inner = a;
            r.inner_n = 1;
        }
        return r;
    });
}

/// SAH cost of a wide tree, the binary definition (sah.hpp) with wide nodes as inner nodes:
/// (1 / SA(root)) * (Ct * sum over wide nodes SA(node) + Ci * sum over leaves SA(l) * count(l)),
/// where SA(node) is the area of the union of its children's boxes (one visit tests all of them).
/// The leaf term equals the binary tree's; the inner term sums a subset of its inner nodes.
/// Degenerate roots as in sah_cost(Bvh). O(nodes), parallel over `ex`.
template <class WN, class P, class Exec = exec::default_executor>
double sah_cost(const WideBvh<WN, P>& wide, const SahCost& cfg = {}, const Exec& ex = {}) {
    return detail::sah_of(wide.nodes, cfg, ex, [](const WN& n) {
        detail::SahSums r;
        r.inner = detail::area(n.bounds());
        r.inner_n = 1;
        for (int k = 0; k < WN::width; ++k) {
            if (n.empty_slot(k) || !n.is_leaf(k)) continue;
            r.leaf += detail::area(n.bounds(k)) * double(n.count[k]);
            r.refs += double(n.count[k]);
        }
        return r;
    });
}

namespace detail {

/// Area of the part of triangle (a, b, c) inside the closed box [lo, hi]: the triangle clipped
/// against the six planes (detail/polygon.hpp), in double. Exact up to double rounding.
inline double clipped_triangle_area(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& lo, const Vec3d& hi) {
    Polygon<double> poly, below, above;
    poly.push(a);
    poly.push(b);
    poly.push(c);
    poly.close();
    for (int axis = 0; axis < 3 && poly.n >= 3; ++axis) {
        split_polygon(poly, axis, lo[std::size_t(axis)], below, above);   // keep x[axis] >= lo
        split_polygon(above, axis, hi[std::size_t(axis)], poly, below);   // keep x[axis] <= hi
    }
    if (poly.n < 3) return 0.0;
    Vec3d sum{};
    for (int i = 1; i + 1 < poly.n; ++i) sum += cross(poly[i] - poly[0], poly[i + 1] - poly[0]);
    return 0.5 * length(sum);
}

} // namespace detail

/// End-point overlap (Aila, Karras, Laine 2013):
///   EPO = (1 / A(S)) * sum over nodes n of C(n) * A( (S \ S(n)) ∩ box(n) ),
/// S = all scene triangles, S(n) = triangles referenced in n's subtree, A = surface area,
/// C(n) = Ct for inner nodes and Ci for leaves. It measures how much surface a ray starting or ending
/// on the geometry must wade through in boxes that do not hold that geometry. The root contributes 0.
/// The area inside a box is computed exactly (in double) by clipping each triangle to the box.
/// Presplit trees: a triangle counts as inside n's subtree when any of its fragments is (a small
/// under-estimate of the paper's fragment-exact definition).
/// Cost: for each triangle, a descent from the root into every node whose box overlaps the
/// triangle's box — O(n log n) for well-separated trees, up to O(n * nodes) for pathological overlap;
/// parallel over triangles with `ex`. Returns 0 for an empty tree or a scene of zero area.
/// `tris` must be the array the tree was built over (else std::invalid_argument).
template <class NodeT, class Prim, class Exec = exec::default_executor>
double epo(const Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris,
           const SahCost& cfg = {}, const Exec& ex = {}) {
    using Index = typename NodeT::index_type;
    detail::check_triangles(bvh, tris.size(), "epo");
    const auto& nodes = bvh.nodes;
    if (nodes.empty() || tris.empty()) return 0.0;

    // Pre-order numbers: node m is in n's subtree iff first[n] <= first[m] <= last[n].
    const std::size_t nn = nodes.size();
    std::vector<std::size_t> first(nn, ~std::size_t(0)), last(nn, 0);
    std::vector<std::size_t> leaf_order;  // pre-order number of each leaf slot's leaf
    leaf_order.assign(bvh.prim_ids.size(), ~std::size_t(0));
    {
        std::vector<std::pair<Index, bool>> todo{{Index(0), false}};
        std::size_t counter = 0;
        while (!todo.empty()) {
            const auto [id, done] = todo.back();
            todo.pop_back();
            if (done) {
                last[id] = counter - 1;
                continue;
            }
            if (id >= nn || first[id] != ~std::size_t(0)) continue;  // broken tree: ignore
            first[id] = counter++;
            const NodeT& n = nodes[id];
            todo.push_back({id, true});
            if (n.is_leaf()) {
                for (std::size_t s = n.index; s < std::size_t(n.index) + n.count && s < leaf_order.size(); ++s)
                    leaf_order[s] = first[id];
            } else {
                todo.push_back({Index(n.index + 1), false});
                todo.push_back({n.index, false});
            }
        }
    }
    // Per triangle: the pre-order numbers of the leaves referencing it (CSR).
    const std::size_t nt = tris.size();
    std::vector<std::size_t> offset(nt + 1, 0);
    for (std::size_t s = 0; s < bvh.prim_ids.size(); ++s)
        if (std::size_t(bvh.prim_ids[s]) < nt && leaf_order[s] != ~std::size_t(0)) ++offset[bvh.prim_ids[s] + 1];
    for (std::size_t i = 0; i < nt; ++i) offset[i + 1] += offset[i];
    std::vector<std::size_t> tri_leaves(offset[nt]);
    {
        std::vector<std::size_t> fill(offset.begin(), offset.end() - 1);
        for (std::size_t s = 0; s < bvh.prim_ids.size(); ++s)
            if (std::size_t(bvh.prim_ids[s]) < nt && leaf_order[s] != ~std::size_t(0))
                tri_leaves[fill[bvh.prim_ids[s]]++] = leaf_order[s];
    }

    struct Sums {
        double epo = 0, area = 0;
    };
    const std::size_t block = 256;
    const std::size_t blocks = (nt + block - 1) / block;
    const Sums total = ex.reduce(
        std::size_t(0), blocks, Sums{},
        [&](std::size_t b) {
            Sums acc;
            std::vector<Index> stack;
            stack.reserve(2 * max_depth);
            for (std::size_t i = b * block; i < std::min(nt, (b + 1) * block); ++i) {
                const auto& tri = tris[i];
                if (!tri.is_finite() || offset[i] == offset[i + 1]) continue;  // not in the tree
                const Vec3d a(tri.p0), bb(tri.p1), c(tri.p2);
                acc.area += 0.5 * length(cross(bb - a, c - a));
                const AABB<double> tb = AABB<double>{}.extend(a).extend(bb).extend(c);
                stack.clear();
                stack.push_back(Index(0));
                while (!stack.empty()) {
                    const Index id = stack.back();
                    stack.pop_back();
                    if (id >= nn || first[id] == ~std::size_t(0)) continue;
                    const NodeT& n = nodes[id];
                    const Vec3d lo(n.min), hi(n.max);
                    if (tb.max.x < lo.x || tb.min.x > hi.x || tb.max.y < lo.y || tb.min.y > hi.y || tb.max.z < lo.z ||
                        tb.min.z > hi.z)
                        continue;  // boxes disjoint: neither n nor its descendants hold any of the triangle
                    bool inside = false;
                    for (std::size_t k = offset[i]; k < offset[i + 1] && !inside; ++k)
                        inside = first[id] <= tri_leaves[k] && tri_leaves[k] <= last[id];
                    if (!inside) {
                        const double clipped = detail::clipped_triangle_area(a, bb, c, lo, hi);
                        if (!(clipped > 0)) continue;  // touches only: descendants' boxes are inside n's
                        acc.epo += (n.is_leaf() ? cfg.ci : cfg.ct) * clipped;
                    }
                    if (!n.is_leaf()) {
                        stack.push_back(Index(n.index + 1));
                        stack.push_back(n.index);
                    }
                }
            }
            return acc;
        },
        [](const Sums& x, const Sums& y) { return Sums{x.epo + y.epo, x.area + y.area}; });
    if (!(total.area > 0)) return 0.0;
    return total.epo / total.area;
}

} // namespace dynbvh
