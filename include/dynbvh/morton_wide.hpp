// SPDX-License-Identifier: MIT
/// @file morton_wide.hpp
/// The fastest builder: a W-wide BVH (W = 4 or 8) straight from the sorted Morton codes, top down,
/// with no binary tree, no node facts and no SAH (the kind of build Embree's LOW quality does).
/// References are sorted along the Morton curve (Lauterbach et al. 2009, as LBVH); a key range is
/// split where its highest differing key bit changes (found by binary search, Karras 2012's split
/// rule), a range of equal keys at its middle. A wide node takes its range and splits its largest
/// child (by reference count) until it has W children or every child is a leaf: a range of at most
/// `max_leaf_size` references. Boxes are computed bottom up, each triangle read once, for its leaf.
/// Leaves are contiguous runs of the Morton order, so `prim_ids` is the sorted reference array itself.
///
/// Against `lbvh::build_wide` (the LBVH radix tree, SAH leaf collapse, then the wide collapse by
/// area): fewer passes over memory, leaves sized by count rather than by SAH, and children chosen by
/// count rather than by area: a somewhat different tree of similar quality (compare `sah_cost`), built
/// in about half the time. Made for scenes rebuilt every frame; `build_blocks` gives the traced layout
/// (leaves in SIMD triangle blocks, wide_blocks.hpp) in the same pass.
/// @code
///   auto wide = dynbvh::morton_wide::build(tris);                   // 8-wide, prim::indexed
///   auto fast = dynbvh::morton_wide::build_blocks(tris, {}, ex);    // the same tree, leaves in blocks of 8
/// @endcode
/// Passes: the centroid bounds (one read of the triangles), the codes (a second read), the radix sort
/// of the codes with the triangle ids, then the tree: the top is split serially, breadth first, until
/// 256 ranges are pending; each range's topology is built depth first by one task (binary searches on
/// the keys alone); one scan over the tasks places their nodes and blocks; each task then writes its
/// nodes straight into the tree, reading each of its triangles once for the leaf boxes (and blocks or
/// leaf copies). No reference boxes are stored, and no array is copied or converted after the build.
/// The same tree on every executor and thread count. O(n log n) for the binary searches (short:
/// within each range), O(n) memory traffic otherwise; 10 parallel steps (fork-joins) in all, 6 of
/// them the radix sort's (30-bit codes).
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
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
#include "wide_blocks.hpp"

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

/// The references sorted along the curve: their keys and user triangles (finite triangles only).
template <class Key>
struct Sorted {
    scratch_vector<Key> keys;
    scratch_vector<std::uint32_t> prim;
    std::size_t excluded = 0;   ///< triangles left out (a NaN or infinite vertex)
};

/// Box of a triangle, the expression make_references uses (the same bits, signed zeros included).
template <class T>
inline AABB<T> triangle_box(const Triangle<T>& t) noexcept {
    return {dynbvh::min(dynbvh::min(t.p0, t.p1), t.p2), dynbvh::max(dynbvh::max(t.p0, t.p1), t.p2)};
}

