// SPDX-License-Identifier: MIT
/// @file intersect.hpp
/// Ray-box and ray-triangle tests as compile-time policies.
///
/// Every policy has the same two-step shape: a per-ray precomputation
/// `Policy::prepared<T> p(ray)` (done once per ray) and a static `Policy::test(p, ...)`
/// (done once per box or triangle; box policies also offer `test_octant<Oct>`, the same test with
/// the ray's direction signs known at compile time). Traversal (traverse.hpp) bundles one box and
/// one triangle policy; the defaults are the robust ones. One-off queries: `intersect_triangle`,
/// `intersect_box` (end of this file).
///
///  - box::robust (default)        Ize 2013, "Robust BVH Ray Traversal": no hit is lost to rounding.
///  - box::fast                    plain slab test with a precomputed inverse direction.
///  - tri::watertight (default)    Woop, Benthin, Wald 2013, "Watertight Ray/Triangle Intersection":
///                                 a ray through a shared edge or vertex never passes between triangles.
///  - tri::moller_trumbore         Möller & Trumbore 1997, fast, not watertight.
///
/// Limits (README "Robustness", tests/test_robust_limits.cpp):
///  - tri::watertight forms vertex - origin in float: a closed solid thinner than about
///    |origin - object| / 3e7 (half a float ulp of the distance) can be missed; solids at least
///    max(|origin - object|, |object|) / 1e6 thick are hit through their middle. Use double, or an origin
///    near the object, beyond that.
///  - tri::moller_trumbore misses when det = 2 area |dir| cos < 1/FLT_MAX ~ 3e-39 (1/det overflows): with
///    unit directions, triangles with edges below ~5e-20 (slivers sooner). Edges of 1e-18 seen within
///    70 degrees of the normal are hit.
///
/// All tests treat NaN as "no hit" (comparisons are written so that NaN fails them) and are free of UB
/// for any input. A prepared ray of a ray that is not `traceable` (NaN or infinite origin or direction,
/// zero direction, NaN or empty [tmin, tmax]) misses everything; traversal also rejects such rays up front.
/// Scalars: float or double (the scalar of the BVH's nodes).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#include "detail/simd.hpp"
#include "ray.hpp"
#include "triangle.hpp"


