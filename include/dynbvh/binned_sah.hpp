// SPDX-License-Identifier: MIT
/// @file binned_sah.hpp
/// Top-down binned SAH builder: Wald 2007, "On fast Construction of SAH-based Bounding Volume
/// Hierarchies" (IEEE RT). Every node bins its references' centres into `bins` equal slots per axis
/// over the centroid bounds, evaluates the SAH at every bin boundary of all three axes and partitions
/// at the cheapest. The slowest builder here and the best trees: the quality reference the others
/// are measured against.
///
/// Nodes of at most 16 references use an exact SAH sweep over their sorted centres instead of bins.
/// Splits go down to single references (emit_bvh collapses leaves by SAH afterwards). A node whose
/// centres all coincide is split in the middle by index; a node that would make the tree deeper
/// than max_depth is split at its object median, so the raw tree never exceeds max_depth and
/// millions of identical centroids cost O(n log n). Large nodes (the top of the tree) are binned
/// and partitioned data-parallel, block by block; the subtrees below are then built in parallel,
/// one task each, with an explicit stack. The result does not depend on the executor.
#pragma once

#include <algorithm>
#include <array>
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
#include "detail/references.hpp"
#include "detail/sah_bins.hpp"
#include "detail/triangle_source.hpp"

namespace dynbvh::binned_sah {

/// Binned SAH knobs. Designated-initialiser friendly: `{.bins = 16}`.
struct Config {
    /// Bins per axis (Wald 2007 uses 16 to 32). More = closer to a full sweep, slower. Must be >= 2.
    std::uint32_t bins = 32;
    LeafConfig leaves{};  ///< SAH leaf collapse (shared by every builder)
};

namespace detail {

using dynbvh::detail::Binner;
using dynbvh::detail::Bins;
using dynbvh::detail::Split;
using dynbvh::detail::best_split;

template <class T>
struct Item {
    AABB<T> box;
    std::uint32_t ref;
};

/// One pending node: items [begin, end), where its id goes in the parent, and its depth.
struct Range {
    std::uint32_t begin, end;
    std::uint32_t parent;    ///< inner node id of the parent; BinaryTree::leaf_flag for the root
    std::uint32_t side;      ///< 0 = parent's left child, 1 = right
    std::uint32_t depth;     ///< edges from the root
};

template <class T>
void bin_items(const Item<T>* items, std::size_t n, const Binner<T>& binner, Bins<T>& bins) noexcept {
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3<T> c = items[i].box.center();
        for (std::size_t a = 0; a < 3; ++a) {
            const std::size_t b = a * bins.k + binner.bin(c, a);
            ++bins.count[b];
            bins.box[b].extend(items[i].box);
        }
    }
}

template <class T>
AABB<T> centroid_bounds(const Item<T>* items, std::size_t n) noexcept {
    AABB<T> b;
    for (std::size_t i = 0; i < n; ++i) b.extend(items[i].box.center());
    return b;
}

/// Nodes this small are split by a full SAH sweep over sorted centres instead of bins.
inline constexpr std::size_t sweep_limit = 16;

/// Exact SAH split of a small node (n <= sweep_limit): sorts the centres on each axis and tries every
/// position. Reorders the items to the best axis' order and returns the size of the left part, or 0
/// when all centres coincide.
template <class T>
std::size_t sweep_split(Item<T>* items, std::size_t n, const AABB<T>& centroids) {
    const Vec3<T> ext = centroids.diagonal();
    std::uint8_t order[sweep_limit], best_order[sweep_limit];
    double right[sweep_limit];
    double best_cost = std::numeric_limits<double>::infinity();
    std::size_t best_pos = 0;
    for (std::size_t a = 0; a < 3; ++a) {
        if (!(ext[a] > T(0))) continue;
        for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint8_t>(i);
        std::sort(order, order + n, [&](std::uint8_t x, std::uint8_t y) {
            const T cx = items[x].box.min[a] + items[x].box.max[a], cy = items[y].box.min[a] + items[y].box.max[a];
            return cx < cy || (cx == cy && x < y);
        });
        AABB<T> acc;
        for (std::size_t i = n - 1; i > 0; --i) {
            acc.extend(items[order[i]].box);
            right[i] = acc.template half_area_in<double>() * static_cast<double>(n - i);
        }
        acc = AABB<T>{};
        for (std::size_t i = 1; i < n; ++i) {
            acc.extend(items[order[i - 1]].box);
            const double cost = acc.template half_area_in<double>() * static_cast<double>(i) + right[i];
            if (cost < best_cost) {
                best_cost = cost;
                best_pos = i;
                std::copy(order, order + n, best_order);
            }
        }
    }
    if (best_pos == 0) return 0;
    Item<T> tmp[sweep_limit];
    for (std::size_t i = 0; i < n; ++i) tmp[i] = items[best_order[i]];
    std::copy(tmp, tmp + n, items);
    return best_pos;
}

/// Splits items [0, n) at their median along the longest centroid axis (by index when all centres
/// coincide). Returns the size of the left part (n / 2).
template <class T>
std::size_t median_split(Item<T>* items, std::size_t n, const AABB<T>& centroids) {
    const std::size_t mid = n / 2;
    const Vec3<T> ext = centroids.diagonal();
    const std::size_t a = std::size_t(largest_axis(ext));
    if (ext[a] > T(0))
        std::nth_element(items, items + mid, items + n, [a](const Item<T>& x, const Item<T>& y) {
            return x.box.min[a] + x.box.max[a] < y.box.min[a] + y.box.max[a];
        });
    return mid;
}

/// Deepest edge count a subtree of n leaves has when split at medians: ceil(log2 n).
inline std::uint32_t balanced_height(std::size_t n) noexcept {
    return n <= 1 ? 0u : static_cast<std::uint32_t>(std::bit_width(n - 1));
}

/// Makes raw node `id` the child of `r`'s parent (or the root).
inline void link(BinaryTree& tree, const Range& r, std::uint32_t id) noexcept {
    if (r.parent == BinaryTree::leaf_flag) tree.root = id;
    else (r.side == 0 ? tree.left : tree.right)[r.parent] = id;
}

/// Whether a split of `n` references at `r` may follow the SAH: a median split below keeps the
/// subtree within max_depth.
inline bool sah_allowed(const Range& r, std::size_t n) noexcept { return r.depth + balanced_height(n) < max_depth; }

/// The split step the serial and the data-parallel builder share: inner node `id` over `r` is linked
/// to its parent; `find(it, n)` partitions the range's n items and returns how many go left (0 or n:
/// no useful split, and the median along the centroid bounds `cb` is used). Returns the children's
/// ranges, left first.
template <class T, class Find>
std::array<Range, 2> split_range(BinaryTree& tree, Item<T>* items, const Range& r, std::uint32_t id, const AABB<T>& cb,
                                 Find&& find) {
    link(tree, r, id);
    Item<T>* it = items + r.begin;
    const std::size_t n = r.end - r.begin;
    std::size_t nl = find(it, n);
    if (nl == 0 || nl == n) nl = median_split(it, n, cb);
    const auto mid = static_cast<std::uint32_t>(r.begin + nl);
    return {Range{r.begin, mid, id, 0, r.depth + 1}, Range{mid, r.end, id, 1, r.depth + 1}};
}

/// Serial builder state for one subtree.
template <class T>
struct Worker {
    Item<T>* items;
    BinaryTree& tree;
    std::uint32_t bin_count;
    Bins<T> bins;
    std::vector<double> right;
    std::vector<Range> stack;

