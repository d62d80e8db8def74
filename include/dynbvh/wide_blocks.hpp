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
/// Dynamic scenes: refit(block tree, tris) reloads every block's vertices from `tris` and refits the
/// boxes in place (no conversion); make_wide_blocks also packs a wide tree straight from a builder's
/// build_wide (no binary tree). The traced layout's fastest build is morton_wide::build_blocks
/// (morton_wide.hpp): the tree make_wide_blocks(morton_wide::build(...)) gives, packed as it is built.
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
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
#include "refit.hpp"
#include "sah.hpp"
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

/// Packs the leaves of `w` (its nodes set, leaf slots naming prim_ids ranges) into blocks and points each
/// leaf slot at its first block. `tri_of(slot)` is the triangle of prim_ids slot `slot`. O(references),
/// parallel: leaves are numbered in node order (a count and a scan), then packed (pack_triangle_blocks).
template <class WideTree, class Index, class TriOf, class Exec>
void pack_wide_leaves(WideTree& w, std::span<const Index> prim_ids, const TriOf& tri_of, const Exec& ex) {
    constexpr int W = WideTree::node_type::width;
    constexpr int L = WideTree::block_lanes;
    // Step 1: leaves per node, and each node's first leaf (leaves are numbered in node order).
    const std::size_t nn = w.nodes.size();
    scratch_vector<std::size_t> first_leaf(nn);   // scratch: no fresh pages per build (these reach 100s of KiB)
    ex.for_each(0, nn, [&](std::size_t i) {
        std::size_t c = 0;
        for (int k = 0; k < W; ++k) c += w.nodes[i].count[k] != 0;
        first_leaf[i] = c;
    });
    const std::size_t leaf_count = ex.exclusive_scan(std::span<const std::size_t>(first_leaf), std::span<std::size_t>(first_leaf));
    // Step 2: the leaves' slot ranges.
    scratch_vector<LeafRange> leaves(leaf_count);
    ex.for_each(0, nn, [&](std::size_t i) {
        std::size_t j = first_leaf[i];
        for (int k = 0; k < W; ++k)
            if (w.nodes[i].count[k] != 0) leaves[j++] = {w.nodes[i].child[k], w.nodes[i].count[k]};
    });
    // Step 3: pack, then point each leaf slot at its first block.
    scratch_vector<std::size_t> first_block;
    pack_triangle_blocks<L>(std::span<const LeafRange>(leaves), prim_ids, tri_of, w.blocks, first_block, ex);
    ex.for_each(0, nn, [&](std::size_t i) {
        std::size_t j = first_leaf[i];
        for (int k = 0; k < W; ++k)
            if (w.nodes[i].count[k] != 0) w.nodes[i].child[k] = typename WideTree::index_type(first_block[j++]);
    });
}

/// pack_wide_leaves over a tree's leaf part `src` (prim::indexed: the user's triangles `tris`, a span or
/// a MeshView; prim::copied: its own leaf triangles).
template <class WideTree, class Src, class Source, class Exec>
void pack_from(WideTree& w, const Src& src, Source tris, const Exec& ex) {
    using Index = typename WideTree::index_type;
    if constexpr (Src::precomputed)
        pack_wide_leaves(w, std::span<const Index>(src.prim_ids), [&](std::size_t s) -> const Triangle<float>& { return src.leaf_triangles[s]; }, ex);
    else
        pack_wide_leaves(w, std::span<const Index>(src.prim_ids), [&](std::size_t s) -> decltype(auto) { return tris[src.prim_ids[s]]; }, ex);
}

/// make_wide_blocks of a binary tree over any triangle source (a span or a MeshView): one code path.
template <int W, int L, class NodeT, class Prim, class Source, class Exec>
wide_blocks_bvh_of<Bvh<NodeT, Prim>, W, L> blocks_of_binary(const Bvh<NodeT, Prim>& bvh, Source tris, const Exec& ex) {
    static_assert(std::is_same_v<typename NodeT::scalar_type, float>, "dynbvh::make_wide_blocks: triangle blocks are float");
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
    if (!w.nodes.empty()) pack_from(w, bvh, tris, ex);
    return w;
}

