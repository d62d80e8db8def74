// SPDX-License-Identifier: MIT
/// @file detail/triangle_block.hpp
/// SIMD triangle leaves: up to L = 4 (SSE) or 8 (AVX) triangles of one leaf stored structure of
/// arrays, packed in leaf order, and the two triangle tests on a whole block at once.
///
///  - `TriangleBlock<L>`: the three vertices of up to L triangles (v[vertex][axis][lane], 64-byte
///    aligned), the user's triangle index per lane and the number of valid lanes (padding lanes have
///    NaN vertices and are masked off: never hit).
///  - `pack_triangle_blocks`: leaves (first slot, count) -> blocks in leaf order; a leaf of n
///    references takes ceil(n / L) blocks. O(n), parallel over leaves.
///  - `BlockTest<Tri, L>`: the per-ray state and the block loop for triangle policy Tri, with the
///    contract of traverse.hpp's test_leaf (same hits, t, u, v, tie rule, any-hit order).
///
/// Exactness (tri::watertight). The SIMD part is only a conservative filter: it evaluates the
/// Woop-Benthin-Wald edge functions in float with a forward error bound and rejects a lane only when
/// two edge functions have certainly strictly opposite signs - exactly the lanes the scalar
/// tri::watertight::test rejects by its (exact) sign test whatever tmax is. Every other valid lane goes,
/// in slot order and with the current tmax, through tri::watertight::test on that lane's triangle
/// (rebuilt from the block's floats, which are copies of the user's floats). So the result is the
/// scalar loop's, bit for bit: same hits, t, u, v, the larger index winning an exact tie
/// (replaces_hit), the same first hit for any-hit queries. A kept lane whose three float edge
/// functions all lie beyond the bound on the same side (certainly all positive or all negative: most
/// hits) goes through tri::watertight::test_inside instead, which skips the sign test the bound has
/// decided and gives the same t, u, v (2-5 % less single-ray time on the study's scenes).
///
/// The bound (see `WatertightFilter`), u = 2^-24, eta = 2^-150:
/// X = p[kx] - org[kx] etc. are the scalar test's differences bit for bit (one rounding each). The
/// sheared x = X - sx Z is within 3u (|X| + |sx Z|) + 2 eta of the scalar test's value whether either
/// side contracts it into an FMA or not (each is within 2u resp. u of the exact X - sx Z), and
/// |sx|, |sy| <= 1 (kz is the largest axis), so D = 4u M + 4 eta covers x and y (M = |X| + |Y| + |Z|).
/// The filter does not form M: with P = |x| + |y| (as rounded), M <= (1 + 4u)(P + 3|Z|) + 5 eta, so
/// Dm = 5u (Pm + 3 Zm) + FLT_MIN, over the largest P and |Z| of the three vertices and rounded, is at
/// least 1.2 times every vertex's D (FLT_MIN = 2^-126 stands for the eta terms).
/// An edge function F = cx by - cy bx of those perturbed inputs moves by at most
/// Pc Db + Pb Dc + 2 Dc Db, and its float evaluation adds at most 3u Pc Pb + 2 eta, so
/// E = Pm (4u Pm + 2 Dm) + 2 Dm^2 + FLT_MIN, rounded, bounds |f - F_scalar| for all three edges (the
/// slack of 4u over 3u(1 + u)^2 and of Dm over D absorbs the rounding of E itself). A lane is rejected
/// when max(fu, fv, fw) > E and min(fu, fv, fw) < -E. Lanes with Pm >= 2^60 are never rejected (below
/// it no f overflows; an infinite P or |Z| makes E infinite). NaN anywhere in a vertex makes the two
/// edge functions through it NaN, so at most one f is a number and the lane is kept.
///
/// trace::fast (tri::moller_trumbore): the SIMD test is the scalar test's arithmetic, the same
/// operations in the same order per lane (including the division), so its t, u, v and hit/miss are
/// the scalar test's bit for bit as long as neither is FMA-contracted (DYNBVH_NATIVE builds use
/// -ffp-contract=off); lanes then go through tmax and the tie rule in slot order as in test_leaf.
///
/// SIMD (detail/simd.hpp lane wrappers): SSE2 for L = 4; AVX for L = 8 where the compiler targets it
/// (__AVX__), else two SSE steps.
/// With -DDYNBVH_NO_SIMD or on other targets, both tests are the scalar loop (same results).
/// Float triangles only.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <type_traits>
#include <vector>

