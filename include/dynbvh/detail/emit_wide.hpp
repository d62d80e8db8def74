// SPDX-License-Identifier: MIT
/// @file detail/emit_wide.hpp
/// Direct wide emission: a builder's raw binary tree and its node facts (detail/emit.hpp: boxes and
/// the SAH leaf collapse, computed bottom-up) become a W-wide tree (wide.hpp) in one parallel
/// top-down pass, without the binary `Bvh`'s node array: the top is opened on the raw tree itself;
/// each of the (up to) 256 subtrees below it is emitted by one task as binary nodes into a task-local,
/// cache-sized array (the binary emission's own Emitter) and collapsed from there at once, so the
/// binary nodes never go through main memory. The result is the tree
/// `make_wide<W>(emit_bvh(...))` gives, node for node and bit for bit:
///  - a raw node is a wide leaf slot exactly when the binary emission makes it a leaf (the facts'
///    `collapsed`, or a single reference); its references go to the prim_ids slots the binary
///    emission gives them (depth first, left subtree first: a node's first slot is its parent's, or
///    that plus its left sibling's reference count), collected in the same order;
///  - a wide node opens the inner child of largest surface area, computed from the same box in the
///    same precision, as detail::open_wide does on the binary nodes;
///  - the node order follows detail::collapse_to_wide step for step (the top breadth first until 256
///    subtrees are open, each subtree depth first by one task, then concatenated);
///  - deduplicated leaves (presplit fragments) are compacted by first slot, as compact_references does.
/// A raw tree whose emitted height exceeds max_depth (the binary emission would rebalance part of it)
/// takes the two-step path instead, so the contract holds there too. O(n), parallel.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "../bvh.hpp"
#include "../cost.hpp"
#include "../executor.hpp"
#include "../wide.hpp"
#include "../wide_blocks.hpp"
#include "emit.hpp"
#include "references.hpp"
#include "scratch.hpp"
#include "triangle_block.hpp"

namespace dynbvh {
namespace detail {

/// State of the direct wide emission (see the file comment): the raw tree, its facts and the output.
template <int W, class Index, class T>
struct WideEmitter {
    using WNode = WideNode<T, Index, W>;
    const BinaryTree& tree;
    const References<T>& refs;
    std::span<const RawNodeInfo<T>> info;
    Index* prim_ids;
    std::atomic<bool> deduplicated{false};   ///< some leaf held two fragments of one triangle

    /// A raw node (inner id or leaf-flagged reference) and the first prim_ids slot of its references.
    struct Raw {
        std::uint32_t id;
        std::uint32_t ref;
    };

    bool emits_leaf(std::uint32_t id) const { return BinaryTree::is_leaf(id) || info[id].collapsed; }
    std::uint32_t refs_of(std::uint32_t id) const { return BinaryTree::is_leaf(id) ? 1u : info[id].refs; }
    std::uint32_t size_of(std::uint32_t id) const { return BinaryTree::is_leaf(id) ? 1u : info[id].size; }
    AABB<T> box_of(std::uint32_t id) const { return BinaryTree::is_leaf(id) ? refs.box[BinaryTree::ref_of(id)] : info[id].box(); }

    /// The two children of inner raw node `b`, with their first slots (left subtree first).
    std::pair<Raw, Raw> children(const Raw& b) const {
        const std::uint32_t l = tree.left[b.id], r = tree.right[b.id];
        return {Raw{l, b.ref}, Raw{r, b.ref + refs_of(l)}};
    }

    /// A child while a wide node is opened: its raw node, box, area (opening order) and kind, each
    /// read from the facts once.
    struct Child {
        Raw raw;
        AABB<T> box;
        double area;
        bool leaf;
    };
    Child child(const Raw& r) const {
        const bool leaf = emits_leaf(r.id);
        const AABB<T> box = box_of(r.id);
        return {r, box, leaf ? 0.0 : area(box), leaf};
    }