    Worker(Item<T>* it, BinaryTree& t, std::uint32_t k) : items(it), tree(t), bin_count(k), bins(k) {}

    /// Builds the subtree over `r`, numbering its inner nodes from `next` on.
    void build(const Range& r0, std::uint32_t next) {
        stack.clear();
        stack.push_back(r0);
        while (!stack.empty()) {
            const Range r = stack.back();
            stack.pop_back();
            const std::size_t n = r.end - r.begin;
            if (n == 1) {
                link(tree, r, BinaryTree::leaf(items[r.begin].ref));
                continue;
            }
            const AABB<T> cb = centroid_bounds(items + r.begin, n);
            const auto [left, right_child] = split_range(tree, items, r, next++, cb, [&](Item<T>* it, std::size_t m) -> std::size_t {
                if (m <= 2 || !sah_allowed(r, m)) return 0;
                if (m <= sweep_limit) return sweep_split(it, m, cb);
                // Fewer bins than references in small nodes: empty bins only cost time.
                const auto k = static_cast<std::uint32_t>(std::min<std::size_t>(bin_count, m));
                const Binner<T> binner(cb, k);
                bins.reset(k);
                bin_items(it, m, binner, bins);
                const Split s = best_split(bins, cb, right);
                if (s.axis < 0) return 0;
                return static_cast<std::size_t>(
                    std::partition(it, it + m, [&](const Item<T>& x) { return binner.bin(x.box.center(), std::size_t(s.axis)) < s.bin; }) - it);
            });
            stack.push_back(right_child);
            stack.push_back(left);
        }
    }
};

} // namespace detail

