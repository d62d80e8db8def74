// SPDX-License-Identifier: MIT
/// @file affine.hpp
/// Affine transforms of instances (two_level.hpp): a 3x4 matrix, its inverse computed in double, and
/// the one arithmetic that takes a world ray into an object's space (`object_ray`). Every product-sum
/// is a chain of std::fma, so the result is the same bits wherever it is computed (no compiler choice
/// of contraction), which the two-level exactness contract relies on.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

#include "detail/simd.hpp"
#include "ray.hpp"
#include "vec.hpp"

namespace dynbvh {

/// Row-major 3x4 affine transform p -> L p + t: `m[4 * r + c]`, columns 0..2 the linear part L,
/// column 3 the translation t. Default: identity. Mirrored transforms (det L < 0) are fine.
template <class T>
struct Affine {
    /// The 12 entries, row-major (see the struct comment); identity by default.
    std::array<T, 12> m{T(1), T(0), T(0), T(0), T(0), T(1), T(0), T(0), T(0), T(0), T(1), T(0)};

    /// L p + t, each row as fma(m0, x, fma(m1, y, fma(m2, z, m3))).
    DYNBVH_ALWAYS_INLINE Vec3<T> point(const Vec3<T>& p) const noexcept {
        return {row(0, p, m[3]), row(1, p, m[7]), row(2, p, m[11])};
    }
    /// L v (directions), each row as fma(m0, x, fma(m1, y, fma(m2, z, 0))).
    DYNBVH_ALWAYS_INLINE Vec3<T> vector(const Vec3<T>& v) const noexcept {
        return {row(0, v, T(0)), row(1, v, T(0)), row(2, v, T(0))};
    }
    /// Whether all 12 entries are finite.
    bool is_finite() const noexcept {
        return std::all_of(m.begin(), m.end(), [](T x) { return std::isfinite(x); });
    }
    /// Translation by `t`.
    static Affine translation(const Vec3<T>& t) noexcept {
        Affine a;
        a.m[3] = t.x;
        a.m[7] = t.y;
        a.m[11] = t.z;
        return a;
    }

private:
    DYNBVH_ALWAYS_INLINE T row(std::size_t r, const Vec3<T>& p, T add) const noexcept {
        const T* q = m.data() + 4 * r;
        return std::fma(q[0], p.x, std::fma(q[1], p.y, std::fma(q[2], p.z, add)));
    }
};

/// The float transform the default trees use.
using Affinef = Affine<float>;

namespace detail {
/// Infinity norm (largest row sum of absolute values) of the linear part, in double.
template <class T>
double linear_norm(const Affine<T>& a) noexcept {
    double n = 0;
    for (std::size_t r = 0; r < 3; ++r)
        n = std::max(n, std::abs(double(a.m[4 * r])) + std::abs(double(a.m[4 * r + 1])) + std::abs(double(a.m[4 * r + 2])));
    return n;
}
} // namespace detail

/// Largest condition number ||L|| ||L^-1|| (infinity norm) `inverse` accepts: beyond it the inverse's
/// rounding would make the object-space rays (and the culling margins of two_level.hpp) meaningless.
inline constexpr double max_transform_condition = 1e7;

/// The inverse transform, computed in double (adjugate over determinant) and rounded to T.
/// Throws std::invalid_argument naming `what` when an entry is NaN or infinite, when L is singular or
/// its condition number exceeds max_transform_condition, or when the inverse overflows T. O(1).
template <class T>
Affine<T> inverse(const Affine<T>& a, const std::string& what = "transform") {
    if (!a.is_finite()) throw std::invalid_argument("dynbvh::inverse: " + what + " has a NaN or infinite entry");
    const auto e = [&](std::size_t r, std::size_t c) { return double(a.m[4 * r + c]); };
    // Cofactors of L (row r, column c of the adjugate = cofactor of (c, r)).
    const double c00 = e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1), c01 = e(1, 2) * e(2, 0) - e(1, 0) * e(2, 2),
                 c02 = e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0);
    const double det = e(0, 0) * c00 + e(0, 1) * c01 + e(0, 2) * c02;
    if (!(std::abs(det) > 0) || !std::isfinite(det))
        throw std::invalid_argument("dynbvh::inverse: " + what + " is singular (determinant " + std::to_string(det) + ")");
    const double inv[3][3] = {
        {c00 / det, (e(0, 2) * e(2, 1) - e(0, 1) * e(2, 2)) / det, (e(0, 1) * e(1, 2) - e(0, 2) * e(1, 1)) / det},
        {c01 / det, (e(0, 0) * e(2, 2) - e(0, 2) * e(2, 0)) / det, (e(0, 2) * e(1, 0) - e(0, 0) * e(1, 2)) / det},
        {c02 / det, (e(0, 1) * e(2, 0) - e(0, 0) * e(2, 1)) / det, (e(0, 0) * e(1, 1) - e(0, 1) * e(1, 0)) / det}};
    Affine<T> out;
    double inv_norm = 0;
    for (std::size_t r = 0; r < 3; ++r) {
        double t = 0, row = 0;
        for (std::size_t c = 0; c < 3; ++c) {
            t -= inv[r][c] * e(c, 3);
            row += std::abs(inv[r][c]);
            out.m[4 * r + c] = T(inv[r][c]);
        }
        out.m[4 * r + 3] = T(t);
        inv_norm = std::max(inv_norm, row);
    }
    const double cond = detail::linear_norm(a) * inv_norm;
    if (!(cond <= max_transform_condition))
        throw std::invalid_argument("dynbvh::inverse: " + what + " is too close to singular (condition number " +
                                    std::to_string(cond) + " > " + std::to_string(max_transform_condition) + ")");
    if (!out.is_finite()) throw std::invalid_argument("dynbvh::inverse: the inverse of " + what + " overflows");
    return out;
}

/// The world ray `r` in the space whose world-to-object transform is `inv` (the inverse of the
/// instance's transform): origin inv.point(org), direction inv.vector(dir) (not renormalised), the
/// same [tmin, tmax], so t means the same point in both spaces. The one transformation of the
/// two-level traversal and of its brute-force reference. O(1).
template <class T>
DYNBVH_ALWAYS_INLINE Ray<T> object_ray(const Affine<T>& inv, const Ray<T>& r) noexcept {
    return {inv.point(r.org), inv.vector(r.dir), r.tmin, r.tmax};
}

} // namespace dynbvh
