// SPDX-License-Identifier: MIT
/// @file refit.hpp
/// Bottom-up refit: keeps a tree's topology and recomputes every box from the
/// triangles' current positions — the cheap alternative to a rebuild when a frame's
/// motion is small (the tree's quality decays as the motion grows; compare `sah_cost`
/// (sah.hpp) before and after to decide when to rebuild). Works for every builder's output.
/// Presplit fragments are refitted to their whole triangle's box (no re-clipping).
#pragma once

#include <cstdint>
#include <span>

#include "bvh.hpp"
#include "detail/check_triangles.hpp"
#include "executor.hpp"

namespace dynbvh {

/// Recomputes all boxes of `bvh` from `tris` (same triangle count and indexing as at build time;
/// a span whose size is not `bvh.primitive_count` throws std::invalid_argument, `bvh` unchanged).
/// For prim::copied the leaf triangles are updated too. O(nodes + references): leaves in
/// parallel, inner nodes in one reverse sweep (children always follow their parent in the layout).
template <class NodeT, class Prim, class Exec = exec::default_executor>
void refit(Bvh<NodeT, Prim>& bvh, std::span<const Triangle<typename NodeT::scalar_type>> tris, const Exec& ex = {}) {
    using T = typename NodeT::scalar_type;
    detail::check_triangles(bvh, tris.size(), "refit");
    if (bvh.empty()) return;
    if constexpr (Bvh<NodeT, Prim>::precomputed)
        ex.for_each(0, bvh.prim_ids.size(), [&](std::size_t s) { bvh.leaf_triangles[s] = tris[bvh.prim_ids[s]]; });
    ex.for_each(0, bvh.nodes.size(), [&](std::size_t i) {
        NodeT& node = bvh.nodes[i];
        if (!node.is_leaf()) return;
        AABB<T> box;
        for (std::size_t s = node.index; s < std::size_t(node.index) + node.count; ++s) box.extend(tris[bvh.prim_ids[s]].bounds());
        node.set_bounds(box);
    }, 4096);
    for (std::size_t i = bvh.nodes.size(); i-- > 0;) {
        NodeT& node = bvh.nodes[i];
        if (node.is_leaf()) continue;
        node.set_bounds(merge(bvh.nodes[node.left()].bounds(), bvh.nodes[node.right()].bounds()));
    }
}

} // namespace dynbvh
