// SPDX-License-Identifier: MIT
/// @file node.hpp
/// The node layout policy. Every builder emits the same layout:
///  - the root is node 0;
///  - an inner node (count == 0) has its two children adjacent at `index` and `index + 1`;
///  - a leaf (count > 0) references `count` consecutive entries of Bvh::prim_ids starting at `index`.
/// The default Node<float, uint32_t> is 32 bytes: two float corners and a packed first/count pair.
#pragma once

#include <cstdint>
#include <type_traits>

#include "aabb.hpp"

namespace dynbvh {

/// Binary BVH node templated on the bounds scalar and the index width.
/// Node<float, uint32_t> (default, 32 bytes) holds up to 2^32 - 1 references;
/// Node<double, uint64_t> (64 bytes) suits very large or very precise scenes.
template <class Scalar = float, class Index = std::uint32_t>
struct Node {
    static_assert(std::is_floating_point_v<Scalar> && std::is_unsigned_v<Index>);
    /// The bounds' scalar type.
    using scalar_type = Scalar;
    /// The type of `index` and `count`.
    using index_type = Index;

    Vec3<Scalar> min;   ///< lower corner of the bounds
    Vec3<Scalar> max;   ///< upper corner of the bounds
    Index index = 0;    ///< inner: index of the first child (second is index + 1); leaf: first prim_ids slot
    Index count = 0;    ///< 0 for inner nodes, number of references for leaves

    /// True for a leaf (count > 0).
    constexpr bool is_leaf() const noexcept { return count != 0; }
    /// The node's box.
    constexpr AABB<Scalar> bounds() const noexcept { return {min, max}; }
    /// Sets the node's box.
    constexpr void set_bounds(const AABB<Scalar>& b) noexcept { min = b.min; max = b.max; }
    /// Index of the first child (inner nodes only).
    constexpr Index left() const noexcept { return index; }
    /// Index of the second child, left() + 1 (inner nodes only).
    constexpr Index right() const noexcept { return index + 1; }
};

static_assert(sizeof(Node<>) == 32, "the default node is 32 bytes");

} // namespace dynbvh
