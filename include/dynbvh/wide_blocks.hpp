// SPDX-License-Identifier: MIT
/// @file wide_blocks.hpp
/// Wide BVHs whose leaves are SIMD triangle blocks (prim::blocks<L>), one SIMD step per block.
/// @code
///   auto bvh  = dynbvh::ploc::build(tris, {.leaves = dynbvh::block_leaves}, ex);  // leaves sized for blocks
///   auto fast = dynbvh::make_wide_blocks<8>(bvh, tris, ex);     // 8-wide nodes, leaves in blocks of 8
///   auto w84  = dynbvh::make_wide_blocks<8, 4>(bvh, tris, ex);  // blocks of 4 (SSE steps)
///   auto hit  = dynbvh::intersect(fast, tris, ray);             // same answer as intersect(bvh, ...)
///   bool occ  = dynbvh::occluded<dynbvh::trace::fast>(fast, tris, ray);
/// @endcode
/// The conversion is make_wide's (wide.hpp), then every leaf's triangles are copied into
/// ceil(n / L) blocks of L lanes (detail/triangle_block.hpp: vertices structure of arrays, the
/// user's triangle index per lane), leaves in node order; a leaf slot's `child` becomes its first
/// block (its `count` stays the number of triangles, so sah_cost is unchanged). O(references),
/// parallel over `ex`. The tree owns its triangles' vertices: tracing reads only the tree, yet the
/// `tris` argument of intersect / occluded is still checked to be the array the tree was built over
/// (exactly primitive_count triangles, as for prim::indexed trees), so that a call site can switch
/// tree types and a wrong scene is not traced unnoticed; `prim_ids` / `leaf_triangles` stay empty.
/// Memory: 192 (L = 4) or 384 (L = 8) bytes per block; on the bunny with block_leaves and L = 8 the
/// tree takes 86 bytes per triangle (72 of them blocks), against 40 for the user's array plus a
/// prim::indexed tree's references.
///
/// Leaf tests: trace::robust tests a whole block with a SIMD float filter on the watertight edge
/// functions and confirms the lanes it keeps with the exact scalar test; trace::fast tests a block
/// with SIMD Möller–Trumbore. Both give the scalar per-triangle loop's answers bit for bit (see
/// detail/triangle_block.hpp), so `intersect` on a block tree returns what it returns on the binary
/// tree it came from.
///
/// Leaves: a block tests up to L triangles in about the time of one or two scalar tests, so the
/// builders' default leaf collapse (LeafConfig: Ct 3, Ci 2; about 2 triangles per leaf) leaves most
/// lanes empty. `block_leaves` (Ci 0.5, at most 8 per leaf: about 6 on the bunny) builds the binary
/// tree for blocks of 8: fewer nodes to traverse, fuller blocks.
///
/// Dynamic scenes: a block tree cannot be refitted (the blocks hold the old vertices); refit the
/// binary tree and convert again (refit() on a block tree does not compile).
#pragma once

#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "bvh.hpp"
#include "cost.hpp"
#include "detail/check_triangles.hpp"
#include "detail/triangle_block.hpp"
#include "executor.hpp"
#include "mesh.hpp"
#include "wide.hpp"

namespace dynbvh {

namespace prim {
/// Wide trees only (make_wide_blocks): leaves hold their triangles' vertices in SIMD blocks of L = 4
/// or 8 (structure of arrays, leaf order), one SIMD step per block.
template <int L = 8>
struct blocks {
    static_assert(L == 4 || L == 8, "triangle blocks have 4 or 8 lanes");
    static constexpr int lanes = L;   ///< triangles per block
};
} // namespace prim

/// The leaf part of a block tree: the blocks (leaf after leaf; a leaf slot's `child` is its first
/// block, its `count` the number of triangles, in ceil(count / L) blocks) and the input counts.
/// prim_ids and leaf_triangles stay empty: each block lane names its user triangle itself.
template <class Scalar, class Index, int L>
struct LeafPart<Scalar, Index, prim::blocks<L>> : LeafPart<Scalar, Index, prim::indexed> {
    static_assert(std::is_same_v<Scalar, float>, "dynbvh: triangle blocks are float");
    using prim_policy = prim::blocks<L>;          ///< this leaf part's policy
    using block_type = detail::TriangleBlock<L>;  ///< L triangles, structure of arrays (detail/triangle_block.hpp)
    static constexpr int block_lanes = L;         ///< triangles per block

    /// The leaves' triangles, leaf after leaf in node order (scratch cache, as every tree array).
    scratch_vector<block_type> blocks;

