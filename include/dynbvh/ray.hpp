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
    Vec3<T> org{};
    Vec3<T> dir{0, 0, 1};
    T tmin = T(0);
    T tmax = std::numeric_limits<T>::infinity();
};

/// Marks "no primitive" in Hit::prim.
inline constexpr std::uint32_t invalid_prim = std::numeric_limits<std::uint32_t>::max();

/// Closest-hit record. `prim` is the index of the user's triangle (never a fragment or leaf slot);
/// (u, v) are barycentrics of p1 and p2: p = (1-u-v) p0 + u p1 + v p2.
template <class T>
struct Hit {
    T t = std::numeric_limits<T>::infinity();
    T u = 0, v = 0;
    std::uint32_t prim = invalid_prim;

    constexpr explicit operator bool() const noexcept { return prim != invalid_prim; }
};

using Rayf = Ray<float>;
using Hitf = Hit<float>;

} // namespace dynbvh
