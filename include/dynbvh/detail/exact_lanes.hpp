// SPDX-License-Identifier: MIT
/// @file detail/exact_lanes.hpp
/// tri::watertight::test on several (ray, triangle) pairs at once, one per SIMD lane: the scalar
/// test's operations in the same order (the fused ones fused alike), so each lane's hit or miss and
/// t, u, v are the scalar test's bits. Four lanes with AVX (float steps in SSE, double steps in AVX),
/// eight with AVX-512. Used by the packet traversal (packet.hpp: a packet's rays in the lanes). The
/// block test (detail/triangle_block.hpp) does not use it: on one ray's block, the exact test of every
/// kept lane at once measured slower than the scalar test of the one or two lanes the float filter
/// leaves (BART Robots 0.87x -> 0.83x and kitchen 0.85x -> 0.78x Embree MEDIUM rtcIntersect1).
#pragma once

#include "simd.hpp"

namespace dynbvh::detail {

#if defined(DYNBVH_AVX)
/// The lane forms of intersect.hpp's detail::sub_mul, mul_sub_mul and dot3 (the same roundings, fused
/// where the target has FMA), for the exact lane test below.
DYNBVH_ALWAYS_INLINE __m128 sub_mul(__m128 a, __m128 b, __m128 c) noexcept {
#if defined(__FMA__)
    return _mm_fnmadd_ps(b, c, a);
#else
    return _mm_sub_ps(a, _mm_mul_ps(b, c));
#endif
}
DYNBVH_ALWAYS_INLINE __m256d sub_mul(__m256d a, __m256d b, __m256d c) noexcept {
#if defined(__FMA__)
    return _mm256_fnmadd_pd(b, c, a);
#else
    return _mm256_sub_pd(a, _mm256_mul_pd(b, c));
#endif
}
DYNBVH_ALWAYS_INLINE __m256d mul_sub_mul(__m256d a, __m256d b, __m256d c, __m256d d) noexcept {
#if defined(__FMA__)
    return _mm256_fmsub_pd(a, b, _mm256_mul_pd(c, d));
#else
    return _mm256_sub_pd(_mm256_mul_pd(a, b), _mm256_mul_pd(c, d));
#endif
}
DYNBVH_ALWAYS_INLINE __m256d dot3(__m256d a, __m256d b, __m256d c, __m256d d, __m256d e, __m256d f) noexcept {
#if defined(__FMA__)
    return _mm256_fmadd_pd(a, b, _mm256_fmadd_pd(c, d, _mm256_mul_pd(e, f)));
#else
    return _mm256_add_pd(_mm256_mul_pd(a, b), _mm256_add_pd(_mm256_mul_pd(c, d), _mm256_mul_pd(e, f)));
#endif
}
#endif
#if defined(DYNBVH_AVX512)
/// The eight- and sixteen-lane forms of sub_mul etc., for the eight-lane exact test. (Every
/// AVX-512 target has FMA.)
DYNBVH_ALWAYS_INLINE __m256 sub_mul(__m256 a, __m256 b, __m256 c) noexcept { return _mm256_fnmadd_ps(b, c, a); }
DYNBVH_ALWAYS_INLINE __m512d sub_mul(__m512d a, __m512d b, __m512d c) noexcept { return _mm512_fnmadd_pd(b, c, a); }
DYNBVH_ALWAYS_INLINE __m512d mul_sub_mul(__m512d a, __m512d b, __m512d c, __m512d d) noexcept {
    return _mm512_fmsub_pd(a, b, _mm512_mul_pd(c, d));
}
DYNBVH_ALWAYS_INLINE __m512d dot3(__m512d a, __m512d b, __m512d c, __m512d d, __m512d e, __m512d f) noexcept {
    return _mm512_fmadd_pd(a, b, _mm512_fmadd_pd(c, d, _mm512_mul_pd(e, f)));
}
#endif

#if defined(DYNBVH_AVX)
/// Four lanes of the exact test (exact_lanes): float steps in SSE, double steps in AVX.
struct ExactLanes4 {
    using F = __m128;
    using D = __m256d;
    using M = __m256d;   // a double comparison's lanes
    static DYNBVH_ALWAYS_INLINE D widen(F x) noexcept { return _mm256_cvtps_pd(x); }
    static DYNBVH_ALWAYS_INLINE F narrow(D x) noexcept { return _mm256_cvtpd_ps(x); }
    static DYNBVH_ALWAYS_INLINE F fsub(F a, F b) noexcept { return _mm_sub_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE D set1(double x) noexcept { return _mm256_set1_pd(x); }
    static DYNBVH_ALWAYS_INLINE D add(D a, D b) noexcept { return _mm256_add_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D sub(D a, D b) noexcept { return _mm256_sub_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D mul(D a, D b) noexcept { return _mm256_mul_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D div(D a, D b) noexcept { return _mm256_div_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D absmul(D a, D b) noexcept {
        return _mm256_and_pd(_mm256_mul_pd(a, b), _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL)));
    }
    template <int C>
    static DYNBVH_ALWAYS_INLINE M cmp(D a, D b) noexcept { return _mm256_cmp_pd(a, b, C); }
    static DYNBVH_ALWAYS_INLINE M band(M a, M b) noexcept { return _mm256_and_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE M bor(M a, M b) noexcept { return _mm256_or_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE unsigned bits(M m) noexcept { return unsigned(_mm256_movemask_pd(m)); }
    static DYNBVH_ALWAYS_INLINE D blend(M m, D a, D b) noexcept { return _mm256_blendv_pd(b, a, m); }   // a where m
    static DYNBVH_ALWAYS_INLINE unsigned in_range(F t, F lo, F hi) noexcept {
        return unsigned(_mm_movemask_ps(_mm_and_ps(_mm_cmpge_ps(t, lo), _mm_cmple_ps(t, hi))));
    }
    static DYNBVH_ALWAYS_INLINE void store(float* p, F x) noexcept { _mm_store_ps(p, x); }
    static DYNBVH_ALWAYS_INLINE F plus_zero(F x) noexcept { return _mm_add_ps(x, _mm_setzero_ps()); }
};
#if defined(DYNBVH_AVX512)
/// Eight lanes of the exact test: float steps in AVX, double steps in AVX-512 (zero-masked conversions:
/// see half8).
struct ExactLanes8 {
    using F = __m256;
    using D = __m512d;
    using M = __mmask8;
    static DYNBVH_ALWAYS_INLINE D widen(F x) noexcept { return _mm512_maskz_cvtps_pd(__mmask8(0xff), x); }
    static DYNBVH_ALWAYS_INLINE F narrow(D x) noexcept { return _mm512_maskz_cvtpd_ps(__mmask8(0xff), x); }
    static DYNBVH_ALWAYS_INLINE F fsub(F a, F b) noexcept { return _mm256_sub_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE D set1(double x) noexcept { return _mm512_set1_pd(x); }
    static DYNBVH_ALWAYS_INLINE D add(D a, D b) noexcept { return _mm512_add_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D sub(D a, D b) noexcept { return _mm512_sub_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D mul(D a, D b) noexcept { return _mm512_mul_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D div(D a, D b) noexcept { return _mm512_div_pd(a, b); }
    static DYNBVH_ALWAYS_INLINE D absmul(D a, D b) noexcept {
        return _mm512_castsi512_pd(_mm512_and_si512(_mm512_castpd_si512(_mm512_mul_pd(a, b)), _mm512_set1_epi64(0x7fffffffffffffffLL)));
    }
    template <int C>
    static DYNBVH_ALWAYS_INLINE M cmp(D a, D b) noexcept { return _mm512_cmp_pd_mask(a, b, C); }
    static DYNBVH_ALWAYS_INLINE M band(M a, M b) noexcept { return M(a & b); }
    static DYNBVH_ALWAYS_INLINE M bor(M a, M b) noexcept { return M(a | b); }
    static DYNBVH_ALWAYS_INLINE unsigned bits(M m) noexcept { return unsigned(m); }
    static DYNBVH_ALWAYS_INLINE D blend(M m, D a, D b) noexcept { return _mm512_mask_blend_pd(m, b, a); }   // a where m
    static DYNBVH_ALWAYS_INLINE unsigned in_range(F t, F lo, F hi) noexcept {
        return unsigned(_mm256_movemask_ps(_mm256_and_ps(_mm256_cmp_ps(t, lo, _CMP_GE_OQ), _mm256_cmp_ps(t, hi, _CMP_LE_OQ))));
    }
    static DYNBVH_ALWAYS_INLINE void store(float* p, F x) noexcept { _mm256_store_ps(p, x); }
    static DYNBVH_ALWAYS_INLINE F plus_zero(F x) noexcept { return _mm256_add_ps(x, _mm256_setzero_ps()); }
};
#endif

/// tri::watertight::test on the lanes of E at once: lane j's ray has origin (OX, OY, OZ) along kx, ky,
/// kz, shear SX, SY (float) and SXD, SYD, 1 / dir[kz] RCPD (double), interval [TMIN, TMAX], and its
/// triangle the vertices (px[i], py[i], pz[i]) along kx, ky, kz. The scalar test's operations in the same
/// order (the fused ones fused alike, sub_mul etc.), so each lane's hit or miss and t, u, v are the
/// scalar test's bits. Bit j of the result: lane j hits within [TMIN, TMAX]; its t, u, v are in t[j],
/// u[j], v[j] (arrays of E's lanes, aligned to them).
template <class E, class F = typename E::F, class D = typename E::D>
DYNBVH_ALWAYS_INLINE unsigned exact_lanes(const F (&px)[3], const F (&py)[3], const F (&pz)[3], F OX, F OY, F OZ, F SX, F SY, D SXD, D SYD,
                                          D RCPD, F TMIN, F TMAX, float* t, float* u, float* v) noexcept {
    // float: vertex - origin, sheared (tri::watertight's test_axes), in double
    D xf[3], yf[3];
    for (int i = 0; i < 3; ++i) {
        const F VZ = E::fsub(pz[i], OZ);
        xf[i] = E::widen(sub_mul(E::fsub(px[i], OX), SX, VZ));
        yf[i] = E::widen(sub_mul(E::fsub(py[i], OY), SY, VZ));
    }
    // double edge functions of the float vertices (exact products), the sign decision
    const D eu = E::sub(E::mul(xf[2], yf[1]), E::mul(yf[2], xf[1]));
    const D ev = E::sub(E::mul(xf[0], yf[2]), E::mul(yf[0], xf[2]));
    const D ew = E::sub(E::mul(xf[1], yf[0]), E::mul(yf[1], xf[0]));
    const D zero = E::set1(0.0);
    const auto pos = E::band(E::band(E::template cmp<_CMP_GE_OQ>(eu, zero), E::template cmp<_CMP_GE_OQ>(ev, zero)),
                             E::template cmp<_CMP_GE_OQ>(ew, zero));
    const auto neg = E::band(E::band(E::template cmp<_CMP_LE_OQ>(eu, zero), E::template cmp<_CMP_LE_OQ>(ev, zero)),
                             E::template cmp<_CMP_LE_OQ>(ew, zero));
    const D det = E::add(E::add(eu, ev), ew);
    const auto ok = E::band(E::bor(pos, neg), E::template cmp<_CMP_NEQ_OQ>(det, zero));
    if (E::bits(ok) == 0) return 0;
    // finish: the accurate evaluation in double (tri::watertight::finish)
    const D one = E::set1(1.0);
    const D sg = E::blend(E::template cmp<_CMP_GT_OQ>(det, zero), one, E::set1(-1.0));
    const D DX = E::widen(OX), DY = E::widen(OY), DZ = E::widen(OZ);
    D xd[3], yd[3], zd[3];
    for (int i = 0; i < 3; ++i) {
        zd[i] = E::sub(E::widen(pz[i]), DZ);
        xd[i] = sub_mul(E::sub(E::widen(px[i]), DX), SXD, zd[i]);
        yd[i] = sub_mul(E::sub(E::widen(py[i]), DY), SYD, zd[i]);
    }
    D w0 = E::mul(sg, mul_sub_mul(xd[2], yd[1], yd[2], xd[1]));
    D w1 = E::mul(sg, mul_sub_mul(xd[0], yd[2], yd[0], xd[2]));
    D w2 = E::mul(sg, mul_sub_mul(xd[1], yd[0], yd[1], xd[0]));
    D sum = E::add(E::add(w0, w1), w2);
    D nsum = E::add(E::absmul(xd[2], yd[1]), E::absmul(yd[2], xd[1]));
    nsum = E::add(nsum, E::absmul(xd[0], yd[2]));
    nsum = E::add(nsum, E::absmul(yd[0], xd[2]));
    nsum = E::add(nsum, E::absmul(xd[1], yd[0]));
    nsum = E::add(nsum, E::absmul(yd[1], xd[0]));
    const D noise = E::mul(E::set1(0x1p-48), nsum);
    const auto good = E::band(E::band(E::template cmp<_CMP_GE_OQ>(w0, zero), E::template cmp<_CMP_GE_OQ>(w1, zero)),
                              E::band(E::template cmp<_CMP_GE_OQ>(w2, zero), E::template cmp<_CMP_GT_OQ>(sum, noise)));
    // where the accurate weights are not trusted: the decision's own
    w0 = E::blend(good, w0, E::mul(sg, eu));
    w1 = E::blend(good, w1, E::mul(sg, ev));
    w2 = E::blend(good, w2, E::mul(sg, ew));
    sum = E::blend(good, sum, E::mul(sg, det));
    const D inv = E::div(one, sum);
    const D num = dot3(w0, zd[0], w1, zd[1], w2, zd[2]);
    const F tt = E::narrow(E::mul(E::mul(num, RCPD), inv));
    const unsigned in = E::in_range(tt, TMIN, TMAX);
    E::store(t, E::plus_zero(tt));   // -0 -> +0
    E::store(u, E::narrow(E::mul(w1, inv)));
    E::store(v, E::narrow(E::mul(w2, inv)));
    return in & E::bits(ok);
}
#endif

} // namespace dynbvh::detail
