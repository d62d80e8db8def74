// SPDX-License-Identifier: MIT
/// @file detail/emit.hpp
/// The step every builder ends with: a raw binary tree whose leaves are single
/// references becomes the final `Bvh` layout. In one parallel bottom-up pass it
/// computes node boxes and decides, by the surface area heuristic, which subtrees
/// become leaves (leaf collapse: leaf cost Ci*A*N against Ct*A + children, N <= max_leaf_size);
/// then a parallel top-down pass writes nodes in depth-first order (root at 0, siblings
/// adjacent) and leaf references contiguously. Subtrees that would make the tree deeper
/// than `max_depth` are rebuilt balanced (median splits), so traversal's fixed stack never overflows.
/// Builders that create every node after its children (LBVH bottom-up, PLOC) apply the same
/// CollapseRule while building and call detail::emit_from_info, skipping the bottom-up pass.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "../bvh.hpp"
#include "../cost.hpp"
#include "../executor.hpp"
#include "references.hpp"
#include "scratch.hpp"
#include "simd.hpp"

namespace dynbvh {

/// A builder's raw output: topology only. Inner nodes are 0 .. left.size()-1 in any order;
/// a child id with `leaf_flag` set is a reference index (into References) instead.
struct BinaryTree {
    static constexpr std::uint32_t leaf_flag = 0x80000000u;
    scratch_vector<std::uint32_t> left, right;
    std::uint32_t root = leaf_flag;   ///< an inner node, or (0 | leaf_flag) when there is exactly one reference

    static constexpr bool is_leaf(std::uint32_t id) noexcept { return (id & leaf_flag) != 0; }
    static constexpr std::uint32_t ref_of(std::uint32_t id) noexcept { return id & ~leaf_flag; }
    static constexpr std::uint32_t leaf(std::uint32_t ref) noexcept { return ref | leaf_flag; }
    std::size_t inner_count() const noexcept { return left.size(); }
    /// Throws std::length_error naming `builder` when `refs` references cannot be told from leaf-flagged ids.
    static void check_size(std::size_t refs, const char* builder) {
        if (refs >= leaf_flag)
            throw std::length_error(std::string(builder) + ": " + std::to_string(refs) +
                                    " references exceed the limit of 2^31 - 1");
    }
    /// A builder's start over `refs` references: the size checked (check_size), and the finished tree
    /// when refs < 2 (empty, or one reference as the root).
    static BinaryTree start(std::size_t refs, const char* builder) {
        check_size(refs, builder);
        BinaryTree t;
        if (refs == 1) t.root = leaf(0);
        return t;
    }
};

namespace detail {

/// Per raw node facts computed bottom-up (by emit_bvh, or by a builder that knows its
/// nodes' children as it builds them, such as LBVH).
template <class T>
struct RawNodeInfo {
    /// A box corner with no default member initialisers: Vec3's would zero every entry of a freshly
    /// sized array of facts (tens of MB per build on large scenes) that the builders overwrite anyway.
    struct Corner {
        T x, y, z;
        Corner& operator=(const Vec3<T>& v) noexcept { x = v.x; y = v.y; z = v.z; return *this; }
        operator Vec3<T>() const noexcept { return {x, y, z}; }
    };
    Corner min, max;          ///< box (kept as two corners: no initialisation, written once)
    float cost;               ///< SAH cost of the subtree as it will be emitted
    std::uint32_t refs;       ///< references below
    std::uint32_t size;       ///< emitted nodes in the subtree (1 when collapsed to a leaf)
    std::uint32_t height;     ///< emitted height (0 when collapsed)
    bool collapsed;
    AABB<T> box() const noexcept { return {Vec3<T>(min), Vec3<T>(max)}; }
};

/// The SAH leaf collapse rule of LeafConfig: a parent's facts from its children's facts.
template <class T>
struct CollapseRule {
    float ct, ci;
    std::uint32_t max_leaf;

    // Evaluated in float: the facts are per raw node, and float keeps them small.
    explicit CollapseRule(const LeafConfig& cfg) noexcept
        : ct(float(cfg.cost.ct)), ci(float(cfg.cost.ci)), max_leaf(std::max<std::uint32_t>(1, cfg.max_leaf_size)) {}

