// SPDX-License-Identifier: MIT
/// @file traverse_wide.hpp
/// Closest-hit and any-hit queries of one ray against a `WideBvh` (wide.hpp), with the same policies,
/// contract and answers as the binary traversal (traverse.hpp), whose leaf test and pop-and-skip step
/// it shares (a fixed stack, a heap one for trees deeper than their depth field says). Included by wide.hpp: `#include <dynbvh/wide.hpp>` is enough.
///
/// Each step tests all W child boxes of a node at once: with SSE (detail/simd.hpp) one instruction per
/// slab plane for 4 slots, an 8-wide node in two SSE steps or one AVX step; elsewhere (or with
/// -DDYNBVH_NO_SIMD) a scalar loop over the box policy's own `test_octant`. All paths perform the same
/// IEEE operations in the same order (max/min operand order chosen so that NaN and +-0 resolve as in
/// detail::max_keep/min_keep), so all give the same hits. For float rays and box::robust, the per-ray
/// setup is also done in SSE when it gives exactly box::robust::prepared's values (no subnormal
/// direction component). The triangle test's setup waits for the first leaf: most primary rays of
/// open scenes reach none.
///
/// Block trees (prim::blocks<L>, wide_blocks.hpp): a leaf slot names its first SIMD triangle block and
/// the leaf test is detail::BlockTest (detail/triangle_block.hpp), which returns test_leaf's answers
/// bit for bit, so the traversal is the same as for index leaves.
///
/// Exactness: as in traverse.hpp; `intersect(wide, ...)` returns what `brute_force_intersect` returns
/// (t, u, v to the bit and the same triangle: an exact tie goes to the larger index, detail::replaces_hit). Hit children are visited nearest first; the
/// others go on a fixed stack of W - 1 entries per wide level with their entry distance and are skipped
/// once a closer hit is known. A tree deeper than max_depth, or one whose `depth` is wrong, is traced
/// with a heap stack that cannot overflow.
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

#include "detail/simd.hpp"
#include "detail/triangle_block.hpp"
#include "intersect.hpp"
#include "traverse.hpp"
#include "wide.hpp"

namespace dynbvh {

namespace detail {

/// W box tests at once: a bit mask of the slots hit within [tmin, tmax] and their entry distances
/// (tmax and the distances in the box policy's units, t * p.t_scale, as its test_octant).
/// This portable version runs the box policy's own test_octant on each slot; WideBoxTest is the
/// version traversal uses (SSE, or AVX for 8-wide nodes, for float where available, else this one).
template <class Box, class T>
struct WideBoxTestScalar {
    using prepared = typename Box::template prepared<T>;
    explicit WideBoxTestScalar(const prepared& p) noexcept : p_(p) {}
    template <int Oct, class I, int W>
    DYNBVH_ALWAYS_INLINE unsigned test(const WideNode<T, I, W>& n, T tmax, T* tentry) const noexcept {
        unsigned mask = 0;
        for (int k = 0; k < W; ++k) {
            const Vec3<T> lo{n.lo_x[k], n.lo_y[k], n.lo_z[k]}, hi{n.hi_x[k], n.hi_y[k], n.hi_z[k]};
            mask |= Box::template test_octant<Oct>(p_, lo, hi, tmax, tentry[k]) ? 1u << k : 0u;
        }
        return mask;
    }

private:
    prepared p_;
};

template <class Box, class T, int W = 4>
struct WideBoxTest : WideBoxTestScalar<Box, T> {
    using WideBoxTestScalar<Box, T>::WideBoxTestScalar;
};

#if defined(DYNBVH_SSE)
/// box::robust on W slots, L::n lanes per step.
template <int W>
struct WideBoxTest<box::robust, float, W> {
    using prepared = box::robust::prepared<float>;
    using L = lanes_for<W>;
    using R = typename L::reg;
    explicit WideBoxTest(const prepared& p) noexcept
        : ox(L::set1(p.org.x)), oy(L::set1(p.org.y)), oz(L::set1(p.org.z)), ix(L::set1(p.inv.x)), iy(L::set1(p.inv.y)),
          iz(L::set1(p.inv.z)), tmin(L::set1(p.tmin)) {}

