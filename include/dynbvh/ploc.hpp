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
/// Schedule (Config::subtree_clusters): by default, steps 2-5 run inside the subtrees of the Morton
/// radix tree, bottom up, whenever more than a few clusters are live in one (H-PLOC, Benthin et al.
/// 2024; SubtreeClustering below); with 0, over all clusters at once (Clustering, the paper's schedule).
/// The original schedule's speed, in the spirit of PLOC++ (Benthin et al. 2022): an iteration is two
/// parallel passes over fixed chunks of the clusters: (A) nearest neighbours of the chunk and of `radius` clusters on either side
/// (so mutuality is decided locally), mutual partners, survivors counted; (B) after a scan over the
/// chunks' counts, merged nodes and survivors written in order. Boxes are kept as structure of arrays:
/// with AVX-512 the neighbour search takes 16 clusters per SIMD step (nearest_simd, the order of
/// candidate_key exactly); without it, each pair's distance is computed once and offered to both ends
/// as one packed integer key (nearest_scalar, a branch-free min). Inner node ids follow from the
/// clusters' first leaves, so no counter is needed and the tree is laid out along the curve; buffers are
/// allocated once and swapped; iterations over few clusters run on the calling thread. The builds
/// (build, build_wide, build_blocks) sort the triangles by code alone and write each box once into the
/// references and the clusters (build_from_triangles), and make each node's facts for the emission
/// (box, SAH leaf collapse; detail/emit.hpp) as they make the node, its children's facts travelling
/// with the clusters: no bottom-up pass over the finished tree. build_blocks packs the traced layout's
/// triangle blocks during the wide emission (detail/emit_wide.hpp).
///
/// Termination on any input: the distance is made a strict total order on pairs, so the best pair
/// inside any window is mutual and every iteration merges at least one pair. A guard makes progress
/// certain anyway in the original schedule: an iteration that merges almost nothing (nested or identical
/// boxes) merges Morton-adjacent pairs instead, so the number of iterations stays logarithmic (the
/// hierarchical one iterates over at most 2 L clusters at a time, so it needs no guard).
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
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
#include "morton_wide.hpp"
#include "wide_blocks.hpp"
#include "detail/simd.hpp"

namespace dynbvh::ploc {

/// PLOC knobs. Designated-initialiser friendly: `{.radius = 16}`.
struct Config {
    /// Search window: each cluster looks at `radius` clusters on each side (study default 5; the paper
    /// uses 10 to 25 for higher quality). Larger = better tree, slower build (work ~ radius). 0 acts as 1;
    /// values above 65536 act as 65536.
    std::uint32_t radius = 5;
    /// Morton code width: 30 (uint32_t keys, 2^10 cells per axis) or 63 (uint64_t keys, 2^21 cells).
    int morton_bits = 30;
    /// Clustering schedule. L > 0: the hierarchical schedule of H-PLOC (Benthin et al. 2024; the
    /// default, L = 8): clusters merge within each subtree of the Morton radix tree whenever more than L
    /// are live there, down to L (clamped to 2..1024); with AVX-512 and L <= 8 a subtree's clusters are
    /// merged in registers. 0: the original schedule (Meister & Bittner 2018), iterations over all live
    /// clusters at once. Both give trees of the same SAH within a few per cent; the hierarchical one
    /// builds about a quarter faster (2 threads, 100k triangles).
    std::uint32_t subtree_clusters = 8;
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
inline constexpr std::size_t serial_cluster_count = 1024;
/// Clusters per chunk of a parallel iteration, at least (at most 4 chunks per worker). Both constants
/// were 4096: the iterations from about 8k clusters down (a tenth of the clustering time on a
/// 92k-triangle scene) ran as one chunk while the other workers waited. At 1024 the clustering takes
/// 4-5 % less at 2 threads (cloth-ball, 9 runs of 41 builds, each faster); 512 gains nothing more.
inline constexpr std::size_t chunk_clusters = 1024;
/// An iteration merging fewer than clusters / this pairs falls back to pairing Morton neighbours
/// (real scenes merge 10-40% of the clusters per iteration).
inline constexpr std::size_t min_progress_divisor = 64;

/// Nearest neighbours of positions [a, b) among `c` clusters whose boxes are in SoA form (`box[0..2]`
/// min x, y, z, `box[3..5]` max x, y, z): nn[m - a] = the position of m's best partner within `r`
/// positions, by the order of candidate_key. Plain version: every pair touching [a, b) evaluated once
/// and offered to both of its ends (each pair's distance from the same operands in the same order).
template <class T>
inline void nearest_scalar(const T* const* box, std::size_t c, std::size_t r, std::size_t a, std::size_t b, std::uint32_t* nn,
                           std::uint64_t* best) noexcept {
    constexpr std::uint64_t none = std::numeric_limits<std::uint64_t>::max();
    auto at = [&](std::size_t i) { return AABB<T>{{box[0][i], box[1][i], box[2][i]}, {box[3][i], box[4][i], box[5][i]}}; };
    std::fill(best, best + (b - a), none);
    for (std::size_t i = a >= r ? a - r : 0; i < b; ++i) {
        const AABB<T> bi = at(i);
        const std::size_t end = std::min(c, i + r + 1);
        std::uint64_t best_i = i >= a ? best[i - a] : none;
        for (std::size_t j = std::max(i + 1, a); j < end; ++j) {   // (pairs (i, j < a) concern neither end)
            const std::uint64_t key = candidate_key(merged_half_area(bi, at(j)), j - i, i);
            best_i = std::min(best_i, key | partner_right);
            if (j < b) best[j - a] = std::min(best[j - a], key);
        }
        if (i >= a) best[i - a] = best_i;
    }
    for (std::size_t m = a; m < b; ++m) nn[m - a] = std::uint32_t(partner_of(m, best[m - a]));
}

#if defined(__AVX512F__) && !defined(DYNBVH_NO_SIMD)
namespace simd16 {
// (the zero-masked forms: GCC 12 warns about the undefined source operand of _mm512_min_ps and the like)
inline __m512 max(__m512 x, __m512 y) noexcept { return _mm512_maskz_max_ps(__mmask16(0xffff), x, y); }
inline __m512 min(__m512 x, __m512 y) noexcept { return _mm512_maskz_min_ps(__mmask16(0xffff), x, y); }

/// merged_half_area(lo, hi) of 16 pairs of boxes (min x, y, z, max x, y, z), lo the lower position: the
/// same operands and operations, so the same bits; as integers (non-negative float bits order like the values).
inline __m512i merged_half_area(const __m512 (&lo)[6], const __m512 (&hi)[6]) noexcept {
    const __m512 dx = _mm512_sub_ps(max(hi[3], lo[3]), min(hi[0], lo[0]));
    const __m512 dy = _mm512_sub_ps(max(hi[4], lo[4]), min(hi[1], lo[1]));
    const __m512 dz = _mm512_sub_ps(max(hi[5], lo[5]), min(hi[2], lo[2]));
    return _mm512_castps_si512(_mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dy), _mm512_mul_ps(dy, dz)), _mm512_mul_ps(dz, dx)));
}

