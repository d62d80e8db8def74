// SPDX-License-Identifier: MIT
/// @file morton_wide.hpp
/// The fastest builder: a W-wide BVH (W = 4 or 8) straight from the sorted Morton codes, top down,
/// with no binary tree, no node facts and no SAH (the kind of build Embree's LOW quality does).
/// References are sorted along the Morton curve (Lauterbach et al. 2009, as LBVH); a key range is
/// split where its highest differing key bit changes (found by binary search, Karras 2012's split
/// rule), a range of equal keys at its middle. A wide node takes its range and splits its largest
/// child (by reference count) until it has W children or every child is a leaf: a range of at most
/// `max_leaf_size` references. Boxes are computed on the way back up, each reference box read once.
/// Leaves are contiguous runs of the Morton order, so `prim_ids` is the sorted reference array itself.
///
/// Against `lbvh::build_wide` (the LBVH radix tree, SAH leaf collapse, then the wide collapse by
/// area): fewer passes over memory (references, sort, one top-down pass), leaves sized by count rather
/// than by SAH, and children chosen by count rather than by area: a somewhat different tree of
/// similar quality (compare `sah_cost`), built in about half the time. Made for scenes rebuilt every
/// frame; pair it with block leaves (`make_wide_blocks`, wide_blocks.hpp) for tracing.
/// @code
///   auto wide = dynbvh::morton_wide::build(tris);                        // 8-wide, prim::indexed
///   auto fast = dynbvh::make_wide_blocks(dynbvh::morton_wide::build(tris, {}, ex), tris, ex);
/// @endcode
/// Parallel structure: the top of the tree is split serially, breadth first, until 256 ranges are
/// pending; each is built depth first by one task into its own array, and the arrays are concatenated
/// (as the wide conversions do): the same tree on every executor and thread count. O(n log n) for the
/// sort-free part's binary searches (short: within each range), O(n) memory traffic otherwise.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "bvh.hpp"
#include "detail/emit.hpp"
#include "detail/morton.hpp"
#include "detail/references.hpp"
#include "detail/scratch.hpp"
#include "detail/triangle_source.hpp"
#include "mesh.hpp"
#include "executor.hpp"
#include "wide.hpp"