    /// The same values as from box::robust::prepared (org, inv = 1 / dir correctly rounded, tmin,
    /// octant = direction sign bits, t_scale = 1), computed in a few SSE instructions for the common ray:
    /// traceable and no direction component in (0, FLT_MIN). `ok` is false for any other ray (the
    /// members are then unspecified and the caller uses box::robust::prepared, which handles it).
    /// The per-ray setup is a large part of a primary ray's cost, most of which miss early.
    WideBoxTest(const Ray<float>& r, bool& ok, int& octant) noexcept {
        const __m128 d = _mm_setr_ps(r.dir.x, r.dir.y, r.dir.z, 1.0f);
        const __m128 o = _mm_setr_ps(r.org.x, r.org.y, r.org.z, 0.0f);
        const __m128 sign = _mm_set1_ps(-0.0f), inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
        const __m128 ad = _mm_andnot_ps(sign, d), ao = _mm_andnot_ps(sign, o);
        const int finite = _mm_movemask_ps(_mm_and_ps(_mm_cmplt_ps(ad, inf), _mm_cmplt_ps(ao, inf)));  // false for NaN
        const int tiny = _mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(ad, _mm_setzero_ps()),
                                                    _mm_cmplt_ps(ad, _mm_set1_ps(std::numeric_limits<float>::min()))));
        const int nonzero = _mm_movemask_ps(_mm_cmpneq_ps(d, _mm_setzero_ps())) & 7;
        ok = finite == 15 && tiny == 0 && nonzero != 0 && r.tmin <= r.tmax;
        const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), d);
        octant = _mm_movemask_ps(d) & 7;
        ox = L::from4(_mm_shuffle_ps(o, o, 0x00));
        oy = L::from4(_mm_shuffle_ps(o, o, 0x55));
        oz = L::from4(_mm_shuffle_ps(o, o, 0xaa));
        ix = L::from4(_mm_shuffle_ps(inv, inv, 0x00));
        iy = L::from4(_mm_shuffle_ps(inv, inv, 0x55));
        iz = L::from4(_mm_shuffle_ps(inv, inv, 0xaa));
        tmin = L::set1(r.tmin);
    }
    template <int Oct, class I>
    DYNBVH_ALWAYS_INLINE unsigned test(const WideNode<float, I, W>& n, float tmax, float* tentry) const noexcept {
        unsigned mask = 0;
        for (int h = 0; h < W; h += L::n) {
            const R x0 = L::mul(L::sub(L::load((Oct & 1 ? n.hi_x : n.lo_x) + h), ox), ix);
            const R x1 = L::mul(L::sub(L::load((Oct & 1 ? n.lo_x : n.hi_x) + h), ox), ix);
            const R y0 = L::mul(L::sub(L::load((Oct & 2 ? n.hi_y : n.lo_y) + h), oy), iy);
            const R y1 = L::mul(L::sub(L::load((Oct & 2 ? n.lo_y : n.hi_y) + h), oy), iy);
            const R z0 = L::mul(L::sub(L::load((Oct & 4 ? n.hi_z : n.lo_z) + h), oz), iz);
            const R z1 = L::mul(L::sub(L::load((Oct & 4 ? n.lo_z : n.hi_z) + h), oz), iz);
            const R tn = L::max(z0, L::max(y0, L::max(x0, tmin)));
            R tf = L::min(z1, L::min(y1, L::min(x1, L::set1(tmax))));
            tf = L::add(tf, L::mul(L::set1(2.0f * rounding_gamma<float>(3)), L::abs(tf)));   // box::robust::widen
            L::store(tentry + h, tn);
            mask |= L::le_mask(tn, tf) << h;
        }
        return mask;
    }

private:
    R ox, oy, oz, ix, iy, iz, tmin;
};

/// box::fast on W slots, L::n lanes per step.
template <int W>
struct WideBoxTest<box::fast, float, W> {
    using prepared = box::fast::prepared<float>;
    using L = lanes_for<W>;
    using R = typename L::reg;
    explicit WideBoxTest(const prepared& p) noexcept
        : ix(L::set1(p.inv.x)), iy(L::set1(p.inv.y)), iz(L::set1(p.inv.z)), oix(L::set1(p.org_inv.x)),
          oiy(L::set1(p.org_inv.y)), oiz(L::set1(p.org_inv.z)), tmin(L::set1(p.tmin)) {}
    template <int Oct, class I>
    DYNBVH_ALWAYS_INLINE unsigned test(const WideNode<float, I, W>& n, float tmax, float* tentry) const noexcept {
        unsigned mask = 0;
        for (int h = 0; h < W; h += L::n) {
            const R x0 = L::fmsub(L::load((Oct & 1 ? n.hi_x : n.lo_x) + h), ix, oix);
            const R x1 = L::fmsub(L::load((Oct & 1 ? n.lo_x : n.hi_x) + h), ix, oix);
            const R y0 = L::fmsub(L::load((Oct & 2 ? n.hi_y : n.lo_y) + h), iy, oiy);
            const R y1 = L::fmsub(L::load((Oct & 2 ? n.lo_y : n.hi_y) + h), iy, oiy);
            const R z0 = L::fmsub(L::load((Oct & 4 ? n.hi_z : n.lo_z) + h), iz, oiz);
            const R z1 = L::fmsub(L::load((Oct & 4 ? n.lo_z : n.hi_z) + h), iz, oiz);
            const R tn = L::max(z0, L::max(y0, L::max(x0, tmin)));
            const R tf = L::min(z1, L::min(y1, L::min(x1, L::set1(tmax))));
            L::store(tentry + h, tn);
            mask |= L::le_mask(tn, tf) << h;
        }
        return mask;
    }

private:
    R ix, iy, iz, oix, oiy, oiz, tmin;
};
#endif  // DYNBVH_SSE