namespace dynbvh {

/// Higham's gamma(n) = n u / (1 - n u), u the unit roundoff of T: a bound on the relative error of n
/// chained roundings.
template <class T>
constexpr T rounding_gamma(int n) noexcept {
    constexpr T u = std::numeric_limits<T>::epsilon() * T(0.5);
    return (T(n) * u) / (T(1) - T(n) * u);
}

/// True when a ray can be traced at all: finite origin and direction, a non-zero direction and an
/// interval [tmin, tmax] that is not NaN and not empty (tmin == tmax is allowed; tmax may be +inf).
/// Traversal returns "no hit" for any other ray.
template <class T>
inline bool traceable(const Ray<T>& r) noexcept {
    return is_finite(r.org) && is_finite(r.dir) && (r.dir.x != T(0) || r.dir.y != T(0) || r.dir.z != T(0)) &&
           r.tmin <= r.tmax;  // false when either is NaN
}

namespace detail {
// max/min that ignore a NaN second operand `x` (0 * inf in a slab test when the origin lies exactly on
// a slab plane of an axis the ray is parallel to: such a ray is inside that slab, so the axis must not
// constrain the interval). `acc` starts as tmin / tmax; it is NaN only for the prepared copy of a ray
// that is not traceable, and then stays NaN, so the test fails.
template <class T> inline T max_keep(T acc, T x) noexcept { return acc < x ? x : acc; }
template <class T> inline T min_keep(T acc, T x) noexcept { return x < acc ? x : acc; }

/// The tmin a prepared ray stores: NaN for a ray that is not traceable, which makes every box and
/// triangle test of that prepared ray fail (NaN compares false), so policies are safe on their own too.
template <class T>
inline T prepared_tmin(const Ray<T>& r) noexcept {
    return traceable(r) ? r.tmin : std::numeric_limits<T>::quiet_NaN();
}

/// Calls f(std::integral_constant<int, oct>{}) for the run-time octant 0..7 (one compiled copy each).
template <class F>
DYNBVH_ALWAYS_INLINE decltype(auto) dispatch_octant(int octant, F&& f) {
    switch (octant & 7) {
    case 0: return f(std::integral_constant<int, 0>{});
    case 1: return f(std::integral_constant<int, 1>{});
    case 2: return f(std::integral_constant<int, 2>{});
    case 3: return f(std::integral_constant<int, 3>{});
    case 4: return f(std::integral_constant<int, 4>{});
    case 5: return f(std::integral_constant<int, 5>{});
    case 6: return f(std::integral_constant<int, 6>{});
    default: return f(std::integral_constant<int, 7>{});
    }
}

/// The power of two 2^k by which box tests scale a ray's direction so that 1 / dir[a] stays finite for
/// every non-zero component: k = 0 (no scaling) unless some |dir[a]| is so small (below about 2^-126
/// for float, a subnormal) that its reciprocal would overflow to infinity and the axis would be taken
/// as parallel. k is limited so that the largest component does not overflow. Scaling by a power of
/// two is exact, so box distances are the ray's t times 2^-k (exact while that product is normal).
template <class T>
inline int direction_scale_exponent(const Vec3<T>& dir) noexcept {
    const T ax = std::abs(dir.x), ay = std::abs(dir.y), az = std::abs(dir.z);
    constexpr T smallest = std::numeric_limits<T>::min();
    // the common case, without a libm call: no component in (0, smallest)
    if (!((ax > T(0) && ax < smallest) || (ay > T(0) && ay < smallest) || (az > T(0) && az < smallest))) return 0;
    constexpr int lowest = std::numeric_limits<T>::min_exponent - 1;  // ilogb of the smallest normal
    constexpr int highest = std::numeric_limits<T>::max_exponent - 2;  // keeps 1 / dir above the smallest normal
    int lo = std::numeric_limits<int>::max(), hi = std::numeric_limits<int>::min();
    for (const T d : {ax, ay, az}) {
        if (d == T(0) || !std::isfinite(d)) continue;
        const int e = std::ilogb(d);
        lo = std::min(lo, e);
        hi = std::max(hi, e);
    }
    return std::max(0, std::min(lowest - lo, highest - hi));
}

/// The tie rule of every closest-hit query (binary, wide, block leaves, packets, brute force): a hit of
/// triangle `prim` at t <= tmax (the closest so far, of triangle `best`, or invalid_prim for none)
/// replaces it when it is strictly closer, or at exactly the same t when its index is larger. So the
/// answer is the hit of smallest t and, among those, of largest index, whatever the visit order
/// (brute force in input order gives the same). invalid_prim + 1 wraps to 0: any prim beats "none".
DYNBVH_ALWAYS_INLINE constexpr bool replaces_hit(auto t, auto tmax, std::uint32_t prim, std::uint32_t best) noexcept {
    return t < tmax || prim + 1u > best + 1u;
}

/// A leaf test's hit (t, u, v) of triangle `prim`, recorded as every leaf loop records it (the scalar
/// leaves, the block tests): an any-hit query takes it and stops (true); a closest-hit query keeps it
/// when it replaces the best so far (replaces_hit), narrowing tmax and tbox = tmax * t_scale, and goes
/// on (false).
template <bool AnyHit, class T>
DYNBVH_ALWAYS_INLINE bool record_hit(T t, T u, T v, std::uint32_t prim, T t_scale, T& tmax, T& tbox, std::uint32_t& best_prim,
                                     Hit<T>& hit) noexcept {
    if constexpr (!AnyHit)
        if (!replaces_hit(t, tmax, prim, best_prim)) return false;   // an exact tie with a larger index
    hit.t = t;
    hit.u = u;
    hit.v = v;
    if constexpr (AnyHit) {
        hit.prim = prim;
        return true;
    } else {
        tmax = t;
        tbox = t * t_scale;
        best_prim = prim;
        return false;
    }
}

template <class T>
inline void check_scalar() noexcept {
    static_assert(std::is_same_v<T, float> || std::is_same_v<T, double>, "dynbvh: scalar must be float or double");
}
/// The watertight test's products and sums with the roundings spelled out: fused (one rounding) where
/// the target has FMA, plain otherwise, so that no compiler's contraction choice (-ffp-contract) can
/// change them, and the packet traversal's SIMD exact test (packet.hpp) gives the same bits.
/// a - b * c
template <class T>
DYNBVH_ALWAYS_INLINE T sub_mul(T a, T b, T c) noexcept {
#if defined(__FMA__)
    return std::fma(-b, c, a);
#else
    return a - b * c;
#endif
}
/// a * b - c * d (c * d rounded first)
template <class T>
DYNBVH_ALWAYS_INLINE T mul_sub_mul(T a, T b, T c, T d) noexcept {
#if defined(__FMA__)
    return std::fma(a, b, -(c * d));
#else
    return a * b - c * d;
#endif
}
/// a * b + (c * d + e * f) (e * f rounded first)
template <class T>
DYNBVH_ALWAYS_INLINE T dot3(T a, T b, T c, T d, T e, T f) noexcept {
#if defined(__FMA__)
    return std::fma(a, b, std::fma(c, d, e * f));
#else
    return a * b + (c * d + e * f);
#endif
}

} // namespace detail

namespace box {

/// Ize 2013 robust slab test. The exit distance (the smaller of the slabs' exits and the ray's tmax)
/// is enlarged by 2 gamma(3) of its magnitude, which covers the three roundings of
/// (plane - org) * (1 / dir) on both the entry and the exit side: a box the exact ray touches
/// within [tmin, tmax] is never reported as missed. Direction components +0 and -0 give an
/// inverse of +inf / -inf with the right sign; an origin lying exactly on a slab plane of such an
/// axis counts as inside (boxes are closed). Cost over box::fast: one subtraction per slab
/// (instead of a multiply-add) and three operations per box for the margin.
///
/// Interface shared by every box policy: `prepared<T>(ray)`; `test(p, lo, hi, tmax, tentry)`;
/// `test_octant<Oct>(p, ...)`, the same with the ray's direction octant (`p.octant`, bit a set when
/// dir[a] has its sign bit set) known at compile time, which traversal uses; `before(tentry, tmax)`.
/// `test` takes and gives distances in the ray's t; `test_octant` and `before` work in box units,
/// t * `p.t_scale`, where t_scale = 2^-k is 1 except for rays with a component so small that its
/// reciprocal would overflow (see detail::direction_scale_exponent): traversal converts tmax once per
/// hit, not once per box.
struct robust {
    /// The ray's constants for this test, computed once per ray.
    template <class T>
    struct prepared {
        Vec3<T> org;       ///< ray origin
        Vec3<T> inv;       ///< 1 / (dir 2^k), correctly rounded (+-inf for +-0)
        T tmin;            ///< ray.tmin * t_scale (NaN for a ray that is not traceable: then nothing is hit)
        T t_scale = 1;     ///< 2^-k: box distances are the ray's t times this (1 for all but subnormal directions)
        int octant = 0;    ///< bit a set when dir[a] has its sign bit set (so -0 counts as negative)