/// One window offset k of the neighbour search: lane m's left pair (m - k, m) at distance `dl` and right
/// pair (m, m + k) at `dr` (all ones where absent) offered to its best so far in candidate_key's order:
/// at equal distance the left pair, unless k is odd and m even (`even`: then the right pair's lower
/// position has parity 0); an earlier k wins a tie with the best so far.
inline void offer(std::size_t k, __mmask16 even, __m512i m, __m512i dl, __m512i dr, __m512i& best_d, __m512i& best_p) noexcept {
    const __m512i kk = _mm512_set1_epi32(int(k));
    const __mmask16 right_first = (k & 1) ? even : __mmask16(0);
    const __mmask16 take_r = _mm512_cmplt_epu32_mask(dr, dl) | (_mm512_cmpeq_epi32_mask(dr, dl) & right_first);
    const __m512i d = _mm512_mask_blend_epi32(take_r, dl, dr);
    const __m512i p = _mm512_mask_blend_epi32(take_r, _mm512_sub_epi32(m, kk), _mm512_add_epi32(m, kk));
    const __mmask16 better = _mm512_cmplt_epu32_mask(d, best_d);
    best_d = _mm512_mask_blend_epi32(better, best_d, d);
    best_p = _mm512_mask_blend_epi32(better, best_p, p);
}
} // namespace simd16

/// nearest_scalar's answers, 16 positions per SIMD step (AVX-512, float boxes). For each k = 1..r in
/// turn, lane m computes the distances of its pairs (m - k, m) and (m, m + k) (the same operands and
/// operations as merged_half_area, so the same bits), picks the one candidate_key orders first at
/// this k (left, unless m is even and k odd: then the right pair's lower position has parity 0), and
/// keeps it if its distance bits are strictly below the best so far (an earlier k wins a tie).
inline void nearest_simd(const float* const* box, std::size_t c, std::size_t r, std::size_t a, std::size_t b, std::uint32_t* nn) noexcept {
    const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const __m512i cnt = _mm512_set1_epi32(int(c)), end = _mm512_set1_epi32(int(b)), all = _mm512_set1_epi32(-1);
    const __m512i one = _mm512_set1_epi32(1);
    for (std::size_t m0 = a; m0 < b; m0 += 16) {
        const __m512i m = _mm512_add_epi32(_mm512_set1_epi32(int(m0)), iota);
        const __mmask16 live = _mm512_cmplt_epi32_mask(m, end);
        __m512 self[6];
        for (int q = 0; q < 6; ++q) self[q] = _mm512_maskz_loadu_ps(live, box[q] + m0);
        // m even: the right pair of an odd k comes first on a tie with the left one
        const __mmask16 even = _mm512_testn_epi32_mask(m, one);
        __m512i best_d = all, best_p = m;
        for (std::size_t k = 1; k <= r; ++k) {
            const __m512i kk = _mm512_set1_epi32(int(k));
            const __mmask16 has_r = _mm512_mask_cmplt_epi32_mask(live, _mm512_add_epi32(m, kk), cnt);
            const __mmask16 has_l = _mm512_mask_cmpge_epi32_mask(live, m, kk);
            __m512 other[6];
            for (int q = 0; q < 6; ++q) other[q] = _mm512_maskz_loadu_ps(has_r, box[q] + m0 + k);
            const __m512i dr = _mm512_mask_blend_epi32(has_r, all, simd16::merged_half_area(self, other));
            if (has_l) {   // (m0 - k may be below 0 in the first lanes: those are masked off)
                for (int q = 0; q < 6; ++q) other[q] = _mm512_maskz_loadu_ps(has_l, box[q] + std::ptrdiff_t(m0) - std::ptrdiff_t(k));
            }
            const __m512i dl = has_l ? _mm512_mask_blend_epi32(has_l, all, simd16::merged_half_area(other, self)) : all;
            simd16::offer(k, even, m, dl, dr, best_d, best_p);
        }
        _mm512_mask_storeu_epi32(nn + (m0 - a), live, best_p);
    }
}
#endif

/// Nearest neighbours of positions [a, b) of `c` clusters into nn[0 .. b - a): nearest_simd with AVX-512
/// and float boxes, else nearest_scalar (`keys`: its scratch, b - a entries).
template <class T>
inline void nearest(const T* const* box, std::size_t c, std::size_t r, std::size_t a, std::size_t b, std::uint32_t* nn,
                    std::uint64_t* keys) noexcept {
#if defined(__AVX512F__) && !defined(DYNBVH_NO_SIMD)
    if constexpr (std::is_same_v<T, float>) {
        (void)keys;
        nearest_simd(box, c, r, a, b, nn);
        return;
    }
#endif
    nearest_scalar(box, c, r, a, b, nn, keys);
}

/// The clustering state: the live clusters in Morton order, as tree node ids with their boxes (structure
/// of arrays, for the SIMD neighbour search) and first leaves, and with the facts of their subtrees when
/// the facts are wanted, in ping-pong buffers (iteration k reads half k % 2, writes the other), plus
/// per-iteration scratch, all allocated once. Iteration 0 reads its ids and first leaves implicitly
/// (cluster i is reference i), so only the boxes are copied in.
template <class T>
class Clustering {
public:
    /// With `info` (tree.inner_count() entries), the facts of every inner node (detail/emit.hpp) are
    /// computed as it is made, by `rule`: the facts compute_node_info would give, bit for bit, without
    /// its bottom-up pass (a node is made after both its children, whose facts travel with the clusters).
    template <class Exec>
    Clustering(const References<T>& refs, std::uint32_t radius, const Exec& ex, dynbvh::detail::RawNodeInfo<T>* info = nullptr,
               const LeafConfig& leaves = {})
        : Clustering(refs.size(), radius, info, leaves) {
        ex.for_each(0, n_, [&](std::size_t i) { set_box(i, refs.box[i]); });
    }