    /// This part alone (to move it between trees).
    LeafPart& leaves() noexcept { return *this; }
    /// This part alone (to move it between trees).
    const LeafPart& leaves() const noexcept { return *this; }
    /// Bytes of the blocks.
    std::size_t leaf_bytes() const noexcept { return blocks.size() * sizeof(block_type); }
};

/// Leaf collapse for trees that will be converted with make_wide_blocks (see the file comment).
inline constexpr LeafConfig block_leaves{.max_leaf_size = 8, .cost = {.ct = 3, .ci = 0.5}};

/// The WideBvh type make_wide_blocks returns for a binary Bvh type.
template <class B, int W = 8, int L = W>
using wide_blocks_bvh_of = WideBvh<WideNode<typename B::scalar_type, typename B::index_type, W>, prim::blocks<L>>;

namespace detail {

/// make_wide_blocks over any triangle source (a span or a MeshView): one code path.
template <int W, int L, class NodeT, class Prim, class Source, class Exec>
wide_blocks_bvh_of<Bvh<NodeT, Prim>, W, L> make_wide_blocks(const Bvh<NodeT, Prim>& bvh, Source tris, const Exec& ex) {
    static_assert(std::is_same_v<typename NodeT::scalar_type, float>, "dynbvh::make_wide_blocks: triangle blocks are float");
    using Index = typename NodeT::index_type;
    check_triangles(bvh, tris.size(), "make_wide_blocks", !Bvh<NodeT, Prim>::precomputed);
    wide_blocks_bvh_of<Bvh<NodeT, Prim>, W, L> w;
    {
        wide_bvh_of<Bvh<NodeT, Prim>, W> topology;   // the nodes of make_wide<W>
        collapse_to_wide<W>(bvh, topology, ex);
        w.nodes = std::move(topology.nodes);
        w.depth = topology.depth;
    }
    w.primitive_count = bvh.primitive_count;
    w.excluded = bvh.excluded;
    if (w.nodes.empty()) return w;

    // Step 1: leaves per node, and each node's first leaf (leaves are numbered in node order).
    const std::size_t nn = w.nodes.size();
    std::vector<std::size_t> first_leaf(nn);
    ex.for_each(0, nn, [&](std::size_t i) {
        std::size_t c = 0;
        for (int k = 0; k < W; ++k) c += w.nodes[i].count[k] != 0;
        first_leaf[i] = c;
    });
    const std::size_t leaf_count = ex.exclusive_scan(std::span<const std::size_t>(first_leaf), std::span<std::size_t>(first_leaf));
    // Step 2: the leaves' slot ranges.
    std::vector<LeafRange> leaves(leaf_count);
    ex.for_each(0, nn, [&](std::size_t i) {
        std::size_t j = first_leaf[i];
        for (int k = 0; k < W; ++k)
            if (w.nodes[i].count[k] != 0) leaves[j++] = {w.nodes[i].child[k], w.nodes[i].count[k]};
    });
    // Step 3: pack, then point each leaf slot at its first block.
    std::vector<std::size_t> first_block;
    if constexpr (Bvh<NodeT, Prim>::precomputed)
        pack_triangle_blocks<L>(std::span<const LeafRange>(leaves), std::span<const Index>(bvh.prim_ids),
                                [&](std::size_t s) -> const Triangle<float>& { return bvh.leaf_triangles[s]; }, w.blocks,
                                first_block, ex);
    else
        pack_triangle_blocks<L>(std::span<const LeafRange>(leaves), std::span<const Index>(bvh.prim_ids),
                                [&](std::size_t s) -> decltype(auto) { return tris[bvh.prim_ids[s]]; }, w.blocks,
                                first_block, ex);
    ex.for_each(0, nn, [&](std::size_t i) {
        std::size_t j = first_leaf[i];
        for (int k = 0; k < W; ++k)
            if (w.nodes[i].count[k] != 0) w.nodes[i].child[k] = Index(first_block[j++]);
    });
    return w;
}

} // namespace detail

/// Converts a binary float BVH into a W-wide one with leaves in blocks of L triangles (see the file
/// comment). `tris` is the array the binary tree was built over (unused for prim::copied trees; any
/// other size than `bvh.primitive_count` throws std::invalid_argument). O(references), parallel over `ex`.
template <int W = 8, int L = W, class NodeT, class Prim, class Exec = exec::default_executor>
wide_blocks_bvh_of<Bvh<NodeT, Prim>, W, L> make_wide_blocks(const Bvh<NodeT, Prim>& bvh,
                                                            std::span<const Triangle<typename NodeT::scalar_type>> tris,
                                                            const Exec& ex = {}) {
    return detail::make_wide_blocks<W, L>(bvh, tris, ex);
}

/// The same from an indexed mesh read in place (mesh.hpp): the same tree as from make_triangles' array,
/// bit for bit.
template <int W = 8, int L = W, class NodeT, class Prim, class Index, class Exec = exec::default_executor>
wide_blocks_bvh_of<Bvh<NodeT, Prim>, W, L> make_wide_blocks(const Bvh<NodeT, Prim>& bvh,
                                                            const MeshView<typename NodeT::scalar_type, Index>& mesh,
                                                            const Exec& ex = {}) {
    return detail::make_wide_blocks<W, L>(bvh, mesh, ex);
}

/// Block trees hold copies of the vertices and cannot be refitted: refit the binary tree and call
/// make_wide_blocks again.
template <class WN, int L, class... Rest>
void refit(WideBvh<WN, prim::blocks<L>>&, Rest&&...) = delete;

} // namespace dynbvh
