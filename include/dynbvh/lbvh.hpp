// SPDX-License-Identifier: MIT
/// @file lbvh.hpp
/// LBVH: the linear BVH of Lauterbach et al. 2009 as a binary radix tree over the sorted Morton
/// codes (Karras 2012, "Maximizing Parallelism in the Construction of BVHs, Octrees, and k-d Trees"),
/// built bottom-up as in Apetrei 2014, "Fast and Simple Agglomerative LBVH Construction": every
/// leaf walks up, each node knowing its key range [lo, hi]; its parent is the neighbouring node
/// that shares the longer key prefix (split at hi, or at lo - 1), and the second child to arrive
/// at a parent carries on. The walk computes each node's box and SAH leaf collapse on the way
/// (detail/emit.hpp's CollapseRule), so no separate bottom-up pass is needed before emission.
/// Equal codes are told apart by appending the sorted index to the key ("index augmentation"),
/// so duplicates form a balanced subtree instead of a chain. Inner node ids are split positions
/// (node p separates sorted references p and p + 1), so a node's id lies between its leaves.
/// Fastest builder, lowest quality. O(n) work per step, fully parallel.
#pragma once

#include <atomic>
#include <bit>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "bvh.hpp"
#include "detail/emit.hpp"
#include "detail/emit_wide.hpp"
#include "executor.hpp"
#include "mesh.hpp"
#include "detail/morton.hpp"
#include "detail/references.hpp"
#include "detail/sah_top.hpp"
#include "detail/scratch.hpp"
#include "detail/triangle_source.hpp"

