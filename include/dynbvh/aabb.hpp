// SPDX-License-Identifier: MIT
/// @file aabb.hpp
/// Axis-aligned bounding box. The empty box has min = +inf and max = -inf so that
/// extending it by anything yields that thing; its area is 0.
#pragma once

#include <limits>

#include "vec.hpp"

namespace dynbvh {

/// Axis-aligned bounding box [min, max] in scene units.
template <class T>
struct AABB {
    /// @{
    /// Lower and upper corner; the default is the empty box (min = +inf, max = -inf).
    Vec3<T> min{std::numeric_limits<T>::infinity(), std::numeric_limits<T>::infinity(), std::numeric_limits<T>::infinity()};
    Vec3<T> max{-std::numeric_limits<T>::infinity(), -std::numeric_limits<T>::infinity(), -std::numeric_limits<T>::infinity()};
    /// @}

    /// The empty box (min = +inf, max = -inf).
    static constexpr AABB empty() noexcept { return {}; }

    /// Grows the box to contain a point or another box; returns *this.
    /// @{
    constexpr AABB& extend(const Vec3<T>& p) noexcept { min = dynbvh::min(min, p); max = dynbvh::max(max, p); return *this; }
    constexpr AABB& extend(const AABB& b) noexcept { min = dynbvh::min(min, b.min); max = dynbvh::max(max, b.max); return *this; }
    /// @}

    /// True when min > max on some axis (or a corner is NaN): the box holds nothing.
    constexpr bool is_empty() const noexcept { return !(min.x <= max.x && min.y <= max.y && min.z <= max.z); }
    /// max - min (-inf components for the empty box).
    constexpr Vec3<T> diagonal() const noexcept { return max - min; }
    /// Midpoint (min + max) / 2.
    constexpr Vec3<T> center() const noexcept { return (min + max) * T(0.5); }

    /// Surface area in square scene units; 0 for an empty box.
    constexpr T area() const noexcept {
        if (is_empty()) return T(0);
        const Vec3<T> d = diagonal();
        return T(2) * (d.x * d.y + d.y * d.z + d.z * d.x);
    }
    /// Half the surface area: what SAH comparisons need (the factor 2 cancels).
    constexpr T half_area() const noexcept {
        if (is_empty()) return T(0);
        const Vec3<T> d = diagonal();
        return d.x * d.y + d.y * d.z + d.z * d.x;
    }
    /// Half the surface area evaluated in `U` (double: extents near 1e-30 or 1e30 neither underflow
    /// nor overflow in the products, as they would in float).
    template <class U>
    constexpr U half_area_in() const noexcept {
        if (is_empty()) return U(0);
        const U dx = U(max.x) - U(min.x), dy = U(max.y) - U(min.y), dz = U(max.z) - U(min.z);
        return dx * dy + dy * dz + dz * dx;
    }
    /// Whether point `p` lies in the closed box.
    constexpr bool contains(const Vec3<T>& p) const noexcept {
        return min.x <= p.x && p.x <= max.x && min.y <= p.y && p.y <= max.y && min.z <= p.z && p.z <= max.z;
    }
    /// Whether box `b` lies in this box (an empty `b` lies in every box).
    constexpr bool contains(const AABB& b) const noexcept { return b.is_empty() || (contains(b.min) && contains(b.max)); }

    /// Exact comparison of both corners.
    friend constexpr bool operator==(const AABB&, const AABB&) noexcept = default;
};

/// The smallest box containing both.
template <class T> constexpr AABB<T> merge(AABB<T> a, const AABB<T>& b) noexcept { return a.extend(b); }
/// Intersection of two boxes (possibly empty).
template <class T> constexpr AABB<T> intersection(const AABB<T>& a, const AABB<T>& b) noexcept {
    return {dynbvh::max(a.min, b.min), dynbvh::min(a.max, b.max)};
}

/// Single-precision box (node bounds).
using AABBf = AABB<float>;
/// Double-precision box.
using AABBd = AABB<double>;

} // namespace dynbvh