        /// Prepares `r`: reciprocal direction (scaled for subnormal components), octant, tmin.
        explicit prepared(const Ray<T>& r) noexcept : org(r.org), tmin(detail::prepared_tmin(r)) {
            detail::check_scalar<T>();
            const int k = detail::direction_scale_exponent(r.dir);
            if (k != 0) [[unlikely]] {  // (ldexp is a libm call: kept off the common path)
                t_scale = std::ldexp(T(1), -k);
                tmin *= t_scale;
            }
            for (std::size_t a = 0; a < 3; ++a) {
                inv[a] = T(1) / (k != 0 ? std::ldexp(r.dir[a], k) : r.dir[a]);  // IEEE: 1/+0 = +inf, 1/-0 = -inf
                octant |= std::signbit(r.dir[a]) ? 1 << a : 0;
            }
        }
    };

    /// The conservative exit bound: x + 2 gamma(3) |x| (the abs form also stays conservative for
    /// negative distances, i.e. tmin < 0).
    template <class T>
    static DYNBVH_ALWAYS_INLINE T widen(T x) noexcept {
        constexpr T k = T(2) * rounding_gamma<T>(3);
        return x + k * std::abs(x);
    }

    /// True when the ray hits box [lo, hi] within [p.tmin, tmax]; `tentry` receives the entry distance
    /// (>= p.tmin). Never reports a miss for a box the exact ray touches. `Oct` must be `p.octant`.
    template <int Oct, class T>
    static DYNBVH_ALWAYS_INLINE bool test_octant(const prepared<T>& p, const Vec3<T>& lo, const Vec3<T>& hi, T tmax,
                                                 T& tentry) noexcept {
        const T x0 = ((Oct & 1 ? hi.x : lo.x) - p.org.x) * p.inv.x;
        const T x1 = ((Oct & 1 ? lo.x : hi.x) - p.org.x) * p.inv.x;
        const T y0 = ((Oct & 2 ? hi.y : lo.y) - p.org.y) * p.inv.y;
        const T y1 = ((Oct & 2 ? lo.y : hi.y) - p.org.y) * p.inv.y;
        const T z0 = ((Oct & 4 ? hi.z : lo.z) - p.org.z) * p.inv.z;
        const T z1 = ((Oct & 4 ? lo.z : hi.z) - p.org.z) * p.inv.z;
        const T tn = detail::max_keep(detail::max_keep(detail::max_keep(p.tmin, x0), y0), z0);
        const T tf = widen(detail::min_keep(detail::min_keep(detail::min_keep(tmax, x1), y1), z1));
        tentry = tn;
        return tn <= tf;  // tf is NaN (a miss) only for -inf exits: the ray is parallel to and outside a slab
    }