/// Raw binned SAH topology over `refs` (see BinaryTree); refs are not reordered. O(n log n) work,
/// parallel. Throws std::invalid_argument for bins < 2 and std::length_error beyond 2^31 - 1 refs.
template <class T, class Exec>
BinaryTree build_tree(const References<T>& refs, const Config& cfg, const Exec& ex) {
    using namespace detail;
    if (cfg.bins < 2)
        throw std::invalid_argument("dynbvh::binned_sah: bins must be >= 2, got " + std::to_string(cfg.bins));
    const std::size_t n = refs.size();
    BinaryTree tree = BinaryTree::start(n, "dynbvh::binned_sah");
    if (n < 2) return tree;
    tree.left.assign(n - 1, 0);
    tree.right.assign(n - 1, 0);

    std::vector<Item<T>> items(n);
    ex.for_each(0, n, [&](std::size_t i) { items[i] = {refs.box[i], static_cast<std::uint32_t>(i)}; });

    // Step 1: nodes above this size are split data-parallel one at a time, top down; the rest become
    // independent subtrees. Fixed by n alone, so every executor builds the same tree.
    const std::size_t large = std::max<std::size_t>(4096, n / 128);
    const std::uint32_t k = cfg.bins;
    std::vector<Item<T>> scratch;
    std::vector<Range> subtrees;
    std::vector<Range> queue{{0, static_cast<std::uint32_t>(n), BinaryTree::leaf_flag, 0, 0}};
    std::uint32_t next_id = 0;
    std::vector<double> right;

    for (std::size_t q = 0; q < queue.size(); ++q) {
        const Range r = queue[q];
        const std::size_t m = r.end - r.begin;
        if (m < large) {
            subtrees.push_back(r);
            continue;
        }
        Item<T>* it = items.data() + r.begin;

        // Blocks of the range; every reduction below is exact (min/max, integer sums), so the
        // block count never changes the result.
        const std::size_t blocks = std::min<std::size_t>(m / 2048, std::max<std::size_t>(1, ex.concurrency() * 4));
        const std::size_t chunk = (m + blocks - 1) / blocks;
        auto lo_of = [&](std::size_t b) { return std::min(m, b * chunk); };
        auto hi_of = [&](std::size_t b) { return std::min(m, (b + 1) * chunk); };

        std::vector<AABB<T>> cbs(blocks);
        ex.for_tasks(blocks, [&](std::size_t b) { cbs[b] = centroid_bounds(it + lo_of(b), hi_of(b) - lo_of(b)); });
        AABB<T> cb;
        for (const auto& b : cbs) cb.extend(b);

        const auto [left, right_child] = split_range(tree, items.data(), r, next_id++, cb, [&](Item<T>*, std::size_t) -> std::size_t {   // over `it`, m items, in blocks
            if (!sah_allowed(r, m)) return 0;
            const Binner<T> binner(cb, k);
            std::vector<Bins<T>> part(blocks, Bins<T>(k));
            ex.for_tasks(blocks, [&](std::size_t b) { bin_items(it + lo_of(b), hi_of(b) - lo_of(b), binner, part[b]); });
            for (std::size_t b = 1; b < blocks; ++b) part[0].merge(part[b]);
            const Split s = best_split(part[0], cb, right);
            if (s.axis < 0) return 0;
            // Stable parallel partition: count per block, scan, scatter, copy back.
            auto goes_left = [&](const Item<T>& x) { return binner.bin(x.box.center(), std::size_t(s.axis)) < s.bin; };
            std::vector<std::size_t> left_count(blocks), left_at(blocks), right_at(blocks);
            ex.for_tasks(blocks, [&](std::size_t b) {
                std::size_t c = 0;
                for (std::size_t i = lo_of(b); i < hi_of(b); ++i) c += goes_left(it[i]) ? 1u : 0u;
                left_count[b] = c;
            });
            std::size_t lsum = 0, rsum = 0;
            for (std::size_t b = 0; b < blocks; ++b) {
                left_at[b] = lsum;
                right_at[b] = rsum;
                lsum += left_count[b];
                rsum += (hi_of(b) - lo_of(b)) - left_count[b];
            }
            const std::size_t nl = lsum;
            if (nl > 0 && nl < m) {
                scratch.resize(m);
                ex.for_tasks(blocks, [&](std::size_t b) {
                    std::size_t l = left_at[b], rr = nl + right_at[b];
                    for (std::size_t i = lo_of(b); i < hi_of(b); ++i) scratch[goes_left(it[i]) ? l++ : rr++] = it[i];
                });
                ex.for_each(0, m, [&](std::size_t i) { it[i] = scratch[i]; }, 4096);
            }
            return nl;
        });
        queue.push_back(left);
        queue.push_back(right_child);
    }

    // Step 2: the subtrees, one serial task each; a subtree of s references owns s - 1 consecutive
    // inner node ids.
    std::vector<std::uint32_t> first(subtrees.size());
    for (std::size_t i = 0; i < subtrees.size(); ++i) {
        first[i] = next_id;
        next_id += subtrees[i].end - subtrees[i].begin - 1;
    }
    // Biggest subtrees first for load balance; ids are already fixed, so order does not matter.
    std::vector<std::uint32_t> order(subtrees.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
        return subtrees[a].end - subtrees[a].begin > subtrees[b].end - subtrees[b].begin;
    });
    ex.for_tasks(order.size(), [&](std::size_t j) {
        const std::uint32_t s = order[j];
        detail::Worker<T> w(items.data(), tree, k);
        w.build(subtrees[s], first[s]);
    });
    return tree;
}