    /// The state for `n` >= 2 references whose boxes the caller sets (set_box, every i < n) before run.
    Clustering(std::size_t n, std::uint32_t radius, dynbvh::detail::RawNodeInfo<T>* info, const LeafConfig& leaves)
        : info_(info), rule_(leaves), radius_(std::clamp<std::uint32_t>(radius, 1, max_radius)), n_(n), count_(n_), partner_(n_) {
        for (auto& b : box_) b.resize(6 * n_);
        for (auto& v : ids_) v.resize(n_);
        for (auto& v : first_leaf_) v.resize(n_);
        if (info_)
            for (auto& v : facts_) v.resize(n_);
        tree_.left.resize(n_ - 1);
        tree_.right.resize(n_ - 1);
    }

    /// The box of reference (first cluster) i.
    void set_box(std::size_t i, const AABB<T>& r) noexcept {
        T* const b = box_[0].data();
        const std::size_t n = n_;
        b[i] = r.min.x; b[n + i] = r.min.y; b[2 * n + i] = r.min.z;
        b[3 * n + i] = r.max.x; b[4 * n + i] = r.max.y; b[5 * n + i] = r.max.z;
    }

    /// Runs iterations until one cluster is left; returns the tree (root = the last cluster).
    template <class Exec>
    BinaryTree run(const Exec& ex) {
        while (count_ > 1) {
            if (count_ < serial_cluster_count) iterate(exec::serial{});
            else iterate(ex);
        }
        tree_.root = iteration_ == 0 ? BinaryTree::leaf(0) : ids_[iteration_ & 1][0];
        return std::move(tree_);
    }

private:
    /// Facts of a cluster's subtree apart from its box (16 bytes: they travel with the cluster).
    struct Facts {
        float cost;
        std::uint32_t refs, size, height;   // height: bit 31 set when collapsed
    };

    /// One PLOC iteration over fixed chunks of the clusters, in two parallel passes: (A) each chunk
    /// finds the nearest neighbours of its clusters and of the `radius` on either side of it, keeps the
    /// mutual pairs (partner_) and counts its survivors; (B) after a scan over the chunks' counts, each
    /// chunk writes its merged nodes and its survivors, in order, into the other buffers. Nearest
    /// neighbours, mutual merges and the compaction of the file comment, without any array of keys or
    /// flags going through memory.
    template <class Exec>
    void iterate(const Exec& ex) {
        const std::size_t c = count_, r = radius_;
        const std::size_t chunks = std::clamp<std::size_t>(c / chunk_clusters, 1, 4 * ex.concurrency());
        const std::size_t size = (c + chunks - 1) / chunks;
        // One scratch array for every chunk's neighbours (with halos): taken from the scratch cache
        // once, not a page-faulted allocation per chunk and build.
        const std::size_t span = size + 2 * r;
        if (nn_.size() < chunks * span) nn_.resize(chunks * span);
        if constexpr (!simd_search) {
            if (keys_.size() < chunks * span) keys_.resize(chunks * span);
        }
        survivors_.assign(chunks + 1, 0);
        const T* const cur = box_[iteration_ & 1].data();
        const T* const box[6] = {cur, cur + n_, cur + 2 * n_, cur + 3 * n_, cur + 4 * n_, cur + 5 * n_};
        // Pass A: neighbours (with halos), mutual partners, survivors per chunk.
        ex.for_tasks(chunks, [&](std::size_t k) {
            const std::size_t lo = std::min(c, k * size), hi = std::min(c, lo + size);
            if (lo == hi) return;
            const std::size_t a = lo >= r ? lo - r : 0, b = std::min(c, hi + r);
            std::uint32_t* const nn = nn_.data() + k * span;
            nearest(box, c, r, a, b, nn, simd_search ? nullptr : keys_.data() + k * span);
            std::size_t kept = 0;
            for (std::size_t i = lo; i < hi; ++i) {
                const std::uint32_t p = nn[i - a];
                const std::uint32_t j = nn[p - a] == i ? p : std::uint32_t(i);
                partner_[i] = j;
                kept += j >= i;
            }
            survivors_[k] = kept;
        });
        const std::size_t kept = exec::serial{}.exclusive_scan(std::span<const std::size_t>(survivors_.data(), chunks),
                                                                std::span<std::size_t>(survivors_.data(), chunks));
        const std::size_t merges = c - kept;
        // Progress guard: pair positions (0,1), (2,3), ... instead (survivor i even goes to i / 2).
        const bool adjacent = merges == 0 || merges < c / min_progress_divisor;
        // Pass B: merged nodes and survivors into the other buffers.
        ex.for_tasks(chunks, [&](std::size_t k) {
            const std::size_t lo = std::min(c, k * size), hi = std::min(c, lo + size);
            if (lo == hi) return;
            if (iteration_ == 0) compact_chunk<true>(lo, hi, adjacent, survivors_[k]);
            else compact_chunk<false>(lo, hi, adjacent, survivors_[k]);
        });
        ++iteration_;
        count_ = adjacent ? (c + 1) / 2 : kept;
    }

#if defined(__AVX512F__) && !defined(DYNBVH_NO_SIMD)
    static constexpr bool simd_search = std::is_same_v<T, float>;
#else
    static constexpr bool simd_search = false;
#endif