    /// `test_octant` with the octant read at run time, `tmax` and `tentry` in the ray's t.
    template <class T>
    static bool test(const prepared<T>& p, const Vec3<T>& lo, const Vec3<T>& hi, T tmax, T& tentry) noexcept {
        const bool h = detail::dispatch_octant(
            p.octant, [&](auto oct) { return test_octant<decltype(oct)::value>(p, lo, hi, tmax * p.t_scale, tentry); });
        tentry /= p.t_scale;
        return h;
    }

    /// Whether a box entered at `tentry` can still hold a hit closer than `tmax` (used to skip stale
    /// stack entries; never stricter than `test`).
    template <class T>
    static DYNBVH_ALWAYS_INLINE bool before(T tentry, T tmax) noexcept { return tentry <= widen(tmax); }
};

/// Plain slab test with precomputed inverse direction and origin * inverse (one multiply-add per
/// slab). May report a miss for a box the ray only grazes within rounding error, so a triangle lying
/// in a box face or hit exactly at a vertex can be lost. Direction components smaller than 1e-30
/// (float) / 1e-300 (double) in magnitude, zeros included, are replaced by +-1e-30 / +-1e-300 with
/// their sign, so no NaN arises from 0 * inf (rays in scenes smaller than that need box::robust); a ray parallel
/// to an axis and lying exactly in the box's max face on that axis (with +0) or min face (with -0)
/// therefore counts as leaving the box. Use box::robust where that matters. Same interface as robust.
struct fast {
    /// The ray's constants for this test, computed once per ray.
    template <class T>
    struct prepared {
        Vec3<T> inv;       ///< 1 / dir (tiny components replaced, see above)
        Vec3<T> org_inv;   ///< org * inv
        /// ray.tmin (NaN for a ray that is not traceable: then nothing is hit)
        T tmin;
        static constexpr T t_scale = 1;  ///< never scaled (see box::robust): tiny components are replaced instead
        /// bit a set when dir[a] has its sign bit set
        int octant = 0;

        /// Prepares `r`: reciprocal direction (tiny components replaced), org * inv, octant, tmin.
        explicit prepared(const Ray<T>& r) noexcept : tmin(detail::prepared_tmin(r)) {
            detail::check_scalar<T>();
            constexpr T tiny = std::is_same_v<T, float> ? T(1e-30) : T(1e-300);
            for (std::size_t a = 0; a < 3; ++a) {
                const T d = std::abs(r.dir[a]) < tiny ? std::copysign(tiny, r.dir[a]) : r.dir[a];
                inv[a] = T(1) / d;
                org_inv[a] = r.org[a] * inv[a];
                octant |= std::signbit(r.dir[a]) ? 1 << a : 0;
            }
        }
    };

    /// As box::robust::test_octant, without the margin: may report a miss for a box the ray only grazes.
    template <int Oct, class T>
    static DYNBVH_ALWAYS_INLINE bool test_octant(const prepared<T>& p, const Vec3<T>& lo, const Vec3<T>& hi, T tmax,
                                                 T& tentry) noexcept {
        const T x0 = (Oct & 1 ? hi.x : lo.x) * p.inv.x - p.org_inv.x;
        const T x1 = (Oct & 1 ? lo.x : hi.x) * p.inv.x - p.org_inv.x;
        const T y0 = (Oct & 2 ? hi.y : lo.y) * p.inv.y - p.org_inv.y;
        const T y1 = (Oct & 2 ? lo.y : hi.y) * p.inv.y - p.org_inv.y;
        const T z0 = (Oct & 4 ? hi.z : lo.z) * p.inv.z - p.org_inv.z;
        const T z1 = (Oct & 4 ? lo.z : hi.z) * p.inv.z - p.org_inv.z;
        const T tn = detail::max_keep(detail::max_keep(detail::max_keep(p.tmin, x0), y0), z0);
        const T tf = detail::min_keep(detail::min_keep(detail::min_keep(tmax, x1), y1), z1);
        tentry = tn;
        return tn <= tf;
    }