    /// Facts of a single reference with box `b`.
    DYNBVH_ALWAYS_INLINE void leaf(const AABB<T>& b, RawNodeInfo<T>& f) const noexcept {
        f.min = b.min;
        f.max = b.max;
        f.cost = ci * float(b.half_area());
        f.refs = 1;
        f.size = 1;
        f.height = 0;
        f.collapsed = true;
    }
    /// Facts of the inner node over children `l` and `r`: collapsed to a leaf when that is cheaper
    /// (leaf cost Ci*A*N against Ct*A + children) and N <= max_leaf.
    DYNBVH_ALWAYS_INLINE void parent(const RawNodeInfo<T>& l, const RawNodeInfo<T>& r, RawNodeInfo<T>& f) const noexcept {
        const AABB<T> box = merge(l.box(), r.box());
        f.min = box.min;
        f.max = box.max;
        f.refs = l.refs + r.refs;
        const float area = float(box.half_area());
        const float split_cost = ct * area + l.cost + r.cost;
        const float leaf_cost = ci * area * float(f.refs);
        f.collapsed = f.refs <= max_leaf && leaf_cost <= split_cost;
        if (f.collapsed) { f.cost = leaf_cost; f.size = 1; f.height = 0; }
        else { f.cost = split_cost; f.size = 1 + l.size + r.size; f.height = 1 + std::max(l.height, r.height); }
    }
    /// Facts of inner node `p` of `tree` once both its children's are known: a reference child's
    /// from its box in `refs`, an inner child's from `info`. The one rule for every bottom-up walk
    /// (compute_node_info below, LBVH's radix tree).
    void node(const BinaryTree& tree, const References<T>& refs, RawNodeInfo<T>* info, std::uint32_t p) const noexcept {
        RawNodeInfo<T> l, r;
        const std::uint32_t a = tree.left[p], b = tree.right[p];
        if (BinaryTree::is_leaf(a)) leaf(refs.box[BinaryTree::ref_of(a)], l); else l = info[a];
        if (BinaryTree::is_leaf(b)) leaf(refs.box[BinaryTree::ref_of(b)], r); else r = info[b];
        parent(l, r, info[p]);
    }
};

/// Emission state shared by the top-down workers.
template <class NodeT, class T>
struct Emitter {
    const BinaryTree& tree;
    const References<T>& refs;
    std::span<const RawNodeInfo<T>> info;
    NodeT* nodes;   ///< the output nodes (a Bvh's array, or a task's part of a shared one)
    decltype(Bvh<NodeT>::prim_ids)& prim_ids;
    std::atomic<bool> deduplicated{false};   ///< some leaf held two fragments of one triangle

    /// Where a node goes in the output.
    struct Place {
        std::uint32_t pos;   ///< output position of this node
        std::uint32_t free;  ///< first output slot for its descendants
        std::uint32_t ref;   ///< first prim_ids slot of its references
        std::uint32_t depth;
    };
    struct Item {
        std::uint32_t id;    ///< raw child id (inner node or leaf-flagged reference)
        Place at;
    };
    /// The items of the two children of inner raw node `id` placed at `at`, after writing it.
    std::array<Item, 2> split(const Item& it) {
        const std::uint32_t l = tree.left[it.id], r = tree.right[it.id];
        const auto [lp, rp] = write_inner(it.at, info[it.id].box(), size_of(l), refs_of(l));
        return {Item{l, lp}, Item{r, rp}};
    }