    /// Pass B over clusters [lo, hi): survivor i goes to position `pos` onwards (in adjacent mode, i / 2);
    /// a merge of i with j > i becomes inner node first_leaf(j) - 1. Clusters keep the Morton order of
    /// their first (smallest) leaf position, so the disappearing cluster j's first leaf is never 0 and
    /// never the first leaf of a later disappearing cluster: the n - 1 merges get the ids 0 .. n - 2
    /// exactly once, without any counter, and a node's id lies next to its leaves' positions (as in
    /// Karras's radix tree), which keeps the emission's passes over the tree local in memory.
    /// First: iteration 0 (cluster i is reference i: its id leaf(i), first leaf i, the facts of a leaf).
    template <bool First>
    void compact_chunk(std::size_t lo, std::size_t hi, bool adjacent, std::size_t pos) {
        const std::size_t c = count_, n = n_, in = iteration_ & 1, out = in ^ 1;
        const T* const b = box_[in].data();
        T* const nb = box_[out].data();
        const std::uint32_t* const ids = ids_[in].data();
        const std::uint32_t* const first = first_leaf_[in].data();
        std::uint32_t* const next_ids = ids_[out].data();
        std::uint32_t* const next_first = first_leaf_[out].data();
        const Facts* const facts = facts_[in].data();
        Facts* const next_facts = facts_[out].data();
        // (members in locals: the stores below could alias them, and reloading them costs in this loop)
        std::uint32_t* const left = tree_.left.data();
        std::uint32_t* const right = tree_.right.data();
        dynbvh::detail::RawNodeInfo<T>* const info = info_;
        const std::uint32_t* const partners = partner_.data();
        const dynbvh::detail::CollapseRule<T> rule = rule_;
        auto box_at = [&](std::size_t i) { return AABB<T>{{b[i], b[n + i], b[2 * n + i]}, {b[3 * n + i], b[4 * n + i], b[5 * n + i]}}; };
        auto id_of = [&](std::size_t i) { return First ? BinaryTree::leaf(std::uint32_t(i)) : ids[i]; };
        auto first_of = [&](std::size_t i) { return First ? std::uint32_t(i) : first[i]; };
        auto node_facts = [&](std::size_t i, const AABB<T>& bx, dynbvh::detail::RawNodeInfo<T>& f) {
            if (First) {
                rule.leaf(bx, f);
            } else {
                const Facts& s = facts[i];
                f.min = bx.min;
                f.max = bx.max;
                f.cost = s.cost;
                f.refs = s.refs;
                f.size = s.size;
                f.height = s.height & 0x7fffffffu;
                f.collapsed = (s.height >> 31) != 0;
            }
        };
        if (adjacent) pos = (lo + 1) / 2;
        auto partner = [&](std::size_t i) { return adjacent ? ((i ^ 1) < c ? (i ^ 1) : i) : std::size_t(partners[i]); };
        // (no software prefetch of the new nodes' far-away slots: prefetching left, right and info 16
        // clusters ahead made the clustering about 10 % slower, cloth-ball 2 threads)
        for (std::size_t i = lo; i < hi; ++i) {
            const std::size_t j = partner(i);
            if (j < i) continue;   // merged into its lower partner
            AABB<T> box = box_at(i);
            std::uint32_t id = id_of(i);
            if (j != i) {
                const AABB<T> other = box_at(j);
                id = first_of(j) - 1;
                left[id] = id_of(i);
                right[id] = id_of(j);
                if (info) {
                    dynbvh::detail::RawNodeInfo<T> l, r;
                    node_facts(i, box, l);
                    node_facts(j, other, r);
                    dynbvh::detail::RawNodeInfo<T> f;   // (made here, stored once: info_[id] is far away)
                    rule.parent(l, r, f);
                    info[id] = f;
                    box = f.box();
                    next_facts[pos] = {f.cost, f.refs, f.size, f.height | (f.collapsed ? 0x80000000u : 0u)};
                } else {
                    box = merge(box, other);
                }
            } else if (info) {
                if (First) {
                    dynbvh::detail::RawNodeInfo<T> f;
                    rule.leaf(box, f);
                    next_facts[pos] = {f.cost, f.refs, f.size, f.height | 0x80000000u};
                } else {
                    next_facts[pos] = facts[i];
                }
            }
            next_first[pos] = first_of(i);
            next_ids[pos] = id;
            nb[pos] = box.min.x; nb[n + pos] = box.min.y; nb[2 * n + pos] = box.min.z;
            nb[3 * n + pos] = box.max.x; nb[4 * n + pos] = box.max.y; nb[5 * n + pos] = box.max.z;
            ++pos;
        }
    }

    dynbvh::detail::RawNodeInfo<T>* info_;   // facts of the inner nodes, made with them (or none)
    dynbvh::detail::CollapseRule<T> rule_;
    std::uint32_t radius_;
    std::size_t n_;                     // references (the stride of the box components)
    std::size_t count_;                 // live clusters
    std::size_t iteration_ = 0;         // selects the current half of each ping-pong pair
    scratch_vector<T> box_[2];                     // cluster -> its box: min x, y, z, max x, y, z arrays of n_
    scratch_vector<std::uint32_t> ids_[2];         // cluster -> tree node id (BinaryTree::leaf(ref) or inner)
    scratch_vector<std::uint32_t> first_leaf_[2];  // cluster -> smallest leaf position in it
    scratch_vector<Facts> facts_[2];               // cluster -> facts of its subtree (with info_ only)
    scratch_vector<std::uint32_t> partner_;        // cluster -> its mutual partner, or itself (pass A)
    std::vector<std::size_t> survivors_;           // per chunk: survivors, then their first position
    scratch_vector<std::uint32_t> nn_;             // per chunk: nearest neighbours of its clusters and halos
    scratch_vector<std::uint64_t> keys_;           // per chunk: the plain search's best keys
    BinaryTree tree_;
};

/// Hierarchical clustering (H-PLOC: Benthin, Meister, Barczak, Mehalwal, Tsakok, Kensler 2024,
/// "H-PLOC: Hierarchical Parallel Locally-Ordered Clustering for Bounding Volume Hierarchy
/// Construction", HPG): the same nearest-neighbour merges as Clustering, scheduled over the subtrees of
/// the Morton radix tree (Karras 2012's split rule, morton_wide::detail::split_of) instead of global
/// iterations. Walking that tree bottom up, a subtree's live clusters are its children's, in Morton
/// order; whenever more than `limit` are live, PLOC iterations among just those (same window, same
/// candidate_key order over their positions in the subtree's list) merge them down to at most `limit`;
/// at the root, down to one. A subtree's clusters stay in L1 (with AVX-512 and limit <= 8, in registers:
/// reduce16), and no iteration waits for the whole scene: that is what makes it faster than the global
/// schedule. The cost: clusters of different subtrees meet only once their subtree's count passes
/// `limit`. Ids follow the global schedule's rule (the merge of clusters i < j is node
/// first_leaf(j) - 1) and the facts travel with the clusters as there. The top of the radix tree is
/// split on the calling thread into ranges of about n / (16 * workers), each clustered by one task; the
/// top subtrees are merged on the calling thread. The tree does not depend on the executor or the
/// thread count.
template <class T, class Key>
class SubtreeClustering {
public:
    /// `keys`: the n >= 2 sorted Morton codes; `info`: the facts of every inner node (n - 1 entries) or null.
    SubtreeClustering(const Key* keys, std::size_t n, std::uint32_t radius, std::uint32_t limit, dynbvh::detail::RawNodeInfo<T>* info,
                      const LeafConfig& leaves)
        : keys_(keys), n_(n), radius_(std::clamp<std::uint32_t>(radius, 1, max_radius)), limit_(std::clamp<std::uint32_t>(limit, 2, 1024)),
          info_(info), rule_(leaves) {
        tree_.left.resize(n_ - 1);
        tree_.right.resize(n_ - 1);
    }

