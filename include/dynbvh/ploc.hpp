// SPDX-License-Identifier: MIT
/// @file ploc.hpp
/// PLOC: Parallel Locally-Ordered Clustering (Meister & Bittner 2018, "Parallel Locally-Ordered
/// Clustering for Bounding Volume Hierarchy Construction", IEEE TVCG 24(3)).
///
/// Bottom-up agglomerative clustering along the Morton curve:
///  1. references are sorted by the Morton code of their box centre; each is a cluster;
///  2. every cluster finds, among the `radius` clusters on each side of it, the one whose merged
///     box has the smallest surface area (its nearest neighbour);
///  3. mutual nearest neighbours merge into a new inner node (the lower position keeps it);
///  4. a prefix sum compacts the surviving clusters, keeping their Morton order;
///  5. repeat until one cluster, the root, is left.
/// Speed, in the spirit of PLOC++ (Benthin et al. 2022): each pair's distance is computed once per
/// iteration and offered to both clusters as one packed integer key (a branch-free min); inner node ids
/// follow from the clusters' first leaves, so no counter is needed and the tree is laid out along the
/// curve; buffers are allocated once and swapped; iterations over few clusters run on the calling thread.
///
/// Termination on any input: the distance is made a strict total order on pairs, so the best pair
/// inside any window is mutual and every iteration merges at least one pair. A guard makes progress
/// certain anyway: an iteration that merges almost nothing (nested or identical boxes) merges
/// Morton-adjacent pairs instead, so the number of iterations stays logarithmic.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bvh.hpp"
#include "detail/emit.hpp"
#include "detail/emit_wide.hpp"
#include "executor.hpp"
#include "mesh.hpp"
#include "detail/morton.hpp"
#include "detail/references.hpp"
#include "detail/triangle_source.hpp"
#include "detail/scratch.hpp"

namespace dynbvh::ploc {

/// PLOC knobs. Designated-initialiser friendly: `{.radius = 16}`.
struct Config {
    /// Search window: each cluster looks at `radius` clusters on each side (study default 5; the paper
    /// uses 10 to 25 for higher quality). Larger = better tree, slower build (work ~ radius). 0 acts as 1;
    /// values above 65536 act as 65536.
    std::uint32_t radius = 5;
    /// Morton code width: 30 (uint32_t keys, 2^10 cells per axis) or 63 (uint64_t keys, 2^21 cells).
    int morton_bits = 30;
    LeafConfig leaves{};  ///< leaf collapse after clustering (shared by every builder)
};

namespace detail {

/// Half the surface area of the union of two boxes: the distance PLOC minimises, in single precision.
template <class T>
inline float merged_half_area(const AABB<T>& a, const AABB<T>& b) noexcept {
    const Vec3<T> d = dynbvh::max(a.max, b.max) - dynbvh::min(a.min, b.min);
    return static_cast<float>(d.x * d.y + d.y * d.z + d.z * d.x);
}

/// A candidate neighbour of cluster m as one integer, so that "best so far" is a branch-free min.
/// candidate_key gives pair (lower, lower + k) as seen from lower + k; `| partner_right` as seen from lower:
///   bits 63..32  the distance (non-negative float bits order like the values; a NaN from overflowing
///                extents sorts after +inf, and each pair's distance is computed from the same operands
///                wherever it is needed, so the order stays consistent),
///   bits 31..2   k = |m - partner| (nearer first on equal distance),
///   bit  1       parity of the pair's lower position (pairs (0,1), (2,3), ... first),
///   bit  0       1 when the partner lies right of m (left first).
/// This is cluster m's view of one strict total order on pairs, (distance, k, parity, lower position):
/// so the best pair of any window is chosen by both its ends (mutual), every iteration merges, and a
/// run of identical boxes merges pairwise (halving per iteration) instead of one pair per iteration.
inline std::uint64_t candidate_key(float distance, std::size_t k, std::size_t lower) noexcept {
    return (std::uint64_t(std::bit_cast<std::uint32_t>(distance)) << 32) | (std::uint64_t(k) << 2) |
           (std::uint64_t(lower & 1) << 1);
}
/// Bit 0 of a key: set in the key of pair (lower, lower + k) as seen from `lower`.
inline constexpr std::uint64_t partner_right = 1;
/// The partner position encoded in cluster m's best key.
inline std::size_t partner_of(std::size_t m, std::uint64_t key) noexcept {
    const std::size_t k = static_cast<std::size_t>((key >> 2) & 0x3fffffffu);
    return (key & partner_right) ? m + k : m - k;
}

/// Largest usable radius (k must fit the candidate key's 30 bits; far beyond any useful window).
inline constexpr std::uint32_t max_radius = 1u << 16;
/// Below this many clusters an iteration runs on the calling thread (threading costs more than it saves).
inline constexpr std::size_t serial_cluster_count = 4096;
/// An iteration merging fewer than clusters / this pairs falls back to pairing Morton neighbours
/// (real scenes merge 10-40% of the clusters per iteration).
inline constexpr std::size_t min_progress_divisor = 64;

/// The clustering state: the live clusters in Morton order, as tree node ids with their boxes and first
/// leaves, in ping-pong buffers (iteration k reads half k % 2, writes the other), plus per-iteration
/// scratch, all allocated once.
template <class T>
class Clustering {
public:
    static constexpr std::uint64_t no_candidate = std::numeric_limits<std::uint64_t>::max();