    /// `test_octant` with the octant read at run time.
    template <class T>
    static bool test(const prepared<T>& p, const Vec3<T>& lo, const Vec3<T>& hi, T tmax, T& tentry) noexcept {
        return detail::dispatch_octant(p.octant, [&](auto oct) { return test_octant<decltype(oct)::value>(p, lo, hi, tmax, tentry); });
    }

    /// Whether a box entered at `tentry` can still hold a hit closer than `tmax`.
    template <class T>
    static DYNBVH_ALWAYS_INLINE bool before(T tentry, T tmax) noexcept { return tentry <= tmax; }
};

} // namespace box

namespace tri {

/// Woop, Benthin, Wald 2013 watertight test. The triangle is translated to the ray origin and sheared
/// so that the ray runs along the kz axis (kz = axis of largest |dir|); then the 2D edge functions
/// U, V, W decide the hit by their signs alone. Signs are exact: for float the edge functions are
/// evaluated in double (products of floats are exact in double, so the sign is exact and no FMA
/// contraction can change it); for double they are evaluated plainly and re-evaluated with an
/// error-free difference of products (std::fma) when one is exactly 0 (always, when the target has
/// FMA, because contraction could break the exact negation of a shared edge's function). Because each
/// vertex is transformed the same way in every triangle that shares it, neighbouring triangles agree
/// on which side of their shared edge the ray passes: on a closed mesh no ray escapes through an edge
/// or a vertex. Front and back faces both hit (so the paper's kx/ky swap for dir[kz] < 0, which only
/// keeps the winding for culling, is left out); edge-on triangles (U + V + W == 0) miss. t, u, v of a
/// hit come from a second, accurate evaluation in double (see the code); a hit at t = -0 is reported
/// as +0. The shear and that evaluation spell out their fused operations (detail::sub_mul, mul_sub_mul,
/// dot3: fused where the target has FMA), so their bits do not depend on the compiler's contraction
/// choice and the packet traversal's SIMD copy of the test (packet.hpp) gives the same ones.
/// Output: t, and (u, v) with p = (1-u-v) p0 + u p1 + v p2 (the Hit convention).
/// Limit: vertex - origin is rounded to float before the signs are taken, so a closed solid thinner than
/// about |origin - object| / 3e7 can be missed as a whole (watertightness holds between its triangles,
/// but the rounded solid may have no area along the ray); see the file comment for the guaranteed side.
///
/// Interface shared by every triangle policy: `prepared<T>(ray)`; `test(p, tri, tmax, t, u, v)`,
/// true for a hit with t in [ray.tmin, tmax] (t, u, v written only then).
struct watertight {
    /// The ray's constants for this test, computed once per ray.
    template <class T>
    struct prepared {
        /// ray origin
        Vec3<T> org;
        int kz = 2;                   ///< axis of the largest |dir| (kx = kz + 1, ky = kz + 2, mod 3)
        /// shear dir[kx] / dir[kz] (sy: dir[ky] / dir[kz])
        T sx = 0, sy = 0;             ///< shear dir[kx] / dir[kz], dir[ky] / dir[kz]
        T tmin;                       ///< NaN for a ray that is not traceable: then nothing is hit
        Vec3d org_d;                  ///< origin in double, for t, u, v
        /// shear in double (sx)
        double sx_d = 0, sy_d = 0;    ///< shear in double
        double rcp_dz = 1;            ///< 1 / dir[kz] in double

