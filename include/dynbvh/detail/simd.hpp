// SPDX-License-Identifier: MIT
/// @file detail/simd.hpp
/// Platform macros and the SIMD lane wrappers the traversal uses (internal).
///  - DYNBVH_ALWAYS_INLINE / DYNBVH_NOINLINE: inlining control for the per-box and per-triangle tests.
///  - DYNBVH_SSE: defined when SSE2 intrinsics are used (every x86-64 compiler: `__SSE2__` or MSVC's
///    `_M_X64`), unless DYNBVH_NO_SIMD is defined. DYNBVH_AVX: also `__AVX__` (e.g. -mavx2, -march=native).
///    DYNBVH_AVX512: also `__AVX512F__` (e.g. -march=native on a CPU with AVX-512), unless
///    DYNBVH_NO_AVX512 is defined: packets of 16 rays then take one step per operation (Lanes16).
///    The library does not choose instruction sets: the user's compiler flags do.
///  - detail::Lanes4 (SSE), detail::Lanes8 (AVX), detail::Lanes16 (AVX-512) and detail::lanes_for<W>:
///    the few float operations the wide box tests, the triangle-block tests and the packet traversal
///    need, so one test body serves every lane width.
#pragma once

#include <type_traits>

/// Forces inlining of the per-box and per-triangle tests into traversal loops (they are small, and a
/// call per box costs more than the test).
/// DYNBVH_NOINLINE keeps rarely taken paths out of those loops.
#if defined(__GNUC__) || defined(__clang__)
#if !defined(DYNBVH_ALWAYS_INLINE)
#define DYNBVH_ALWAYS_INLINE inline __attribute__((always_inline))
#endif
#if !defined(DYNBVH_NOINLINE)
#define DYNBVH_NOINLINE __attribute__((noinline))
#endif
#elif defined(_MSC_VER)
#if !defined(DYNBVH_ALWAYS_INLINE)
#define DYNBVH_ALWAYS_INLINE __forceinline
#endif
#if !defined(DYNBVH_NOINLINE)
#define DYNBVH_NOINLINE __declspec(noinline)
#endif
#else
#if !defined(DYNBVH_ALWAYS_INLINE)
#define DYNBVH_ALWAYS_INLINE inline
#endif
#if !defined(DYNBVH_NOINLINE)
#define DYNBVH_NOINLINE
#endif
#endif

#if (defined(__SSE2__) || defined(_M_X64)) && !defined(DYNBVH_NO_SIMD)
#include <immintrin.h>
#define DYNBVH_SSE 1
#if defined(__AVX__)
#define DYNBVH_AVX 1
#endif
#if defined(__AVX512F__) && !defined(DYNBVH_NO_AVX512)
#define DYNBVH_AVX512 1
#endif
#endif