template <class Index, class T>
struct WideStackEntry {
    Index child;   ///< node index (count 0) or first prim_ids slot (count > 0)
    Index count;
    T tentry;
};

/// Slot `slot` with entry distance `t` as an integer key: keys order as (t, slot), for t not NaN (the
/// float's bits made monotonic: -0 sorts just below +0, which only changes the visit order of exact ties).
template <class T>
DYNBVH_ALWAYS_INLINE std::uint64_t sort_key(T t, int slot) noexcept {
    const float f = float(t);   // (double distances: rounding to float only coarsens the visit order)
    const std::uint32_t u = std::bit_cast<std::uint32_t>(f);
    const std::uint32_t ordered = u ^ ((u >> 31) != 0 ? 0xffffffffu : 0x80000000u);
    return (std::uint64_t(ordered) << 32) | std::uint64_t(slot);
}

/// Compare-exchange: a <= b afterwards (branch-free: min and max compile to conditional moves).
DYNBVH_ALWAYS_INLINE void compare_exchange(std::uint64_t& a, std::uint64_t& b) noexcept {
    const std::uint64_t lo = a < b ? a : b, hi = a < b ? b : a;
    a = lo;
    b = hi;
}

/// Sorting networks on 4 keys (5 compare-exchanges) and 8 keys (19, depth 6); checked on every 0/1
/// input (the zero-one principle) by tests/test_wide.cpp.
DYNBVH_ALWAYS_INLINE void sort4(std::uint64_t* k) noexcept {
    compare_exchange(k[0], k[1]); compare_exchange(k[2], k[3]);
    compare_exchange(k[0], k[2]); compare_exchange(k[1], k[3]);
    compare_exchange(k[1], k[2]);
}
DYNBVH_ALWAYS_INLINE void sort8(std::uint64_t* k) noexcept {
    compare_exchange(k[0], k[2]); compare_exchange(k[1], k[3]); compare_exchange(k[4], k[6]); compare_exchange(k[5], k[7]);
    compare_exchange(k[0], k[4]); compare_exchange(k[1], k[5]); compare_exchange(k[2], k[6]); compare_exchange(k[3], k[7]);
    compare_exchange(k[0], k[1]); compare_exchange(k[2], k[3]); compare_exchange(k[4], k[5]); compare_exchange(k[6], k[7]);
    compare_exchange(k[2], k[4]); compare_exchange(k[3], k[5]);
    compare_exchange(k[1], k[4]); compare_exchange(k[3], k[6]);
    compare_exchange(k[1], k[2]); compare_exchange(k[3], k[4]); compare_exchange(k[5], k[6]);
}

/// Sorts key[0 .. m) ascending in place (m <= W, W = 4 or 8; key has W entries): the children of one
/// wide node in visit order, without an insertion sort's data-dependent branches (they were a third of
/// the traversal loop's time where many children are hit: long thin crossing triangles).
template <int W>
DYNBVH_ALWAYS_INLINE void sort_keys(std::uint64_t* key, int m) noexcept {
    static_assert(W == 4 || W == 8);
    if (m <= 2) {
        if (m == 2) compare_exchange(key[0], key[1]);
        return;
    }
    if (W == 4 || m <= 4) {
        for (int i = m; i < 4; ++i) key[i] = ~std::uint64_t(0);
        sort4(key);
    } else if constexpr (W == 8) {
        for (int i = m; i < 8; ++i) key[i] = ~std::uint64_t(0);
        sort8(key);
    }
}