/// The finite triangles of `tris` sorted by the Morton code of their box centres: the keys and
/// order make_references + morton::sort_references give, without the reference boxes (the tree reads
/// each triangle once, later, where it packs the leaves). Two passes over the triangles (centroid
/// bounds; codes), then the radix sort; a triangle with a non-finite vertex gets a key above every
/// code and is cut off after the sort (the finite ones keep their order: the sort is stable).
template <class Key, class Source, class Exec>
Sorted<Key> sort_triangles(Source tris, const Exec& ex) {
    using T = dynbvh::detail::source_scalar_t<Source>;
    const std::size_t n = tris.size();
    struct Acc {
        Vec3<T> lo, hi;   // centroid bounds, as corners (kept in registers)
        std::size_t bad;
    };
    constexpr T inf = std::numeric_limits<T>::infinity();
    const Acc empty{{inf, inf, inf}, {-inf, -inf, -inf}, 0};
    // Step 1: centroid bounds of the finite triangles (the chunks of make_references: the same floats).
    const std::size_t tasks = std::clamp<std::size_t>(n / 4096, 1, 4 * ex.concurrency());
    const std::size_t chunk = (n + tasks - 1) / tasks;
    scratch_vector<Acc> partial(tasks, empty);   // (with operator new replaced, as in test_mesh_view_alloc, GCC 12 warns of a mismatched new/free in std::vector here)
    ex.for_tasks(tasks, [&](std::size_t k) {
        Acc a = empty;
        for (std::size_t i = std::min(n, k * chunk), e = std::min(n, i + chunk); i < e; ++i) {
            const Triangle<T>& t = tris[i];
            if (t.is_finite()) {
                const AABB<T> b = triangle_box(t);
                const Vec3<T> c = (b.min + b.max) * T(0.5);
                a.lo = dynbvh::min(a.lo, c);
                a.hi = dynbvh::max(a.hi, c);
            } else {
                ++a.bad;
            }
        }
        partial[k] = a;
    });
    Acc acc = empty;
    for (const Acc& a : partial) acc = {dynbvh::min(acc.lo, a.lo), dynbvh::max(acc.hi, a.hi), acc.bad + a.bad};
    Sorted<Key> out;
    out.excluded = acc.bad;
    if (acc.bad == n) return out;
    // Step 2: the codes (a non-finite triangle: the key just above every code).
    const morton::Quantizer<T> q(AABB<T>{acc.lo, acc.hi}, morton::grid_bits<Key>);
    constexpr Key beyond = Key(1) << morton::code_bits<Key>;
    out.keys.resize(n);
    Key* keys = out.keys.data();
    if (acc.bad == 0)   // (the common case: no test per triangle)
        ex.for_each(0, n, [&](std::size_t i) {
            const Triangle<T>& t = tris[i];
            keys[i] = morton::encode<Key>(q, triangle_box(t).center());
        });
    else
        ex.for_each(0, n, [&](std::size_t i) {
            const Triangle<T>& t = tris[i];
            keys[i] = t.is_finite() ? morton::encode<Key>(q, triangle_box(t).center()) : beyond;
        });
    // Step 3: sort (the original positions are the triangle ids), cut the non-finite tail.
    out.prim = radix_sort_order(out.keys, ex, morton::code_bits<Key> + (acc.bad != 0 ? 1 : 0));
    out.keys.resize(n - acc.bad);
    out.prim.resize(n - acc.bad);
    return out;
}

/// One wide node of a task's subtree before its boxes are known: its children's ranges and, for an
/// inner child, the child's index in the task's array; the task-local index of its first block.
template <int W>
struct Topology {
    Range c[std::size_t(W)];
    std::uint32_t child[std::size_t(W)];
    std::uint32_t first_block;
    int n;
};

/// Step 2a of build_nodes: the subtree over `r` (r.size() > max_leaf) depth first into `out` (its root
/// at `at`), the node order of the boxes-included build; `blocks` counts the blocks of its leaves in
/// node order (L lanes; 0: no blocks) and `deepest` is raised to the deepest wide level reached.
template <int W, int L, class Key>
void build_topology(const Key* keys, std::uint32_t max_leaf, Range r, std::size_t at, std::uint32_t depth,
                    scratch_vector<Topology<W>>& out, std::uint32_t& deepest, std::uint32_t& blocks) {
    deepest = std::max(deepest, depth);
    Topology<W>& t = out[at];
    t.n = open_range<W>(keys, r, max_leaf, t.c);
    t.first_block = blocks;
    const int n = t.n;
    Range c[std::size_t(W)];
    std::copy(t.c, t.c + n, c);   // `t` moves when `out` grows below
    if constexpr (L != 0)
        for (int k = 0; k < n; ++k)
            if (c[k].size() <= max_leaf) blocks += std::uint32_t(dynbvh::detail::blocks_for<L>(c[k].size()));
    for (int k = 0; k < n; ++k) {
        if (c[k].size() <= max_leaf) continue;
        const std::size_t child = out.size();
        out.emplace_back();
        out[at].child[k] = std::uint32_t(child);
        build_topology<W, L>(keys, max_leaf, c[k], child, depth + 1, out, deepest, blocks);
    }
}