namespace dynbvh::lbvh {

/// LBVH knobs.
struct Config {
    int morton_bits = 30;      ///< 30 (uint32 keys, faster sort) or 63 (uint64 keys, finer grid for large scenes)
    LeafConfig leaves{};       ///< SAH leaf collapse
    /// 0 (default): the plain LBVH (the thesis's builder). m > 0: HLBVH (Pantaleoni and Luebke 2010):
    /// the tree above the subtrees of at most m references is rebuilt by binned SAH over those subtrees
    /// (detail/sah_top.hpp): a better top for a little more build time. `build_tree` ignores it.
    std::uint32_t sah_top = 0;
};

namespace detail {

using dynbvh::detail::CollapseRule;
using dynbvh::detail::RawNodeInfo;

/// How far apart sorted keys i and i + 1 are, as one integer: smaller = longer common prefix of
/// the index-augmented keys (key bits, then position bits). For 32-bit keys that is the XOR of the
/// augmented keys itself; 64-bit keys that differ are moved above every equal pair instead. Only
/// the order of the two ends of one key range matters, and those never share a prefix length
/// (Apetrei 2014), so any order that agrees with the prefix lengths will do.
template <class Key>
inline std::uint64_t split_distance(const Key* keys, std::size_t i) noexcept {
    const Key x = keys[i] ^ keys[i + 1];
    const std::uint64_t pos = std::uint32_t(i ^ (i + 1));
    if constexpr (sizeof(Key) == 4) return (std::uint64_t(x) << 32) | pos;
    else return x != 0 ? (std::uint64_t(x) | (std::uint64_t(1) << 63)) : pos;   // codes use 63 bits
}

/// The radix tree over sorted `keys`, built bottom-up; when `info` is given (size n - 1), also the
/// facts of every inner node under `rule`, from the boxes of the (sorted) references `refs`.
template <class Key, class T, class Exec>
BinaryTree radix_tree(std::span<const Key> keys, const References<T>& refs, const CollapseRule<T>& rule,
                      RawNodeInfo<T>* info, const Exec& ex) {
    const std::size_t n = keys.size();
    BinaryTree tree = BinaryTree::start(n, "dynbvh::lbvh");
    if (n < 2) return tree;
    tree.left.resize(n - 1);
    tree.right.resize(n - 1);
    constexpr std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
    // The far end of the range of the first child to arrive at each node (none: no child yet).
    scratch_vector<std::atomic<std::uint32_t>> other(n - 1);
    ex.for_each(0, n - 1, [&](std::size_t i) { other[i].store(none, std::memory_order_relaxed); });
    const Key* k = keys.data();
    const auto last = static_cast<std::uint32_t>(n - 1);
    std::uint32_t root = 0;
    ex.for_each(0, n, [&](std::size_t i) {
        std::uint32_t lo = std::uint32_t(i), hi = lo, node = BinaryTree::leaf(lo);
        for (;;) {
            // Parent: split at hi (we are its left child) or at lo - 1 (its right child).
            const bool left_child = lo == 0 || (hi != last && split_distance(k, hi) < split_distance(k, lo - 1));
            const std::uint32_t p = left_child ? hi : lo - 1;
            (left_child ? tree.left : tree.right)[p] = node;
            const std::uint32_t far = other[p].exchange(left_child ? lo : hi, std::memory_order_acq_rel);
            if (far == none) return;   // the sibling is not finished: it carries on
            (left_child ? hi : lo) = far;
            if (info) rule.node(tree, refs, info, p);
            node = p;
            if (lo == 0 && hi == last) { root = p; return; }
        }
    });
    tree.root = root;
    return tree;
}

/// Sorts `refs` along the Morton curve and builds the radix tree (and the node facts, see radix_tree).
template <class T, class Exec>
BinaryTree build_tree(References<T>& refs, const Config& cfg, RawNodeInfo<T>* info, const Exec& ex) {
    morton::check_bits(cfg.morton_bits, "dynbvh::lbvh");
    const CollapseRule<T> rule(cfg.leaves);
    if (cfg.morton_bits == 63) {
        const auto keys = morton::sort_references<std::uint64_t>(refs, ex);
        return radix_tree<std::uint64_t>(std::span<const std::uint64_t>(keys), refs, rule, info, ex);
    }
    const auto keys = morton::sort_references<std::uint32_t>(refs, ex);
    return radix_tree<std::uint32_t>(std::span<const std::uint32_t>(keys), refs, rule, info, ex);
}

} // namespace detail

/// Raw LBVH topology over `refs` (see BinaryTree). Reorders `refs` into Morton order; the
/// tree's leaf ids index the reordered refs. Used by kbvh (presplit + LBVH).
/// Throws std::invalid_argument for morton_bits other than 30 or 63, std::length_error beyond 2^31 - 1 references.
template <class T, class Exec>
BinaryTree build_tree(References<T>& refs, const Config& cfg, const Exec& ex) {
    return detail::build_tree(refs, cfg, static_cast<detail::RawNodeInfo<T>*>(nullptr), ex);
}

namespace detail {

/// Config::sah_top: the radix tree's top rebuilt by binned SAH over its subtrees of at most sah_top references.
template <class T, class Exec>
void rebuild_top(BinaryTree& tree, const References<T>& refs, const Config& cfg, std::span<RawNodeInfo<T>> info, const Exec& ex) {
    dynbvh::detail::rebuild_top_by_sah(tree, refs, CollapseRule<T>(cfg.leaves), info, cfg.sah_top, ex);
}

/// build and build_wide over any triangle source (a span or a MeshView): one code path.
template <class NodeT, class Prim, class Source, class Exec>
Bvh<NodeT, Prim> build(Source tris, const Config& cfg, const Exec& ex) {
    using T = typename NodeT::scalar_type;
    auto refs = make_references(tris, ex);
    // The bottom-up construction computes every node's box and leaf collapse as it goes.
    scratch_vector<RawNodeInfo<T>> info(refs.size() > 1 ? refs.size() - 1 : 0);
    auto tree = build_tree(refs, cfg, info.data(), ex);
    if (cfg.sah_top != 0) rebuild_top(tree, refs, cfg, std::span<RawNodeInfo<T>>(info), ex);
    return dynbvh::detail::emit_from_info<NodeT, Prim>(tree, refs, tris, std::span<const RawNodeInfo<T>>(info), ex);
}

template <int W, class NodeT, class Prim, class Source, class Exec>
wide_bvh_of<Bvh<NodeT, Prim>, W> build_wide(Source tris, const Config& cfg, const Exec& ex) {
    using T = typename NodeT::scalar_type;
    auto refs = make_references(tris, ex);
    scratch_vector<RawNodeInfo<T>> info(refs.size() > 1 ? refs.size() - 1 : 0);
    auto tree = build_tree(refs, cfg, info.data(), ex);
    if (cfg.sah_top != 0) rebuild_top(tree, refs, cfg, std::span<RawNodeInfo<T>>(info), ex);
    return dynbvh::detail::emit_wide_from_info<W, NodeT, Prim>(tree, refs, tris, std::span<const RawNodeInfo<T>>(info), ex);
}

} // namespace detail

/// Builds an LBVH over `tris`. One line: `auto bvh = dynbvh::lbvh::build(tris);`
/// Triangles with NaN/infinite vertices are left out and counted in Bvh::excluded.
/// @tparam NodeT node layout, @tparam Prim prim::indexed or prim::copied, @tparam Exec backend.
template <class NodeT = Node<>, class Prim = prim::indexed, class Exec = exec::default_executor>
Bvh<NodeT, Prim> build(std::span<const Triangle<typename NodeT::scalar_type>> tris, const Config& cfg = {}, const Exec& ex = {}) {
    return detail::build<NodeT, Prim>(tris, cfg, ex);
}

/// Builds an LBVH over an indexed mesh read in place (mesh.hpp): the tree `build` gives over
/// `make_triangles(vertices, indices)`, bit for bit, without that copy. NodeT defaults to Node<T>.
template <class NodeT = void, class Prim = prim::indexed, class Exec = exec::default_executor, class T, class Index>
Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim> build(const MeshView<T, Index>& mesh, const Config& cfg = {}, const Exec& ex = {}) {
    return detail::build<dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, ex);
}