    /// Starts with one cluster per reference; `refs` must already be in Morton order.
    template <class Exec>
    Clustering(const References<T>& refs, std::uint32_t radius, const Exec& ex)
        : radius_(std::clamp<std::uint32_t>(radius, 1, max_radius)), count_(refs.size()),
          boxes_{scratch_vector<AABB<T>>(count_), scratch_vector<AABB<T>>(count_)},
          ids_{scratch_vector<std::uint32_t>(count_), scratch_vector<std::uint32_t>(count_)},
          first_leaf_{scratch_vector<std::uint32_t>(count_), scratch_vector<std::uint32_t>(count_)},
          best_(count_), survivors_(count_ + 1) {
        tree_.left.resize(count_ - 1);
        tree_.right.resize(count_ - 1);
        ex.for_each(0, count_, [&](std::size_t i) {
            boxes_[0][i] = refs.box[i];
            ids_[0][i] = BinaryTree::leaf(static_cast<std::uint32_t>(i));
            first_leaf_[0][i] = static_cast<std::uint32_t>(i);
        });
    }

    /// Runs iterations until one cluster is left; returns the tree (root = the last cluster).
    template <class Exec>
    BinaryTree run(const Exec& ex) {
        while (count_ > 1) {
            if (count_ < serial_cluster_count) iterate(exec::serial{});
            else iterate(ex);
        }
        tree_.root = ids_[iteration_ & 1][0];
        return std::move(tree_);
    }

private:
    /// One PLOC iteration: nearest neighbours, mutual merges, compaction.
    template <class Exec>
    void iterate(const Exec& ex) {
        find_neighbours(ex);
        std::size_t merges = mark_merges(ex);
        if (merges == 0 || merges < count_ / min_progress_divisor) {
            pair_adjacent(ex);
            merges = mark_merges(ex);
        }
        compact(ex, merges);
    }

    /// Step 2: best_[m] = key of the cluster within `radius` positions of m whose merged box with m has the
    /// smallest half area. Each pair (i, i + k), k = 1..radius, is evaluated once and offered to both ends;
    /// a block also evaluates the pairs reaching into it from the r clusters left of it.
    template <class Exec>
    void find_neighbours(const Exec& ex) {
        const std::size_t c = count_, r = radius_;
        const auto& boxes = boxes_[iteration_ & 1];
        ex.for_blocks(0, c, [&](std::size_t lo, std::size_t hi) {
            std::fill(best_.begin() + std::ptrdiff_t(lo), best_.begin() + std::ptrdiff_t(hi), no_candidate);
            for (std::size_t i = lo >= r ? lo - r : 0; i < lo; ++i)   // pairs from the left into the block
                for (std::size_t j = lo; j < std::min(hi, i + r + 1); ++j)
                    best_[j] = std::min(best_[j], candidate_key(merged_half_area(boxes[i], boxes[j]), j - i, i));
            for (std::size_t i = lo; i < hi; ++i) {
                const AABB<T> bi = boxes[i];
                std::uint64_t best_i = best_[i];
                const std::size_t end = std::min(c, i + r + 1), end_in_block = std::min(end, hi);
                std::size_t j = i + 1;
                for (; j < end_in_block; ++j) {   // both ends in this block
                    const std::uint64_t key = candidate_key(merged_half_area(bi, boxes[j]), j - i, i);
                    best_i = std::min(best_i, key | partner_right);
                    best_[j] = std::min(best_[j], key);
                }
                for (; j < end; ++j)              // j belongs to the next block, which offers i to j itself
                    best_i = std::min(best_i, candidate_key(merged_half_area(bi, boxes[j]), j - i, i) | partner_right);
                best_[i] = best_i;
            }
        }, 1024);
    }