    /// The tree; `leaf_box(i)` gives reference i's box (called once per i, from the tasks).
    template <class LeafBox, class Exec>
    BinaryTree run(LeafBox&& leaf_box, const Exec& ex) {
        using Range = morton_wide::detail::Range;
        // Step 1: the top of the radix tree, ranges split while larger than `grain`.
        const std::size_t grain = std::max<std::size_t>(std::size_t(limit_) * 8, n_ / (16 * ex.concurrency()));
        std::vector<Top> top;
        std::vector<Range> tasks;
        top.push_back({{0, std::uint32_t(n_)}, {0, 0}, -1});
        for (std::size_t t = 0; t < top.size(); ++t) {   // (breadth first: `top` grows behind t)
            const Range r = top[t].range;
            if (r.size() <= grain) {
                top[t].task = int(tasks.size());
                tasks.push_back(r);
                continue;
            }
            const std::uint32_t m = morton_wide::detail::split_of(keys_, r);
            top[t].child[0] = std::uint32_t(top.size());
            top.push_back({{r.begin, m}, {0, 0}, -1});
            top[t].child[1] = std::uint32_t(top.size());
            top.push_back({{m, r.end}, {0, 0}, -1});
        }
        // Step 2: each task clusters its range down to `limit` clusters (workers take tasks in turn, one
        // stack of clusters each); task k's clusters go to results_ from k * limit_ on.
        Stack results(tasks.size() * limit_, limit_);
        result_count_.assign(tasks.size(), 0);
        std::atomic<std::size_t> next{0};
        ex.for_tasks(std::min(tasks.size(), ex.concurrency()), [&](std::size_t) {
            Stack st(capacity(), limit_);
            for (std::size_t k; (k = next.fetch_add(1, std::memory_order_relaxed)) < tasks.size();) {
                st.size = 0;
                solve(tasks[k], st, limit_, leaf_box);
                result_count_[k] = std::uint32_t(st.size);
                for (std::size_t i = 0; i < st.size; ++i) results.copy(k * limit_ + i, st, i);
            }
        });
        // Step 3: the top subtrees, bottom up, on the calling thread.
        Stack st(capacity(), limit_);
        merge_top(top, 0, st, 1, results);
        tree_.root = st.id[0];
        return std::move(tree_);
    }

private:
    struct Top {
        morton_wide::detail::Range range;
        std::uint32_t child[2];
        int task;   // the task clustering this range, or -1 (an inner top node)
    };
    /// Clusters in structure of arrays (the SIMD steps load any component from any position on): the
    /// live clusters of the subtrees on a task's current path, as a stack, or the tasks' results.
    struct Stack {
        std::size_t cap, size = 0;
        std::vector<T> box;   // min x, y, z, max x, y, z: cap each
        std::vector<std::uint32_t> id, first, refs, nodes, height;   // height: bit 31 set when collapsed
        std::vector<float> cost;
        std::vector<std::uint32_t> nn;     // one iteration's nearest neighbours
        std::vector<std::uint64_t> keys;   // the plain search's scratch
        Stack(std::size_t c, std::size_t limit)
            : cap(c), box(6 * c), id(c), first(c), refs(c), nodes(c), height(c), cost(c), nn(2 * limit), keys(2 * limit) {}
        AABB<T> box_at(std::size_t i) const noexcept {
            const T* b = box.data();
            return {{b[i], b[cap + i], b[2 * cap + i]}, {b[3 * cap + i], b[4 * cap + i], b[5 * cap + i]}};
        }
        void facts_at(std::size_t i, dynbvh::detail::RawNodeInfo<T>& f) const noexcept {
            const AABB<T> b = box_at(i);
            f.min = b.min;
            f.max = b.max;
            f.cost = cost[i];
            f.refs = refs[i];
            f.size = nodes[i];
            f.height = height[i] & 0x7fffffffu;
            f.collapsed = (height[i] >> 31) != 0;
        }
        void set(std::size_t i, std::uint32_t node, std::uint32_t f, const dynbvh::detail::RawNodeInfo<T>& x) noexcept {
            T* b = box.data();
            b[i] = x.min.x; b[cap + i] = x.min.y; b[2 * cap + i] = x.min.z;
            b[3 * cap + i] = x.max.x; b[4 * cap + i] = x.max.y; b[5 * cap + i] = x.max.z;
            id[i] = node;
            first[i] = f;
            cost[i] = x.cost;
            refs[i] = x.refs;
            nodes[i] = x.size;
            height[i] = x.height | (x.collapsed ? 0x80000000u : 0u);
        }
        void copy(std::size_t i, const Stack& from, std::size_t j) noexcept {
            for (std::size_t q = 0; q < 6; ++q) box[q * cap + i] = from.box[q * from.cap + j];
            id[i] = from.id[j];
            first[i] = from.first[j];
            cost[i] = from.cost[j];
            refs[i] = from.refs[j];
            nodes[i] = from.nodes[j];
            height[i] = from.height[j];
        }
    };

    /// Stack capacity: the results of the left siblings on a path (at most `limit` each, one per level of
    /// the radix tree: key bits plus the halvings of equal-key runs) and a subtree's two children.
    std::size_t capacity() const noexcept { return (morton::code_bits<Key> + 34) * std::size_t(limit_) + 2 * limit_; }

    /// Pushes the clusters of range `r` (at most `target` of them, in Morton order) onto `s`.
    template <class LeafBox>
    void solve(morton_wide::detail::Range r, Stack& s, std::size_t target, LeafBox& leaf_box) {
        const std::size_t base = s.size;
        if (r.size() <= limit_) {   // the references themselves
            for (std::uint32_t i = r.begin; i < r.end; ++i) {
                dynbvh::detail::RawNodeInfo<T> f;
                rule_.leaf(leaf_box(i), f);
                s.set(s.size++, BinaryTree::leaf(i), i, f);
            }
        } else {
            const std::uint32_t m = morton_wide::detail::split_of(keys_, r);
            solve({r.begin, m}, s, limit_, leaf_box);
            solve({m, r.end}, s, limit_, leaf_box);
        }
        reduce(s, base, target);
    }

    /// The top node `t`'s clusters onto `s`, at most `target`.
    void merge_top(const std::vector<Top>& top, std::size_t t, Stack& s, std::size_t target, const Stack& results) {
        const std::size_t base = s.size;
        if (top[t].task >= 0) {
            const std::size_t k = std::size_t(top[t].task);
            for (std::size_t i = 0; i < result_count_[k]; ++i) s.copy(s.size++, results, k * limit_ + i);
        } else {
            merge_top(top, top[t].child[0], s, limit_, results);
            merge_top(top, top[t].child[1], s, limit_, results);
        }
        reduce(s, base, target);
    }