/// Builds an LBVH straight into the W-wide layout (W = 4 or 8; detail/emit_wide.hpp): the tree
/// `make_wide<W>(build<NodeT, Prim>(tris, cfg, ex), ex)` gives, bit for bit, without the binary nodes.
/// One line: `auto wide = dynbvh::lbvh::build_wide<8>(tris, {}, ex);`
template <int W = 8, class NodeT = Node<>, class Prim = prim::indexed, class Exec = exec::default_executor>
wide_bvh_of<Bvh<NodeT, Prim>, W> build_wide(std::span<const Triangle<typename NodeT::scalar_type>> tris,
                                            const Config& cfg = {}, const Exec& ex = {}) {
    return detail::build_wide<W, NodeT, Prim>(tris, cfg, ex);
}

/// build_wide over an indexed mesh read in place (mesh.hpp); same tree as over make_triangles' array.
template <int W = 8, class NodeT = void, class Prim = prim::indexed, class Exec = exec::default_executor, class T, class Index>
wide_bvh_of<Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim>, W> build_wide(const MeshView<T, Index>& mesh, const Config& cfg = {},
                                                                         const Exec& ex = {}) {
    return detail::build_wide<W, dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, ex);
}

/// The same for a std::vector of triangles of any scalar, the node type following the triangles:
/// `dynbvh::lbvh::build(std::vector<Triangled>{...})` is a Bvh<Node<double>>.
template <int = 0, class T, class Exec = exec::default_executor>
Bvh<Node<T>> build(const std::vector<Triangle<T>>& tris, const Config& cfg = {}, const Exec& ex = {}) {
    return build<Node<T>, prim::indexed, Exec>(std::span<const Triangle<T>>(tris), cfg, ex);
}

} // namespace dynbvh::lbvh