        /// Prepares `r`: dominant axis and shear (one division per ray).
        explicit prepared(const Ray<T>& r) noexcept : org(r.org), tmin(detail::prepared_tmin(r)), org_d(r.org) {
            detail::check_scalar<T>();
            const Vec3<T> a{std::abs(r.dir.x), std::abs(r.dir.y), std::abs(r.dir.z)};
            kz = largest_axis(a);
            const std::size_t z = std::size_t(kz), x = (z + 1) % 3, y = (z + 2) % 3;
            // One division per ray. The shear need not be correctly rounded: watertightness only needs
            // every triangle of this ray to use the same values.
            rcp_dz = 1.0 / double(r.dir[z]);
            sx_d = double(r.dir[x]) * rcp_dz;
            sy_d = double(r.dir[y]) * rcp_dz;
            sx = T(sx_d);
            sy = T(sy_d);
        }
        /// The same for a traceable ray `r` whose dominant axis `axis` and double reciprocal and shears
        /// (1.0 / double(dir[kz]), double(dir[kx]) * rcp, double(dir[ky]) * rcp) were computed elsewhere
        /// with those operations (the packet traversal's SIMD set-up): the same members, bit for bit.
        prepared(const Ray<T>& r, int axis, double rcp, double sxd, double syd) noexcept
            : org(r.org), kz(axis), sx(T(sxd)), sy(T(syd)), tmin(r.tmin), org_d(r.org), sx_d(sxd), sy_d(syd), rcp_dz(rcp) {
            detail::check_scalar<T>();
        }
    };

    /// Left to the compiler to inline: traversal calls it once per leaf triangle, and one copy per
    /// octant-specialised traversal loop would cost more in code size than the call does.
    template <class T>
    static bool test(const prepared<T>& p, const Triangle<T>& tri, T tmax, T& t, T& u, T& v) noexcept {
        switch (p.kz) {
        case 0: return test_axes<1, 2, 0>(p, tri, tmax, t, u, v);
        case 1: return test_axes<2, 0, 1>(p, tri, tmax, t, u, v);
        default: return test_axes<0, 1, 2>(p, tri, tmax, t, u, v);
        }
    }

    /// What test() returns, bit for bit, for a ray and triangle whose three edge functions (test()'s
    /// sign test) are known to be non-zero and all positive (`positive`) or all negative: the SIMD
    /// filter proves this for most hits (detail/triangle_block.hpp), and the sign test is then skipped.
    /// t, u, v come from the accurate evaluation as in test(); where it falls back to the decision's
    /// own weights (a hair outside an edge), those are computed as test() computes them.
    template <class T>
    static bool test_inside(const prepared<T>& p, const Triangle<T>& tri, T tmax, bool positive, T& t, T& u, T& v) noexcept {
        switch (p.kz) {
        case 0: return finish<1, 2, 0>(p, tri, tmax, nullptr, positive ? 1.0 : -1.0, t, u, v);
        case 1: return finish<2, 0, 1>(p, tri, tmax, nullptr, positive ? 1.0 : -1.0, t, u, v);
        default: return finish<0, 1, 2>(p, tri, tmax, nullptr, positive ? 1.0 : -1.0, t, u, v);
        }
    }

private:
    /// The edge functions U, V, W of the sign test (eu, ev, ew) and their sum.
    struct Edges {
        double eu, ev, ew, det;
    };

    template <std::size_t KX, std::size_t KY, std::size_t KZ, class T>
    static DYNBVH_ALWAYS_INLINE Edges edges(const prepared<T>& p, const Triangle<T>& tri) noexcept {
        using W = double;  // edge-function precision: exact signs for float, see the class comment
        const Vec3<T> A = tri.p0 - p.org, B = tri.p1 - p.org, C = tri.p2 - p.org;
        using detail::sub_mul;
        const T ax = sub_mul(A[KX], p.sx, A[KZ]), ay = sub_mul(A[KY], p.sy, A[KZ]);
        const T bx = sub_mul(B[KX], p.sx, B[KZ]), by = sub_mul(B[KY], p.sy, B[KZ]);
        const T cx = sub_mul(C[KX], p.sx, C[KZ]), cy = sub_mul(C[KY], p.sy, C[KZ]);

        W eu, ev, ew;
        if constexpr (std::is_same_v<T, float>) {
            eu = W(cx) * W(by) - W(cy) * W(bx);
            ev = W(ax) * W(cy) - W(ay) * W(cx);
            ew = W(bx) * W(ay) - W(by) * W(ax);
        } else {
#if defined(__FMA__) || defined(FP_FAST_FMA)
            eu = diff_of_products(cx, by, cy, bx);
            ev = diff_of_products(ax, cy, ay, cx);
            ew = diff_of_products(bx, ay, by, ax);
#else
            eu = cx * by - cy * bx;
            ev = ax * cy - ay * cx;
            ew = bx * ay - by * ax;
            if (eu == 0 || ev == 0 || ew == 0) [[unlikely]] {
                eu = diff_of_products(cx, by, cy, bx);
                ev = diff_of_products(ax, cy, ay, cx);
                ew = diff_of_products(bx, ay, by, ax);
            }
#endif
        }
        return {eu, ev, ew, eu + ev + ew};
    }

