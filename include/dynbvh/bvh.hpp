// SPDX-License-Identifier: MIT
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
/// The tree keeps its own copy of the triangles in leaf order (`leaf_triangles`), so traversal
/// reads contiguous memory (faster tracing, 36 extra bytes per float reference); refit updates it.
struct copied {};
/// The former name of prim::copied (it copies, it precomputes nothing).
using precomputed [[deprecated("use dynbvh::prim::copied")]] = copied;
} // namespace prim

/// The leaf part every tree shares, binary (`Bvh`) or wide (`WideBvh`, wide.hpp): the references its
/// leaves point into and the input counts. A conversion between tree shapes moves this one part.
/// A primitive policy that stores more per leaf slot adds its arrays here.
template <class Scalar, class Index, class PrimPolicy>
struct LeafPart {
    /// The bounds' and triangles' scalar type.
    using scalar_type = Scalar;
    /// The type of the references (`prim_ids`) and node indices.
    using index_type = Index;
    /// prim::indexed or prim::copied.
    using prim_policy = PrimPolicy;
    /// The triangle type the tree is built over.
    using triangle_type = Triangle<Scalar>;
    /// Whether leaves read `leaf_triangles` (prim::copied) instead of the user's array.
    static constexpr bool precomputed = std::is_same_v<PrimPolicy, prim::copied>;

    /// Leaf slot -> index of the user's triangle. A triangle split by presplitting may appear in several
    /// leaves, but at most once per leaf. Large blocks come from the scratch cache (detail/scratch.hpp).
    scratch_vector<index_type> prim_ids;
    /// prim::copied only: copy of tris[prim_ids[slot]] for every slot.
    scratch_vector<triangle_type> leaf_triangles;
    /// Input triangles given to the builder.
    std::size_t primitive_count = 0;
    /// Input triangles left out because a vertex was NaN or infinite (they can never be hit).
    std::size_t excluded = 0;

    /// This part alone (to move it between trees).
    LeafPart& leaves() noexcept { return *this; }
    /// This part alone, read-only.
    const LeafPart& leaves() const noexcept { return *this; }
    /// The triangle behind leaf slot `slot`.
    const triangle_type& triangle(std::span<const triangle_type> tris, std::size_t slot) const noexcept {
        if constexpr (precomputed) return leaf_triangles[slot];
        else return tris[prim_ids[slot]];
    }
    /// Bytes of the references and the leaf triangles.
    std::size_t leaf_bytes() const noexcept {
        return prim_ids.size() * sizeof(index_type) + leaf_triangles.size() * sizeof(triangle_type);
    }
};

/// A binary BVH over triangles: nodes (see node.hpp) over a LeafPart.
/// @tparam NodeT       node layout (see node.hpp), default 32-byte float/uint32 node
/// @tparam PrimPolicy  prim::indexed (default) or prim::copied
template <class NodeT = Node<>, class PrimPolicy = prim::indexed>
struct Bvh : LeafPart<typename NodeT::scalar_type, typename NodeT::index_type, PrimPolicy> {
    /// The binary node layout.
    using node_type = NodeT;
    /// The shared leaf part (LeafPart).
    using leaf_part = LeafPart<typename NodeT::scalar_type, typename NodeT::index_type, PrimPolicy>;
    /// The bounds' scalar type (float or double).
    using scalar_type = typename NodeT::scalar_type;   // the rest (index_type, prim_policy, ...) from LeafPart

    /// Root at 0; an inner node's children are adjacent (see node.hpp). Empty when there is nothing to trace.
    /// The arrays are std::vectors whose large blocks come from the scratch cache (detail/scratch.hpp):
    /// a dynamic scene rebuilding every frame reuses the previous frame's blocks instead of faulting in
    /// fresh pages (about 3 microseconds per 4 KiB page, tens of ms per frame at a million triangles).
    /// Freed blocks stay cached for the next build; release_scratch() returns them to the system.
    scratch_vector<NodeT> nodes;
    /// Edges from the root to the deepest leaf (0 for a single leaf); always <= max_depth.
    std::uint32_t depth = 0;

    /// True when there is nothing to trace (no triangle, or none finite).
    bool empty() const noexcept { return nodes.empty(); }
    /// The root's box (the empty box for an empty tree).
    AABB<scalar_type> bounds() const noexcept { return empty() ? AABB<scalar_type>{} : nodes[0].bounds(); }
    /// Bytes held by the tree (nodes, references and copied leaf triangles).
    std::size_t memory_bytes() const noexcept { return nodes.size() * sizeof(NodeT) + this->leaf_bytes(); }
};

} // namespace dynbvh