#include "../executor.hpp"
#include "../intersect.hpp"
#include "../ray.hpp"
#include "scratch.hpp"
#include "simd.hpp"
#include "../triangle.hpp"


namespace dynbvh::detail {

/// Up to L triangles of one leaf, structure of arrays: v[vertex][axis][lane].
template <int L>
struct alignas(64) TriangleBlock {
    static_assert(L == 4 || L == 8, "triangle blocks have 4 or 8 lanes");
    static constexpr int lanes = L;

    float v[3][3][std::size_t(L)];          ///< vertex i's coordinate a of lane k: v[i][a][k]
    std::uint32_t prim[std::size_t(L)];     ///< the user's triangle index of each lane (invalid_prim for padding)
    std::uint32_t count;       ///< valid lanes 0..count-1; the others are padding (NaN vertices)

    /// Lanes from `used` on become padding; `count` = used.
    void pad(int used) noexcept {
        for (int i = 0; i < 3; ++i)
            for (int a = 0; a < 3; ++a)
                for (int k = used; k < L; ++k) v[i][a][k] = std::numeric_limits<float>::quiet_NaN();
        for (int k = used; k < L; ++k) prim[k] = invalid_prim;
        count = std::uint32_t(used);
    }
    /// Every lane padding.
    void clear() noexcept { pad(0); }
    void set(int k, const Triangle<float>& t, std::uint32_t id) noexcept {
        for (int a = 0; a < 3; ++a) {
            v[0][a][k] = t.p0[std::size_t(a)];
            v[1][a][k] = t.p1[std::size_t(a)];
            v[2][a][k] = t.p2[std::size_t(a)];
        }
        prim[k] = id;
    }
    /// Lane k's triangle (the floats it was packed from, bit for bit).
    Triangle<float> triangle(int k) const noexcept {
        return {{v[0][0][k], v[0][1][k], v[0][2][k]}, {v[1][0][k], v[1][1][k], v[1][2][k]}, {v[2][0][k], v[2][1][k], v[2][2][k]}};
    }
    /// Bit k set for each valid lane.
    unsigned valid_mask() const noexcept { return count >= 32 ? ~0u : (1u << count) - 1u; }
    /// Bit k set for each valid lane whose triangle has a NaN or infinite vertex: |x| <= FLT_MAX fails
    /// for exactly those, nine compares per lane group (SIMD where compiled in).
    unsigned nonfinite_mask() const noexcept {
        unsigned finite = 0;
#if defined(DYNBVH_SSE)
        using V = lanes_for<L>;
        const auto big = V::set1(std::numeric_limits<float>::max());
        for (int h = 0; h < L; h += V::n) {
            unsigned f = ~0u;
            for (int i = 0; i < 3; ++i)
                for (int a = 0; a < 3; ++a) f &= V::bits(V::le(V::abs(V::load(&v[i][a][h])), big));
            finite |= (f & ((1u << V::n) - 1u)) << h;
        }
#else
        for (int k = 0; k < L; ++k) {
            bool f = true;
            for (int i = 0; i < 3; ++i)
                for (int a = 0; a < 3; ++a) f &= std::abs(v[i][a][k]) <= std::numeric_limits<float>::max();
            finite |= unsigned(f) << k;
        }
#endif
        return valid_mask() & ~finite;
    }
};

static_assert(sizeof(TriangleBlock<4>) == 192 && sizeof(TriangleBlock<8>) == 384);

/// Blocks a leaf of n references takes.
template <int L>
constexpr std::size_t blocks_for(std::size_t n) noexcept { return (n + std::size_t(L) - 1) / std::size_t(L); }

/// One leaf to pack: `count` references from slot `first` of prim_ids.
struct LeafRange {
    std::size_t first = 0, count = 0;
};

/// How many prim_ids slots ahead pack_triangle_blocks prefetches the triangle it will gather.
inline constexpr std::size_t prefetch_distance = 24;

/// Packs one leaf: slots first .. first + count - 1 of `prim_ids` (triangle `tri_of(slot)`) into the
/// blocks from `b` on, lane by lane in slot order, the last block padded (the one packing loop, shared
/// by pack_triangle_blocks and the builders that emit blocks directly). Fetches the triangle
/// prefetch_distance slots ahead (below `slots`).
template <int L, class Index, class TriOf>
inline void pack_leaf(TriangleBlock<L>* b, std::size_t first, std::size_t count, const Index* prim_ids, std::size_t slots,
                      const TriOf& tri_of) {
    for (std::size_t i = 0; i < count; i += std::size_t(L), ++b) {
        const std::size_t m = std::min<std::size_t>(std::size_t(L), count - i);
        for (std::size_t k = 0; k < m; ++k) {
            const std::size_t slot = first + i + k;
#if defined(__GNUC__)
            // The triangles are gathered in leaf order, scattered in memory: fetch a few leaves ahead
            // (leaves mostly follow one another in prim_ids).
            // (a MeshView's triangles are made on the fly: nothing to prefetch there)
            if constexpr (std::is_lvalue_reference_v<decltype(tri_of(slot))>)
                if (slot + prefetch_distance < slots) __builtin_prefetch(&tri_of(slot + prefetch_distance));
#else
            (void)slots;
#endif
            b->set(int(k), tri_of(slot), static_cast<std::uint32_t>(prim_ids[slot]));
        }
        b->pad(int(m));
    }
}

/// Packs `leaves` into `blocks`, in the order given: leaf j's references (slot first .. first+count-1,
/// triangle `tri_of(slot)`, user index prim_ids[slot]) go to blocks first_block[j] ..
/// first_block[j] + ceil(count / L) - 1, lane by lane in slot order (the last block padded).
/// `first_block` gets leaves.size() + 1 entries (the last is the total). O(references), parallel over
/// leaves (one exclusive scan, one loop).
template <int L, class Index, class TriOf, class Exec = exec::serial>
void pack_triangle_blocks(std::span<const LeafRange> leaves, std::span<const Index> prim_ids, const TriOf& tri_of,
                          scratch_vector<TriangleBlock<L>>& blocks, scratch_vector<std::size_t>& first_block, const Exec& ex = {}) {
    const std::size_t n = leaves.size();
    first_block.assign(n + 1, 0);
    ex.for_each(0, n, [&](std::size_t j) { first_block[j] = blocks_for<L>(leaves[j].count); });
    const std::size_t total = ex.exclusive_scan(std::span<const std::size_t>(first_block.data(), n), std::span<std::size_t>(first_block.data(), n));
    first_block[n] = total;
    blocks.resize(total);
    const std::size_t slots = prim_ids.size();
    ex.for_each(0, n, [&](std::size_t j) {
        pack_leaf<L>(blocks.data() + first_block[j], leaves[j].first, leaves[j].count, prim_ids.data(), slots, tri_of);
    }, 256);
}

/// The generic block test: Tri's own scalar test on each valid lane in slot order (every policy
/// without a SIMD version, and every policy under DYNBVH_NO_SIMD).
template <class Tri, int L>
struct BlockTest {
    using prepared = typename Tri::template prepared<float>;
    prepared pt;

