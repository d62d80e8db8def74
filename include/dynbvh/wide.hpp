// SPDX-License-Identifier: MIT
/// @file wide.hpp
/// A 4- or 8-wide BVH converted from any binary `Bvh`. Including this header is enough to trace it
/// (traverse_wide.hpp: intersect / occluded, the same answers as on the binary tree).
/// @code
///   auto bvh  = dynbvh::lbvh::build(tris, {}, ex);
///   auto wide = dynbvh::make_wide(std::move(bvh), ex);        // O(n), parallel over `ex` (or copy: make_wide(bvh, ex))
///   auto w8   = dynbvh::make_wide<8>(other_bvh, ex);          // 8 children per node (best with AVX)
///   auto hit  = dynbvh::intersect(wide, tris, ray);           // same answer as intersect(bvh, ...)
/// @endcode
///
/// Layout: a `WideNode<Scalar, Index, W>` holds the boxes of up to W children in structure-of-arrays
/// form (lo_x[W], hi_x[W], ...), so one traversal step tests all W boxes with one SIMD instruction per
/// slab plane. A slot is an inner node (count 0, `child` = node index), a leaf (`child` = first
/// prim_ids slot, `count` references) or empty (an inverted box every test misses).
/// WideNode<float, uint32_t, 4> is 128 bytes (32 per child, as a binary node), the 8-wide node 256.
/// The leaf part (bvh.hpp: prim_ids, leaf triangles, counts) is the binary tree's, unchanged.
/// `make_wide_blocks` (wide_blocks.hpp) converts to the same nodes with leaves in SIMD triangle blocks.
///
/// Collapse (after Wald et al. 2008 "Getting rid of packets", and Pinto 2010): each wide node starts
/// from a binary inner node's two children and repeatedly opens the inner child of largest surface
/// area until it has W children or only leaves. Wide nodes are a subset of the binary inner nodes with
/// their boxes unchanged, so `sah_cost(WideBvh)` has the binary tree's leaf term and a smaller inner
/// term. The top is collapsed serially, then 256 subtrees in parallel tasks: O(binary nodes), the
/// same tree on every executor; a build step, to be timed as one (see bench_trace.cpp).
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "bvh.hpp"
#include "executor.hpp"
#include "detail/scratch.hpp"
#include "sah.hpp"


namespace dynbvh {

/// One node of a W-wide BVH (W = 4 or 8): the boxes of up to W children, structure of arrays.
/// Slot k: `count[k] == 0` and a valid box: inner child, node `child[k]`; `count[k] > 0`: leaf of
/// `count[k]` references from prim_ids slot `child[k]`; inverted box (lo = +inf, hi = -inf): empty.
template <class Scalar = float, class Index = std::uint32_t, int W = 4>
struct alignas(64) WideNode {
    static_assert(std::is_floating_point_v<Scalar> && std::is_unsigned_v<Index>);
    static_assert(W == 4 || W == 8, "wide nodes have 4 or 8 children");
    /// The boxes' scalar type.
    using scalar_type = Scalar;
    /// The type of `child` and `count`.
    using index_type = Index;
    /// Children per node (4 or 8).
    static constexpr int width = W;

    // Bounds std::size_t(W): an int bound warns under g++ -Wsign-conversion.
    /// @{
    /// Child boxes, structure of arrays: slot k is [lo_x[k], hi_x[k]] x [lo_y[k], hi_y[k]] x [lo_z[k], hi_z[k]].
    Scalar lo_x[std::size_t(W)], hi_x[std::size_t(W)], lo_y[std::size_t(W)], hi_y[std::size_t(W)], lo_z[std::size_t(W)], hi_z[std::size_t(W)];
    /// @}
    /// Slot k: the child node's index (inner child), or its first prim_ids slot (leaf).
    Index child[std::size_t(W)];
    /// Slot k: the leaf's reference count; 0 for an inner child or an empty slot.
    Index count[std::size_t(W)];