#if defined(DYNBVH_SSE)
namespace dynbvh::detail {

// _mm_max_ps(x, acc) == (x > acc ? x : acc) == max_keep(acc, x), including NaN x and +-0;
// _mm_min_ps(x, acc) == (x < acc ? x : acc) == min_keep(acc, x). The AVX forms behave alike.

/// The SIMD operations the wide box tests use, on four float lanes (SSE).
struct Lanes4 {
    using reg = __m128;
    using mask = reg;   ///< a comparison's result: all bits of a lane set or clear
    static constexpr int n = 4;
    static DYNBVH_ALWAYS_INLINE reg from4(__m128 x) noexcept { return x; }
    static DYNBVH_ALWAYS_INLINE reg set1(float x) noexcept { return _mm_set1_ps(x); }
    static DYNBVH_ALWAYS_INLINE reg load(const float* p) noexcept { return _mm_load_ps(p); }
    static DYNBVH_ALWAYS_INLINE void store(float* p, reg a) noexcept { _mm_storeu_ps(p, a); }
    static DYNBVH_ALWAYS_INLINE reg add(reg a, reg b) noexcept { return _mm_add_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg sub(reg a, reg b) noexcept { return _mm_sub_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg mul(reg a, reg b) noexcept { return _mm_mul_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg min(reg a, reg b) noexcept { return _mm_min_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg max(reg a, reg b) noexcept { return _mm_max_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg abs(reg a) noexcept { return _mm_andnot_ps(_mm_set1_ps(-0.0f), a); }
    /// a * b - c (fused when the compiler targets FMA)
    static DYNBVH_ALWAYS_INLINE reg fmsub(reg a, reg b, reg c) noexcept {
#if defined(__FMA__)
        return _mm_fmsub_ps(a, b, c);
#else
        return _mm_sub_ps(_mm_mul_ps(a, b), c);
#endif
    }
    /// Bit k set when a[k] <= b[k] (false for NaN).
    static DYNBVH_ALWAYS_INLINE unsigned le_mask(reg a, reg b) noexcept { return unsigned(_mm_movemask_ps(_mm_cmple_ps(a, b))); }
    // For the triangle-block tests (detail/triangle_block.hpp):
    static DYNBVH_ALWAYS_INLINE reg div(reg a, reg b) noexcept { return _mm_div_ps(a, b); }
    /// a * b + c, fused when the compiler targets FMA (only where either rounding will do)
    static DYNBVH_ALWAYS_INLINE reg madd(reg a, reg b, reg c) noexcept {
#if defined(__FMA__)
        return _mm_fmadd_ps(a, b, c);
#else
        return _mm_add_ps(_mm_mul_ps(a, b), c);
#endif
    }
    static DYNBVH_ALWAYS_INLINE reg neg(reg a) noexcept { return _mm_xor_ps(_mm_set1_ps(-0.0f), a); }
    static DYNBVH_ALWAYS_INLINE reg band(reg a, reg b) noexcept { return _mm_and_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg bor(reg a, reg b) noexcept { return _mm_or_ps(a, b); }
    /// Lane masks of ordered comparisons (false when either side is NaN); ne is true for NaN.
    static DYNBVH_ALWAYS_INLINE reg gt(reg a, reg b) noexcept { return _mm_cmpgt_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg lt(reg a, reg b) noexcept { return _mm_cmplt_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg ge(reg a, reg b) noexcept { return _mm_cmpge_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg le(reg a, reg b) noexcept { return _mm_cmple_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg ne(reg a, reg b) noexcept { return _mm_cmpneq_ps(a, b); }
    /// Bit k set for each lane k of mask m.
    static DYNBVH_ALWAYS_INLINE unsigned bits(reg m) noexcept { return unsigned(_mm_movemask_ps(m)); }
    /// The inverse of bits: lane k all ones where bit k of b is set, else 0 (in registers: a mask
    /// stored lane by lane and loaded as a vector stalls on store forwarding).
    static DYNBVH_ALWAYS_INLINE reg from_bits(unsigned b) noexcept {
        const __m128i sel = _mm_setr_epi32(1, 2, 4, 8);
        return _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32(int(b)), sel), sel));
    }
};

#if defined(DYNBVH_AVX)
/// The same operations on eight float lanes (AVX), for 8-wide nodes.
struct Lanes8 {
    using reg = __m256;
    using mask = reg;
    static constexpr int n = 8;
    static DYNBVH_ALWAYS_INLINE reg from4(__m128 x) noexcept { return _mm256_insertf128_ps(_mm256_castps128_ps256(x), x, 1); }
    static DYNBVH_ALWAYS_INLINE reg set1(float x) noexcept { return _mm256_set1_ps(x); }
    static DYNBVH_ALWAYS_INLINE reg load(const float* p) noexcept { return _mm256_load_ps(p); }
    static DYNBVH_ALWAYS_INLINE void store(float* p, reg a) noexcept { _mm256_storeu_ps(p, a); }
    static DYNBVH_ALWAYS_INLINE reg add(reg a, reg b) noexcept { return _mm256_add_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg sub(reg a, reg b) noexcept { return _mm256_sub_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg mul(reg a, reg b) noexcept { return _mm256_mul_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg min(reg a, reg b) noexcept { return _mm256_min_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg max(reg a, reg b) noexcept { return _mm256_max_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg abs(reg a) noexcept { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), a); }
    static DYNBVH_ALWAYS_INLINE reg fmsub(reg a, reg b, reg c) noexcept {
#if defined(__FMA__)
        return _mm256_fmsub_ps(a, b, c);
#else
        return _mm256_sub_ps(_mm256_mul_ps(a, b), c);
#endif
    }
    static DYNBVH_ALWAYS_INLINE unsigned le_mask(reg a, reg b) noexcept {
        return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)));
    }
    static DYNBVH_ALWAYS_INLINE reg div(reg a, reg b) noexcept { return _mm256_div_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg madd(reg a, reg b, reg c) noexcept {
#if defined(__FMA__)
        return _mm256_fmadd_ps(a, b, c);
#else
        return _mm256_add_ps(_mm256_mul_ps(a, b), c);
#endif
    }
    static DYNBVH_ALWAYS_INLINE reg neg(reg a) noexcept { return _mm256_xor_ps(_mm256_set1_ps(-0.0f), a); }
    static DYNBVH_ALWAYS_INLINE reg band(reg a, reg b) noexcept { return _mm256_and_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg bor(reg a, reg b) noexcept { return _mm256_or_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg gt(reg a, reg b) noexcept { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
    static DYNBVH_ALWAYS_INLINE reg lt(reg a, reg b) noexcept { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
    static DYNBVH_ALWAYS_INLINE reg ge(reg a, reg b) noexcept { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); }
    static DYNBVH_ALWAYS_INLINE reg le(reg a, reg b) noexcept { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
    static DYNBVH_ALWAYS_INLINE reg ne(reg a, reg b) noexcept { return _mm256_cmp_ps(a, b, _CMP_NEQ_UQ); }
    static DYNBVH_ALWAYS_INLINE unsigned bits(reg m) noexcept { return unsigned(_mm256_movemask_ps(m)); }
    /// The inverse of bits (see Lanes4::from_bits); AVX only: the lane bits become small integers,
    /// converted to float and compared with 0.
    static DYNBVH_ALWAYS_INLINE reg from_bits(unsigned b) noexcept {
        const __m256 sel = _mm256_castsi256_ps(_mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128));
        const __m256 in = _mm256_and_ps(_mm256_castsi256_ps(_mm256_set1_epi32(int(b & 0xffu))), sel);
        return _mm256_cmp_ps(_mm256_cvtepi32_ps(_mm256_castps_si256(in)), _mm256_setzero_ps(), _CMP_NEQ_OQ);
    }
};
/// The widest lanes that divide W: one AVX step per 8-wide node.
template <int W>
using lanes_for = std::conditional_t<W % 8 == 0, Lanes8, Lanes4>;

#if defined(DYNBVH_AVX512)
/// The same operations on sixteen float lanes (AVX-512F), for packets of 16 rays. Comparisons give
/// a lane mask (`mask`, one bit per lane) instead of a register with all bits of a lane set; band,
/// bor, bits and select take either.
struct Lanes16 {
    using reg = __m512;
    using mask = __mmask16;
    static constexpr int n = 16;
    static DYNBVH_ALWAYS_INLINE reg set1(float x) noexcept { return _mm512_set1_ps(x); }
    static DYNBVH_ALWAYS_INLINE reg load(const float* p) noexcept { return _mm512_load_ps(p); }
    static DYNBVH_ALWAYS_INLINE void store(float* p, reg a) noexcept { _mm512_storeu_ps(p, a); }
    static DYNBVH_ALWAYS_INLINE reg add(reg a, reg b) noexcept { return _mm512_add_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg sub(reg a, reg b) noexcept { return _mm512_sub_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg mul(reg a, reg b) noexcept { return _mm512_mul_ps(a, b); }
    // (the zero-masked forms with every lane set: GCC 12's _mm512_min_ps / _mm512_max_ps read an
    // undefined register and trip -Wuninitialized)
    static DYNBVH_ALWAYS_INLINE reg min(reg a, reg b) noexcept { return _mm512_maskz_min_ps(mask(0xffff), a, b); }
    static DYNBVH_ALWAYS_INLINE reg max(reg a, reg b) noexcept { return _mm512_maskz_max_ps(mask(0xffff), a, b); }
    static DYNBVH_ALWAYS_INLINE reg abs(reg a) noexcept {
        return _mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(a), _mm512_set1_epi32(0x7fffffff)));
    }
    static DYNBVH_ALWAYS_INLINE reg neg(reg a) noexcept {
        return _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(a), _mm512_set1_epi32(int(0x80000000u))));
    }
    static DYNBVH_ALWAYS_INLINE reg div(reg a, reg b) noexcept { return _mm512_div_ps(a, b); }
    static DYNBVH_ALWAYS_INLINE reg madd(reg a, reg b, reg c) noexcept { return _mm512_fmadd_ps(a, b, c); }
    static DYNBVH_ALWAYS_INLINE mask gt(reg a, reg b) noexcept { return _mm512_cmp_ps_mask(a, b, _CMP_GT_OQ); }
    static DYNBVH_ALWAYS_INLINE mask lt(reg a, reg b) noexcept { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
    static DYNBVH_ALWAYS_INLINE mask ge(reg a, reg b) noexcept { return _mm512_cmp_ps_mask(a, b, _CMP_GE_OQ); }
    static DYNBVH_ALWAYS_INLINE mask le(reg a, reg b) noexcept { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
    static DYNBVH_ALWAYS_INLINE mask ne(reg a, reg b) noexcept { return _mm512_cmp_ps_mask(a, b, _CMP_NEQ_UQ); }
    static DYNBVH_ALWAYS_INLINE mask band(mask a, mask b) noexcept { return mask(a & b); }
    static DYNBVH_ALWAYS_INLINE mask bor(mask a, mask b) noexcept { return mask(a | b); }
    static DYNBVH_ALWAYS_INLINE unsigned bits(mask m) noexcept { return unsigned(m); }
    /// The sign bits of the lanes (as _mm_movemask_ps).
    static DYNBVH_ALWAYS_INLINE unsigned bits(reg a) noexcept {
        return unsigned(_mm512_cmplt_epi32_mask(_mm512_castps_si512(a), _mm512_setzero_si512()));
    }
    static DYNBVH_ALWAYS_INLINE mask from_bits(unsigned b) noexcept { return mask(b & 0xffffu); }
};
#endif
#else
/// Without AVX, an 8-wide node takes two SSE steps.
template <int W>
using lanes_for = Lanes4;
#endif

} // namespace dynbvh::detail
#endif  // DYNBVH_SSE
