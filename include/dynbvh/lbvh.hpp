/// @file lbvh.hpp
/// LBVH: the linear BVH of Lauterbach et al. 2009 in the fully parallel radix-tree form of
/// Karras 2012, "Maximizing Parallelism in the Construction of BVHs, Octrees, and k-d Trees".
/// Steps: Morton codes of reference centres -> radix sort -> every inner node i of the
/// radix tree finds its key range and split independently -> boxes bottom-up and SAH leaf
/// collapse (collapse.hpp). Equal codes are told apart by appending the sorted index to the
/// key ("index augmentation"), so duplicates form a balanced subtree instead of a chain.
/// Fastest builder, lowest quality. O(n) work per step, fully parallel.
#pragma once

#include <bit>
#include <cstdint>
#include <span>
#include <vector>

#include "bvh.hpp"
#include "collapse.hpp"
#include "executor.hpp"
#include "morton.hpp"
#include "references.hpp"

namespace dynbvh::lbvh {

/// LBVH knobs.
struct Config {
    int morton_bits = 30;      ///< 30 (uint32 keys, faster sort) or 63 (uint64 keys, finer grid for large scenes)
    LeafConfig leaves{};       ///< SAH leaf collapse
};

namespace detail {

/// Karras's radix tree over sorted keys. Inner node i covers a key range with i at one end.
template <class Key, class Exec>
BinaryTree radix_tree(std::span<const Key> keys, const Exec& ex) {
    const auto n = static_cast<std::int64_t>(keys.size());
    BinaryTree tree;
    if (n == 0) return tree;
    if (n == 1) { tree.root = BinaryTree::leaf(0); return tree; }
    tree.left.resize(std::size_t(n - 1));
    tree.right.resize(std::size_t(n - 1));
    tree.root = 0;
    // Length of the common prefix of keys i and j (index-augmented), -1 when j is out of range.
    auto delta = [&](std::int64_t i, std::int64_t j) -> int {
        if (j < 0 || j >= n) return -1;
        const Key a = keys[std::size_t(i)], b = keys[std::size_t(j)];
        if (a != b) return std::countl_zero(Key(a ^ b));
        return int(sizeof(Key) * 8) + std::countl_zero(std::uint64_t(i ^ j));
    };
    ex.for_each(0, std::size_t(n - 1), [&](std::size_t ui) {
        const auto i = static_cast<std::int64_t>(ui);
        const int d = delta(i, i + 1) > delta(i, i - 1) ? 1 : -1;
        const int delta_min = delta(i, i - d);
        std::int64_t lmax = 2;
        while (delta(i, i + lmax * d) > delta_min) lmax *= 2;
        std::int64_t l = 0;
        for (std::int64_t t = lmax / 2; t >= 1; t /= 2)
            if (delta(i, i + (l + t) * d) > delta_min) l += t;
        const std::int64_t j = i + l * d;
        const int delta_node = delta(i, j);
        std::int64_t s = 0;
        for (std::int64_t t = (l + 1) / 2;; t = (t + 1) / 2) {
            if (delta(i, i + (s + t) * d) > delta_node) s += t;
            if (t == 1) break;
        }
        const std::int64_t gamma = i + s * d + std::min(d, 0);
        const std::int64_t lo = std::min(i, j), hi = std::max(i, j);
        tree.left[ui] = lo == gamma ? BinaryTree::leaf(std::uint32_t(gamma)) : std::uint32_t(gamma);
        tree.right[ui] = hi == gamma + 1 ? BinaryTree::leaf(std::uint32_t(gamma + 1)) : std::uint32_t(gamma + 1);
    });
    return tree;
}

} // namespace detail

/// Raw LBVH topology over `refs` (see BinaryTree). Reorders `refs` into Morton order; the
/// tree's leaf ids index the reordered refs. Used by build() and by kbvh (presplit + LBVH).
template <class T, class Exec>
BinaryTree build_tree(References<T>& refs, const Config& cfg, const Exec& ex) {
    if (cfg.morton_bits > 30) {
        const auto keys = morton::sort_references<std::uint64_t>(refs, ex);
        return detail::radix_tree<std::uint64_t>(std::span<const std::uint64_t>(keys), ex);
    }
    const auto keys = morton::sort_references<std::uint32_t>(refs, ex);
    return detail::radix_tree<std::uint32_t>(std::span<const std::uint32_t>(keys), ex);
}

/// Builds an LBVH over `tris`. One line: `auto bvh = dynbvh::lbvh::build(tris);`
/// Triangles with NaN/infinite vertices are left out and counted in Bvh::excluded.
/// @tparam NodeT node layout, @tparam Prim prim::indexed or prim::precomputed, @tparam Exec backend.
template <class NodeT = Node<>, class Prim = prim::indexed, class Exec = exec::default_executor>
Bvh<NodeT, Prim> build(std::span<const Triangle<typename NodeT::scalar_type>> tris, const Config& cfg = {}, const Exec& ex = {}) {
    auto refs = make_references(tris, ex);
    const auto tree = build_tree(refs, cfg, ex);
    return emit_bvh<NodeT, Prim>(tree, refs, tris, cfg.leaves, ex);
}

} // namespace dynbvh::lbvh