/// Fills order[0 .. n) with 0 .. n - 1 sorted by dist[i] (ties by index; n <= W, distances not NaN).
template <int W, class T>
DYNBVH_ALWAYS_INLINE void order_by_distance(const T* dist, int n, int* order) noexcept {
    std::uint64_t key[std::size_t(W)];
    for (int i = 0; i < n; ++i) key[i] = sort_key(dist[i], i);
    sort_keys<W>(key, n);
    for (int i = 0; i < n; ++i) order[i] = int(key[i] & 7u);
}

/// One step down from wide node `n` whose hit slots are `mask` (entry distances t[slot]): the nearest
/// child becomes (cur, cur_count), the others go on the stack farthest first, so they pop nearest first.
/// False (nothing changed) when the stack has no room for them (the caller takes the heap stack).
/// Shared by the wide traversal and two-level scenes' top level (two_level.hpp).
template <class WN, class Entry, class T, class I = typename WN::index_type>
DYNBVH_ALWAYS_INLINE bool descend_nearest(const WN& n, unsigned mask, const T* t, Entry* stack, std::size_t& sp, std::size_t cap,
                                          I& cur, I& cur_count) noexcept {
    constexpr int W = WN::width;
    const int a = std::countr_zero(mask);
    mask &= mask - 1;
    if (mask == 0) {   // one child hit: go there
        cur = n.child[a];
        cur_count = n.count[a];
        return true;
    }
    const int b = std::countr_zero(mask);
    mask &= mask - 1;
    if (mask == 0) {   // two: the nearer now, the farther on the stack
        if (sp + 1 > cap) [[unlikely]] return false;
        const bool swap = t[b] < t[a];
        const int near = swap ? b : a, far = swap ? a : b;
        stack[sp++] = Entry{n.child[far], n.count[far], t[far]};
        cur = n.child[near];
        cur_count = n.count[near];
        return true;
    }
    // Three or more: sort by entry distance (sort_keys), push all but the nearest, farthest first.
    if (sp + (W - 1) > cap) [[unlikely]] return false;
    std::uint64_t key[std::size_t(W)];
    int m = 0;
    key[m++] = sort_key(t[a], a);
    key[m++] = sort_key(t[b], b);
    for (; mask != 0; mask &= mask - 1) {
        const int c = std::countr_zero(mask);
        key[m++] = sort_key(t[c], c);
    }
    sort_keys<W>(key, m);
    for (int i = m - 1; i > 0; --i) {
        const int c = int(key[i] & 7u);
        stack[sp++] = Entry{n.child[c], n.count[c], t[c]};
    }
    const int near = int(key[0] & 7u);
    cur = n.child[near];
    cur_count = n.count[near];
    return true;
}

/// The wide traversal loop for one direction octant; same contract as traverse_octant (traverse.hpp).
/// Box distances are in box::robust's units (t * t_scale). The triangle test's per-ray setup is
/// done when the first leaf is reached: most primary rays of an open scene never reach one.
/// It starts at node `start` (or at the leaf slot (start, start_count) when start_count > 0) with
/// the closest hit so far `hit` (t = tmax0, triangle best0; invalid_prim and ray.tmax for a fresh
/// query), so that a packet traversal (packet.hpp) can finish a subtree ray by ray.
// GCC cannot see that the lazily made triangle setup (`pt`, guarded by have_pt) is made before use
// once the start slot is a run-time argument: a false -Wmaybe-uninitialized.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
template <class Policy, bool AnyHit, int Oct, class WN, class P, class S = typename WN::scalar_type,
          class I = typename WN::index_type, int W = WN::width, class Source>
