// SPDX-License-Identifier: MIT
/// @file triangle.hpp
/// The triangle the library builds over, and the helpers that turn the user's
/// triangles into the per-primitive boxes and centroids every builder starts from.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "aabb.hpp"

namespace dynbvh {

/// A triangle by its three vertices (36 bytes for float). Users holding indexed meshes pass a
/// MeshView (mesh.hpp), read in place, or flatten them with `make_triangles`.
template <class T>
struct Triangle {
    /// @{
    /// The vertices in scene units; their order sets the normal's direction and the meaning of u, v.
    Vec3<T> p0, p1, p2;
    /// @}

    /// The triangle's bounding box.
    constexpr AABB<T> bounds() const noexcept { AABB<T> b; b.extend(p0).extend(p1).extend(p2); return b; }
    /// Mean of the three vertices.
    constexpr Vec3<T> centroid() const noexcept { return (p0 + p1 + p2) * (T(1) / T(3)); }
    /// Geometric (unnormalised) normal, (p1 - p0) x (p2 - p0).
    constexpr Vec3<T> normal() const noexcept { return cross(p1 - p0, p2 - p0); }
    /// Area in square scene units.
    T area() const noexcept { return T(0.5) * length(normal()); }
    /// True when no vertex has a NaN or infinite coordinate (builders leave the others out). Branch-free,
    /// as the per-frame scans need it: x - x is +0 for a finite x and NaN otherwise, and a sum with a
    /// NaN is NaN.
    bool is_finite() const noexcept {
        const Vec3<T> z = (p0 - p0) + (p1 - p1) + (p2 - p2);
        return z.x + z.y + z.z == T(0);
    }
};

/// Single-precision triangle (36 bytes): what the loaders produce.
using Trianglef = Triangle<float>;
/// Double-precision triangle (72 bytes), for `Node<double, ...>` trees.
using Triangled = Triangle<double>;

/// Flattens an indexed mesh into triangles. Indices out of range throw std::out_of_range.
template <class T, class Index>
std::vector<Triangle<T>> make_triangles(std::span<const Vec3<T>> vertices, std::span<const Index> indices);

} // namespace dynbvh

#include <stdexcept>
#include <string>

namespace dynbvh {

template <class T, class Index>
std::vector<Triangle<T>> make_triangles(std::span<const Vec3<T>> vertices, std::span<const Index> indices) {
    if (indices.size() % 3 != 0)
        throw std::invalid_argument("dynbvh::make_triangles: index count " + std::to_string(indices.size()) + " is not a multiple of 3");
    std::vector<Triangle<T>> out(indices.size() / 3);
    for (std::size_t t = 0; t < out.size(); ++t) {
        for (std::size_t k = 0; k < 3; ++k) {
            const auto i = static_cast<std::uint64_t>(indices[3 * t + k]);
            if (i >= vertices.size())
                throw std::out_of_range("dynbvh::make_triangles: triangle " + std::to_string(t) + " uses vertex " +
                                        std::to_string(i) + " but there are " + std::to_string(vertices.size()));
        }
        // Checked above: each index is in [0, vertices.size()), also for a signed Index type.
        out[t] = {vertices[static_cast<std::size_t>(indices[3 * t])], vertices[static_cast<std::size_t>(indices[3 * t + 1])],
                  vertices[static_cast<std::size_t>(indices[3 * t + 2])]};
    }
    return out;
}

} // namespace dynbvh