    explicit BlockTest(const Ray<float>& r) noexcept : pt(r) {}

    /// Lanes that may hit (here: every valid lane); `pos` / `neg` (lanes proved inside): none.
    unsigned candidates(const TriangleBlock<L>& b, unsigned& pos, unsigned& neg) const noexcept {
        pos = neg = 0;
        return b.valid_mask();
    }

    /// Blocks [first, end) with test_leaf's contract: each hit narrows tmax and tbox = tmax * t_scale and
    /// sets best_prim and hit.t/u/v; with AnyHit the first hit sets hit.prim and returns true.
    template <bool AnyHit>
    DYNBVH_ALWAYS_INLINE bool test(const TriangleBlock<L>* blocks, std::size_t first, std::size_t end, float t_scale, float& tmax,
                                   float& tbox, std::uint32_t& best_prim, Hit<float>& hit) const {
        for (std::size_t i = first; i < end; ++i) {
            const TriangleBlock<L>& b = blocks[i];
            for (int k = 0; k < int(b.count); ++k)
                if (confirm<AnyHit>(b, k, t_scale, tmax, tbox, best_prim, hit)) return true;
        }
        return false;
    }

protected:
    /// The scalar test on lane k with the current tmax, recorded as test_leaf records it.
    template <bool AnyHit>
    DYNBVH_ALWAYS_INLINE bool confirm(const TriangleBlock<L>& b, int k, float t_scale, float& tmax, float& tbox,
                                      std::uint32_t& best_prim, Hit<float>& hit) const {
        float t, u, v;
        return Tri::test(pt, b.triangle(k), tmax, t, u, v) && record_hit<AnyHit>(t, u, v, b.prim[k], t_scale, tmax, tbox, best_prim, hit);
    }
};

#if defined(DYNBVH_SSE)

/// The SIMD float filter of tri::watertight on V::n (ray, triangle) pairs, one per lane: each lane
/// holds one vertex's X, Y, Z = vertex - origin (the scalar test's differences: one rounding each) and
/// the ray's shear sx, sy. `rejects` gives the lanes whose edge functions certainly have strictly
/// opposite signs (see the file comment for the bound), which the scalar test misses whatever tmax.
/// Shared by the block test (lanes = triangles) and the packet test (packet.hpp: lanes = rays).
template <class V>
struct WatertightFilter {
    using R = typename V::reg;
    /// One vertex: sheared x, y (the scalar test's operations), P = |x| + |y| and |Z|.
    struct Sheared {
        R x, y, P, Z;
    };
    static DYNBVH_ALWAYS_INLINE Sheared shear(R X, R Y, R Z, R sx, R sy) noexcept {
        Sheared s;
        s.x = V::sub(X, V::mul(sx, Z));
        s.y = V::sub(Y, V::mul(sy, Z));
        s.P = V::add(V::abs(s.x), V::abs(s.y));
        s.Z = V::abs(Z);
        return s;
    }
    /// Lane masks (V::mask) of one step: the pairs certainly missed (two edge functions of certainly
    /// opposite signs), and those whose three edge functions are certainly all positive or all negative
    /// (tri::watertight::test_inside's precondition: the same bound E, the other way round).
    struct Classes {
        typename V::mask reject, pos, neg;
    };
    static DYNBVH_ALWAYS_INLINE Classes classify(const Sheared& a, const Sheared& bb, const Sheared& c) noexcept {
        constexpr float u = std::numeric_limits<float>::epsilon() * 0.5f;
        // FLT_MIN stands for the eta terms (a larger bound is as sound, and no operand is subnormal:
        // a microcode assist on Intel cores, measured 3.2x slower packets on n-body)
        const R tiny = V::set1(std::numeric_limits<float>::min());
        // Step 3: edge functions U (c, b), V (a, c), W (b, a) in float.
        const R fu = V::sub(V::mul(c.x, bb.y), V::mul(c.y, bb.x));
        const R fv = V::sub(V::mul(a.x, c.y), V::mul(a.y, c.x));
        const R fw = V::sub(V::mul(bb.x, a.y), V::mul(bb.y, a.x));
        // Step 4: one bound for all three, E = Pm (4u Pm + 2 Dm) + 2 Dm^2 + FLT_MIN with the shear
        // uncertainty Dm = 5u (Pm + 3 Zm) + FLT_MIN (Pm, Zm: the largest P, |Z|; see the file comment).
        const R pm = V::max(V::max(a.P, bb.P), c.P);
        const R zm = V::max(V::max(a.Z, bb.Z), c.Z);
        const R dm = V::madd(V::set1(5.0f * u), V::madd(V::set1(3.0f), zm, pm), tiny);
        const R dm2 = V::add(dm, dm);
        const R e = V::madd(pm, V::madd(V::set1(4.0f * u), pm, dm2), V::madd(dm2, dm, tiny));
        // Step 5: reject when one edge function is certainly positive and another certainly negative
        // (NaN compares false), below 2^60 (no overflow in f); inside when all three certainly share a sign.
        const R fmax = V::max(V::max(fu, fv), fw), fmin = V::min(V::min(fu, fv), fw), ne = V::neg(e);
        const auto small = V::lt(pm, V::set1(0x1p60f));
        return {V::band(V::band(V::gt(fmax, e), V::lt(fmin, ne)), small), V::band(V::gt(fmin, e), small),
                V::band(V::lt(fmax, ne), small)};
    }
    /// Lane mask (V::mask) of the pairs certainly missed.
    static DYNBVH_ALWAYS_INLINE typename V::mask rejects(const Sheared& a, const Sheared& bb, const Sheared& c) noexcept {
        return classify(a, bb, c).reject;
    }
};

/// tri::watertight on a block: the SIMD float filter, then the scalar test on the lanes it keeps
/// (see the file comment for the exactness argument and the bound).
template <int L>
struct BlockTest<tri::watertight, L> {
    using V = lanes_for<L>;   // L = 8: AVX where compiled in, else two SSE steps
    using R = typename V::reg;
    using prepared = tri::watertight::prepared<float>;
    prepared pt;