bool wide_traverse_octant(const WideBvh<WN, P>& bvh, const Source tris, const Ray<S>& ray,
                          const S t_scale,
                          const WideBoxTest<typename Policy::box_test, S, W>& wb_in, Hit<S>& hit,
                          WideStackEntry<I, S>* const stack, const std::size_t cap, const I start, const I start_count,
                          const S tmax0, const std::uint32_t best0) {
    // A local copy: its registers need not be reloaded after stores (the SIMD types may alias anything),
    // and taking it by reference spares the caller a copy of the whole box test on every ray.
    const WideBoxTest<typename Policy::box_test, S, W> wb = wb_in;
    using Box = typename Policy::box_test;
    using Tri = typename Policy::triangle_test;
    using Entry = WideStackEntry<I, S>;
    using WB = WideBvh<WN, P>;

    const WN* const nodes = bvh.nodes.data();
    const I* const ids = bvh.prim_ids.data();
    const auto leaf_tris = leaf_triangles_of(bvh, tris);
    constexpr int BL = WB::block_lanes;   // > 0: leaves are triangle blocks (wide_blocks.hpp)
    // The triangle test's setup, made at the first leaf. (Not std::optional: GCC zero-fills its storage
    // with `rep stos` on every ray, a tenth of a primary ray's cost when most rays reach no leaf.)
    using TriPrepared =
        std::conditional_t<(BL > 0), BlockTest<Tri, (BL > 0 ? BL : 4)>, typename Tri::template prepared<S>>;
    static_assert(std::is_trivially_destructible_v<TriPrepared>);
    union LazyPrepared {
        LazyPrepared() noexcept {}
        TriPrepared value;
    } pt;
    bool have_pt = false;

    S tmax = tmax0;
    S tbox = tmax * t_scale;   // tmax in box units
    std::size_t sp = 0;
    std::uint32_t best_prim = best0;
    I cur = start, cur_count = start_count;
    for (;;) {
        if (cur_count == 0) {
            const WN& n = nodes[cur];
            alignas(32) S t[std::size_t(W)];
            const unsigned mask = wb.template test<Oct>(n, tbox, t);
            if (mask != 0) {
                if (!descend_nearest(n, mask, t, stack, sp, cap, cur, cur_count)) [[unlikely]] return false;
                continue;
            }
        } else {
            if (!have_pt) [[unlikely]] {
                ::new (static_cast<void*>(&pt.value)) TriPrepared(ray);
                have_pt = true;
            }
            if constexpr (BL > 0) {   // a leaf slot: first block, number of triangles
                if (pt.value.template test<AnyHit>(bvh.blocks.data(), cur, std::size_t(cur) + blocks_for<BL>(cur_count), t_scale,
                                                   tmax, tbox, best_prim, hit))
                    return true;
            } else {
                if (test_leaf<Tri, AnyHit, WB::precomputed>(pt.value, leaf_tris, ids, cur, std::size_t(cur) + cur_count, t_scale,
                                                            tmax, tbox, best_prim, hit))
                    return true;
            }
        }
        // Pop the next subtree that can still hold a closer hit.
        Entry next;
        if (!pop_closer<Box>(stack, sp, tbox, next)) {
            hit.prim = best_prim;
            return true;
        }
        cur = next.child;
        cur_count = next.count;
    }
}

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

/// Octant dispatch of wide_traverse_octant from the root for a prepared ray, on `stack` (cap entries);
/// false when that stack would overflow.
template <class Policy, bool AnyHit, class WN, class P, class S, class I, int W, class Source>
DYNBVH_ALWAYS_INLINE bool wide_run_on(const WideBvh<WN, P>& bvh, const Source tris, const Ray<S>& ray,
                                      const WideBoxTest<typename Policy::box_test, S, W>& wb, S t_scale, int octant,
                                      WideStackEntry<I, S>* stack, std::size_t cap, Hit<S>& hit) {
    return dispatch_octant(octant, [&](auto oct) {
        return wide_traverse_octant<Policy, AnyHit, decltype(oct)::value>(bvh, tris, ray, t_scale, wb, hit, stack, cap, I(0), I(0),
                                                                          ray.tmax, invalid_prim);
    });
}

/// The heap-stack retry of wide_run (a tree whose depth field understates its depth; kept off the hot path).
template <class Policy, bool AnyHit, class WN, class P, class S, class I, int W, class Source>
DYNBVH_NOINLINE Hit<S> wide_run_heap(const WideBvh<WN, P>& bvh, const Source tris, const Ray<S>& ray,
                                     const WideBoxTest<typename Policy::box_test, S, W>& wb, S t_scale, int octant) {
    // Each node's children are pushed at most once, W - 1 entries per node.
    std::vector<WideStackEntry<I, S>> heap(std::size_t(W - 1) * (bvh.nodes.size() + 1));
    Hit<S> hit;
    wide_run_on<Policy, AnyHit, WN, P, S, I, W>(bvh, tris, ray, wb, t_scale, octant, heap.data(), heap.size(), hit);
    return hit;
}

/// Stack and octant dispatch around wide_traverse_octant for a prepared ray (inlined into the caller:
/// the per-ray set-up is a large part of a primary ray's cost, and each call level adds a frame).
template <class Policy, bool AnyHit, class WN, class P, class S = typename WN::scalar_type, class I = typename WN::index_type,
          int W = WN::width, class Source>