namespace dynbvh::morton_wide {

/// morton_wide knobs.
struct Config {
    int morton_bits = 30;               ///< 30 (uint32 keys, faster sort) or 63 (uint64 keys, finer grid)
    std::uint32_t max_leaf_size = 8;    ///< most references per leaf (1..255): 8 fills one 8-lane triangle block
};

namespace detail {

/// A range [begin, end) of the sorted references.
struct Range {
    std::uint32_t begin, end;
    std::uint32_t size() const noexcept { return end - begin; }
};

/// Where range `r` splits: the first key whose highest bit differing within the range is set; the
/// middle when all its keys are equal. Both halves are non-empty (r.size() >= 2).
template <class Key>
inline std::uint32_t split_of(const Key* keys, Range r) noexcept {
    const Key a = keys[r.begin], b = keys[r.end - 1];
    if (a == b) return r.begin + r.size() / 2;
    const int bit = int(std::bit_width(a ^ b)) - 1;
    // keys[begin..end) agree above `bit`; bit `bit` is 0 then 1: find the first 1
    std::uint32_t lo = r.begin + 1, hi = r.end - 1;   // keys[lo - 1] has the bit clear, keys[hi] set
    while (lo < hi) {
        const std::uint32_t mid = lo + (hi - lo) / 2;
        if ((keys[mid] >> bit) & 1) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/// The children of the wide node over range `r` (r.size() > max_leaf): starting from `r`, the child
/// with the most references that is not a leaf is split in two (the halves in Morton order) while
/// fewer than W. Returns how many.
template <int W, class Key>
inline int open_range(const Key* keys, Range r, std::uint32_t max_leaf, Range* c) noexcept {
    c[0] = r;
    int n = 1;
    while (n < W) {
        int best = -1;
        for (int k = 0; k < n; ++k)
            if (c[k].size() > max_leaf && (best < 0 || c[k].size() > c[best].size())) best = k;
        if (best < 0) break;
        const std::uint32_t s = split_of(keys, c[best]);
        for (int k = n; k > best + 1; --k) c[k] = c[k - 1];
        c[best + 1] = {s, c[best].end};
        c[best].end = s;
        ++n;
    }
    return n;
}

/// Builds the subtree over `r` (r.size() > max_leaf) depth first into `out` (its root at `at`, child
/// indices local to `out`); returns its box. `deepest` is raised to the deepest wide level reached.
template <int W, class WNode, class Key, class T>
AABB<T> build_subtree(const Key* keys, const References<T>& refs, std::uint32_t max_leaf, Range r, std::size_t at,
                      std::uint32_t depth, scratch_vector<WNode>& out, std::uint32_t& deepest) {
    using Index = typename WNode::index_type;
    deepest = std::max(deepest, depth);
    Range c[std::size_t(W)];
    const int n = open_range<W>(keys, r, max_leaf, c);
    WNode w;
    w.clear();
    AABB<T> all;
    for (int k = 0; k < n; ++k) {
        AABB<T> box;
        if (c[k].size() <= max_leaf) {
            for (std::uint32_t i = c[k].begin; i < c[k].end; ++i) box.extend(refs.box[i]);
            w.child[k] = Index(c[k].begin);
            w.count[k] = Index(c[k].size());
        } else {
            const std::size_t child = out.size();
            out.emplace_back();
            box = build_subtree<W>(keys, refs, max_leaf, c[k], child, depth + 1, out, deepest);
            w.child[k] = Index(child);
        }
        w.set_bounds(k, box);
        all.extend(box);
    }
    out[at] = w;
    return all;
}

/// The tree over sorted `keys` / `refs` (see the file comment).
template <int W, class Result, class Key, class T, class Exec>
void build_nodes(const Key* keys, const References<T>& refs, std::uint32_t max_leaf, Result& wide, const Exec& ex) {
    using WNode = typename Result::node_type;
    using Index = typename WNode::index_type;
    const auto n = std::uint32_t(refs.size());
    if (n <= max_leaf) {   // one wide node with one leaf slot
        WNode w;
        w.clear();
        AABB<T> box;
        for (std::uint32_t i = 0; i < n; ++i) box.extend(refs.box[i]);
        w.set_bounds(0, box);
        w.child[0] = 0;
        w.count[0] = Index(n);
        wide.nodes.push_back(w);
        return;
    }
    struct Pending {
        Range range;          // range still to build (more than max_leaf references)
        Index parent;         // top node whose slot `slot` points to it
        int slot;
        std::uint32_t depth;  // its wide depth
    };
    constexpr std::size_t target = 256;   // as the wide conversions: the same tree on every executor
    std::vector<WNode> top;
    std::vector<Pending> queue;
    std::size_t head = 0;
    auto expand_top = [&](Range r, std::uint32_t depth) {
        const auto id = Index(top.size());
        Range c[std::size_t(W)];
        const int m = open_range<W>(keys, r, max_leaf, c);
        WNode w;
        w.clear();
        for (int k = 0; k < m; ++k) {
            if (c[k].size() <= max_leaf) {
                AABB<T> box;
                for (std::uint32_t i = c[k].begin; i < c[k].end; ++i) box.extend(refs.box[i]);
                w.set_bounds(k, box);
                w.child[k] = Index(c[k].begin);
                w.count[k] = Index(c[k].size());
            } else {
                w.set_bounds(k, AABB<T>{refs.bounds.min, refs.bounds.max});   // a valid box until the subtree's is known
                queue.push_back({c[k], id, k, depth + 1});
            }
        }
        top.push_back(w);
        wide.depth = std::max(wide.depth, depth);
        return id;
    };
    // Step 1: the top, breadth first and serially, until `target` ranges are pending.
    expand_top({0, n}, 0);
    while (head < queue.size() && queue.size() - head < target) {
        const Pending p = queue[head++];
        top[p.parent].child[p.slot] = expand_top(p.range, p.depth);
    }
    // Step 2: each pending range depth first by one task, into its own array.
    const std::size_t tasks = queue.size() - head;
    std::vector<scratch_vector<WNode>> local(tasks);
    std::vector<std::uint32_t> local_depth(tasks, 0);
    std::vector<AABB<T>> local_box(tasks);
    ex.for_tasks(tasks, [&](std::size_t k) {
        const Pending& p = queue[head + k];
        scratch_vector<WNode>& out = local[k];
        out.reserve(p.range.size() / (W * max_leaf / 2) + 8);
        out.emplace_back();
        local_depth[k] = p.depth;
        local_box[k] = build_subtree<W>(keys, refs, max_leaf, p.range, 0, p.depth, out, local_depth[k]);
    });
    for (std::size_t k = 0; k < tasks; ++k) top[queue[head + k].parent].set_bounds(queue[head + k].slot, local_box[k]);
    // Step 3: the top slots' boxes bottom-up (a top node's inner children come after it, breadth first),
    // then the arrays after the top, linked in, with shifted child indices.
    for (std::size_t i = head; i-- > 0;) {
        const Pending& p = queue[i];
        top[p.parent].set_bounds(p.slot, top[top[p.parent].child[p.slot]].bounds());
    }
    dynbvh::detail::concatenate_wide<W>(top, queue.data() + head, local, local_depth, wide.nodes, wide.depth, ex);
}

} // namespace detail

namespace detail {

/// build over any triangle source (a span or a MeshView): one code path.
template <int W, class NodeT, class Prim, class Source, class Exec>
WideBvh<WideNode<typename NodeT::scalar_type, typename NodeT::index_type, W>, Prim> build(Source tris, const Config& cfg,
                                                                                         const Exec& ex) {
    using T = typename NodeT::scalar_type;
    using Result = WideBvh<WideNode<T, typename NodeT::index_type, W>, Prim>;
    morton::check_bits(cfg.morton_bits, "dynbvh::morton_wide::build");
    if (cfg.max_leaf_size < 1 || cfg.max_leaf_size > 255)
        throw std::invalid_argument("dynbvh::morton_wide::build: max_leaf_size must be 1..255, got " + std::to_string(cfg.max_leaf_size));
    BinaryTree::check_size(tris.size(), "dynbvh::morton_wide::build");
    auto refs = make_references(tris, ex);
    Result wide;
    wide.primitive_count = refs.primitive_count;
    wide.excluded = refs.excluded;
    if (refs.size() == 0) return wide;
    // Sort along the curve, then split top down.
    auto run = [&](auto key) {
        using Key = decltype(key);
        const scratch_vector<Key> keys = morton::sort_references<Key>(refs, ex);
        build_nodes<W>(keys.data(), refs, cfg.max_leaf_size, wide, ex);
    };
    if (cfg.morton_bits == 63) run(std::uint64_t{});
    else run(std::uint32_t{});
    // Leaves are runs of the sorted references: their prim array is prim_ids as it stands.
    if constexpr (std::is_same_v<decltype(wide.prim_ids), decltype(refs.prim)>) {
        wide.prim_ids = std::move(refs.prim);
    } else {
        wide.prim_ids.resize(refs.size());
        ex.for_each(0, refs.size(), [&](std::size_t i) { wide.prim_ids[i] = typename NodeT::index_type(refs.prim[i]); });
    }
    if constexpr (Result::precomputed) {
        wide.leaf_triangles.resize(wide.prim_ids.size());
        ex.for_each(0, wide.prim_ids.size(), [&](std::size_t s) { wide.leaf_triangles[s] = tris[wide.prim_ids[s]]; });
    }
    return wide;
}

} // namespace detail

/// Builds a W-wide BVH over `tris` straight from the sorted Morton codes (see the file comment).
/// Triangles with NaN/infinite vertices are left out and counted in `excluded`. Throws
/// std::invalid_argument for morton_bits other than 30 or 63 or a max_leaf_size outside 1..255,
/// std::length_error beyond 2^31 - 1 triangles. O(n) passes plus the radix sort, parallel over `ex`.
/// @tparam W 4 or 8, @tparam NodeT the binary node type whose scalar and index the wide node takes,
/// @tparam Prim prim::indexed or prim::copied.
template <int W = 8, class NodeT = Node<>, class Prim = prim::indexed, class Exec = exec::default_executor>
WideBvh<WideNode<typename NodeT::scalar_type, typename NodeT::index_type, W>, Prim>
build(std::span<const Triangle<typename NodeT::scalar_type>> tris, const Config& cfg = {}, const Exec& ex = {}) {
    return detail::build<W, NodeT, Prim>(tris, cfg, ex);
}

/// The same over an indexed mesh read in place (mesh.hpp): the tree `build` gives over
/// `make_triangles(vertices, indices)`, bit for bit, without that copy. NodeT defaults to Node<T>.
template <int W = 8, class NodeT = void, class Prim = prim::indexed, class Exec = exec::default_executor, class T, class Index>
WideBvh<WideNode<T, typename dynbvh::detail::node_for_t<NodeT, T>::index_type, W>, Prim>
build(const MeshView<T, Index>& mesh, const Config& cfg = {}, const Exec& ex = {}) {
    return detail::build<W, dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, ex);
}

/// The same for a std::vector of triangles of any scalar: `dynbvh::morton_wide::build(tris)`.
template <int W = 8, class T, class Exec = exec::default_executor>
WideBvh<WideNode<T, std::uint32_t, W>> build(const std::vector<Triangle<T>>& tris, const Config& cfg = {}, const Exec& ex = {}) {
    return build<W, Node<T>, prim::indexed, Exec>(std::span<const Triangle<T>>(tris), cfg, ex);
}

} // namespace dynbvh::morton_wide
