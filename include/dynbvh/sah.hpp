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
#include "detail/check_triangles.hpp"
#include "executor.hpp"

namespace dynbvh {

/// Costs of the SAH and EPO: Ct per inner node visited, Ci per primitive intersected.
/// Defaults are the study's (Ct = 3, Ci = 2, after the PLOC paper).
struct SahConfig {
    double ct = 3;  ///< traversal cost of an inner node
    double ci = 2;  ///< intersection cost of one reference in a leaf
};

namespace detail {
template <class S>
inline double box_area(const Vec3<S>& lo, const Vec3<S>& hi) noexcept {
    if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return 0.0;
    const double dx = double(hi.x) - double(lo.x), dy = double(hi.y) - double(lo.y), dz = double(hi.z) - double(lo.z);
    return 2.0 * (dx * dy + dy * dz + dz * dx);
}

struct SahSums {
    double inner = 0, leaf = 0;   // sum SA(n) over inner nodes; sum SA(l) * count(l) over leaves
    double inner_n = 0, refs = 0; // number of inner nodes; number of references
    static SahSums combine(const SahSums& a, const SahSums& b) noexcept {
        return {a.inner + b.inner, a.leaf + b.leaf, a.inner_n + b.inner_n, a.refs + b.refs};
    }
};
} // namespace detail

/// SAH cost = (1 / SA(root)) * (Ct * sum over inner nodes SA(n) + Ci * sum over leaves SA(l) * count(l)),
/// count(l) = references in leaf l, SA = box surface area (computed in double). Every node in
/// `bvh.nodes` counts (a valid tree has no unreachable nodes). An empty tree costs 0. When the root's
/// area is 0 (all geometry on one line or at one point) every box is the root's degenerate box and
/// the limit of the formula is used: Ct * inner nodes + Ci * references. O(nodes), parallel over `ex`.
template <class NodeT, class Prim, class Exec = exec::serial>
double sah_cost(const Bvh<NodeT, Prim>& bvh, const SahConfig& cfg = {}, const Exec& ex = {}) {
    if (bvh.nodes.empty()) return 0.0;
    const auto& nodes = bvh.nodes;
    const detail::SahSums s = ex.reduce(
        std::size_t(0), nodes.size(), detail::SahSums{},
        [&](std::size_t i) {
            const NodeT& n = nodes[i];
            const double a = detail::box_area(n.min, n.max);
            detail::SahSums r;
            if (n.is_leaf()) {
                r.leaf = a * double(n.count);
                r.refs = double(n.count);
            } else {
                r.inner = a;
                r.inner_n = 1;
            }
            return r;
        },
        [](const detail::SahSums& a, const detail::SahSums& b) { return detail::SahSums::combine(a, b); });
    const double root = detail::box_area(nodes[0].min, nodes[0].max);
    if (!(root > 0)) return cfg.ct * s.inner_n + cfg.ci * s.refs;
    return (cfg.ct * s.inner + cfg.ci * s.leaf) / root;
}

namespace detail {

/// Area of the part of triangle (a, b, c) inside the closed box [lo, hi]: Sutherland–Hodgman clipping
/// against the six planes, in double. Exact up to double rounding.
inline double clipped_triangle_area(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& lo, const Vec3d& hi) {
    Vec3d buf0[9], buf1[9];
    Vec3d* in = buf0;
    Vec3d* out = buf1;
    int n = 3;
    in[0] = a;
    in[1] = b;
    in[2] = c;
    for (int plane = 0; plane < 6 && n > 0; ++plane) {
        const std::size_t axis = std::size_t(plane >> 1);
        const bool upper = (plane & 1) != 0;
        const double bound = upper ? hi[axis] : lo[axis];
        auto inside = [&](const Vec3d& p) { return upper ? p[axis] <= bound : p[axis] >= bound; };
        int m = 0;
        for (int i = 0; i < n; ++i) {
            const Vec3d& p = in[i];
            const Vec3d& q = in[(i + 1) % n];
            const bool pin = inside(p), qin = inside(q);
            if (pin) out[m++] = p;
            if (pin != qin) {
                const double s = (bound - p[axis]) / (q[axis] - p[axis]);
                Vec3d x = p + (q - p) * s;
                x[axis] = bound;
                out[m++] = x;
            }
        }
        n = m;
        std::swap(in, out);
    }
    if (n < 3) return 0.0;
    Vec3d sum{};
    for (int i = 1; i + 1 < n; ++i) sum += cross(in[i] - in[0], in[i + 1] - in[0]);
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
template <class NodeT, class Prim, class Exec = exec::serial>
double epo(const Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris,
           const SahConfig& cfg = {}, const Exec& ex = {}) {
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