DYNBVH_ALWAYS_INLINE Hit<S> wide_run(const WideBvh<WN, P>& bvh, const Source tris, const Ray<S>& ray,
                                     const WideBoxTest<typename Policy::box_test, S, W>& wb, S t_scale, int octant) {
    // At most W - 1 entries per wide level: wide depth < binary depth <= max_depth.
    constexpr std::size_t fixed_cap = std::size_t(W - 1) * std::size_t(max_depth);
    if (bvh.depth < max_depth) [[likely]] {
        WideStackEntry<I, S> stack[fixed_cap];
        Hit<S> hit;
        if (wide_run_on<Policy, AnyHit, WN, P, S, I, W>(bvh, tris, ray, wb, t_scale, octant, stack, fixed_cap, hit)) [[likely]]
            return hit;
    }
    return wide_run_heap<Policy, AnyHit, WN, P, S, I, W>(bvh, tris, ray, wb, t_scale, octant);
}

template <class Policy, bool AnyHit, class WN, class P, class S = typename WN::scalar_type, class I = typename WN::index_type,
          int W = WN::width, class Source>
Hit<S> wide_traverse(const WideBvh<WN, P>& bvh, const Source tris, const Ray<S>& ray) {
    using Box = typename Policy::box_test;
    if (bvh.nodes.empty()) return {};
#if defined(DYNBVH_SSE)
    if constexpr (std::is_same_v<Box, box::robust> && std::is_same_v<S, float>) {
        bool ok;
        int octant;
        const WideBoxTest<Box, S, W> wb(ray, ok, octant);
        if (ok) [[likely]] return wide_run<Policy, AnyHit>(bvh, tris, ray, wb, S(1), octant);
    }
#endif
    // No separate traceable() check: the prepared ray of a ray that is not traceable has a NaN tmin,
    // so every box test misses and no leaf is reached (tests cover it).
    const typename Box::template prepared<S> pb(ray);
    return wide_run<Policy, AnyHit>(bvh, tris, ray, WideBoxTest<Box, S, W>(pb), pb.t_scale, pb.octant);
}

} // namespace detail

/// Closest hit in a wide BVH; same contract as intersect(Bvh, ...) in traverse.hpp.
template <class Policy = trace::robust, class WN, class P, class S = typename WN::scalar_type>
Hit<S> intersect(const WideBvh<WN, P>& bvh, std::type_identity_t<std::span<const Triangle<S>>> tris,
                 const std::type_identity_t<Ray<S>>& ray) {
    detail::check_triangles(bvh, tris.size(), "intersect", !WideBvh<WN, P>::precomputed);
    return detail::wide_traverse<Policy, false>(bvh, tris, ray);
}

/// Closest hit in a wide BVH over an indexed mesh read in place (mesh.hpp); same answer as over
/// make_triangles' array, bit for bit.
template <class Policy = trace::robust, class WN, class P, class Index, class S = typename WN::scalar_type>
Hit<S> intersect(const WideBvh<WN, P>& bvh, const MeshView<std::type_identity_t<S>, Index>& mesh,
                 const std::type_identity_t<Ray<S>>& ray) {
    detail::check_triangles(bvh, mesh.size(), "intersect", !WideBvh<WN, P>::precomputed);
    return detail::wide_traverse<Policy, false>(bvh, mesh, ray);
}

/// Any hit in a wide BVH over an indexed mesh read in place (mesh.hpp).
template <class Policy = trace::robust, class WN, class P, class Index, class S = typename WN::scalar_type>
bool occluded(const WideBvh<WN, P>& bvh, const MeshView<std::type_identity_t<S>, Index>& mesh,
              const std::type_identity_t<Ray<S>>& ray) {
    detail::check_triangles(bvh, mesh.size(), "occluded", !WideBvh<WN, P>::precomputed);
    return static_cast<bool>(detail::wide_traverse<Policy, true>(bvh, mesh, ray));
}

/// Any hit in a wide BVH; same contract as occluded(Bvh, ...) in traverse.hpp.
template <class Policy = trace::robust, class WN, class P, class S = typename WN::scalar_type>
bool occluded(const WideBvh<WN, P>& bvh, std::type_identity_t<std::span<const Triangle<S>>> tris,
              const std::type_identity_t<Ray<S>>& ray) {
    detail::check_triangles(bvh, tris.size(), "occluded", !WideBvh<WN, P>::precomputed);
    return static_cast<bool>(detail::wide_traverse<Policy, true>(bvh, tris, ray));
}

} // namespace dynbvh