    explicit BlockTest(const Ray<float>& r) noexcept : pt(r) {
        kz_ = pt.kz;
        kx_ = (kz_ + 1) % 3;
        ky_ = (kz_ + 2) % 3;
        ox_ = V::set1(pt.org[std::size_t(kx_)]);
        oy_ = V::set1(pt.org[std::size_t(ky_)]);
        oz_ = V::set1(pt.org[std::size_t(kz_)]);
        sx_ = V::set1(pt.sx);
        sy_ = V::set1(pt.sy);
    }

    /// Valid lanes the filter cannot reject (the scalar test misses every other lane, whatever tmax);
    /// `pos` / `neg` get the lanes whose edge functions are certainly all positive / all negative.
    DYNBVH_ALWAYS_INLINE unsigned candidates(const TriangleBlock<L>& b, unsigned& pos, unsigned& neg) const noexcept {
        using F = WatertightFilter<V>;
        unsigned rejected = 0;
        pos = neg = 0;
        for (int h = 0; h < L; h += V::n) {
            // (one call per vertex, not a loop over arrays: GCC keeps such arrays on the stack)
            const auto va = F::shear(V::sub(V::load(&b.v[0][kx_][h]), ox_), V::sub(V::load(&b.v[0][ky_][h]), oy_),
                                     V::sub(V::load(&b.v[0][kz_][h]), oz_), sx_, sy_);
            const auto vb = F::shear(V::sub(V::load(&b.v[1][kx_][h]), ox_), V::sub(V::load(&b.v[1][ky_][h]), oy_),
                                     V::sub(V::load(&b.v[1][kz_][h]), oz_), sx_, sy_);
            const auto vc = F::shear(V::sub(V::load(&b.v[2][kx_][h]), ox_), V::sub(V::load(&b.v[2][ky_][h]), oy_),
                                     V::sub(V::load(&b.v[2][kz_][h]), oz_), sx_, sy_);
            const auto c = F::classify(va, vb, vc);
            rejected |= V::bits(c.reject) << h;
            pos |= V::bits(c.pos) << h;
            neg |= V::bits(c.neg) << h;
        }
        return b.valid_mask() & ~rejected;
    }