    /// Fallback when an iteration makes (almost) no progress: pair positions (0,1), (2,3), ...
    template <class Exec>
    void pair_adjacent(const Exec& ex) {
        const std::size_t c = count_;
        ex.for_each(0, c, [&](std::size_t i) {
            const bool right = (i & 1) == 0;
            best_[i] = (right && i + 1 == c) ? no_candidate
                                             : candidate_key(0.0f, 1, i & ~std::size_t(1)) | (right ? partner_right : 0);
        });
    }

    /// Position of m's merge partner, or m itself when m does not merge this iteration.
    std::size_t mutual_partner(std::size_t m) const noexcept {
        if (best_[m] == no_candidate) return m;
        const std::size_t j = partner_of(m, best_[m]);
        return partner_of(j, best_[j]) == m ? j : m;
    }

    /// Step 3: i and j merge iff they are each other's best; the lower position keeps the merged cluster,
    /// the higher one disappears. survivors_[i] = 1 unless i disappears; one exclusive scan (total stored
    /// at survivors_[c]) then gives each survivor its new position. Returns the number of merges.
    template <class Exec>
    std::size_t mark_merges(const Exec& ex) {
        const std::size_t c = count_;
        ex.for_each(0, c, [&](std::size_t i) { survivors_[i] = mutual_partner(i) >= i ? 1u : 0u; });
        survivors_[c] = ex.exclusive_scan(std::span<const std::uint32_t>(survivors_.data(), c),
                                          std::span<std::uint32_t>(survivors_.data(), c));
        return c - survivors_[c];
    }

    /// Step 4: writes the merged nodes and scatters the survivors, in order, into the other buffers.
    /// A merge of i with j > i becomes inner node first_leaf(j) - 1. Clusters keep the Morton order of their
    /// first (smallest) leaf position, so the disappearing cluster j's first leaf is never 0 and never the
    /// first leaf of a later disappearing cluster: the n - 1 merges get the ids 0 .. n - 2 exactly once,
    /// without any counter, and a node's id lies next to its leaves' positions (as in Karras's radix tree),
    /// which keeps emit_bvh's passes over the tree local in memory.
    template <class Exec>
    void compact(const Exec& ex, std::size_t merges) {
        const std::size_t in = iteration_ & 1, out = in ^ 1;
        const auto& boxes = boxes_[in];
        const auto &ids = ids_[in], &first = first_leaf_[in];
        auto& next_boxes = boxes_[out];
        auto &next_ids = ids_[out], &next_first = first_leaf_[out];
        ex.for_each(0, count_, [&](std::size_t i) {
            const std::size_t pos = survivors_[i];
            if (survivors_[i + 1] == pos) return;  // merged into its lower partner
            const std::size_t j = mutual_partner(i);   // i itself when i does not merge
            next_first[pos] = first[i];
            next_boxes[pos] = merge(boxes[i], boxes[j]);
            std::uint32_t id = ids[i];
            if (j != i) {
                id = first[j] - 1;
                tree_.left[id] = ids[i];
                tree_.right[id] = ids[j];
            }
            next_ids[pos] = id;
        });
        ++iteration_;
        count_ -= merges;
    }