    /// detail::open_wide on the raw tree: up to W children of `b` in `c`; returns how many. The same
    /// areas (in double, from the same boxes) in the same order, so the same choices.
    int open(const Raw& b, Child* c) const {
        const auto [l, r] = children(b);
        c[0] = child(l);
        c[1] = child(r);
        int n = 2;
        while (n < W) {
            int best = -1;
            double best_area = -1;
            for (int k = 0; k < n; ++k) {
                if (c[k].leaf) continue;
                if (c[k].area > best_area) {
                    best_area = c[k].area;
                    best = k;
                }
            }
            if (best < 0) break;
            const auto [cl, cr] = children(c[best].raw);
            c[best] = child(cl);
            c[n++] = child(cr);
        }
        return n;
    }

    /// Writes the references of leaf `it` to its slots (Emitter::write_leaf's order and deduplication);
    /// returns the count.
    Index write_leaf(const Raw& it, std::vector<std::uint32_t>& stack) {
        Index* out = prim_ids + it.ref;
        std::uint32_t n = 0;
        if (BinaryTree::is_leaf(it.id)) {
            out[n++] = static_cast<Index>(refs.prim[BinaryTree::ref_of(it.id)]);
        } else {
            stack.clear();
            stack.push_back(it.id);
            while (!stack.empty()) {
                const std::uint32_t c = stack.back();
                stack.pop_back();
                for (std::uint32_t child : {tree.left[c], tree.right[c]}) {
                    if (BinaryTree::is_leaf(child)) out[n++] = static_cast<Index>(refs.prim[BinaryTree::ref_of(child)]);
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
        return static_cast<Index>(count);
    }

    /// detail::fill_wide on the raw tree: the wide node for inner raw node `b` (leaf slots written,
    /// their references too); calls inner(slot, raw child) for each inner child.
    template <class Inner>
    void fill(const Raw& b, WNode& w, std::vector<std::uint32_t>& stack, Inner&& inner) {
        Child c[std::size_t(W)];
        const int n = open(b, c);
        w.clear();
        for (int k = 0; k < n; ++k) {
            w.set_bounds(k, c[k].box);
            if (c[k].leaf) {
                w.child[k] = static_cast<Index>(c[k].raw.ref);
                w.count[k] = write_leaf(c[k].raw, stack);
            } else {
                inner(k, c[k].raw);
            }
        }
    }
};

/// Closes the gaps deduplicated leaves left in prim_ids (compact_references on a wide tree: the leaf
/// slots in order of their first slot, packed). O(n log n), serial; presplit trees only.
template <class WNodeT, class Prim>
void compact_wide_references(WideBvh<WNodeT, Prim>& bvh) {
    using Index = typename WNodeT::index_type;
    struct LeafSlot { Index first; std::size_t node; int slot; };
    std::vector<LeafSlot> leaves;
    for (std::size_t i = 0; i < bvh.nodes.size(); ++i)
        for (int k = 0; k < WNodeT::width; ++k)
            if (bvh.nodes[i].is_leaf(k)) leaves.push_back({bvh.nodes[i].child[k], i, k});
    std::sort(leaves.begin(), leaves.end(), [](const LeafSlot& a, const LeafSlot& b) { return a.first < b.first; });
    std::size_t out = 0;
    for (const LeafSlot& l : leaves) {
        WNodeT& node = bvh.nodes[l.node];
        const Index count = node.count[l.slot];
        std::copy(bvh.prim_ids.begin() + std::ptrdiff_t(l.first), bvh.prim_ids.begin() + std::ptrdiff_t(l.first + count),
                  bvh.prim_ids.begin() + std::ptrdiff_t(out));
        node.child[l.slot] = static_cast<Index>(out);
        out += count;
    }
    bvh.prim_ids.resize(out);
}

/// The W-wide tree type emit_wide_from_info makes: wide_bvh_of<Bvh<NodeT, Prim>, W>, or for
/// prim::blocks<L> the traced layout (leaves in SIMD triangle blocks, wide_blocks.hpp).
template <int W, class NodeT, class Prim>
struct wide_result {
    using type = wide_bvh_of<Bvh<NodeT, Prim>, W>;
};
template <int W, class NodeT, int L>
struct wide_result<W, NodeT, prim::blocks<L>> {
    using type = WideBvh<WideNode<typename NodeT::scalar_type, typename NodeT::index_type, W>, prim::blocks<L>>;
};

/// emit_wide_bvh's top-down pass from the facts of every inner node (computed by compute_node_info or
/// by the builder itself, as LBVH and PLOC do). See the file comment. O(n), parallel.
/// Prim = prim::blocks<L>: the traced layout in the same pass, the tree
/// make_wide_blocks<L>(emit_wide_from_info<W, NodeT, prim::indexed>(...), tris) gives, bit for bit: the
/// references go to a scratch slot array instead of prim_ids, and the step that links the subtrees'
/// arrays in also packs their leaves (blocks in node order, as make_wide_blocks numbers them), so the
/// nodes are not walked again, counted and scanned, and no slot array is kept.
template <int W, class NodeT, class Prim, class T, triangle_source Source, class Exec>
typename wide_result<W, NodeT, Prim>::type emit_wide_from_info(const BinaryTree& tree, const References<T>& refs, Source tris,
                                                              std::span<const RawNodeInfo<T>> info, const Exec& ex) {
    using Index = typename NodeT::index_type;
    using Result = typename wide_result<W, NodeT, Prim>::type;
    using WNode = typename Result::node_type;
    using Em = WideEmitter<W, Index, T>;
    using Raw = typename Em::Raw;
    constexpr int L = Result::block_lanes;   // 0: leaves in prim_ids
    const std::size_t n_refs = refs.size();
    const std::uint32_t root = tree.root;
    // Too deep: the binary emission rebalances, so take its path to keep the same tree.
    if (n_refs != 0 && !BinaryTree::is_leaf(root) && !info[root].collapsed && info[root].height > max_depth) {
        if constexpr (L != 0) return blocks_of_binary<W, L>(emit_from_info<NodeT, prim::indexed>(tree, refs, tris, info, ex), tris, ex);
        else return make_wide<W>(emit_from_info<NodeT, Prim>(tree, refs, tris, info, ex), ex);
    }

    Result wide;
    wide.primitive_count = refs.primitive_count;
    wide.excluded = refs.excluded;
    if (n_refs == 0) return wide;
    // The references' slots: the tree's prim_ids, or (blocks) scratch read back while packing.
    scratch_vector<Index> slots_scratch;
    auto& slots = L != 0 ? slots_scratch : wide.prim_ids;
    slots.resize(n_refs);
    Em em{tree, refs, info, slots.data()};
    std::vector<std::uint32_t> stack;
    [[maybe_unused]] auto tri_of = [&](std::size_t s) -> decltype(auto) { return tris[slots[s]]; };
    // The leaf slots of nodes [first, last) of `nodes` packed from block `block` on; each leaf slot is
    // pointed at its first block. Returns the block after the last.
    [[maybe_unused]] auto pack_nodes = [&](WNode* first, WNode* last, std::size_t block) {
        if constexpr (L != 0)
            for (WNode* w = first; w != last; ++w)
                for (int s = 0; s < W; ++s)
                    if (w->count[s] != 0) {
                        pack_leaf<L>(wide.blocks.data() + block, std::size_t(w->child[s]), std::size_t(w->count[s]), slots.data(),
                                     n_refs, tri_of);
                        w->child[s] = Index(block);
                        block += blocks_for<L>(std::size_t(w->count[s]));
                    }
        return block;
    };
    [[maybe_unused]] auto count_blocks = [&](const WNode* first, const WNode* last) {
        std::size_t b = 0;
        if constexpr (L != 0)
            for (const WNode* w = first; w != last; ++w)
                for (int s = 0; s < W; ++s) b += blocks_for<(L == 0 ? 1 : L)>(std::size_t(w->count[s]));
        return b;
    };

    if (em.emits_leaf(root)) {   // a single leaf: one wide node with one slot
        WNode w;
        w.clear();
        w.set_bounds(0, em.box_of(root));
        w.child[0] = 0;
        w.count[0] = em.write_leaf(Raw{root, 0}, stack);
        wide.nodes.push_back(w);
        if constexpr (L != 0) {
            wide.blocks.resize(count_blocks(wide.nodes.data(), wide.nodes.data() + 1));
            pack_nodes(wide.nodes.data(), wide.nodes.data() + 1, 0);
        }
    } else {
        struct Pending {
            Raw raw;              // raw inner node still to collapse
            Index parent;         // top node whose slot `slot` points to it
            int slot;
            std::uint32_t depth;  // its wide depth
        };
        // The same fixed subtree count as collapse_to_wide, so the same node order.
        constexpr std::size_t target = 256;
        std::vector<WNode> top;
        std::vector<Pending> queue;
        std::size_t head = 0;
        auto expand_top = [&](const Raw& b, std::uint32_t depth) {
            const Index id = Index(top.size());
            top.emplace_back();
            em.fill(b, top.back(), stack, [&](int slot, const Raw& c) { queue.push_back({c, id, slot, depth + 1}); });
            wide.depth = std::max(wide.depth, depth);
            return id;
        };
        // Step 1: the top, breadth first and serially, until `target` subtrees are pending.
        expand_top(Raw{root, 0}, 0);
        while (head < queue.size() && queue.size() - head < target) {
            const Pending p = queue[head++];
            top[p.parent].child[p.slot] = expand_top(p.raw, p.depth);
        }
        // Step 2: each pending subtree by one task, into its own array. The task first emits its raw
        // subtree as binary nodes into a task-local array (Emitter: the binary emission's own code and
        // memory order, the references written to their final slots), small enough to stay in cache, then
        // collapses that array as collapse_to_wide does (fill_wide): the same wide nodes, without the
        // whole binary tree going through memory. Opening the raw tree directly here (as the top does)
        // was slower than the two-step path: it walks the scattered facts in opening order, latency bound.
        // The tasks' binary nodes and wide nodes live in two arrays shared by all tasks (each task's
        // part sized by its subtree: the binary nodes it emits, and at most one wide node per binary
        // inner node), taken from the scratch cache: an array per task came from malloc and was faulted
        // in afresh at every build (a third of the emission on a 99k-triangle lattice, 1 thread).
        const std::size_t tasks = queue.size() - head;
        std::vector<std::size_t> bin_base(tasks + 1, 0), wide_base(tasks + 1, 0);
        for (std::size_t k = 0; k < tasks; ++k) {
            const std::size_t size = em.size_of(queue[head + k].raw.id);
            bin_base[k + 1] = bin_base[k] + size;
            wide_base[k + 1] = wide_base[k] + (size + 1) / 2;
        }
        scratch_vector<NodeT> bin_nodes(bin_base[tasks]);
        scratch_vector<WNode> wide_nodes(wide_base[tasks]);
        std::vector<NodeRun<WNode>> local(tasks);
        std::vector<std::uint32_t> local_depth(tasks, 0);
        std::vector<std::size_t> local_blocks(tasks + 1, 0);   // (blocks) per task, then the first block of each
        std::atomic<bool> local_dedup{false};
        ex.for_tasks(tasks, [&](std::size_t k) {
            const Pending& p = queue[head + k];
            Emitter<NodeT, T> bin_em{tree, refs, info, bin_nodes.data() + bin_base[k], slots};
            bin_em.emit_subtree({p.raw.id, {0, 1, p.raw.ref, 0}});   // no rebalancing: the tree is within max_depth
            if (bin_em.deduplicated.load(std::memory_order_relaxed)) local_dedup.store(true, std::memory_order_relaxed);
            const std::span<const NodeT> bin(bin_nodes.data() + bin_base[k], bin_base[k + 1] - bin_base[k]);
            NodeRun<WNode>& out = local[k];
            out.first = wide_nodes.data() + wide_base[k];
            local_depth[k] = collapse_subtree<W>(bin, Index(0), p.depth, out);
            local_blocks[k + 1] = count_blocks(out.begin(), out.end());
        });
        if (local_dedup.load()) em.deduplicated.store(true);
        // Step 3: the arrays after the top, linked in, copied with shifted child indices.
        concatenate_wide<W>(top, queue.data() + head, local, local_depth, wide.nodes, wide.depth, ex);
        if constexpr (L != 0) {
            // Step 4 (blocks): the top's leaves first, then each task's, in node order (as make_wide_blocks).
            local_blocks[0] = count_blocks(wide.nodes.data(), wide.nodes.data() + top.size());
            const std::size_t total = exec::serial{}.exclusive_scan(std::span<const std::size_t>(local_blocks.data(), tasks + 1),
                                                                     std::span<std::size_t>(local_blocks.data(), tasks + 1));
            wide.blocks.resize(total);
            std::vector<std::size_t> node_base(tasks + 2);
            node_base[0] = 0;
            node_base[1] = top.size();
            for (std::size_t k = 0; k < tasks; ++k) node_base[k + 2] = node_base[k + 1] + local[k].size();
            ex.for_tasks(tasks + 1, [&](std::size_t k) {
                pack_nodes(wide.nodes.data() + node_base[k], wide.nodes.data() + node_base[k + 1], local_blocks[k]);
            });
        }
    }
    if constexpr (L == 0) {
        if (em.deduplicated.load()) compact_wide_references(wide);   // (blocks: each leaf packs its own slots)
    }
    // The leaf-order copy of the triangles (prim::copied).
    if constexpr (Result::precomputed) {
        wide.leaf_triangles.resize(wide.prim_ids.size());
        ex.for_each(0, wide.prim_ids.size(), [&](std::size_t s) { wide.leaf_triangles[s] = tris[wide.prim_ids[s]]; });
    } else {
        (void)tris;
    }
    return wide;
}

} // namespace detail

/// Turns a raw tree over `refs` straight into the W-wide layout (W = 4 or 8): the tree
/// `make_wide<W>(emit_bvh<NodeT, Prim>(tree, refs, tris, cfg, ex), ex)` gives, bit for bit, without
/// the binary nodes (see detail/emit_wide.hpp). For prim::copied the leaf triangles are copied from
/// `tris`. O(n) work, parallel.
template <int W, class NodeT, class Prim, class T, detail::triangle_source Source, class Exec>
wide_bvh_of<Bvh<NodeT, Prim>, W> emit_wide_bvh(const BinaryTree& tree, const References<T>& refs, Source tris,
                                               const LeafConfig& cfg, const Exec& ex) {
    scratch_vector<detail::RawNodeInfo<T>> info(refs.size() == 0 ? 0 : tree.inner_count());
    if (refs.size() != 0) detail::compute_node_info(tree, refs, cfg, std::span<detail::RawNodeInfo<T>>(info), ex);
    return detail::emit_wide_from_info<W, NodeT, Prim>(tree, refs, tris, std::span<const detail::RawNodeInfo<T>>(info), ex);
}

namespace detail {

/// The whole build of a builder whose topology step sees references alone (PLOC, binned SAH): the
/// references of `tris` (any triangle source: a span or a MeshView), `topology(refs, cfg, ex)`, then
/// emission with cfg.leaves, binary when W == 0, else W-wide. One code path for every input. A
/// topology with `from_triangles` (PLOC) is called as `topology(tris, cfg, info, ex)`: it makes the
/// references itself and fills the facts of its inner nodes (emission then skips compute_node_info).
template <int W, class NodeT, class Prim, class Source, class Config, class Topology, class Exec>
auto build_over(Source tris, const Config& cfg, Topology topology, const Exec& ex) {
    if constexpr (requires { Topology::from_triangles; }) {   // references, tree and facts in one step (PLOC)
        using T = source_scalar_t<Source>;
        scratch_vector<RawNodeInfo<T>> info;
        const auto [refs, tree] = topology(tris, cfg, info, ex);
        const std::span<const RawNodeInfo<T>> facts(info);
        if constexpr (W == 0) return emit_from_info<NodeT, Prim>(tree, refs, tris, facts, ex);
        else return emit_wide_from_info<W, NodeT, Prim>(tree, refs, tris, facts, ex);
    } else {
        auto refs = make_references(tris, ex);
        const BinaryTree tree = topology(refs, cfg, ex);
        if constexpr (W == 0) return emit_bvh<NodeT, Prim>(tree, refs, tris, cfg.leaves, ex);
        else return emit_wide_bvh<W, NodeT, Prim>(tree, refs, tris, cfg.leaves, ex);
    }
}

} // namespace detail

} // namespace dynbvh