namespace detail {

/// build_tree as a function object, for dynbvh::detail::build_over (detail/emit_wide.hpp).
struct Topology {
    template <class T, class Exec>
    BinaryTree operator()(References<T>& refs, const Config& cfg, const Exec& ex) const { return dynbvh::binned_sah::build_tree(refs, cfg, ex); }
};

} // namespace detail

/// Builds a binned SAH BVH over `tris` in one call:
/// `auto bvh = dynbvh::binned_sah::build(tris, {.bins = 32}, dynbvh::exec::omp{});`
/// Triangles with non-finite vertices are left out (counted in Bvh::excluded). `tris` is not modified.
template <class NodeT = Node<>, class Prim = prim::indexed, class Exec = exec::default_executor>
Bvh<NodeT, Prim> build(std::span<const Triangle<typename NodeT::scalar_type>> tris, const Config& cfg = {},
                       const Exec& ex = {}) {
    return dynbvh::detail::build_over<0, NodeT, Prim>(tris, cfg, detail::Topology{}, ex);
}

/// Builds a binned SAH BVH over an indexed mesh read in place (mesh.hpp): the tree `build` gives over
/// `make_triangles(vertices, indices)`, bit for bit, without that copy. NodeT defaults to Node<T>.
template <class NodeT = void, class Prim = prim::indexed, class Exec = exec::default_executor, class T, class Index>
Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim> build(const MeshView<T, Index>& mesh, const Config& cfg = {}, const Exec& ex = {}) {
    return dynbvh::detail::build_over<0, dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, detail::Topology{}, ex);
}

/// Builds a binned SAH BVH straight into the W-wide layout (W = 4 or 8; detail/emit_wide.hpp): the tree
/// `make_wide<W>(build<NodeT, Prim>(tris, cfg, ex), ex)` gives, bit for bit, without the binary nodes.
template <int W = 8, class NodeT = Node<>, class Prim = prim::indexed, class Exec = exec::default_executor>
wide_bvh_of<Bvh<NodeT, Prim>, W> build_wide(std::span<const Triangle<typename NodeT::scalar_type>> tris,
                                            const Config& cfg = {}, const Exec& ex = {}) {
    return dynbvh::detail::build_over<W, NodeT, Prim>(tris, cfg, detail::Topology{}, ex);
}

/// build_wide over an indexed mesh read in place (mesh.hpp); same tree as over make_triangles' array.
template <int W = 8, class NodeT = void, class Prim = prim::indexed, class Exec = exec::default_executor, class T, class Index>
wide_bvh_of<Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim>, W> build_wide(const MeshView<T, Index>& mesh, const Config& cfg = {},
                                                                         const Exec& ex = {}) {
    return dynbvh::detail::build_over<W, dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, detail::Topology{}, ex);
}

/// The same for a std::vector of triangles of any scalar, the node type following the triangles:
/// `dynbvh::binned_sah::build(std::vector<Triangled>{...})` is a Bvh<Node<double>>.
template <int = 0, class T, class Exec = exec::default_executor>
Bvh<Node<T>> build(const std::vector<Triangle<T>>& tris, const Config& cfg = {}, const Exec& ex = {}) {
    return build<Node<T>, prim::indexed, Exec>(std::span<const Triangle<T>>(tris), cfg, ex);
}

} // namespace dynbvh::binned_sah