    std::uint32_t radius_;
    std::size_t count_;                 // live clusters
    std::size_t iteration_ = 0;         // selects the current half of each ping-pong pair
    scratch_vector<AABB<T>> boxes_[2];             // cluster -> its box
    scratch_vector<std::uint32_t> ids_[2];         // cluster -> tree node id (BinaryTree::leaf(ref) or inner)
    scratch_vector<std::uint32_t> first_leaf_[2];  // cluster -> smallest leaf position in it
    scratch_vector<std::uint64_t> best_;           // cluster -> key of its best candidate (see candidate_key)
    scratch_vector<std::uint32_t> survivors_;      // exclusive scan of survivor flags + total, see mark_merges
    BinaryTree tree_;
};

} // namespace detail

/// PLOC topology over `refs` (shared with kbvh.hpp, which clusters presplit fragments).
/// Reorders `refs` into Morton order (morton::sort_references); the tree's leaf ids index the reordered
/// refs. The inner node merging clusters A and B (B later on the curve) gets id (smallest leaf of B) - 1.
/// O(n) for the sort plus O(n * radius) per iteration over a shrinking cluster count; parallel.
/// Throws std::invalid_argument for morton_bits other than 30 or 63, std::length_error beyond 2^31 - 1 refs.
template <class T, class Exec>
BinaryTree build_tree(References<T>& refs, const Config& cfg, const Exec& ex) {
    morton::check_bits(cfg.morton_bits, "dynbvh::ploc");
    const std::size_t n = refs.size();
    if (BinaryTree tree = BinaryTree::start(n, "dynbvh::ploc"); n < 2) return tree;
    // Step 1: clusters = references along the Morton curve.
    if (cfg.morton_bits == 63) morton::sort_references<std::uint64_t>(refs, ex);
    else morton::sort_references<std::uint32_t>(refs, ex);
    return detail::Clustering<T>(refs, cfg.radius, ex).run(ex);
}

namespace detail {

/// build_tree as a function object, for dynbvh::detail::build_over (detail/emit_wide.hpp).
struct Topology {
    template <class T, class Exec>
    BinaryTree operator()(References<T>& refs, const Config& cfg, const Exec& ex) const { return dynbvh::ploc::build_tree(refs, cfg, ex); }
};

} // namespace detail

/// Builds a PLOC BVH over `tris` in one call:
/// `auto bvh = dynbvh::ploc::build(tris, {.radius = 5}, dynbvh::exec::omp{});`
/// Triangles with non-finite vertices are left out (counted in Bvh::excluded). `tris` is not modified.
template <class NodeT = Node<>, class Prim = prim::indexed, class Exec = exec::default_executor>
Bvh<NodeT, Prim> build(std::span<const Triangle<typename NodeT::scalar_type>> tris, const Config& cfg = {},
                       const Exec& ex = {}) {
    return dynbvh::detail::build_over<0, NodeT, Prim>(tris, cfg, detail::Topology{}, ex);
}

/// Builds a PLOC BVH over an indexed mesh read in place (mesh.hpp): the tree `build` gives over
/// `make_triangles(vertices, indices)`, bit for bit, without that copy. NodeT defaults to Node<T>.
template <class NodeT = void, class Prim = prim::indexed, class Exec = exec::default_executor, class T, class Index>
Bvh<dynbvh::detail::node_for_t<NodeT, T>, Prim> build(const MeshView<T, Index>& mesh, const Config& cfg = {}, const Exec& ex = {}) {
    return dynbvh::detail::build_over<0, dynbvh::detail::node_for_t<NodeT, T>, Prim>(mesh, cfg, detail::Topology{}, ex);
}

/// Builds a PLOC BVH straight into the W-wide layout (W = 4 or 8; detail/emit_wide.hpp): the tree
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
/// `dynbvh::ploc::build(std::vector<Triangled>{...})` is a Bvh<Node<double>>.
template <int = 0, class T, class Exec = exec::default_executor>
Bvh<Node<T>> build(const std::vector<Triangle<T>>& tris, const Config& cfg = {}, const Exec& ex = {}) {
    return build<Node<T>, prim::indexed, Exec>(std::span<const Triangle<T>>(tris), cfg, ex);
}

} // namespace dynbvh::ploc