    /// Marks every slot empty.
    constexpr void clear() noexcept {
        constexpr Scalar inf = std::numeric_limits<Scalar>::infinity();
        for (int k = 0; k < W; ++k) {
            lo_x[k] = lo_y[k] = lo_z[k] = inf;
            hi_x[k] = hi_y[k] = hi_z[k] = -inf;
            child[k] = 0;
            count[k] = 0;
        }
    }
    /// True when slot k holds nothing (inverted box).
    constexpr bool empty_slot(int k) const noexcept { return !(lo_x[k] <= hi_x[k]); }
    /// True when slot k is a leaf.
    constexpr bool is_leaf(int k) const noexcept { return count[k] != 0; }
    /// The box of slot k.
    constexpr AABB<Scalar> bounds(int k) const noexcept { return {{lo_x[k], lo_y[k], lo_z[k]}, {hi_x[k], hi_y[k], hi_z[k]}}; }
    /// Sets the box of slot k.
    constexpr void set_bounds(int k, const AABB<Scalar>& b) noexcept {
        lo_x[k] = b.min.x; lo_y[k] = b.min.y; lo_z[k] = b.min.z;
        hi_x[k] = b.max.x; hi_y[k] = b.max.y; hi_z[k] = b.max.z;
    }
    /// Union of the non-empty slots' boxes.
    constexpr AABB<Scalar> bounds() const noexcept {
        AABB<Scalar> b;
        for (int k = 0; k < W; ++k)
            if (!empty_slot(k)) b.extend(bounds(k));
        return b;
    }
};

static_assert(sizeof(WideNode<>) == 128, "the default wide node is 128 bytes");
static_assert(sizeof(WideNode<float, std::uint32_t, 8>) == 256, "the 8-wide node is 256 bytes");

/// A wide BVH (see the file comment): wide nodes over the same LeafPart as the binary tree it was made
/// from, `WideBvh<WideNodeT, Prim>` as `Bvh<NodeT, Prim>`. Made by `make_wide` from a binary `Bvh`.
template <class WideNodeT = WideNode<>, class PrimPolicy = prim::indexed>
struct WideBvh : LeafPart<typename WideNodeT::scalar_type, typename WideNodeT::index_type, PrimPolicy> {
    /// The wide node layout.
    using node_type = WideNodeT;
    /// The leaf part shared with the binary tree (LeafPart).
    using leaf_part = LeafPart<typename WideNodeT::scalar_type, typename WideNodeT::index_type, PrimPolicy>;
    /// The boxes' scalar type (float or double).
    using scalar_type = typename WideNodeT::scalar_type;   // the rest (index_type, prim_policy, ...) from LeafPart
    /// Children per node (4 or 8).
    static constexpr int width = WideNodeT::width;

    /// Root at 0; the children of a node are adjacent (top levels breadth first, subtrees below them depth
    /// first). Empty when there is nothing to trace. Allocated through the scratch cache
    /// (detail/scratch.hpp): a dynamic scene converting every frame reuses the previous frame's block.
    scratch_vector<node_type> nodes;
    /// Edges from the root to the deepest wide node (a leaf slot of that node is one level deeper).
    std::uint32_t depth = 0;