/// make_wide_blocks of a wide tree over any triangle source: one code path.
template <int L, class WN, class Prim, class Source, class Exec>
WideBvh<WN, prim::blocks<(L == 0 ? WN::width : L)>> blocks_of_wide(WideBvh<WN, Prim>&& wide, Source tris, const Exec& ex) {
    static_assert(std::is_same_v<typename WN::scalar_type, float>, "dynbvh::make_wide_blocks: triangle blocks are float");
    static_assert(!requires { Prim::lanes; }, "dynbvh::make_wide_blocks: the tree already has block leaves");
    check_triangles(wide, tris.size(), "make_wide_blocks", !WideBvh<WN, Prim>::precomputed);
    WideBvh<WN, prim::blocks<(L == 0 ? WN::width : L)>> w;
    w.nodes = std::move(wide.nodes);
    w.depth = wide.depth;
    w.primitive_count = wide.primitive_count;
    w.excluded = wide.excluded;
    if (!w.nodes.empty()) pack_from(w, wide, tris, ex);
    return w;
}

/// The block tree refit over any triangle source: one code path. With Count, returns the number of
/// triangles it loaded that have a NaN or infinite vertex (refit_sah's report): each block's lanes are
/// checked in the box pass, nine SIMD compares per block (TriangleBlock::nonfinite_mask). (Loading the blocks inside the wide refit's leaf pass
/// instead, one visit per leaf for its triangles and box, measured 10-25 % slower, and a per-triangle
/// check while loading 15 %: dynbvh-bench-build BM_refit_wide8_blocks, 2 threads.)
template <bool Count, class WN, int L, class Source, class Exec>
std::size_t refit_blocks(WideBvh<WN, prim::blocks<L>>& bvh, Source tris, const Exec& ex) {
    check_triangles(bvh, tris.size(), "refit");
    if (bvh.empty()) return 0;
    std::atomic<std::size_t> nonfinite{0};   // (touched only where a block holds one: almost never)
    ex.for_each(0, bvh.blocks.size(), [&](std::size_t i) {
        TriangleBlock<L>& b = bvh.blocks[i];
        for (int k = 0; k < int(b.count); ++k) b.set(k, tris[b.prim[k]], b.prim[k]);
    }, 1024);
    // (the non-finite lanes are counted in the box pass, which reads every block anyway: checked right
    // after loading, the SIMD loads of the lanes just stored one float at a time could not be forwarded
    // from the stores and stalled, +0.19 ms over the whole refit's 0.71 on a 146k-triangle n-body frame)
    refit_wide_boxes(bvh, [&](const WN& node, int k) {
        AABB<float> box;
        std::size_t left = node.count[k];
        for (const TriangleBlock<L>* b = bvh.blocks.data() + node.child[k]; left != 0; ++b) {
            for (int j = 0; j < int(b->count); ++j) box.extend(b->triangle(j).bounds());
            if constexpr (Count)
                if (const unsigned bad = b->nonfinite_mask(); bad != 0)
                    nonfinite.fetch_add(std::size_t(std::popcount(bad)), std::memory_order_relaxed);
            left -= std::min<std::size_t>(left, b->count);
        }
        return box;
    }, ex);
    return nonfinite.load(std::memory_order_relaxed);
}

} // namespace detail

/// Converts a binary float BVH into a W-wide one with leaves in blocks of L triangles (see the file
/// comment). `tris` is the array the binary tree was built over (unused for prim::copied trees; any
/// other size than `bvh.primitive_count` throws std::invalid_argument). O(references), parallel over `ex`.
template <int W = 8, int L = W, class NodeT, class Prim, class Exec = exec::default_executor>
wide_blocks_bvh_of<Bvh<NodeT, Prim>, W, L> make_wide_blocks(const Bvh<NodeT, Prim>& bvh,
                                                            std::span<const Triangle<typename NodeT::scalar_type>> tris,
                                                            const Exec& ex = {}) {
    return detail::blocks_of_binary<W, L>(bvh, tris, ex);
}

/// The same from an indexed mesh read in place (mesh.hpp): the same tree as from make_triangles' array,
/// bit for bit.
template <int W = 8, int L = W, class NodeT, class Prim, class Index, class Exec = exec::default_executor>
wide_blocks_bvh_of<Bvh<NodeT, Prim>, W, L> make_wide_blocks(const Bvh<NodeT, Prim>& bvh,
                                                            const MeshView<typename NodeT::scalar_type, Index>& mesh,
                                                            const Exec& ex = {}) {
    return detail::blocks_of_binary<W, L>(bvh, mesh, ex);
}

