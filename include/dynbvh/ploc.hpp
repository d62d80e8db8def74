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
/// Speed, in the spirit of PLOC++ (Benthin et al. 2022): an iteration is two parallel passes over fixed
/// chunks of the clusters: (A) nearest neighbours of the chunk and of `radius` clusters on either side
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
/// nearest_scalar's answers, 16 positions per SIMD step (AVX-512, float boxes). For each k = 1..r in
/// turn, lane m computes the distances of its pairs (m - k, m) and (m, m + k) (the same operands and
/// operations as merged_half_area, so the same bits), picks the one candidate_key orders first at
/// this k (left, unless m is even and k odd: then the right pair's lower position has parity 0), and
/// keeps it if its distance bits are strictly below the best so far (an earlier k wins a tie).
inline void nearest_simd(const float* const* box, std::size_t c, std::size_t r, std::size_t a, std::size_t b, std::uint32_t* nn) noexcept {
    const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const __m512i cnt = _mm512_set1_epi32(int(c)), end = _mm512_set1_epi32(int(b)), all = _mm512_set1_epi32(-1);
    const __m512i one = _mm512_set1_epi32(1);
    // (the zero-masked forms: GCC 12 warns about the undefined source operand of _mm512_min_ps)
    auto mx = [](__m512 x, __m512 y) { return _mm512_maskz_max_ps(__mmask16(0xffff), x, y); };
    auto mn = [](__m512 x, __m512 y) { return _mm512_maskz_min_ps(__mmask16(0xffff), x, y); };
    auto dist = [&](const __m512 (&lo)[6], const __m512 (&hi)[6]) {   // merged_half_area(lo, hi), lo the lower position
        const __m512 dx = _mm512_sub_ps(mx(hi[3], lo[3]), mn(hi[0], lo[0]));
        const __m512 dy = _mm512_sub_ps(mx(hi[4], lo[4]), mn(hi[1], lo[1]));
        const __m512 dz = _mm512_sub_ps(mx(hi[5], lo[5]), mn(hi[2], lo[2]));
        return _mm512_castps_si512(_mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dy), _mm512_mul_ps(dy, dz)), _mm512_mul_ps(dz, dx)));
    };
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
            const __m512i dr = _mm512_mask_blend_epi32(has_r, all, dist(self, other));
            if (has_l) {   // (m0 - k may be below 0 in the first lanes: those are masked off)
                for (int q = 0; q < 6; ++q) other[q] = _mm512_maskz_loadu_ps(has_l, box[q] + std::ptrdiff_t(m0) - std::ptrdiff_t(k));
            }
            const __m512i dl = has_l ? _mm512_mask_blend_epi32(has_l, all, dist(other, self)) : all;
            const __mmask16 right_first = (k & 1) ? even : __mmask16(0);
            const __mmask16 take_r = _mm512_cmplt_epu32_mask(dr, dl) | (_mm512_cmpeq_epi32_mask(dr, dl) & right_first);
            const __m512i d = _mm512_mask_blend_epi32(take_r, dl, dr);
            const __m512i p = _mm512_mask_blend_epi32(take_r, _mm512_sub_epi32(m, kk), _mm512_add_epi32(m, kk));
            const __mmask16 better = _mm512_cmplt_epu32_mask(d, best_d);
            best_d = _mm512_mask_blend_epi32(better, best_d, d);
            best_p = _mm512_mask_blend_epi32(better, best_p, p);
        }
        _mm512_mask_storeu_epi32(nn + (m0 - a), live, best_p);
    }
}
#endif

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

    /// Nearest neighbours of positions [a, b) into nn[0 .. b - a) (`keys`: the plain search's scratch).
    static void nearest(const T* const* box, std::size_t c, std::size_t r, std::size_t a, std::size_t b, std::uint32_t* nn,
                        std::uint64_t* keys) {
#if defined(__AVX512F__) && !defined(DYNBVH_NO_SIMD)
        if constexpr (simd_search) {
            (void)keys;
            nearest_simd(box, c, r, a, b, nn);
            return;
        }
#endif
        if constexpr (!simd_search) nearest_scalar(box, c, r, a, b, nn, keys);
    }

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

/// build_tree with the facts of every inner node computed as the clustering makes it (the emission
/// then skips compute_node_info's bottom-up pass): `info` is resized to the inner node count.
template <class T, class Exec>
BinaryTree build_tree_with_info(References<T>& refs, const Config& cfg, scratch_vector<dynbvh::detail::RawNodeInfo<T>>& info, const Exec& ex) {
    morton::check_bits(cfg.morton_bits, "dynbvh::ploc");
    const std::size_t n = refs.size();
    if (BinaryTree tree = BinaryTree::start(n, "dynbvh::ploc"); n < 2) return tree;
    if (cfg.morton_bits == 63) morton::sort_references<std::uint64_t>(refs, ex);
    else morton::sort_references<std::uint32_t>(refs, ex);
    info.resize(n - 1);
    return Clustering<T>(refs, cfg.radius, ex, info.data(), cfg.leaves).run(ex);
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