    /// PLOC iterations over the clusters at [base, s.size) until at most `target` are left.
    void reduce(Stack& s, std::size_t base, std::size_t target) {
        std::size_t c = s.size - base;
        if (c <= target) return;
#if defined(__AVX512F__) && !defined(DYNBVH_NO_SIMD)
        if constexpr (std::is_same_v<T, float>)
            if (c <= 16) {
                s.size = base + reduce16(s, base, c, target);
                return;
            }
#endif
        while (c > target) c = iterate(s, base, c);
        s.size = base + c;
    }

    /// One iteration over the c clusters at `base`: nearest neighbours, mutual pairs merged into the
    /// lower position (node first_leaf(higher) - 1), the survivors compacted in place; returns how many.
    std::size_t iterate(Stack& s, std::size_t base, std::size_t c) {
        const T* const b0 = s.box.data() + base;
        const T* const box[6] = {b0, b0 + s.cap, b0 + 2 * s.cap, b0 + 3 * s.cap, b0 + 4 * s.cap, b0 + 5 * s.cap};
        std::uint32_t* const nn = s.nn.data();
        nearest(box, c, radius_, 0, c, nn, s.keys.data());
        std::size_t pos = base;
        for (std::size_t i = 0; i < c; ++i) {
            const std::size_t j = nn[i];
            const bool mutual = nn[j] == i;
            if (mutual && j < i) continue;   // merged into its lower partner
            const std::size_t a = base + i;
            if (mutual) {
                const std::size_t bj = base + j;
                dynbvh::detail::RawNodeInfo<T> l, r, f;
                s.facts_at(a, l);
                s.facts_at(bj, r);
                rule_.parent(l, r, f);
                const std::uint32_t id = s.first[bj] - 1;
                tree_.left[id] = s.id[a];
                tree_.right[id] = s.id[bj];
                if (info_) info_[id] = f;
                s.set(pos, id, s.first[a], f);
            } else if (pos != a) {
                s.copy(pos, s, a);
            }
            ++pos;
        }
        return pos - base;
    }

#if defined(__AVX512F__) && !defined(DYNBVH_NO_SIMD)
    /// reduce for at most 16 float clusters, the whole state in AVX-512 registers (one lane per
    /// cluster): iterate's answers, bit for bit. Nearest neighbours as nearest_simd (each pair's distance
    /// computed once, for its lower end, and moved to the higher end by a lane permute), the merged boxes
    /// and facts (CollapseRule::parent's operations, in its order) for every lane at once, the merges'
    /// children and facts stored one by one, survivors compacted by vcompress. Returns the count left.
    std::size_t reduce16(Stack& s, std::size_t base, std::size_t c, std::size_t target) {
        const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        const __m512i all = _mm512_set1_epi32(-1), one = _mm512_set1_epi32(1);
        const __m512i flag = _mm512_set1_epi32(int(0x80000000u)), low31 = _mm512_set1_epi32(0x7fffffff);
        auto pf = [](__m512i i, __m512 x) { return _mm512_maskz_permutexvar_ps(__mmask16(0xffff), i, x); };
        auto pi = [](__m512i i, __m512i x) { return _mm512_maskz_permutexvar_epi32(__mmask16(0xffff), i, x); };
        auto live_of = [](std::size_t k) { return __mmask16(k >= 16 ? 0xffffu : (1u << k) - 1u); };
        __mmask16 live = live_of(c);
        __m512 b[6];
        for (int q = 0; q < 6; ++q) b[q] = _mm512_maskz_loadu_ps(live, s.box.data() + std::size_t(q) * s.cap + base);
        __m512i id = _mm512_maskz_loadu_epi32(live, s.id.data() + base), first = _mm512_maskz_loadu_epi32(live, s.first.data() + base);
        __m512i refs = _mm512_maskz_loadu_epi32(live, s.refs.data() + base), nodes = _mm512_maskz_loadu_epi32(live, s.nodes.data() + base);
        __m512i height = _mm512_maskz_loadu_epi32(live, s.height.data() + base);
        __m512 cost = _mm512_maskz_loadu_ps(live, s.cost.data() + base);
        const __m512 ct = _mm512_set1_ps(rule_.ct), ci = _mm512_set1_ps(rule_.ci);
        const __m512i max_leaf = _mm512_set1_epi32(int(rule_.max_leaf));
        const __mmask16 even = _mm512_testn_epi32_mask(iota, one);
        alignas(64) float lane_box[6][16], lane_cost[16];
        alignas(64) std::uint32_t lane_node[16], lane_left[16], lane_right[16], lane_refs[16], lane_nodes[16], lane_height[16];
        while (c > target) {
            // Nearest neighbours: lane m's best partner within the window, candidate_key's order.
            const __m512i cnt = _mm512_set1_epi32(int(c));
            __m512i best_d = all, best_p = iota;
            const std::size_t kmax = std::min<std::size_t>(radius_, c - 1);
            for (std::size_t k = 1; k <= kmax; ++k) {
                const __m512i kk = _mm512_set1_epi32(int(k));
                const __m512i up = _mm512_add_epi32(iota, kk);
                const __mmask16 has_r = _mm512_mask_cmplt_epi32_mask(live, up, cnt);
                __m512 o[6];
                for (int q = 0; q < 6; ++q) o[q] = pf(up, b[q]);
                const __m512i dr = _mm512_mask_blend_epi32(has_r, all, simd16::merged_half_area(b, o));
                // the left pair (m - k, m) is lane m - k's right pair
                const __mmask16 has_l = _mm512_mask_cmpge_epi32_mask(live, iota, kk);
                const __m512i dl = _mm512_mask_blend_epi32(has_l, all, pi(_mm512_sub_epi32(iota, kk), dr));
                simd16::offer(k, even, iota, dl, dr, best_d, best_p);
            }
            // Mutual pairs: the lower end makes the node, the higher end disappears.
            const __mmask16 mutual = _mm512_mask_cmpeq_epi32_mask(live, pi(best_p, best_p), iota);
            const __mmask16 lower = _mm512_mask_cmpgt_epi32_mask(mutual, best_p, iota);
            const __mmask16 higher = mutual & __mmask16(~lower);
            // Every lane's merge with its partner (CollapseRule::parent), kept where lower.
            __m512 nb[6];
            for (int q = 0; q < 3; ++q) nb[q] = simd16::min(pf(best_p, b[q]), b[q]);
            for (int q = 3; q < 6; ++q) nb[q] = simd16::max(pf(best_p, b[q]), b[q]);
            const __m512 ex_ = _mm512_sub_ps(nb[3], nb[0]), ey = _mm512_sub_ps(nb[4], nb[1]), ez = _mm512_sub_ps(nb[5], nb[2]);
            const __m512 area = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(ex_, ey), _mm512_mul_ps(ey, ez)), _mm512_mul_ps(ez, ex_));
            const __m512i mrefs = _mm512_add_epi32(refs, pi(best_p, refs));
            const __m512 split = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(ct, area), cost), pf(best_p, cost));
            const __m512 leafc = _mm512_mul_ps(_mm512_mul_ps(ci, area), _mm512_maskz_cvtepu32_ps(__mmask16(0xffff), mrefs));
            const __mmask16 coll = _mm512_cmple_epu32_mask(mrefs, max_leaf) & _mm512_cmp_ps_mask(leafc, split, _CMP_LE_OQ);
            const __m512 mcost = _mm512_mask_blend_ps(coll, split, leafc);
            const __m512i onodes = pi(best_p, nodes);
            const __m512i mnodes = _mm512_mask_blend_epi32(coll, _mm512_add_epi32(_mm512_add_epi32(one, nodes), onodes), one);
            const __m512i hmax = _mm512_maskz_max_epu32(__mmask16(0xffff), _mm512_and_si512(height, low31), _mm512_and_si512(pi(best_p, height), low31));
            const __m512i mheight = _mm512_maskz_mov_epi32(__mmask16(~coll), _mm512_add_epi32(one, hmax));
            const __m512i node = _mm512_sub_epi32(pi(best_p, first), one);
            // The merges' children and facts, one by one (far apart in memory).
            for (int q = 0; q < 6; ++q) _mm512_store_ps(lane_box[q], nb[q]);
            _mm512_store_ps(lane_cost, mcost);
            _mm512_store_si512(lane_node, node);
            _mm512_store_si512(lane_left, id);
            _mm512_store_si512(lane_right, pi(best_p, id));
            _mm512_store_si512(lane_refs, mrefs);
            _mm512_store_si512(lane_nodes, mnodes);
            _mm512_store_si512(lane_height, mheight);
            for (unsigned m = lower; m != 0; m &= m - 1) {
                const int l = std::countr_zero(m);
                const std::uint32_t at = lane_node[l];
                tree_.left[at] = lane_left[l];
                tree_.right[at] = lane_right[l];
                if (info_) {
                    dynbvh::detail::RawNodeInfo<T>& f = info_[at];
                    f.min = Vec3<T>{lane_box[0][l], lane_box[1][l], lane_box[2][l]};
                    f.max = Vec3<T>{lane_box[3][l], lane_box[4][l], lane_box[5][l]};
                    f.cost = lane_cost[l];
                    f.refs = lane_refs[l];
                    f.size = lane_nodes[l];
                    f.height = lane_height[l];
                    f.collapsed = ((coll >> l) & 1) != 0;
                }
            }
            // The lower ends become the merged clusters; the survivors close up.
            for (int q = 0; q < 6; ++q) b[q] = _mm512_mask_blend_ps(lower, b[q], nb[q]);
            cost = _mm512_mask_blend_ps(lower, cost, mcost);
            refs = _mm512_mask_blend_epi32(lower, refs, mrefs);
            nodes = _mm512_mask_blend_epi32(lower, nodes, mnodes);
            height = _mm512_mask_blend_epi32(lower, height, _mm512_mask_or_epi32(mheight, coll, mheight, flag));
            id = _mm512_mask_blend_epi32(lower, id, node);
            const __mmask16 keep = live & __mmask16(~higher);
            for (int q = 0; q < 6; ++q) b[q] = _mm512_maskz_compress_ps(keep, b[q]);
            cost = _mm512_maskz_compress_ps(keep, cost);
            refs = _mm512_maskz_compress_epi32(keep, refs);
            nodes = _mm512_maskz_compress_epi32(keep, nodes);
            height = _mm512_maskz_compress_epi32(keep, height);
            id = _mm512_maskz_compress_epi32(keep, id);
            first = _mm512_maskz_compress_epi32(keep, first);
            c = std::size_t(std::popcount(unsigned(keep)));
            live = live_of(c);
        }
        for (int q = 0; q < 6; ++q) _mm512_mask_storeu_ps(s.box.data() + std::size_t(q) * s.cap + base, live, b[q]);
        _mm512_mask_storeu_epi32(s.id.data() + base, live, id);
        _mm512_mask_storeu_epi32(s.first.data() + base, live, first);
        _mm512_mask_storeu_epi32(s.refs.data() + base, live, refs);
        _mm512_mask_storeu_epi32(s.nodes.data() + base, live, nodes);
        _mm512_mask_storeu_epi32(s.height.data() + base, live, height);
        _mm512_mask_storeu_ps(s.cost.data() + base, live, cost);
        return c;
    }
