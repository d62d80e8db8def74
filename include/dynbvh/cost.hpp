// SPDX-License-Identifier: MIT
/// @file cost.hpp
/// The surface area heuristic's cost model, one for every decision and metric: the leaf collapse of
/// every builder (LeafConfig), `sah_cost` and `epo` (sah.hpp) take the same `SahCost`.
#pragma once

#include <cstdint>

#include "aabb.hpp"

namespace dynbvh {

/// Ct per inner node visited, Ci per primitive intersected (MacDonald and Booth 1990). Defaults are
/// the study's (Ct = 3, Ci = 2, after the PLOC paper).
struct SahCost {
    double ct = 3;  ///< traversal cost of an inner node
    double ci = 2;  ///< intersection cost of one reference in a leaf
};
/// The name sah_cost and epo used before SahCost served every decision.
using SahConfig = SahCost;

/// Leaf collapse knobs shared by every builder (detail/emit.hpp): a subtree becomes one leaf when
/// Ci * A * N <= Ct * A + its children's cost and N <= max_leaf_size.
struct LeafConfig {
    std::uint32_t max_leaf_size = 8;  ///< most references in one leaf (1 disables collapsing)
    SahCost cost{};                   ///< Ct and Ci of the collapse decision
};

namespace detail {
/// Surface area of `b` in double (0 for an empty box): the one area of the metrics. Decisions compare
/// `b.half_area_in<double>()` (aabb.hpp), which this is twice.
template <class T>
inline double area(const AABB<T>& b) noexcept {
    return 2.0 * b.template half_area_in<double>();
}
} // namespace detail

} // namespace dynbvh