    template <std::size_t KX, std::size_t KY, std::size_t KZ, class T>
    static DYNBVH_ALWAYS_INLINE bool test_axes(const prepared<T>& p, const Triangle<T>& tri, T tmax, T& t, T& u, T& v) noexcept {
        const Edges e = edges<KX, KY, KZ>(p, tri);
        // Both windings hit; a NaN fails both alternatives. Bitwise & and | (one branch instead of six
        // hard-to-predict ones).
        const bool inside_pos = (e.eu >= 0) & (e.ev >= 0) & (e.ew >= 0);
        const bool inside_neg = (e.eu <= 0) & (e.ev <= 0) & (e.ew <= 0);
        if (!(inside_pos | inside_neg)) return false;
        if (e.det == 0) return false;
        return finish<KX, KY, KZ>(p, tri, tmax, &e, e.det > 0 ? 1.0 : -1.0, t, u, v);
    }

    // t, u, v from a second, accurate evaluation in double (only for hits, so it hardly costs):
    // vertices relative to the origin (exact differences for float input), sheared in double, edge
    // functions in double. Where the exact ray passes inside the triangle this gives the plane's t to
    // within a hair, so equal hits of overlapping coplanar triangles agree to the last bit of float.
    // Where the sign test accepted a ray that passes a hair outside (at an edge or vertex), the
    // weights of that test are used instead: they put the hit point on the triangle, so t stays
    // consistent with the triangle's box (up to box::robust's margin) and traversal finds what brute
    // force finds.
    // `e`: the sign test's edge functions (nullptr: computed here if needed, as test() computes them);
    // `s`: the sign of their sum.
    template <std::size_t KX, std::size_t KY, std::size_t KZ, class T>
    static DYNBVH_NOINLINE bool finish(const prepared<T>& p, const Triangle<T>& tri, T tmax, const Edges* e, double s,
                       T& t, T& u, T& v) noexcept {
        const double az = double(tri.p0[KZ]) - p.org_d[KZ], bz = double(tri.p1[KZ]) - p.org_d[KZ],
                     cz = double(tri.p2[KZ]) - p.org_d[KZ];
        using detail::sub_mul;
        using detail::mul_sub_mul;
        const double axd = sub_mul(double(tri.p0[KX]) - p.org_d[KX], p.sx_d, az), ayd = sub_mul(double(tri.p0[KY]) - p.org_d[KY], p.sy_d, az);
        const double bxd = sub_mul(double(tri.p1[KX]) - p.org_d[KX], p.sx_d, bz), byd = sub_mul(double(tri.p1[KY]) - p.org_d[KY], p.sy_d, bz);
        const double cxd = sub_mul(double(tri.p2[KX]) - p.org_d[KX], p.sx_d, cz), cyd = sub_mul(double(tri.p2[KY]) - p.org_d[KY], p.sy_d, cz);
        double w0 = s * mul_sub_mul(cxd, byd, cyd, bxd);
        double w1 = s * mul_sub_mul(axd, cyd, ayd, cxd);
        double w2 = s * mul_sub_mul(bxd, ayd, byd, axd);
        double sum = w0 + w1 + w2;
        // The accurate weights are only trusted when their sum (twice the projected area) exceeds its
        // own rounding error: for a zero-area triangle whose line the ray meets, or a triangle the
        // ray grazes edge-on, all three are rounding noise and would put t anywhere on the ray.
        const double noise = 0x1p-48 * (std::abs(cxd * byd) + std::abs(cyd * bxd) + std::abs(axd * cyd) +
                                         std::abs(ayd * cxd) + std::abs(bxd * ayd) + std::abs(byd * axd));
        if (!(w0 >= 0 && w1 >= 0 && w2 >= 0 && sum > noise)) {
            // The accurate evaluation says the ray passes a hair outside (or is degenerate): keep the
            // weights of the decision itself, which place the hit on the triangle (they are exact
            // barycentrics of the sheared float triangle, whose area the decision found non-zero).
            const Edges d = e ? *e : edges<KX, KY, KZ>(p, tri);
            w0 = s * d.eu;
            w1 = s * d.ev;
            w2 = s * d.ew;
            sum = s * d.det;
        }
        // one division for t, u and v (t is within 2.5 ulp of double before its rounding to T)
        const double inv = 1.0 / sum;
        const T tt = T(detail::dot3(w0, az, w1, bz, w2, cz) * p.rcp_dz * inv);
        if (!(tt >= p.tmin && tt <= tmax)) return false;
        t = tt + T(0);  // -0 -> +0, so equal hits compare equal bit for bit
        u = T(w1 * inv);
        v = T(w2 * inv);
        return true;
    }

