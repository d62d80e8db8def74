// SPDX-License-Identifier: MIT
/// @file vec.hpp
/// Small fixed-size vector math used everywhere in dynbvh: Vec3<T>, component-wise
/// min/max, dot and cross products. Plain aggregates, no SIMD intrinsics, so the
/// compiler can vectorise loops over arrays of them.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace dynbvh {

/// A 3-component vector (points, directions, extents). Aggregate: `Vec3f{1, 2, 3}`.
template <class T>
struct Vec3 {
    /// @{
    /// The components (also `v[0]`, `v[1]`, `v[2]`).
    T x{}, y{}, z{};
    /// @}

    /// Component `i`: 0 is x, 1 is y, anything else z (no range check).
    /// @{
    constexpr T& operator[](std::size_t i) noexcept { return i == 0 ? x : (i == 1 ? y : z); }
    constexpr const T& operator[](std::size_t i) const noexcept { return i == 0 ? x : (i == 1 ? y : z); }
    /// @}

    /// Component-wise +=, -= and scaling by `s`; return *this.
    /// @{
    constexpr Vec3& operator+=(const Vec3& o) noexcept { x += o.x; y += o.y; z += o.z; return *this; }
    constexpr Vec3& operator-=(const Vec3& o) noexcept { x -= o.x; y -= o.y; z -= o.z; return *this; }
    constexpr Vec3& operator*=(T s) noexcept { x *= s; y *= s; z *= s; return *this; }
    /// @}

    /// Component-wise arithmetic: sum, difference, negation, scaling by `s`, product and quotient;
    /// `==` compares the three components exactly.
    /// @{
    friend constexpr Vec3 operator+(Vec3 a, const Vec3& b) noexcept { return a += b; }
    friend constexpr Vec3 operator-(Vec3 a, const Vec3& b) noexcept { return a -= b; }
    friend constexpr Vec3 operator-(const Vec3& a) noexcept { return {-a.x, -a.y, -a.z}; }
    friend constexpr Vec3 operator*(Vec3 a, T s) noexcept { return a *= s; }
    friend constexpr Vec3 operator*(T s, Vec3 a) noexcept { return a *= s; }
    friend constexpr Vec3 operator*(const Vec3& a, const Vec3& b) noexcept { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
    friend constexpr Vec3 operator/(const Vec3& a, const Vec3& b) noexcept { return {a.x / b.x, a.y / b.y, a.z / b.z}; }
    friend constexpr bool operator==(const Vec3& a, const Vec3& b) noexcept = default;
    /// @}

    /// Converting copy to another scalar type (e.g. double positions to float).
    template <class U>
    constexpr explicit operator Vec3<U>() const noexcept { return {U(x), U(y), U(z)}; }
};

/// Single-precision vector: positions, ray origins and directions.
using Vec3f = Vec3<float>;
/// Double-precision vector.
using Vec3d = Vec3<double>;

/// Dot product.
template <class T> constexpr T dot(const Vec3<T>& a, const Vec3<T>& b) noexcept { return a.x * b.x + a.y * b.y + a.z * b.z; }
/// Cross product a x b (right-handed).
template <class T> constexpr Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b) noexcept {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
/// Component-wise minimum (a NaN in `b` is ignored, one in `a` is kept).
template <class T> constexpr Vec3<T> min(const Vec3<T>& a, const Vec3<T>& b) noexcept {
    return {b.x < a.x ? b.x : a.x, b.y < a.y ? b.y : a.y, b.z < a.z ? b.z : a.z};
}
/// Component-wise maximum (a NaN in `b` is ignored, one in `a` is kept).
template <class T> constexpr Vec3<T> max(const Vec3<T>& a, const Vec3<T>& b) noexcept {
    return {a.x < b.x ? b.x : a.x, a.y < b.y ? b.y : a.y, a.z < b.z ? b.z : a.z};
}
/// Euclidean length.
template <class T> inline T length(const Vec3<T>& a) noexcept { return std::sqrt(dot(a, a)); }
/// `a` scaled to unit length (NaN components for the zero vector).
template <class T> inline Vec3<T> normalize(const Vec3<T>& a) noexcept { return a * (T(1) / length(a)); }
/// Index (0, 1, 2) of the largest component.
template <class T> constexpr int largest_axis(const Vec3<T>& a) noexcept {
    return a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
}
/// True when every component is finite (no NaN, no infinity).
template <class T> inline bool is_finite(const Vec3<T>& a) noexcept {
    return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

} // namespace dynbvh
