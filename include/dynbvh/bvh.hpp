/// @file bvh.hpp
/// The one BVH type every builder returns, and the primitive policies.
/// Traversal, SAH, refit, validation and the benchmark only ever see `Bvh`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>
#include <vector>

#include "node.hpp"
#include "detail/scratch.hpp"
#include "triangle.hpp"

namespace dynbvh {

/// Traversal uses a fixed stack of this many entries; every builder guarantees
/// `Bvh::depth <= max_depth` (deeper subtrees are rebalanced when the tree is emitted).
inline constexpr std::uint32_t max_depth = 64;

/// Primitive policies: how leaves reach triangles.
namespace prim {
/// Leaves index the user's triangle array (`tris[prim_ids[slot]]`). Smallest tree;
/// the user's array must stay alive and unchanged (or be refitted) while tracing.
struct indexed {};
/// The Bvh keeps its own copy of the triangles in leaf order, so traversal reads
/// contiguous memory (faster tracing, 36 extra bytes per reference).
struct precomputed {};
} // namespace prim

/// A binary BVH over triangles.
/// @tparam NodeT       node layout (see node.hpp), default 32-byte float/uint32 node
/// @tparam PrimPolicy  prim::indexed (default) or prim::precomputed
template <class NodeT = Node<>, class PrimPolicy = prim::indexed>
struct Bvh {
    using node_type = NodeT;
    using scalar_type = typename NodeT::scalar_type;
    using index_type = typename NodeT::index_type;
    using prim_policy = PrimPolicy;
    using triangle_type = Triangle<scalar_type>;
    static constexpr bool precomputed = std::is_same_v<PrimPolicy, prim::precomputed>;

    /// Root at 0; an inner node's children are adjacent (see node.hpp). Empty when there is nothing to trace.
    /// The three arrays are std::vectors whose large blocks come from the scratch cache (scratch.hpp):
    /// a dynamic scene rebuilding every frame reuses the previous frame's blocks instead of faulting in
    /// fresh pages (about 3 microseconds per 4 KiB page, tens of ms per frame at a million triangles).
    /// Freed blocks stay cached for the next build; release_scratch() returns them to the system.
    scratch_vector<NodeT> nodes;
    /// Leaf slot -> index of the user's triangle. A triangle split by presplitting may appear in several
    /// leaves, but at most once per leaf.
    scratch_vector<index_type> prim_ids;
    /// prim::precomputed only: copy of tris[prim_ids[slot]] for every slot.
    scratch_vector<triangle_type> leaf_triangles;
    /// Edges from the root to the deepest leaf (0 for a single leaf); always <= max_depth.
    std::uint32_t depth = 0;
    /// Input triangles given to the builder.
    std::size_t primitive_count = 0;
    /// Input triangles left out because a vertex was NaN or infinite (they can never be hit).
    std::size_t excluded = 0;

    bool empty() const noexcept { return nodes.empty(); }
    AABB<scalar_type> bounds() const noexcept { return empty() ? AABB<scalar_type>{} : nodes[0].bounds(); }
    /// Bytes held by the tree (nodes, references and precomputed triangles).
    std::size_t memory_bytes() const noexcept {
        return nodes.size() * sizeof(NodeT) + prim_ids.size() * sizeof(index_type) +
               leaf_triangles.size() * sizeof(triangle_type);
    }
    /// The triangle behind leaf slot `slot`.
    const triangle_type& triangle(std::span<const triangle_type> tris, std::size_t slot) const noexcept {
        if constexpr (precomputed) return leaf_triangles[slot];
        else return tris[prim_ids[slot]];
    }
};

} // namespace dynbvh