/// Packs the leaves of a float wide tree (prim::indexed or prim::copied; e.g. straight from a builder's
/// build_wide) into blocks of L triangles: the same nodes (leaf slots pointing at blocks), the same hits.
/// With the tree passed as an rvalue its node array is reused. The traced layout in one line:
/// `auto t = dynbvh::make_wide_blocks(dynbvh::ploc::build_wide<8>(tris, {.leaves = dynbvh::block_leaves}), tris);`
/// `tris`: as for the binary overload. O(references), parallel over `ex`, no node conversion.
template <int L = 0, class WN, class Prim, class Exec = exec::default_executor>
WideBvh<WN, prim::blocks<(L == 0 ? WN::width : L)>> make_wide_blocks(WideBvh<WN, Prim> wide,
                                                                      std::span<const Triangle<typename WN::scalar_type>> tris,
                                                                      const Exec& ex = {}) {
    return detail::blocks_of_wide<L>(std::move(wide), tris, ex);
}

/// The same from an indexed mesh read in place (mesh.hpp): the same tree as from make_triangles' array.
template <int L = 0, class WN, class Prim, class Index, class Exec = exec::default_executor>
WideBvh<WN, prim::blocks<(L == 0 ? WN::width : L)>> make_wide_blocks(WideBvh<WN, Prim> wide,
                                                                      const MeshView<typename WN::scalar_type, Index>& mesh,
                                                                      const Exec& ex = {}) {
    return detail::blocks_of_wide<L>(std::move(wide), mesh, ex);
}

/// Refits a block tree in place: every block lane reloads its triangle from `tris` (by the user index
/// it holds), then the boxes are recomputed as the wide refit does (refit.hpp), leaf slot boxes from the
/// blocks. Same contract as refit(WideBvh): a span whose size is not `bvh.primitive_count` throws
/// std::invalid_argument, `bvh` unchanged. The result equals make_wide_blocks of the refitted index
/// tree it was packed from, bit for bit (boxes, blocks, hits). O(nodes + references), parallel.
template <class WN, int L, class Exec = exec::default_executor>
void refit(WideBvh<WN, prim::blocks<L>>& bvh, std::span<const Triangle<float>> tris, const Exec& ex = {}) {
    detail::refit_blocks<false>(bvh, tris, ex);
}

/// The same from an indexed mesh read in place (mesh.hpp); the same blocks and boxes as from
/// make_triangles' array, bit for bit.
template <class WN, int L, class Index, class Exec = exec::default_executor>
void refit(WideBvh<WN, prim::blocks<L>>& bvh, const MeshView<float, Index>& mesh, const Exec& ex = {}) {
    detail::refit_blocks<false>(bvh, mesh, ex);
}

/// refit(blocks, tris, ex) that also returns the refitted tree's SAH (sah_cost of the wide tree, sah.hpp:
/// the same value, bit for bit) and counts the non-finite triangles it loaded (while loading them):
/// what the refit-or-rebuild policy needs each frame when it holds the traced tree itself
/// (Dynamic over a WideNode with prim::blocks, dynamic.hpp). The SAH is one pass over the nodes after
/// the refit. Same errors as refit.
template <class WN, int L, class Exec = exec::default_executor>
RefitReport refit_sah(WideBvh<WN, prim::blocks<L>>& bvh, std::span<const Triangle<float>> tris, const SahCost& cost = {},
                      const Exec& ex = {}) {
    const std::size_t nonfinite = detail::refit_blocks<true>(bvh, tris, ex);
    return {sah_cost(bvh, cost, ex), nonfinite};
}

/// refit_sah of a block tree from an indexed mesh read in place (mesh.hpp): the same blocks, boxes and
/// report as from make_triangles' array.
template <class WN, int L, class Index, class Exec = exec::default_executor>
RefitReport refit_sah(WideBvh<WN, prim::blocks<L>>& bvh, const MeshView<float, Index>& mesh, const SahCost& cost = {},
                      const Exec& ex = {}) {
    const std::size_t nonfinite = detail::refit_blocks<true>(bvh, mesh, ex);
    return {sah_cost(bvh, cost, ex), nonfinite};
}

} // namespace dynbvh