/// Writes the leaf over sorted references [r.begin, r.end) and returns its box: the box of each
/// triangle (tris[prim[i]], read once) extended in order; prim::copied also copies the triangles to
/// their leaf slots, prim::blocks<L> packs them into the blocks from `block` on (lane by lane in
/// slot order, the last block padded: what make_wide_blocks does).
template <class Result, class Source>
AABB<typename Result::scalar_type> write_leaf(const std::uint32_t* prim, Range r, Source tris, Result& wide, std::size_t block) {
    using T = typename Result::scalar_type;
    constexpr int L = Result::block_lanes;
    AABB<T> box;
    if constexpr (L != 0) {
        auto* b = wide.blocks.data() + block;
        for (std::uint32_t i = r.begin; i < r.end; i += std::uint32_t(L), ++b) {
            const int m = int(std::min<std::uint32_t>(std::uint32_t(L), r.end - i));
            for (int k = 0; k < m; ++k) {
                const Triangle<T>& t = tris[prim[i + std::uint32_t(k)]];
                box.extend(triangle_box(t));
                b->set(k, t, prim[i + std::uint32_t(k)]);
            }
            b->pad(m);
        }
    } else {
        (void)block;
        for (std::uint32_t i = r.begin; i < r.end; ++i) {
            const Triangle<T>& t = tris[prim[i]];
            box.extend(triangle_box(t));
            if constexpr (Result::precomputed) wide.leaf_triangles[i] = t;
        }
    }
    return box;
}

/// Fetches the triangles of node `t`'s leaves ahead of write_leaf (a span's triangles are scattered
/// in memory in Morton order; a MeshView's are made on the fly: nothing to fetch).
template <int W, class Source>
void prefetch_leaves(const Topology<W>& t, const std::uint32_t* prim, std::uint32_t max_leaf, Source tris) {
#if defined(__GNUC__)
    if constexpr (std::is_lvalue_reference_v<decltype(tris[0])>)
        for (int k = 0; k < t.n; ++k)
            if (t.c[k].size() <= max_leaf)
                for (std::uint32_t i = t.c[k].begin; i < t.c[k].end; ++i) __builtin_prefetch(&tris[prim[i]]);
#else
    (void)t; (void)prim; (void)max_leaf; (void)tris;
#endif
}

