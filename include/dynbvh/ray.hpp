// SPDX-License-Identifier: MIT
/// @file ray.hpp
/// Ray and hit records used by traversal.
#pragma once

#include <cstdint>
#include <limits>

#include "vec.hpp"

namespace dynbvh {

/// A ray org + t * dir for t in [tmin, tmax]. `dir` need not be normalised; t is in units of |dir|.
template <class T>
struct Ray {
    /// Origin, in scene units.
    Vec3<T> org{};
    /// Direction; need not be normalised (t counts multiples of |dir|).
    Vec3<T> dir{0, 0, 1};
    /// Start of the hit interval (closed): hits with t < tmin are ignored (offset secondary rays with it).
    T tmin = T(0);
    /// End of the hit interval (closed), +inf by default: for a shadow ray, the light's t.
    T tmax = std::numeric_limits<T>::infinity();
};

/// Marks "no primitive" in Hit::prim.
inline constexpr std::uint32_t invalid_prim = std::numeric_limits<std::uint32_t>::max();

/// Closest-hit record. `prim` is the index of the user's triangle (never a fragment or leaf slot);
/// (u, v) are barycentrics of p1 and p2: p = (1-u-v) p0 + u p1 + v p2.
template <class T>
struct Hit {
    /// Distance along the ray in multiples of |dir|; +inf when nothing was hit.
    T t = std::numeric_limits<T>::infinity();
    /// @{
    /// Barycentric coordinates of p1 and p2 (see above); 0 when nothing was hit.
    T u = 0, v = 0;
    /// @}
    /// Index of the hit triangle in the array the tree was built over, or invalid_prim.
    std::uint32_t prim = invalid_prim;

    /// True when something was hit.
    constexpr explicit operator bool() const noexcept { return prim != invalid_prim; }
};

/// Single-precision ray (use `Ray<double>` with double trees).
using Rayf = Ray<float>;
/// Single-precision hit record.
using Hitf = Hit<float>;

} // namespace dynbvh
