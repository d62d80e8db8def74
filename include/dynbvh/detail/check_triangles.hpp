// SPDX-License-Identifier: MIT
/// @file detail/check_triangles.hpp
/// The one check every public function taking a tree (binary or wide) and the user's triangles
/// makes before touching them: the span must be the array the tree was built over, i.e. hold
/// exactly `primitive_count` triangles. A shorter span would be read out of bounds through the
/// leaves' triangle indices, a longer one means another array (its extra triangles are not in the tree).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace dynbvh::detail {

/// Empty when `given` triangles fit `tree`, else the message (starting with "dynbvh::<fn>: ").
template <class Tree>
std::string triangle_mismatch(const Tree& tree, std::size_t given, const char* fn) {
    if (given == tree.primitive_count) return {};
    return std::string("dynbvh::") + fn + ": " + std::to_string(given) + " triangles were passed (span or mesh view)" +
           " but the tree was built over " + std::to_string(tree.primitive_count) +
           " (primitive_count is " + std::to_string(tree.primitive_count) + "; pass the triangles it was built over)";
}

/// Throws std::invalid_argument with triangle_mismatch's message when `given` does not fit `tree`.
/// `reads` says whether `fn` reads the triangles at all: traversal of prim::copied trees does
/// not (their leaves hold copies), so any span, even an empty one, is accepted there.
template <class Tree>
void check_triangles(const Tree& tree, std::size_t given, const char* fn, bool reads = true) {
    // (the comparison first: building even an empty message per traced ray cost about 3% of a primary ray)
    if (!reads || given == tree.primitive_count) [[likely]] return;
    throw std::invalid_argument(triangle_mismatch(tree, given, fn));
}

} // namespace dynbvh::detail
