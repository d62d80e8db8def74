// SPDX-License-Identifier: MIT
/// @file refit.hpp
/// Bottom-up refit: keeps a tree's topology and recomputes every box from the
/// triangles' current positions — the cheap alternative to a rebuild when a frame's
/// motion is small (the tree's quality decays as the motion grows; compare `sah_cost`
/// (sah.hpp) before and after to decide when to rebuild). Works for every builder's output.
/// Presplit fragments are refitted to their whole triangle's box (no re-clipping).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>

#include "bvh.hpp"
#include "detail/check_triangles.hpp"
#include "detail/scratch.hpp"
#include "executor.hpp"
#include "mesh.hpp"
#include "sah.hpp"
#include "wide.hpp"

namespace dynbvh {

namespace detail {

/// What a refit with sums measured (refit_binary<true>): the refitted tree's SAH sums and the number
/// of triangles read that have a NaN or infinite vertex.
struct RefitSums {
    SahSums sah;
    std::size_t nonfinite = 0;
};

/// The binary refit over any triangle source (a span or a MeshView): one code path. With `Sums`, the
/// same passes also add up the refitted tree's SAH sums (leaf terms in the parallel leaf pass, inner
/// terms in the serial sweep) and count the triangles read that have a NaN or infinite vertex: what
/// refit_sah returns, at the cost of one area per node instead of a second pass over the tree.
template <bool Sums = false, class NodeT, class Prim, class Source, class Exec>
RefitSums refit_binary(Bvh<NodeT, Prim>& bvh, Source tris, const Exec& ex) {
    using T = typename NodeT::scalar_type;
    check_triangles(bvh, tris.size(), "refit");
    RefitSums out;
    if (bvh.empty()) return out;
    if constexpr (Bvh<NodeT, Prim>::precomputed)
        ex.for_each(0, bvh.prim_ids.size(), [&](std::size_t s) { bvh.leaf_triangles[s] = tris[bvh.prim_ids[s]]; });
    // Step 1: leaf boxes, in parallel (with Sums: their SAH terms and the non-finite triangles, reduced).
    const auto leaf = [&](std::size_t i) {
        NodeT& node = bvh.nodes[i];
        RefitSums r;
        if (!node.is_leaf()) return r;
        AABB<T> box;
        for (std::size_t s = node.index; s < std::size_t(node.index) + node.count; ++s) {
            const Triangle<T> t = tris[bvh.prim_ids[s]];
            box.extend(t.bounds());
            if constexpr (Sums) r.nonfinite += t.is_finite() ? 0u : 1u;
        }
        node.set_bounds(box);
        if constexpr (Sums) {
            r.sah.leaf = area(box) * double(node.count);
            r.sah.refs = double(node.count);
        }
        return r;
    };
    if constexpr (Sums)
        out = ex.reduce(std::size_t(0), bvh.nodes.size(), RefitSums{}, leaf, [](const RefitSums& a, const RefitSums& b) {
            return RefitSums{SahSums::combine(a.sah, b.sah), a.nonfinite + b.nonfinite};
        });
    else
        ex.for_each(0, bvh.nodes.size(), [&](std::size_t i) { leaf(i); }, 4096);
    // Step 2: inner boxes, children first (they always follow their parent in the layout).
    for (std::size_t i = bvh.nodes.size(); i-- > 0;) {
        NodeT& node = bvh.nodes[i];
        if (node.is_leaf()) continue;
        node.set_bounds(merge(bvh.nodes[node.left()].bounds(), bvh.nodes[node.right()].bounds()));
        if constexpr (Sums) {
            out.sah.inner += area(node.bounds());
            out.sah.inner_n += 1;
        }
    }
    return out;
}

/// The wide refit's box passes over `bvh.nodes`: every leaf slot k of node i gets leaf_box(node, k),
/// then inner slots bottom-up, each node finished by the last of its inner children (an atomic count
/// per node, no assumption on the node order). Shared by the refit of index, copied and block trees.
template <class WideTree, class LeafBox, class Exec>
void refit_wide_boxes(WideTree& bvh, const LeafBox& leaf_box, const Exec& ex) {
    using WNodeT = typename WideTree::node_type;
    constexpr int W = WNodeT::width;
    const std::size_t n = bvh.nodes.size();
    constexpr std::size_t none = ~std::size_t(0);
    // Step 1: leaf slots; each node's parent slot (node * W + slot) and inner child count.
    scratch_vector<std::size_t> parent(n);
    scratch_vector<std::atomic<std::uint32_t>> pending(n);
    scratch_vector<std::uint8_t> starts(n);   // no inner child: a walk starts here (pending changes in step 2)
    parent[0] = none;
    ex.for_each(0, n, [&](std::size_t i) {
        WNodeT& node = bvh.nodes[i];
        std::uint32_t inner = 0;
        for (int k = 0; k < W; ++k) {
            if (node.empty_slot(k)) continue;
            if (!node.is_leaf(k)) {
                parent[node.child[k]] = i * std::size_t(W) + std::size_t(k);
                ++inner;
                continue;
            }
            node.set_bounds(k, leaf_box(node, k));
        }
        pending[i].store(inner, std::memory_order_relaxed);
        starts[i] = std::uint8_t(inner == 0 ? 1 : 0);
    }, 1024);
    // Step 2: from every node with no inner child, up while this node is its parent's last to finish.
    ex.for_each(0, n, [&](std::size_t i) {
        if (!starts[i]) return;
        for (std::size_t c = i; parent[c] != none;) {
            const std::size_t p = parent[c] / std::size_t(W);
            bvh.nodes[p].set_bounds(int(parent[c] % std::size_t(W)), bvh.nodes[c].bounds());
            if (pending[p].fetch_sub(1, std::memory_order_acq_rel) != 1) return;   // a sibling is still open
            c = p;
        }
    }, 1024);
}

/// The wide refit over any triangle source (see refit(WideBvh&, ...) below).
template <class WNodeT, class Prim, class Source, class Exec>
void refit_wide(WideBvh<WNodeT, Prim>& bvh, Source tris, const Exec& ex) {
    static_assert(WideBvh<WNodeT, Prim>::block_lanes == 0, "dynbvh::refit: block trees refit through wide_blocks.hpp");
    using T = typename WNodeT::scalar_type;
    check_triangles(bvh, tris.size(), "refit");
    if (bvh.empty()) return;
    if constexpr (WideBvh<WNodeT, Prim>::precomputed)
        ex.for_each(0, bvh.prim_ids.size(), [&](std::size_t s) { bvh.leaf_triangles[s] = tris[bvh.prim_ids[s]]; });
    refit_wide_boxes(bvh, [&](const WNodeT& node, int k) {
        AABB<T> box;
        for (std::size_t s = node.child[k]; s < std::size_t(node.child[k]) + node.count[k]; ++s) box.extend(tris[bvh.prim_ids[s]].bounds());
        return box;
    }, ex);
}

} // namespace detail

/// Recomputes all boxes of `bvh` from `tris` (same triangle count and indexing as at build time;
/// a span whose size is not `bvh.primitive_count` throws std::invalid_argument, `bvh` unchanged).
/// For prim::copied the leaf triangles are updated too. O(nodes + references): leaves in
/// parallel, inner nodes in one reverse sweep (children always follow their parent in the layout).
template <class NodeT, class Prim, class Exec = exec::default_executor>
void refit(Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris, const Exec& ex = {}) {
    detail::refit_binary(bvh, tris, ex);
}

/// The same from an indexed mesh read in place (mesh.hpp), typically the view the tree was built from
/// after its vertices moved: the same boxes as from make_triangles' array, bit for bit. No allocation.
template <class NodeT, class Prim, class Index, class Exec = exec::default_executor>
void refit(Bvh<NodeT, Prim>& bvh, const MeshView<typename NodeT::scalar_type, Index>& mesh, const Exec& ex = {}) {
    detail::refit_binary(bvh, mesh, ex);
}

/// What refit_sah measured.
struct RefitReport {
    /// SAH of the refitted tree: sah_cost's formula and cost (sah.hpp), its terms added in another
    /// order (leaves by the executor's reduction, inner nodes in reverse layout order), so within a
    /// relative 1e-12 of sah_cost(bvh, cost, ex), not always equal to its last bit.
    double sah = 0;
    /// Triangles the tree references that have a NaN or infinite vertex (their boxes are then not
    /// finite either: a caller would rebuild, which leaves such triangles out).
    std::size_t nonfinite = 0;
};

namespace detail {
/// refit_sah's report from the refit's sums (sah_cost's formula, degenerate roots included).
template <class NodeT, class Prim>
RefitReport refit_report(const RefitSums& r, const Bvh<NodeT, Prim>& bvh, const SahCost& cost) noexcept {
    return {bvh.empty() ? 0.0 : sah_from_sums(r.sah, area(bvh.nodes[0].bounds()), cost), r.nonfinite};
}
} // namespace detail

/// refit(bvh, tris, ex) that also returns the refitted tree's SAH and counts the non-finite triangles
/// it read, in the same passes: what a refit-or-rebuild policy needs each frame (dynamic.hpp), without
/// a second pass over the tree for sah_cost. The same boxes as refit, bit for bit; same errors.
/// O(nodes + references), the leaves in parallel, the inner nodes in one serial sweep.
template <class NodeT, class Prim, class Exec = exec::default_executor>
RefitReport refit_sah(Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris, const SahCost& cost = {},
                      const Exec& ex = {}) {
    return detail::refit_report(detail::refit_binary<true>(bvh, tris, ex), bvh, cost);
}

/// refit_sah from an indexed mesh read in place (mesh.hpp): the same boxes and report as from
/// make_triangles' array. No allocation.
template <class NodeT, class Prim, class Index, class Exec = exec::default_executor>
RefitReport refit_sah(Bvh<NodeT, Prim>& bvh, const MeshView<typename NodeT::scalar_type, Index>& mesh, const SahCost& cost = {},
                      const Exec& ex = {}) {
    return detail::refit_report(detail::refit_binary<true>(bvh, mesh, ex), bvh, cost);
}

/// Recomputes all boxes of the wide tree `bvh` from `tris` in place (same contract as the binary refit:
/// a span whose size is not `bvh.primitive_count` throws std::invalid_argument, `bvh` unchanged; for
/// prim::copied the leaf triangles are updated too). The topology stays; every slot box equals, bit for
/// bit, the refitted binary tree's box of the binary node the slot was collapsed from (min/max unions agree
/// in any order, a -0/+0 tie aside). make_wide of the refitted binary tree may differ: it would open nodes
/// by their new areas. O(nodes + references), parallel (detail::refit_wide_boxes). Block trees
/// (wide_blocks.hpp) have their own overload, which reloads the blocks' vertices too.
template <class WNodeT, class Prim, class Exec = exec::default_executor>
void refit(WideBvh<WNodeT, Prim>& bvh, std::span<const Triangle<typename WNodeT::scalar_type>> tris, const Exec& ex = {}) {
    detail::refit_wide(bvh, tris, ex);
}

/// The wide refit from an indexed mesh read in place (mesh.hpp); the same boxes as from make_triangles'
/// array, bit for bit.
template <class WNodeT, class Prim, class Index, class Exec = exec::default_executor>
void refit(WideBvh<WNodeT, Prim>& bvh, const MeshView<typename WNodeT::scalar_type, Index>& mesh, const Exec& ex = {}) {
    detail::refit_wide(bvh, mesh, ex);
}

} // namespace dynbvh