    std::uint32_t refs_of(std::uint32_t id) const { return BinaryTree::is_leaf(id) ? 1u : info[id].refs; }
    std::uint32_t size_of(std::uint32_t id) const { return BinaryTree::is_leaf(id) ? 1u : info[id].size; }
    std::uint32_t height_of(std::uint32_t id) const { return BinaryTree::is_leaf(id) ? 0u : info[id].height; }
    bool emits_leaf(std::uint32_t id) const { return BinaryTree::is_leaf(id) || info[id].collapsed; }
    AABB<T> box_of(std::uint32_t id) const { return BinaryTree::is_leaf(id) ? refs.box[BinaryTree::ref_of(id)] : info[id].box(); }
    static std::uint32_t ceil_log2(std::uint32_t k) {
        std::uint32_t h = 0;
        while ((std::uint64_t(1) << h) < k) ++h;
        return h;
    }
    /// True when the subtree at `id` (at `depth`) must be rebuilt balanced to respect max_depth:
    /// it is too deep and at least one child could not fix itself one level down.
    bool must_rebalance(std::uint32_t id, std::uint32_t depth) const {
        if (emits_leaf(id) || depth + height_of(id) <= max_depth) return false;
        for (std::uint32_t c : {tree.left[id], tree.right[id]})
            if (!emits_leaf(c) && ceil_log2((size_of(c) + 1) / 2) > max_depth - depth - 1) return true;
        return false;
    }

    /// Writes node `at` as an inner node with box `box` whose children go to at.free and at.free + 1;
    /// the left child's subtree has `left_size` nodes and `left_refs` references (laid out first).
    /// Returns the left and the right child's places. The one copy of the layout arithmetic.
    std::array<Place, 2> write_inner(const Place& at, const AABB<T>& box, std::uint32_t left_size,
                                     std::uint32_t left_refs) {
        NodeT& node = nodes[at.pos];
        node.set_bounds(box);
        node.index = at.free;
        node.count = 0;
        return {Place{at.free, at.free + 2, at.ref, at.depth + 1},
                Place{at.free + 1, at.free + 1 + left_size, at.ref + left_refs, at.depth + 1}};
    }

    /// Writes a leaf holding every reference below `id`, deduplicating fragments of one triangle.
    void write_leaf(const Item& it, std::vector<std::uint32_t>& stack) {
        auto* out = prim_ids.data() + it.at.ref;
        std::uint32_t n = 0;
        if (BinaryTree::is_leaf(it.id)) {
            out[n++] = static_cast<typename NodeT::index_type>(refs.prim[BinaryTree::ref_of(it.id)]);
        } else {
            stack.clear();
            stack.push_back(it.id);
            while (!stack.empty()) {
                const std::uint32_t c = stack.back();
                stack.pop_back();
                for (std::uint32_t child : {tree.left[c], tree.right[c]}) {
                    if (BinaryTree::is_leaf(child)) out[n++] = static_cast<typename NodeT::index_type>(refs.prim[BinaryTree::ref_of(child)]);
                    else stack.push_back(child);
                }
            }
        }
        std::uint32_t count = n;
        if (n > 1 && refs.repeats) {
            std::sort(out, out + n);
            count = static_cast<std::uint32_t>(std::unique(out, out + n) - out);
            if (count < n) deduplicated.store(true, std::memory_order_relaxed);
        }
        NodeT& node = nodes[it.at.pos];
        node.set_bounds(box_of(it.id));
        node.index = it.at.ref;
        node.count = count;
    }

    /// Emits the subtree of `root` depth first; returns its deepest level.
    std::uint32_t emit_subtree(const Item& root) {
        std::vector<Item> work{root};
        std::vector<std::uint32_t> scratch;
        std::uint32_t deepest = root.at.depth;
        while (!work.empty()) {
            const Item it = work.back();
            work.pop_back();
            deepest = std::max(deepest, it.at.depth);
            if (emits_leaf(it.id)) { write_leaf(it, scratch); continue; }
            if (must_rebalance(it.id, it.at.depth)) { deepest = std::max(deepest, rebalance(it)); continue; }
            const auto [l, r] = split(it);
            work.push_back(r);
            work.push_back(l);
        }
        return deepest;
    }