/// The tree over sorted `keys` / `prim` (see the file comment) into `wide`: nodes, leaves (prim_ids
/// slots, leaf triangles or blocks) and depth. Parallel structure: the top serially, breadth first,
/// until 256 ranges are pending; each range's topology by one task (no boxes: binary searches on the
/// keys only); one scan over the tasks places their nodes and blocks; then each task writes its nodes
/// bottom up straight into the tree, reading each of its triangles once for the leaf boxes (and the
/// blocks). The same tree on every executor and thread count.
template <int W, class Result, class Key, class Source, class Exec>
void build_nodes(const Key* keys, const std::uint32_t* prim, std::uint32_t n, std::uint32_t max_leaf, Source tris, Result& wide,
                 const Exec& ex) {
    using WNode = typename Result::node_type;
    using Index = typename WNode::index_type;
    constexpr int L = Result::block_lanes;
    constexpr auto blocks_of = [](std::uint32_t refs) { return L == 0 ? std::size_t(0) : dynbvh::detail::blocks_for<(L == 0 ? 1 : L)>(refs); };
    auto leaf_child = [&](Range r, std::size_t block) { return Index(L != 0 ? block : r.begin); };
    if constexpr (Result::precomputed) wide.leaf_triangles.resize(n);
    if (n <= max_leaf) {   // one wide node with one leaf slot
        if constexpr (L != 0) wide.blocks.resize(blocks_of(n));
        WNode w;
        w.clear();
        w.set_bounds(0, write_leaf(prim, {0, n}, tris, wide, 0));
        w.child[0] = leaf_child({0, n}, 0);
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
    struct TopLeaf {
        Index node;
        int slot;
        std::size_t block;    // its first block (blocks of the top leaves come first, in node order)
    };
    constexpr std::size_t target = 256;   // as the wide conversions: the same tree on every executor
    std::vector<WNode> top;
    std::vector<Pending> queue;
    std::vector<TopLeaf> top_leaves;
    std::size_t top_blocks = 0;
    std::size_t head = 0;
    auto expand_top = [&](Range r, std::uint32_t depth) {
        const auto id = Index(top.size());
        Range c[std::size_t(W)];
        const int m = open_range<W>(keys, r, max_leaf, c);
        WNode w;
        w.clear();
        for (int k = 0; k < m; ++k) {
            if (c[k].size() <= max_leaf) {
                w.child[k] = Index(c[k].begin);   // the range until write_leaf
                w.count[k] = Index(c[k].size());
                top_leaves.push_back({id, k, top_blocks});
                top_blocks += blocks_of(c[k].size());
            } else {
                queue.push_back({c[k], id, k, depth + 1});
            }
            w.lo_x[k] = 0;   // a non-empty slot until its box is known
            w.hi_x[k] = 0;
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
    // Step 2a: each pending range's topology by one task, into its own array.
    const std::size_t tasks = queue.size() - head;
    std::vector<scratch_vector<Topology<W>>> local(tasks);
    std::vector<std::uint32_t> local_depth(tasks, 0), local_blocks(tasks, 0);
    ex.for_tasks(tasks, [&](std::size_t k) {
        const Pending& p = queue[head + k];
        scratch_vector<Topology<W>>& out = local[k];
        out.reserve(p.range.size() / (W * max_leaf / 2) + 8);
        out.emplace_back();
        local_depth[k] = p.depth;
        build_topology<W, L>(keys, max_leaf, p.range, 0, p.depth, out, local_depth[k], local_blocks[k]);
    });
    // Step 2b: where each task's nodes and blocks go (after the top's, in task order); link the top.
    std::vector<std::size_t> node_base(tasks), block_base(tasks);
    std::size_t nodes_total = top.size(), blocks_total = top_blocks;
    for (std::size_t k = 0; k < tasks; ++k) {
        node_base[k] = nodes_total;
        block_base[k] = blocks_total;
        nodes_total += local[k].size();
        blocks_total += local_blocks[k];
        top[queue[head + k].parent].child[queue[head + k].slot] = Index(node_base[k]);
        wide.depth = std::max(wide.depth, local_depth[k]);
    }
    wide.nodes.resize(nodes_total);
    if constexpr (L != 0) wide.blocks.resize(blocks_total);
    // Step 2c: each task's nodes into place: first in order (the leaves: boxes from the triangles, read
    // once, fetched a few nodes ahead; blocks), then last first (the inner boxes: children before parents).
    ex.for_tasks(tasks, [&](std::size_t k) {
        const scratch_vector<Topology<W>>& nodes = local[k];
        const std::size_t base = node_base[k], count = nodes.size();
        constexpr std::size_t ahead = 2;   // nodes (about 40 triangles)
        for (std::size_t i = 0; i < std::min(ahead, count); ++i) prefetch_leaves(nodes[i], prim, max_leaf, tris);
        for (std::size_t i = 0; i < count; ++i) {
            if (i + ahead < count) prefetch_leaves(nodes[i + ahead], prim, max_leaf, tris);
            const Topology<W>& t = nodes[i];
            WNode w;
            w.clear();
            std::size_t block = block_base[k] + t.first_block;
            for (int s = 0; s < t.n; ++s) {
                const Range r = t.c[s];
                if (r.size() <= max_leaf) {
                    w.set_bounds(s, write_leaf(prim, r, tris, wide, block));
                    w.child[s] = leaf_child(r, block);
                    w.count[s] = Index(r.size());
                    block += blocks_of(r.size());
                } else {
                    w.child[s] = Index(base + t.child[s]);
                }
            }
            wide.nodes[base + i] = w;
        }
        for (std::size_t i = count; i-- > 0;) {
            const Topology<W>& t = nodes[i];
            WNode& w = wide.nodes[base + i];
            for (int s = 0; s < t.n; ++s)
                if (t.c[s].size() > max_leaf) w.set_bounds(s, wide.nodes[w.child[s]].bounds());
        }
        top[queue[head + k].parent].set_bounds(queue[head + k].slot, wide.nodes[base].bounds());
    });
    // Step 3: the top's leaves, then its inner slots bottom-up (a top node's inner children come after
    // it, breadth first), then the top nodes into place.
    for (const TopLeaf& l : top_leaves) {
        WNode& w = top[l.node];
        const Range r{std::uint32_t(w.child[l.slot]), std::uint32_t(w.child[l.slot] + w.count[l.slot])};
        w.set_bounds(l.slot, write_leaf(prim, r, tris, wide, l.block));
        w.child[l.slot] = leaf_child(r, l.block);
    }
    for (std::size_t i = head; i-- > 0;) {
        const Pending& p = queue[i];
        top[p.parent].set_bounds(p.slot, top[top[p.parent].child[p.slot]].bounds());
    }
    std::copy(top.begin(), top.end(), wide.nodes.begin());
}

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
    Result wide;
    wide.primitive_count = tris.size();
    // Sort along the curve, then split top down.
    auto run = [&](auto key) {
        using Key = decltype(key);
        Sorted<Key> sorted = sort_triangles<Key>(tris, ex);
        wide.excluded = sorted.excluded;
        const auto n = std::uint32_t(sorted.prim.size());
        if (n == 0) return;
        build_nodes<W>(sorted.keys.data(), sorted.prim.data(), n, cfg.max_leaf_size, tris, wide, ex);
        // Leaves are runs of the sorted references: their prim array is the sorted ids as they stand.
        if constexpr (Result::block_lanes == 0) {
            if constexpr (std::is_same_v<decltype(wide.prim_ids), decltype(sorted.prim)>) {
                wide.prim_ids = std::move(sorted.prim);
            } else {
                wide.prim_ids.resize(n);
                ex.for_each(0, n, [&](std::size_t i) { wide.prim_ids[i] = typename NodeT::index_type(sorted.prim[i]); });
            }
        }
    };
    if (cfg.morton_bits == 63) run(std::uint64_t{});
    else run(std::uint32_t{});
    return wide;
}

} // namespace detail

/// Builds a W-wide BVH over `tris` straight from the sorted Morton codes (see the file comment).
/// Triangles with NaN/infinite vertices are left out and counted in `excluded`. Throws
/// std::invalid_argument for morton_bits other than 30 or 63 or a max_leaf_size outside 1..255,
/// std::length_error beyond 2^31 - 1 triangles. O(n) passes plus the radix sort, parallel over `ex`.
/// @tparam W 4 or 8, @tparam NodeT the binary node type whose scalar and index the wide node takes,
/// @tparam Prim prim::indexed, prim::copied, or prim::blocks<L> (float only): the traced layout, as
/// `build_blocks` below.
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

/// The traced layout in one step: the W-wide tree `build` gives with its leaves packed into SIMD
/// blocks of L triangles (wide_blocks.hpp), the tree `make_wide_blocks<L>(build<W>(tris, cfg, ex), tris, ex)`
/// gives, bit for bit, without the index tree: each leaf's triangles are read once, for its box and
/// its blocks. `dynbvh::morton_wide::build_blocks(tris)` (a std::vector converts). Same errors as `build`.
template <int W = 8, int L = W, class Exec = exec::default_executor>
WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(std::span<const Triangle<float>> tris, const Config& cfg = {},
                                                                         const Exec& ex = {}) {
    return detail::build<W, Node<float>, prim::blocks<L>>(tris, cfg, ex);
}

/// The same over an indexed float mesh read in place (mesh.hpp): the span's tree, bit for bit.
template <int W = 8, int L = W, class Exec = exec::default_executor, class Index>
WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(const MeshView<float, Index>& mesh, const Config& cfg = {},
                                                                         const Exec& ex = {}) {
    return detail::build<W, Node<float>, prim::blocks<L>>(mesh, cfg, ex);
}

} // namespace dynbvh::morton_wide
