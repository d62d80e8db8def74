// Comparing hits to the bit, shared by the traversal tests (test_traverse, test_wide, the robustness suite).
#pragma once

#include <bit>
#include <cstdint>
#include <span>
#include <sstream>
#include <string>

#include <dynbvh/intersect.hpp>
#include <dynbvh/ray.hpp>
#include <dynbvh/triangle.hpp>

namespace dynbvh::test {

template <class T>
bool same_bits(T a, T b) {
    if constexpr (sizeof(T) == 4) return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b);
    else return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

/// Same closest hit: both miss, or the same t, u, v to the bit and the same triangle. (Exact ties go to
/// the larger index in every traversal and in brute force, so the triangle must match too.) `tris` and
/// `r` name the ray and scene in failure messages of callers; Tri is kept for their call sites.
template <class Tri, class T>
bool same_hit(const Hit<T>& h, const Hit<T>& e, std::span<const Triangle<T>> tris, const Ray<T>& r) {
    (void)tris;
    (void)r;
    if (bool(h) != bool(e)) return false;
    if (!h) return true;
    return same_bits(h.t, e.t) && h.prim == e.prim && same_bits(h.u, e.u) && same_bits(h.v, e.v);
}

/// "org (x, y, z) dir (x, y, z) [tmin, tmax]" with 9 digits.
template <class T>
std::string describe(const Ray<T>& r) {
    std::ostringstream s;
    s.precision(9);
    s << "org (" << r.org.x << ", " << r.org.y << ", " << r.org.z << ") dir (" << r.dir.x << ", " << r.dir.y << ", "
      << r.dir.z << ") [" << r.tmin << ", " << r.tmax << "]";
    return s.str();
}

/// The ray, the hit found and the hit expected.
template <class T>
std::string describe(const Ray<T>& r, const Hit<T>& got, const Hit<T>& want) {
    std::ostringstream s;
    s.precision(9);
    s << "ray " << describe(r) << ": bvh prim " << got.prim << " t " << got.t << " / expected prim " << want.prim << " t "
      << want.t;
    return s.str();
}

} // namespace dynbvh::test