    /// Rebuilds the subtree at `it` as a balanced tree over its emitted leaves (median splits of
    /// leaf centres along the widest axis). Same leaves, so the same node and reference counts.
    std::uint32_t rebalance(const Item& it) {
        struct Leaf { std::uint32_t id; std::uint32_t refs; AABB<T> box; };
        std::vector<Leaf> leaves;
        std::vector<std::uint32_t> stack{it.id};
        while (!stack.empty()) {
            const std::uint32_t c = stack.back();
            stack.pop_back();
            if (emits_leaf(c)) leaves.push_back({c, refs_of(c), box_of(c)});
            else { stack.push_back(tree.right[c]); stack.push_back(tree.left[c]); }
        }
        struct Range { std::uint32_t begin, end; Place at; };
        std::vector<Range> work{{0, std::uint32_t(leaves.size()), it.at}};
        std::vector<std::uint32_t> scratch;
        std::uint32_t deepest = it.at.depth;
        while (!work.empty()) {
            const Range r = work.back();
            work.pop_back();
            deepest = std::max(deepest, r.at.depth);
            if (r.end - r.begin == 1) {
                write_leaf({leaves[r.begin].id, r.at}, scratch);
                continue;
            }
            AABB<T> box, centres;
            for (std::uint32_t k = r.begin; k < r.end; ++k) { box.extend(leaves[k].box); centres.extend(leaves[k].box.center()); }
            const std::size_t axis = std::size_t(largest_axis(centres.diagonal()));
            const std::uint32_t mid = r.begin + (r.end - r.begin) / 2;
            std::nth_element(leaves.begin() + r.begin, leaves.begin() + mid, leaves.begin() + r.end,
                             [axis](const Leaf& a, const Leaf& b) { return a.box.center()[axis] < b.box.center()[axis]; });
            std::uint32_t left_refs = 0;
            for (std::uint32_t k = r.begin; k < mid; ++k) left_refs += leaves[k].refs;
            const std::uint32_t left_size = 2 * (mid - r.begin) - 1;
            const auto [lp, rp] = write_inner(r.at, box, left_size, left_refs);
            work.push_back({mid, r.end, rp});
            work.push_back({r.begin, mid, lp});
        }
        return deepest;
    }
};

/// Closes the gaps that deduplicated leaves left in prim_ids (presplit trees only). O(n log n), serial.
template <class NodeT, class Prim>
void compact_references(Bvh<NodeT, Prim>& bvh) {
    std::vector<std::pair<typename NodeT::index_type, std::size_t>> leaves;   // (first slot, node)
    for (std::size_t i = 0; i < bvh.nodes.size(); ++i)
        if (bvh.nodes[i].is_leaf()) leaves.push_back({bvh.nodes[i].index, i});
    std::sort(leaves.begin(), leaves.end());
    std::size_t out = 0;
    for (const auto& [first, i] : leaves) {
        NodeT& node = bvh.nodes[i];
        std::copy(bvh.prim_ids.begin() + std::ptrdiff_t(first), bvh.prim_ids.begin() + std::ptrdiff_t(first + node.count),
                  bvh.prim_ids.begin() + std::ptrdiff_t(out));
        node.index = static_cast<typename NodeT::index_type>(out);
        out += node.count;
    }
    bvh.prim_ids.resize(out);
}

/// Facts of every inner node of `tree`, bottom-up: starting at nodes whose children are both
/// references, a walk goes up while the sibling subtree is finished (Karras 2012 style); index
/// order keeps the walks local in memory. O(n), parallel.
template <class T, class Exec>
void compute_node_info(const BinaryTree& tree, const References<T>& refs, const LeafConfig& cfg,
                       std::span<RawNodeInfo<T>> info, const Exec& ex) {
    const std::size_t n_inner = tree.inner_count();
    constexpr std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
    const CollapseRule<T> rule(cfg);

    // Parents of inner nodes; each node's arrival count starts at its number of reference children.
    scratch_vector<std::uint32_t> parent(n_inner);
    scratch_vector<std::atomic<std::uint32_t>> arrivals(n_inner);
    if (n_inner) parent[tree.root] = none;
    ex.for_each(0, n_inner, [&](std::size_t i) {
        std::uint32_t leaves = 0;
        for (std::uint32_t c : {tree.left[i], tree.right[i]}) {
            if (BinaryTree::is_leaf(c)) ++leaves;
            else parent[c] = std::uint32_t(i);
        }
        arrivals[i].store(leaves, std::memory_order_relaxed);
    });
    auto compute = [&](std::uint32_t p) { rule.node(tree, refs, info.data(), p); };
    ex.for_each(0, n_inner, [&](std::size_t i) {
        if (!BinaryTree::is_leaf(tree.left[i]) || !BinaryTree::is_leaf(tree.right[i])) return;
        std::uint32_t p = std::uint32_t(i);
        compute(p);
        for (p = parent[p]; p != none; p = parent[p]) {
            if (arrivals[p].fetch_add(1, std::memory_order_acq_rel) == 0) return;   // sibling not done yet
            compute(p);
        }
    });
}

/// emit_bvh's top-down half: writes the final layout from the facts of every inner node
/// (computed by compute_node_info or by the builder itself). O(n), parallel.
template <class NodeT, class Prim, class T, triangle_source Source, class Exec>
Bvh<NodeT, Prim> emit_from_info(const BinaryTree& tree, const References<T>& refs, Source tris,
                                std::span<const RawNodeInfo<T>> info, const Exec& ex) {
    Bvh<NodeT, Prim> bvh;
    bvh.primitive_count = refs.primitive_count;
    bvh.excluded = refs.excluded;
    const std::size_t n_refs = refs.size();
    if (n_refs == 0) return bvh;

    detail::Emitter<NodeT, T> em{tree, refs, info, nullptr, bvh.prim_ids};
    const std::uint32_t root = tree.root;
    bvh.nodes.resize(em.size_of(root));
    em.nodes = bvh.nodes.data();
    bvh.prim_ids.resize(n_refs);

    // Step 1: write the top of the tree serially until the rest is independent subtrees.
    using Item = typename detail::Emitter<NodeT, T>::Item;
    std::vector<Item> top, items{{root, {0, 1, 0, 0}}};
    const std::uint32_t grain = std::max<std::uint32_t>(1024, em.size_of(root) / std::uint32_t(64 * ex.concurrency()));
    std::uint32_t deepest = 0;
    for (std::size_t k = 0; k < items.size(); ++k) {
        const Item it = items[k];
        if (em.size_of(it.id) <= grain || em.emits_leaf(it.id) || em.must_rebalance(it.id, it.at.depth)) {
            top.push_back(it);
            continue;
        }
        deepest = std::max(deepest, it.at.depth);
        const auto [l, r] = em.split(it);
        items.push_back(l);
        items.push_back(r);
    }
    // Step 2: emit those subtrees in parallel.
    std::vector<std::uint32_t> depths(top.size());
    ex.for_tasks(top.size(), [&](std::size_t k) { depths[k] = em.emit_subtree(top[k]); });
    for (std::uint32_t d : depths) deepest = std::max(deepest, d);
    bvh.depth = deepest;
    if (em.deduplicated.load()) detail::compact_references(bvh);

    // Step 3: the leaf-order copy of the triangles (prim::copied).
    if constexpr (Bvh<NodeT, Prim>::precomputed) {
        bvh.leaf_triangles.resize(bvh.prim_ids.size());
        ex.for_each(0, bvh.prim_ids.size(), [&](std::size_t s) { bvh.leaf_triangles[s] = tris[bvh.prim_ids[s]]; });
    } else {
        (void)tris;
    }
    return bvh;
}

} // namespace detail

/// Turns a raw tree over `refs` into the final layout (see the file comment).
/// For prim::copied the leaf triangles are copied from `tris` (a span or a MeshView). O(n) work, parallel.
template <class NodeT, class Prim, class T, detail::triangle_source Source, class Exec>
Bvh<NodeT, Prim> emit_bvh(const BinaryTree& tree, const References<T>& refs, Source tris,
                          const LeafConfig& cfg, const Exec& ex) {
    scratch_vector<detail::RawNodeInfo<T>> info(refs.size() == 0 ? 0 : tree.inner_count());
    if (refs.size() != 0) detail::compute_node_info(tree, refs, cfg, std::span<detail::RawNodeInfo<T>>(info), ex);
    return detail::emit_from_info<NodeT, Prim>(tree, refs, tris, std::span<const detail::RawNodeInfo<T>>(info), ex);
}

} // namespace dynbvh
