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
    using scalar_type = Scalar;
    using index_type = Index;

    Vec3<Scalar> min;   ///< lower corner of the bounds
    Vec3<Scalar> max;   ///< upper corner of the bounds
    Index index = 0;    ///< inner: index of the first child (second is index + 1); leaf: first prim_ids slot
    Index count = 0;    ///< 0 for inner nodes, number of references for leaves

    constexpr bool is_leaf() const noexcept { return count != 0; }
    constexpr AABB<Scalar> bounds() const noexcept { return {min, max}; }
    constexpr void set_bounds(const AABB<Scalar>& b) noexcept { min = b.min; max = b.max; }
    constexpr Index left() const noexcept { return index; }
    constexpr Index right() const noexcept { return index + 1; }
};

static_assert(sizeof(Node<>) == 32, "the default node is 32 bytes");

} // namespace dynbvh
