// SPDX-License-Identifier: MIT
/// @file validate.hpp
/// Structural check of a finished `Bvh` against the triangles it was built over. Every builder test
/// runs it; users can run it on trees they build or modify themselves. The report says in words what
/// is wrong, so a failing test prints why.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <span>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "bvh.hpp"
#include "detail/check_triangles.hpp"

namespace dynbvh {

/// What `validate` may assume about the builder.
struct ValidateConfig {
    /// Every finite triangle is referenced exactly once overall (true for every builder except presplit
    /// ones, whose fragments put one triangle into several leaves: pass false for kbvh).
    bool expect_single_reference = true;
    /// Most failure messages kept in the report (the count of all failures is always exact).
    std::size_t max_messages = 32;
};

/// The outcome of `validate`: failures in words plus a few counts.
struct ValidationReport {
    std::vector<std::string> errors;   ///< the first `max_messages` failures, human-readable
    std::size_t error_count = 0;       ///< all failures found
    std::size_t reached_nodes = 0;     ///< nodes reached from the root
    std::size_t leaves = 0;            ///< leaves reached
    std::size_t references = 0;        ///< leaf references reached
    std::uint32_t depth = 0;           ///< depth measured (edges root -> deepest leaf)

    /// True when no check failed.
    bool ok() const noexcept { return error_count == 0; }
    /// Same as ok().
    explicit operator bool() const noexcept { return ok(); }
    /// One line per failure (plus "... and N more"), or a one-line summary when the tree is valid.
    std::string summary() const {
        std::ostringstream s;
        if (ok()) {
            s << "valid BVH: " << reached_nodes << " nodes, " << leaves << " leaves, " << references
              << " references, depth " << depth;
            return s.str();
        }
        s << error_count << " problem(s):";
        for (const auto& e : errors) s << "\n  - " << e;
        if (error_count > errors.size()) s << "\n  ... and " << (error_count - errors.size()) << " more";
        return s.str();
    }
};

/// Checks, reporting every failure:
///  - bookkeeping: `primitive_count == tris.size()` (the message refit/intersect throw), `excluded` == number of non-finite triangles;
///    an empty tree only when no triangle is finite (and then no references);
///  - topology: root at 0; every inner node's children `index`, `index + 1` in range; every node reached
///    exactly once from the root (no sharing, no cycles, no unreachable nodes); every leaf's range
///    inside `prim_ids`, and every `prim_ids` slot in exactly one leaf;
///  - boxes: no NaN, not inverted; every parent box contains its children's boxes (exact comparison);
///  - references: each id is a valid index of a finite triangle, at most once per leaf; every finite
///    triangle referenced at least once, and exactly once when `cfg.expect_single_reference`;
///  - leaf boxes vs triangles: with `expect_single_reference` each leaf box contains its triangles' boxes
///    (exact). Presplit fragments only cover part of a triangle and the leaf does not say which part,
///    so without it: each leaf box must overlap the triangle's box, every vertex of a triangle must lie
///    in the box of some leaf referencing it (exact), and its edge midpoints and centroid too (within a
///    few ulps of the triangle's coordinates), i.e. the fragments cover the triangle;
///  - depth: measured depth == `bvh.depth` and <= `max_depth`;
///  - prim::copied: `leaf_triangles[slot] == tris[prim_ids[slot]]` for every slot.
/// Cost: O(nodes + references + triangles) time and memory, serial.
template <class NodeT, class Prim>
ValidationReport validate(const Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris,
                          const ValidateConfig& cfg = {}) {
    using T = typename NodeT::scalar_type;
    ValidationReport rep;
    auto fail = [&](const std::string& msg) {
        if (rep.errors.size() < cfg.max_messages) rep.errors.push_back(msg);
        ++rep.error_count;
    };
    auto str = [](const auto& v) {
        std::ostringstream s;
        s.precision(9);
        s << '(' << v.x << ", " << v.y << ", " << v.z << ')';
        return s.str();
    };
    auto box_str = [&](const NodeT& n) { return "[" + str(n.min) + " .. " + str(n.max) + "]"; };

    const std::size_t nt = tris.size();
    std::size_t non_finite = 0;
    for (const auto& t : tris) non_finite += t.is_finite() ? 0u : 1u;
    if (std::string msg = detail::triangle_mismatch(bvh, nt, "validate"); !msg.empty()) fail(msg);  // reported, not thrown
    if (bvh.excluded != non_finite)
        fail("excluded is " + std::to_string(bvh.excluded) + " but " + std::to_string(non_finite) +
             " triangles have a NaN or infinite vertex");
    if (bvh.depth > max_depth)
        fail("depth " + std::to_string(bvh.depth) + " exceeds max_depth " + std::to_string(max_depth));

    const auto& nodes = bvh.nodes;
    const std::size_t nn = nodes.size();
    const std::size_t ns = bvh.prim_ids.size();
    if (nn == 0) {
        if (ns != 0) fail("empty tree but prim_ids has " + std::to_string(ns) + " entries");
        if (bvh.depth != 0) fail("empty tree but depth is " + std::to_string(bvh.depth));
        if (non_finite != nt) fail("empty tree but " + std::to_string(nt - non_finite) + " triangles are finite");
        return rep;
    }

    std::vector<std::uint32_t> reached(nn, 0);
    std::vector<std::int64_t> slot_leaf(ns, -1);      // leaf owning each slot
    std::vector<std::uint32_t> refcount(nt, 0);
    std::vector<std::int64_t> last_leaf(nt, -1);      // for "at most once per leaf"
    std::vector<std::uint8_t> covered(cfg.expect_single_reference ? 0 : nt, 0);  // bits: 3 vertices, 3 midpoints, centroid

    auto box_ok = [](const NodeT& n) {
        return n.min.x <= n.max.x && n.min.y <= n.max.y && n.min.z <= n.max.z;  // false for NaN
    };
    auto contains = [](const NodeT& outer, const NodeT& inner) {
        return outer.min.x <= inner.min.x && outer.min.y <= inner.min.y && outer.min.z <= inner.min.z &&
               inner.max.x <= outer.max.x && inner.max.y <= outer.max.y && inner.max.z <= outer.max.z;
    };

    struct Item {
        std::size_t node, parent;
        std::uint32_t depth;
    };
    std::vector<Item> todo{{0, ~std::size_t(0), 0}};
    while (!todo.empty()) {
        const Item it = todo.back();
        todo.pop_back();
        if (++reached[it.node] > 1) {
            fail("node " + std::to_string(it.node) + " is reached more than once (again from node " +
                 std::to_string(it.parent) + ")");
            continue;
        }
        ++rep.reached_nodes;
        const NodeT& n = nodes[it.node];
        if (!box_ok(n)) fail("node " + std::to_string(it.node) + " has an invalid box " + box_str(n));
        if (it.parent != ~std::size_t(0) && !contains(nodes[it.parent], n))
            fail("node " + std::to_string(it.node) + " box " + box_str(n) + " is not inside its parent " +
                 std::to_string(it.parent) + " box " + box_str(nodes[it.parent]));
        if (!n.is_leaf()) {
            const std::size_t c = std::size_t(n.index);
            if (c == 0 || c + 1 >= nn || c + 1 < c) {
                fail("inner node " + std::to_string(it.node) + " has children " + std::to_string(c) + ", " +
                     std::to_string(c + 1) + " outside 1.." + std::to_string(nn - 1));
                continue;
            }
            todo.push_back({c + 1, it.node, it.depth + 1});
            todo.push_back({c, it.node, it.depth + 1});
            continue;
        }
        // Leaf.
        ++rep.leaves;
        rep.depth = std::max(rep.depth, it.depth);
        const std::size_t first = std::size_t(n.index), count = std::size_t(n.count);
        if (first > ns || count > ns - first) {
            fail("leaf " + std::to_string(it.node) + " references slots " + std::to_string(first) + ".." +
                 std::to_string(first + count - 1) + " but prim_ids has " + std::to_string(ns));
            continue;
        }
        const auto leaf_id = static_cast<std::int64_t>(it.node);
        for (std::size_t s = first; s < first + count; ++s) {
            ++rep.references;
            if (slot_leaf[s] >= 0) {
                fail("slot " + std::to_string(s) + " belongs to leaves " + std::to_string(slot_leaf[s]) + " and " +
                     std::to_string(it.node));
                continue;
            }
            slot_leaf[s] = leaf_id;
            const std::size_t p = std::size_t(bvh.prim_ids[s]);
            if (p >= nt) {
                fail("slot " + std::to_string(s) + " (leaf " + std::to_string(it.node) + ") references triangle " +
                     std::to_string(p) + " but there are " + std::to_string(nt));
                continue;
            }
            const Triangle<T>& tri = tris[p];
            if (!tri.is_finite()) {
                fail("leaf " + std::to_string(it.node) + " references triangle " + std::to_string(p) +
                     " which has a NaN or infinite vertex");
                continue;
            }
            if (last_leaf[p] == leaf_id)
                fail("leaf " + std::to_string(it.node) + " references triangle " + std::to_string(p) + " twice");
            last_leaf[p] = leaf_id;
            ++refcount[p];
            const AABB<T> tb = tri.bounds();
            if (cfg.expect_single_reference) {
                if (!n.bounds().contains(tb))
                    fail("leaf " + std::to_string(it.node) + " box " + box_str(n) + " does not contain triangle " +
                         std::to_string(p) + " box [" + str(tb.min) + " .. " + str(tb.max) + "]");
            } else {
                if (intersection(n.bounds(), tb).is_empty())
                    fail("leaf " + std::to_string(it.node) + " box " + box_str(n) + " does not overlap triangle " +
                         std::to_string(p) + " box [" + str(tb.min) + " .. " + str(tb.max) + "]");
                const AABB<T> lb = n.bounds();
                std::uint8_t bits = 0;
                if (lb.contains(tri.p0)) bits |= 1;
                if (lb.contains(tri.p1)) bits |= 2;
                if (lb.contains(tri.p2)) bits |= 4;
                // Interior points are computed, so allow a few ulps of the triangle's largest coordinate.
                T mag = T(1);
                for (const auto* q : {&tri.p0, &tri.p1, &tri.p2})
                    mag = std::max({mag, std::abs(q->x), std::abs(q->y), std::abs(q->z)});
                const T tol = T(16) * std::numeric_limits<T>::epsilon() * mag;
                AABB<T> lbe = lb;
                lbe.min -= Vec3<T>{tol, tol, tol};
                lbe.max += Vec3<T>{tol, tol, tol};
                // Scaled before adding, so that coordinates near the largest finite value cannot overflow.
                const T h = T(0.5), third = T(1) / T(3);
                if (lbe.contains(tri.p0 * h + tri.p1 * h)) bits |= 8;
                if (lbe.contains(tri.p1 * h + tri.p2 * h)) bits |= 16;
                if (lbe.contains(tri.p2 * h + tri.p0 * h)) bits |= 32;
                if (lbe.contains(tri.p0 * third + tri.p1 * third + tri.p2 * third)) bits |= 64;
                covered[p] = std::uint8_t(covered[p] | bits);
            }
            if constexpr (Bvh<NodeT, Prim>::precomputed) {
                if (s < bvh.leaf_triangles.size()) {
                    const auto& c = bvh.leaf_triangles[s];
                    if (!(c.p0 == tri.p0 && c.p1 == tri.p1 && c.p2 == tri.p2))
                        fail("leaf_triangles[" + std::to_string(s) + "] differs from triangle " + std::to_string(p));
                }
            }
        }
    }

    std::size_t unreached = 0, first_unreached = 0;
    for (std::size_t i = 0; i < nn; ++i)
        if (reached[i] == 0 && unreached++ == 0) first_unreached = i;
    if (unreached)
        fail(std::to_string(unreached) + " node(s) not reachable from the root (first: " +
             std::to_string(first_unreached) + ")");
    std::size_t orphan = 0, first_orphan = 0;
    for (std::size_t s = 0; s < ns; ++s)
        if (slot_leaf[s] < 0 && orphan++ == 0) first_orphan = s;
    if (orphan)
        fail(std::to_string(orphan) + " prim_ids slot(s) in no leaf (first: " + std::to_string(first_orphan) + ")");

    for (std::size_t p = 0; p < nt; ++p) {
        if (!tris[p].is_finite()) continue;
        if (refcount[p] == 0) {
            fail("triangle " + std::to_string(p) + " is not referenced by any leaf");
            continue;
        }
        if (cfg.expect_single_reference && refcount[p] > 1)
            fail("triangle " + std::to_string(p) + " is referenced " + std::to_string(refcount[p]) +
                 " times (expected once)");
        if (!cfg.expect_single_reference && covered[p] != 127)
            fail("triangle " + std::to_string(p) + " is not covered by the boxes of the leaves referencing it "
                 "(coverage mask " + std::to_string(int(covered[p])) + " of 127: bits 1,2,4 vertices, 8,16,32 edge "
                 "midpoints, 64 centroid)");
    }

    if (rep.depth != bvh.depth)
        fail("depth is " + std::to_string(bvh.depth) + " but the deepest leaf is at depth " + std::to_string(rep.depth));
    if (rep.depth > max_depth)
        fail("measured depth " + std::to_string(rep.depth) + " exceeds max_depth " + std::to_string(max_depth));

    if constexpr (Bvh<NodeT, Prim>::precomputed) {
        if (bvh.leaf_triangles.size() != ns)
            fail("leaf_triangles has " + std::to_string(bvh.leaf_triangles.size()) + " entries but prim_ids has " +
                 std::to_string(ns));
    }
    return rep;
}

} // namespace dynbvh