    template <bool AnyHit>
    DYNBVH_ALWAYS_INLINE bool test(const TriangleBlock<L>* blocks, std::size_t first, std::size_t end, float t_scale, float& tmax,
                                   float& tbox, std::uint32_t& best_prim, Hit<float>& hit) const {
        for (std::size_t i = first; i < end; ++i) {
            const TriangleBlock<L>& b = blocks[i];
            unsigned pos, neg;
            for (unsigned m = candidates(b, pos, neg); m != 0; m &= m - 1) {
                const int k = std::countr_zero(m);
                float t, u, v;
                // (lanes the filter proved inside skip the scalar test's sign test: the same answer)
                const bool h = ((pos | neg) >> k & 1) ? tri::watertight::test_inside(pt, b.triangle(k), tmax, (pos >> k & 1) != 0, t, u, v)
                                                      : tri::watertight::test(pt, b.triangle(k), tmax, t, u, v);
                if (h && record_hit<AnyHit>(t, u, v, b.prim[k], t_scale, tmax, tbox, best_prim, hit)) return true;
            }
        }
        return false;
    }

private:
    int kx_, ky_, kz_;
    R ox_, oy_, oz_, sx_, sy_;
};

/// tri::moller_trumbore on a block: the scalar test's arithmetic lane by lane (same operations in the
/// same order: cross and dot as in vec.hpp, one division), then tmax and the tie rule in slot order.
template <int L>
struct BlockTest<tri::moller_trumbore, L> {
    using V = lanes_for<L>;   // L = 8: AVX where compiled in, else two SSE steps
    using R = typename V::reg;
    using prepared = tri::moller_trumbore::prepared<float>;
    prepared pt;

    explicit BlockTest(const Ray<float>& r) noexcept
        : pt(r), ox_(V::set1(pt.org.x)), oy_(V::set1(pt.org.y)), oz_(V::set1(pt.org.z)), dx_(V::set1(pt.dir.x)),
          dy_(V::set1(pt.dir.y)), dz_(V::set1(pt.dir.z)), tmin_(V::set1(pt.tmin)) {}