    /// True when there is nothing to trace.
    bool empty() const noexcept { return nodes.empty(); }
    /// The root's box (the empty box for an empty tree).
    AABB<scalar_type> bounds() const noexcept { return empty() ? AABB<scalar_type>{} : nodes[0].bounds(); }
    /// Bytes held by the tree (nodes, references and copied leaf triangles).
    std::size_t memory_bytes() const noexcept { return nodes.size() * sizeof(node_type) + this->leaf_bytes(); }
};

/// The WideBvh type `make_wide<W>` returns for a binary Bvh type.
template <class B, int W = 4>
using wide_bvh_of = WideBvh<WideNode<typename B::scalar_type, typename B::index_type, W>, typename B::prim_policy>;

namespace detail {

/// Opens binary inner node `b` into up to W children `c` (returns how many): starting from its two
/// children, the inner child of largest surface area is replaced by its two children while fewer than
/// W and some child is inner.
template <int W, class NodeT>
inline int open_wide(std::span<const NodeT> bin, typename NodeT::index_type b, typename NodeT::index_type* c) {
    c[0] = bin[b].left();
    c[1] = bin[b].right();
    int n = 2;
    while (n < W) {
        int best = -1;
        double best_area = -1;
        for (int k = 0; k < n; ++k) {
            const NodeT& ck = bin[c[k]];
            if (ck.is_leaf()) continue;
            const double a = area(ck.bounds());
            if (a > best_area) {
                best_area = a;
                best = k;
            }
        }
        if (best < 0) break;
        const NodeT& open = bin[c[best]];
        c[best] = open.left();
        c[n++] = open.right();
    }
    return n;
}

/// Writes the wide node for binary inner node `b` into `w`; calls inner(slot, binary child) for each
/// inner child (the caller sets w.child[slot]).
template <int W, class NodeT, class Inner>
inline void fill_wide(std::span<const NodeT> bin, typename NodeT::index_type b,
                      WideNode<typename NodeT::scalar_type, typename NodeT::index_type, W>& w, Inner&& inner) {
    typename NodeT::index_type c[std::size_t(W)];
    const int n = open_wide<W>(bin, b, c);
    w.clear();
    for (int k = 0; k < n; ++k) {
        const NodeT& ck = bin[c[k]];
        w.set_bounds(k, ck.bounds());
        if (ck.is_leaf()) {
            w.child[k] = ck.index;
            w.count[k] = ck.count;
        } else {
            inner(k, c[k]);
        }
    }
}

/// A task's run of wide nodes in memory set aside for it (part of one array shared by all tasks, sized
/// by a bound on the run's length): what collapse_subtree needs of a vector, without an allocation per
/// task (the direct emission's tasks each allocated, and faulted in, their own arrays).
template <class WNode>
struct NodeRun {
    WNode* first = nullptr;
    std::size_t used = 0;
    std::size_t size() const noexcept { return used; }
    void emplace_back() noexcept { ++used; }
    WNode& operator[](std::size_t i) noexcept { return first[i]; }
    const WNode* begin() const noexcept { return first; }
    const WNode* end() const noexcept { return first + used; }
};

/// Step 2 of both wide conversions: collapses the binary subtree at `root` (of wide depth `depth`)
/// depth first into `out` (a scratch_vector or a NodeRun of the wide node type), its wide root at
/// out[0] and child indices local to `out` (shifted when the arrays are concatenated). Returns the
/// deepest wide depth reached. Writes at most as many wide nodes as the subtree has inner nodes.
template <int W, class NodeT, class Out>
std::uint32_t collapse_subtree(std::span<const NodeT> bin, typename NodeT::index_type root, std::uint32_t depth, Out& out) {
    using Index = typename NodeT::index_type;
    using WNode = WideNode<typename NodeT::scalar_type, Index, W>;
    struct Todo {
        Index bin, at;           // binary node; its wide node's position in `out`
        std::uint32_t depth;
    };
    std::vector<Todo> todo;
    todo.reserve(std::size_t(W) * std::size_t(max_depth));
    out.emplace_back();
    todo.push_back({root, 0, depth});
    std::uint32_t deepest = depth;
    while (!todo.empty()) {
        const Todo t = todo.back();
        todo.pop_back();
        deepest = std::max(deepest, t.depth);
        WNode w;
        fill_wide<W>(bin, t.bin, w, [&](int slot, Index c) {
            w.child[slot] = Index(out.size());
            out.emplace_back();
            todo.push_back({c, w.child[slot], t.depth + 1});
        });
        out[t.at] = w;
    }
    return deepest;
}

/// Step 3 of both wide conversions (collapse_to_wide below, emit_wide_bvh in detail/emit_wide.hpp):
/// task k's local array goes after the top nodes, in task order, and is linked into the top slot that
/// `pending[k]` names (`parent`, `slot`); the arrays are then copied in parallel with their inner
/// children's indices shifted by their base. `depth` is raised to the deepest task's.
template <int W, class WNode, class Pending, class Local, class Nodes, class Exec>
void concatenate_wide(std::vector<WNode>& top, const Pending* pending, const std::vector<Local>& local,
                      const std::vector<std::uint32_t>& local_depth, Nodes& nodes, std::uint32_t& depth, const Exec& ex) {
    using Index = typename WNode::index_type;
    const std::size_t tasks = local.size();
    std::vector<std::size_t> base(tasks);
    std::size_t total = top.size();
    for (std::size_t k = 0; k < tasks; ++k) {
        base[k] = total;
        total += local[k].size();
        top[pending[k].parent].child[pending[k].slot] = Index(base[k]);
        depth = std::max(depth, local_depth[k]);
    }
    nodes.resize(total);
    std::copy(top.begin(), top.end(), nodes.begin());
    ex.for_tasks(tasks, [&](std::size_t k) {
        const Index shift = Index(base[k]);
        WNode* dst = nodes.data() + base[k];
        for (const WNode& w : local[k]) {
            *dst = w;
            for (std::size_t s = 0; s < std::size_t(W); ++s)
                if (dst->count[s] == 0 && !dst->empty_slot(int(s))) dst->child[s] += shift;
            ++dst;
        }
    });
}

/// The topology step of the conversion: fills wide.nodes and wide.depth from bvh.nodes. The top of
/// the tree is collapsed serially, breadth first, until 256 subtrees are open; each is then collapsed
/// depth first by one task into its own array, and the arrays are concatenated with their child
/// indices shifted: two parallel steps in all (the cost does not grow with the depth), and the same
/// result on every executor and thread count.
template <int W, class NodeT, class Prim, class Exec>
void collapse_to_wide(const Bvh<NodeT, Prim>& bvh, wide_bvh_of<Bvh<NodeT, Prim>, W>& wide, const Exec& ex) {
    using Index = typename NodeT::index_type;
    using WNode = WideNode<typename NodeT::scalar_type, Index, W>;
    const std::span<const NodeT> bin(bvh.nodes);
    wide.nodes.clear();
    wide.depth = 0;
    if (bin.empty()) return;
    if (bin[0].is_leaf()) {   // a single leaf: one wide node with one slot
        WNode n;
        n.clear();
        n.set_bounds(0, bin[0].bounds());
        n.child[0] = bin[0].index;
        n.count[0] = bin[0].count;
        wide.nodes.push_back(n);
        return;
    }
    struct Pending {
        Index bin;            // binary inner node still to collapse
        Index parent;         // top node whose slot `slot` points to it
        int slot;
        std::uint32_t depth;  // its wide depth
    };
    // Subtrees handed to tasks: a fixed number (not one per worker), so that every executor and
    // thread count produces the same array, and enough to balance a many-core machine.
    constexpr std::size_t target = 256;
    std::vector<WNode> top;
    std::vector<Pending> queue;
    std::size_t head = 0;
    auto expand_top = [&](Index b, std::uint32_t depth) {
        const Index id = Index(top.size());
        top.emplace_back();
        fill_wide<W>(bin, b, top.back(), [&](int slot, Index c) { queue.push_back({c, id, slot, depth + 1}); });
        wide.depth = std::max(wide.depth, depth);
        return id;
    };
    // Step 1: the top, breadth first and serially, until `target` subtrees are pending.
    expand_top(Index(0), 0);
    while (head < queue.size() && queue.size() - head < target) {
        const Pending p = queue[head++];
        top[p.parent].child[p.slot] = expand_top(p.bin, p.depth);
    }
    // Step 2: each pending subtree depth first by one task, into its own array.
    const std::size_t tasks = queue.size() - head;
    std::vector<scratch_vector<WNode>> local(tasks);
    std::vector<std::uint32_t> local_depth(tasks, 0);
    ex.for_tasks(tasks, [&](std::size_t k) {
        const Pending& p = queue[head + k];
        scratch_vector<WNode>& out = local[k];
        // About three binary inner nodes per wide node: a guess that avoids most regrowth.
        out.reserve(bin.size() / (6 * tasks) + 8);
        local_depth[k] = collapse_subtree<W>(bin, p.bin, p.depth, out);
    });
    // Step 3: the arrays after the top, linked in, copied with shifted child indices.
    concatenate_wide<W>(top, queue.data() + head, local, local_depth, wide.nodes, wide.depth, ex);
}


} // namespace detail

/// Converts a binary BVH into a W-wide one (see the file comment): the same leaves, wide nodes
/// collapsed greedily by surface area. The leaf part (bvh.hpp) is copied. O(nodes), parallel
/// over `ex`.
template <int W = 4, class NodeT, class Prim, class Exec = exec::default_executor>
wide_bvh_of<Bvh<NodeT, Prim>, W> make_wide(const Bvh<NodeT, Prim>& bvh, const Exec& ex = {}) {
    wide_bvh_of<Bvh<NodeT, Prim>, W> w;
    w.leaves() = bvh.leaves();
    detail::collapse_to_wide<W>(bvh, w, ex);
    return w;
}

/// As above, taking over the leaf part instead of copying it (the binary tree is left empty).
template <int W = 4, class NodeT, class Prim, class Exec = exec::default_executor>
wide_bvh_of<Bvh<NodeT, Prim>, W> make_wide(Bvh<NodeT, Prim>&& bvh, const Exec& ex = {}) {
    wide_bvh_of<Bvh<NodeT, Prim>, W> w;
    w.leaves() = std::move(bvh.leaves());
    detail::collapse_to_wide<W>(bvh, w, ex);
    bvh = Bvh<NodeT, Prim>{};
    return w;
}

} // namespace dynbvh

// intersect / occluded on wide trees, so that including wide.hpp is enough to trace them.
#include "traverse_wide.hpp"