#endif

    const Key* keys_;
    std::size_t n_;
    std::uint32_t radius_, limit_;
    dynbvh::detail::RawNodeInfo<T>* info_;
    dynbvh::detail::CollapseRule<T> rule_;
    std::vector<std::uint32_t> result_count_;   // per task: its clusters
    BinaryTree tree_;
};

/// The clustering of `cfg`'s schedule over references already in Morton order, `keys` their sorted codes.
template <class T, class Key, class Exec>
BinaryTree cluster_sorted(const References<T>& refs, const Key* keys, const Config& cfg, dynbvh::detail::RawNodeInfo<T>* info,
                          const Exec& ex) {
    if (cfg.subtree_clusters > 0)
        return SubtreeClustering<T, Key>(keys, refs.size(), cfg.radius, cfg.subtree_clusters, info, cfg.leaves)
            .run([&](std::size_t i) { return refs.box[i]; }, ex);
    return Clustering<T>(refs, cfg.radius, ex, info, cfg.leaves).run(ex);
}

/// Sorts `refs` along the curve (morton::sort_references) and clusters them (cluster_sorted).
template <class T, class Exec>
BinaryTree sort_and_cluster(References<T>& refs, const Config& cfg, dynbvh::detail::RawNodeInfo<T>* info, const Exec& ex) {
    if (cfg.morton_bits == 63) {
        const auto keys = morton::sort_references<std::uint64_t>(refs, ex);
        return cluster_sorted(refs, keys.data(), cfg, info, ex);
    }
    const auto keys = morton::sort_references<std::uint32_t>(refs, ex);
    return cluster_sorted(refs, keys.data(), cfg, info, ex);
}

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
    // Step 1: clusters = references along the Morton curve; step 2: the clustering.
    return detail::sort_and_cluster(refs, cfg, static_cast<dynbvh::detail::RawNodeInfo<T>*>(nullptr), ex);
}