    /// a*b - c*d with one rounding of the exact result's magnitude (Kahan): the sign is exact and the
    /// result is exactly 0 iff a*b == c*d.
    static double diff_of_products(double a, double b, double c, double d) noexcept {
        const double cd = c * d;
        const double err = std::fma(-c, d, cd);   // cd - c*d, exact
        const double dop = std::fma(a, b, -cd);   // a*b - cd, rounded once
        return dop + err;
    }
};

/// Möller & Trumbore 1997: edge vectors, one determinant, barycentrics by triple products. Fast, but
/// rays through shared edges and vertices can slip between triangles (see tests/test_intersect.cpp),
/// and tiny triangles are missed: once det = 2 area |dir| cos(angle to the normal) < 1/FLT_MAX (~3e-39),
/// 1/det overflows (unit directions: edges below ~5e-20 are never hit; see the file comment).
/// Front and back faces both hit; triangles parallel to the ray (det == 0) miss. Same interface as
/// watertight.
struct moller_trumbore {
    /// The ray's constants for this test.
    template <class T>
    struct prepared {
        /// @{
        /// ray origin and direction
        Vec3<T> org, dir;
        /// @}
        /// ray.tmin (NaN for a ray that is not traceable: then nothing is hit)
        T tmin;
        /// Copies what the test needs from `r`.
        explicit prepared(const Ray<T>& r) noexcept : org(r.org), dir(r.dir), tmin(detail::prepared_tmin(r)) {
            detail::check_scalar<T>();
        }
    };

    /// True for a hit with t in [p.tmin, tmax]; writes t, u, v only then.
    template <class T>
    static DYNBVH_ALWAYS_INLINE bool test(const prepared<T>& p, const Triangle<T>& tri, T tmax, T& t, T& u, T& v) noexcept {
        const Vec3<T> e1 = tri.p1 - tri.p0, e2 = tri.p2 - tri.p0;
        const Vec3<T> pv = cross(p.dir, e2);
        const T det = dot(e1, pv);
        if (det == T(0)) return false;
        const T inv = T(1) / det;
        const Vec3<T> tv = p.org - tri.p0;
        const T uu = dot(tv, pv) * inv;
        if (!(uu >= T(0) && uu <= T(1))) return false;
        const Vec3<T> qv = cross(tv, e1);
        const T vv = dot(p.dir, qv) * inv;
        if (!(vv >= T(0) && uu + vv <= T(1))) return false;
        const T tt = dot(e2, qv) * inv;
        if (!(tt >= p.tmin && tt <= tmax)) return false;
        t = tt + T(0);  // -0 -> +0
        u = uu;
        v = vv;
        return true;
    }
};

} // namespace tri

/// One ray against one triangle with triangle policy `Tri`: the hit (prim = 0) or no hit. For tests and
/// one-off queries; traversal prepares the ray once instead.
template <class Tri = tri::watertight, class T>
Hit<T> intersect_triangle(const Triangle<T>& triangle, const Ray<T>& ray) noexcept {
    Hit<T> h;
    if (!traceable(ray)) return h;
    const typename Tri::template prepared<T> p(ray);
    if (Tri::test(p, triangle, ray.tmax, h.t, h.u, h.v)) h.prim = 0;
    return h;
}

/// One ray against one box with box policy `Box`: whether it hits within [tmin, tmax].
template <class Box = box::robust, class T>
bool intersect_box(const AABB<T>& b, const Ray<T>& ray) noexcept {
    if (!traceable(ray)) return false;
    const typename Box::template prepared<T> p(ray);
    T tentry;
    return Box::test(p, b.min, b.max, ray.tmax, tentry);
}

} // namespace dynbvh
