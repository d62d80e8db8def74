// SPDX-License-Identifier: MIT
/// @file detail/polygon.hpp
/// The one polygon clipper: a convex polygon split by an axis-aligned plane. Presplitting (presplit.hpp)
/// cuts triangle fragments with it; the end-point overlap metric (sah.hpp) clips triangles to boxes.
#pragma once

#include <cstddef>

#include "../aabb.hpp"

namespace dynbvh::detail {

/// A convex polygon: a triangle clipped by axis-aligned planes has at most 9 corners; the spare
/// room absorbs near-duplicate corners from rounding. Corners are left uninitialised until pushed.
template <class T>
struct Polygon {
    static constexpr int capacity = 16;
    T x[capacity], y[capacity], z[capacity];
    int n = 0;
    bool overflow = false;   ///< a corner was dropped (never in exact arithmetic); the box then falls back
    bool rounded[3] = {false, false, false};   ///< a crossing point's coordinate on this axis was rounded

    Vec3<T> operator[](int k) const noexcept { return {x[k], y[k], z[k]}; }
    T coord(int k, int axis) const noexcept { return axis == 0 ? x[k] : (axis == 1 ? y[k] : z[k]); }
    void push(const Vec3<T>& p) noexcept {
        if (n > 0 && x[n - 1] == p.x && y[n - 1] == p.y && z[n - 1] == p.z) return;
        if (n == capacity) { overflow = true; return; }
        x[n] = p.x;
        y[n] = p.y;
        z[n] = p.z;
        ++n;
    }
    /// Drops a last corner equal to the first (the closing edge).
    void close() noexcept {
        if (n > 1 && x[n - 1] == x[0] && y[n - 1] == y[0] && z[n - 1] == z[0]) --n;
    }
    AABB<T> bounds() const noexcept {
        AABB<T> b;
        for (int k = 0; k < n; ++k) b.extend((*this)[k]);
        return b;
    }
};

/// Splits `in` by the plane x[axis] = pos into the part below (`lo`) and above (`hi`). Corners on the
/// plane go to both; each crossing point is computed once and given to both, with x[axis] = pos exactly.
template <class T>
void split_polygon(const Polygon<T>& in, int axis, T pos, Polygon<T>& lo, Polygon<T>& hi) noexcept {
    lo.n = hi.n = 0;
    lo.overflow = hi.overflow = in.overflow;
    for (std::size_t c = 0; c < 3; ++c) lo.rounded[c] = hi.rounded[c] = in.rounded[c];
    for (int k = 0; k < in.n; ++k) {
        const int k1 = k + 1 == in.n ? 0 : k + 1;
        const Vec3<T> a = in[k];
        const T da = in.coord(k, axis) - pos, db = in.coord(k1, axis) - pos;
        if (da <= T(0)) lo.push(a);
        if (da >= T(0)) hi.push(a);
        if ((da < T(0) && db > T(0)) || (da > T(0) && db < T(0))) {
            const T t = da / (da - db);
            Vec3<T> p = a + (in[k1] - a) * t;
            p[std::size_t(axis)] = pos;
            // Where the same crossing in long double differs, the exact one may lie outside the
            // corners' box: conservative_bounds() then widens that axis.
            const long double tl = (static_cast<long double>(in.coord(k, axis)) - pos) /
                                   (static_cast<long double>(in.coord(k, axis)) - in.coord(k1, axis));
            for (std::size_t c = 0; c < 3; ++c)
                if (c != std::size_t(axis) && static_cast<long double>(p[c]) != a[c] + (static_cast<long double>(in[k1][c]) - a[c]) * tl)
                    lo.rounded[c] = hi.rounded[c] = true;
            lo.push(p);
            hi.push(p);
        }
    }
    lo.close();
    hi.close();
}

} // namespace dynbvh::detail