namespace detail {

/// build_tree with the facts of every inner node computed as the clustering makes it (the emission
/// then skips compute_node_info's bottom-up pass): `info` is resized to the inner node count.
template <class T, class Exec>
BinaryTree build_tree_with_info(References<T>& refs, const Config& cfg, scratch_vector<dynbvh::detail::RawNodeInfo<T>>& info, const Exec& ex) {
    morton::check_bits(cfg.morton_bits, "dynbvh::ploc");
    const std::size_t n = refs.size();
    if (BinaryTree tree = BinaryTree::start(n, "dynbvh::ploc"); n < 2) return tree;
    info.resize(n - 1);
    return sort_and_cluster(refs, cfg, info.data(), ex);
}

/// References and tree straight from the triangles (any triangle source), with the facts of every inner
/// node: the refs make_references + morton::sort_references give and the tree build_tree_with_info
/// makes over them, bit for bit, in fewer passes. The triangles are sorted by their codes alone
/// (morton_wide::detail::sort_triangles: no box array yet), then one pass reads each triangle in
/// Morton order and writes its box twice, into the sorted references (for the emission) and into
/// the clustering's first boxes (replacing make_references' box array, the sort's gather of it and
/// the clustering's copy).
template <class Source, class Exec>
std::pair<References<dynbvh::detail::source_scalar_t<Source>>, BinaryTree>
build_from_triangles(Source tris, const Config& cfg, scratch_vector<dynbvh::detail::RawNodeInfo<dynbvh::detail::source_scalar_t<Source>>>& info,
                     const Exec& ex) {
    using T = dynbvh::detail::source_scalar_t<Source>;
    morton::check_bits(cfg.morton_bits, "dynbvh::ploc");
    BinaryTree::check_size(tris.size(), "dynbvh::ploc");
    References<T> refs;
    refs.primitive_count = tris.size();
    BinaryTree tree;
    auto run = [&](auto key) {
        using Key = decltype(key);
        auto sorted = morton_wide::detail::sort_triangles<Key>(tris, ex);
        refs.excluded = sorted.excluded;
        refs.prim = std::move(sorted.prim);
        const std::size_t n = refs.prim.size();
        refs.box.resize(n);
        tree = BinaryTree::start(n, "dynbvh::ploc");
        if (n < 2) {
            if (n == 1) refs.box[0] = morton_wide::detail::triangle_box<T>(tris[refs.prim[0]]);
            return;
        }
        info.resize(n - 1);
        if (cfg.subtree_clusters > 0) {   // each box made where the task that clusters it reads it
            SubtreeClustering<T, Key> clusters(sorted.keys.data(), n, cfg.radius, cfg.subtree_clusters, info.data(), cfg.leaves);
            const std::uint32_t* prim = refs.prim.data();
            tree = clusters.run([&](std::size_t i) {
                const AABB<T> b = morton_wide::detail::triangle_box<T>(tris[prim[i]]);
                refs.box[i] = b;
                return b;
            }, ex);
            return;
        }
        Clustering<T> clusters(n, cfg.radius, info.data(), cfg.leaves);
        const std::uint32_t* prim = refs.prim.data();
        ex.for_blocks(0, n, [&](std::size_t lo, std::size_t hi) {
            constexpr std::size_t ahead = 16;   // triangles: scattered in memory, read in Morton order
            for (std::size_t i = lo; i < hi; ++i) {
#if defined(__GNUC__)
                if constexpr (std::is_lvalue_reference_v<decltype(tris[0])>)
                    if (i + ahead < hi) __builtin_prefetch(&tris[prim[i + ahead]]);
#endif
                const AABB<T> b = morton_wide::detail::triangle_box<T>(tris[prim[i]]);
                refs.box[i] = b;
                clusters.set_box(i, b);
            }
        }, 4096);
        tree = clusters.run(ex);
    };
    if (cfg.morton_bits == 63) run(std::uint64_t{});
    else run(std::uint32_t{});
    return {std::move(refs), std::move(tree)};
}

/// The whole-build step for dynbvh::detail::build_over (detail/emit_wide.hpp): references, tree and
/// facts from the triangles in one go (build_from_triangles).
struct Topology {
    static constexpr bool from_triangles = true;
    template <class Source, class Exec>
    auto operator()(Source tris, const Config& cfg, scratch_vector<dynbvh::detail::RawNodeInfo<dynbvh::detail::source_scalar_t<Source>>>& info,
                    const Exec& ex) const {
        return build_from_triangles(tris, cfg, info, ex);
    }
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

/// The traced layout in one step: the W-wide tree `build_wide<W>(tris, cfg, ex)` gives with its leaves
/// packed into SIMD blocks of L triangles (wide_blocks.hpp), the tree
/// `make_wide_blocks<L>(build_wide<W>(tris, cfg, ex), tris, ex)` gives, bit for bit, without the index
/// tree (the leaves are packed as the wide nodes are linked together; detail/emit_wide.hpp). Pass
/// `.leaves = dynbvh::block_leaves` for leaves sized for blocks of 8:
/// `auto t = dynbvh::ploc::build_blocks(tris, {.radius = 5, .leaves = dynbvh::block_leaves}, ex);`
template <int W = 8, int L = W, class Exec = exec::default_executor>
WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(std::span<const Triangle<float>> tris, const Config& cfg = {},
                                                                         const Exec& ex = {}) {
    return dynbvh::detail::build_over<W, Node<float>, prim::blocks<L>>(tris, cfg, detail::Topology{}, ex);
}

/// build_blocks over an indexed float mesh read in place (mesh.hpp): the span's tree, bit for bit.
template <int W = 8, int L = W, class Exec = exec::default_executor, class Index>
WideBvh<WideNode<float, std::uint32_t, W>, prim::blocks<L>> build_blocks(const MeshView<float, Index>& mesh, const Config& cfg = {},
                                                                         const Exec& ex = {}) {
    return dynbvh::detail::build_over<W, Node<float>, prim::blocks<L>>(mesh, cfg, detail::Topology{}, ex);
}

/// The same for a std::vector of triangles of any scalar, the node type following the triangles:
/// `dynbvh::ploc::build(std::vector<Triangled>{...})` is a Bvh<Node<double>>.
template <int = 0, class T, class Exec = exec::default_executor>
Bvh<Node<T>> build(const std::vector<Triangle<T>>& tris, const Config& cfg = {}, const Exec& ex = {}) {
    return build<Node<T>, prim::indexed, Exec>(std::span<const Triangle<T>>(tris), cfg, ex);
}

} // namespace dynbvh::ploc