    /// Lanes hit within [tmin, tmax] (each lane on its own, as the scalar test), with t (before the -0
    /// -> +0 step), u, v of every lane written to t[], u[], v[] (64-byte aligned arrays of L).
    DYNBVH_ALWAYS_INLINE unsigned hits(const TriangleBlock<L>& b, float tmax, float* tt, float* uu, float* vv) const noexcept {
        const R zero = V::set1(0.0f), one = V::set1(1.0f), tm = V::set1(tmax);
        unsigned mask = 0;
        for (int h = 0; h < L; h += V::n) {
            const R p0x = V::load(&b.v[0][0][h]), p0y = V::load(&b.v[0][1][h]), p0z = V::load(&b.v[0][2][h]);
            const R e1x = V::sub(V::load(&b.v[1][0][h]), p0x), e1y = V::sub(V::load(&b.v[1][1][h]), p0y),
                    e1z = V::sub(V::load(&b.v[1][2][h]), p0z);
            const R e2x = V::sub(V::load(&b.v[2][0][h]), p0x), e2y = V::sub(V::load(&b.v[2][1][h]), p0y),
                    e2z = V::sub(V::load(&b.v[2][2][h]), p0z);
            // pv = cross(dir, e2); det = dot(e1, pv)
            const R pvx = V::sub(V::mul(dy_, e2z), V::mul(dz_, e2y));
            const R pvy = V::sub(V::mul(dz_, e2x), V::mul(dx_, e2z));
            const R pvz = V::sub(V::mul(dx_, e2y), V::mul(dy_, e2x));
            const R det = V::add(V::add(V::mul(e1x, pvx), V::mul(e1y, pvy)), V::mul(e1z, pvz));
            const R inv = V::div(one, det);
            // tv = org - p0; u = dot(tv, pv) * inv
            const R tvx = V::sub(ox_, p0x), tvy = V::sub(oy_, p0y), tvz = V::sub(oz_, p0z);
            const R u = V::mul(V::add(V::add(V::mul(tvx, pvx), V::mul(tvy, pvy)), V::mul(tvz, pvz)), inv);
            // qv = cross(tv, e1); v = dot(dir, qv) * inv; t = dot(e2, qv) * inv
            const R qx = V::sub(V::mul(tvy, e1z), V::mul(tvz, e1y));
            const R qy = V::sub(V::mul(tvz, e1x), V::mul(tvx, e1z));
            const R qz = V::sub(V::mul(tvx, e1y), V::mul(tvy, e1x));
            const R v = V::mul(V::add(V::add(V::mul(dx_, qx), V::mul(dy_, qy)), V::mul(dz_, qz)), inv);
            const R t = V::mul(V::add(V::add(V::mul(e2x, qx), V::mul(e2y, qy)), V::mul(e2z, qz)), inv);
            // the scalar test's conditions (NaN fails each, as there)
            const R ok = V::band(V::band(V::band(V::ne(det, zero), V::ge(u, zero)), V::band(V::le(u, one), V::ge(v, zero))),
                                 V::band(V::le(V::add(u, v), one), V::band(V::ge(t, tmin_), V::le(t, tm))));
            V::store(tt + h, t);
            V::store(uu + h, u);
            V::store(vv + h, v);
            mask |= V::bits(ok) << h;
        }
        return mask & b.valid_mask();
    }

    template <bool AnyHit>
    DYNBVH_ALWAYS_INLINE bool test(const TriangleBlock<L>* blocks, std::size_t first, std::size_t end, float t_scale, float& tmax,
                                   float& tbox, std::uint32_t& best_prim, Hit<float>& hit) const {
        for (std::size_t i = first; i < end; ++i) {
            const TriangleBlock<L>& b = blocks[i];
            alignas(64) float t[std::size_t(L)], u[std::size_t(L)], v[std::size_t(L)];
            for (unsigned m = hits(b, tmax, t, u, v); m != 0; m &= m - 1) {
                const int k = std::countr_zero(m);
                if (!(t[k] <= tmax)) continue;   // an earlier lane of this block came closer
                // -0 -> +0, as the scalar test
                if (record_hit<AnyHit>(t[k] + 0.0f, u[k], v[k], b.prim[k], t_scale, tmax, tbox, best_prim, hit)) return true;
            }
        }
        return false;
    }

private:
    R ox_, oy_, oz_, dx_, dy_, dz_, tmin_;
};
#endif  // DYNBVH_SSE

} // namespace dynbvh::detail
