/// @file scenes/geometry.hpp
/// Indexed-mesh generators for the built-in scenes: UV sphere, planar grid, closed
/// cylinder, surface of revolution, and the gather that turns an indexed mesh into
/// the flat triangles a Frame holds. Closed meshes are wound counter-clockwise seen
/// from outside (outward normals, positive signed volume).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <stdexcept>
#include <vector>

#include <dynbvh/aabb.hpp>
#include <dynbvh/triangle.hpp>

namespace dynbvh::scenes {

using Face = std::array<std::uint32_t, 3>;

/// Vertices plus triangles indexing them.
struct IndexedMesh {
    std::vector<Vec3f> vertices;
    std::vector<Face> faces;

    std::size_t triangle_count() const noexcept { return faces.size(); }
    /// Appends `m`, offsetting its indices. O(|m|).
    void append(const IndexedMesh& m) {
        const auto base = static_cast<std::uint32_t>(vertices.size());
        vertices.insert(vertices.end(), m.vertices.begin(), m.vertices.end());
        faces.reserve(faces.size() + m.faces.size());
        for (const Face& f : m.faces) faces.push_back({f[0] + base, f[1] + base, f[2] + base});
    }
    AABBf bounds() const noexcept { AABBf b; for (const Vec3f& v : vertices) b.extend(v); return b; }
};

/// Writes the triangles of `faces` over vertex positions `v` to `out` (faces.size() entries). O(n).
inline void gather_triangles(std::span<const Vec3f> v, std::span<const Face> faces, Trianglef* out) noexcept {
    for (std::size_t i = 0; i < faces.size(); ++i) out[i] = {v[faces[i][0]], v[faces[i][1]], v[faces[i][2]]};
}

/// Triangles of `uv_sphere(.., slices, stacks)`.
constexpr std::size_t uv_sphere_triangles(std::uint32_t slices, std::uint32_t stacks) noexcept {
    return 2 * std::size_t(slices) * (stacks - 1);
}

/// Slices and stacks of a UV sphere with about `triangles` triangles (slices ~ stacks).
struct SphereResolution {
    std::uint32_t slices = 3, stacks = 2;
};
inline SphereResolution sphere_resolution(double triangles) noexcept {
    SphereResolution r;
    const double stacks = std::round(std::sqrt(triangles / 2) + 0.5);
    r.stacks = stacks < 2 ? 2u : static_cast<std::uint32_t>(stacks);
    const double slices = std::round(triangles / (2.0 * (r.stacks - 1)));
    r.slices = slices < 3 ? 3u : static_cast<std::uint32_t>(slices);
    return r;
}

/// UV sphere around the y axis: `slices` >= 3 meridians, `stacks` >= 2 bands from pole to pole.
/// slices*(stacks-1)+2 vertices (poles first and last), 2*slices*(stacks-1) triangles.
inline IndexedMesh uv_sphere(Vec3f centre, float radius, std::uint32_t slices, std::uint32_t stacks) {
    if (slices < 3 || stacks < 2) throw std::invalid_argument("dynbvh::scenes::uv_sphere: needs slices >= 3 and stacks >= 2");
    IndexedMesh m;
    m.vertices.reserve(std::size_t(slices) * (stacks - 1) + 2);
    m.vertices.push_back(centre + Vec3f{0, radius, 0});
    for (std::uint32_t k = 1; k < stacks; ++k) {
        const double th = std::numbers::pi * k / stacks;
        for (std::uint32_t s = 0; s < slices; ++s) {
            const double ph = 2 * std::numbers::pi * s / slices;
            m.vertices.push_back(centre + Vec3f{float(radius * std::sin(th) * std::cos(ph)), float(radius * std::cos(th)),
                                                float(radius * std::sin(th) * std::sin(ph))});
        }
    }
    m.vertices.push_back(centre - Vec3f{0, radius, 0});
    const std::uint32_t bottom = static_cast<std::uint32_t>(m.vertices.size() - 1);
    auto ring = [&](std::uint32_t k, std::uint32_t s) { return 1 + (k - 1) * slices + s % slices; };
    m.faces.reserve(uv_sphere_triangles(slices, stacks));
    for (std::uint32_t s = 0; s < slices; ++s) m.faces.push_back({0, ring(1, s + 1), ring(1, s)});
    for (std::uint32_t k = 1; k + 1 < stacks; ++k)
        for (std::uint32_t s = 0; s < slices; ++s) {
            const std::uint32_t a = ring(k, s), b = ring(k, s + 1), c = ring(k + 1, s), d = ring(k + 1, s + 1);
            m.faces.push_back({a, b, d});
            m.faces.push_back({a, d, c});
        }
    for (std::uint32_t s = 0; s < slices; ++s) m.faces.push_back({bottom, ring(stacks - 1, s), ring(stacks - 1, s + 1)});
    return m;
}

/// Faces of an (nu+1) x (nv+1) vertex grid whose vertex (i, j) is `first + j*(nu+1) + i`;
/// 2*nu*nv triangles wound so that the normal is u x v.
inline std::vector<Face> grid_faces(std::uint32_t nu, std::uint32_t nv, std::uint32_t first = 0) {
    std::vector<Face> f;
    f.reserve(2 * std::size_t(nu) * nv);
    for (std::uint32_t j = 0; j < nv; ++j)
        for (std::uint32_t i = 0; i < nu; ++i) {
            const std::uint32_t a = first + j * (nu + 1) + i, b = a + 1, c = a + nu + 1, d = c + 1;
            f.push_back({a, b, d});
            f.push_back({a, d, c});
        }
    return f;
}

/// Planar grid: vertex (i, j) = origin + u*i/nu + v*j/nv, 2*nu*nv triangles, normal along u x v.
inline IndexedMesh grid(Vec3f origin, Vec3f u, Vec3f v, std::uint32_t nu, std::uint32_t nv) {
    if (nu < 1 || nv < 1) throw std::invalid_argument("dynbvh::scenes::grid: needs nu, nv >= 1");
    IndexedMesh m;
    m.vertices.reserve(std::size_t(nu + 1) * (nv + 1));
    for (std::uint32_t j = 0; j <= nv; ++j)
        for (std::uint32_t i = 0; i <= nu; ++i)
            m.vertices.push_back(origin + u * (float(i) / float(nu)) + v * (float(j) / float(nv)));
    m.faces = grid_faces(nu, nv);
    return m;
}

/// Surface of revolution about the vertical axis through `axis`: `profile` holds (radius, height)
/// pairs; `slices` >= 3. Open profile: 2*slices*(n-1) triangles; closed (last point joins the first):
/// 2*slices*n. A profile running counter-clockwise in the (r, y) half-plane gives outward normals.
inline IndexedMesh revolve(Vec3f axis, std::span<const std::array<float, 2>> profile, std::uint32_t slices, bool closed) {
    if (slices < 3 || profile.size() < 2) throw std::invalid_argument("dynbvh::scenes::revolve: needs slices >= 3 and 2 profile points");
    const auto n = static_cast<std::uint32_t>(profile.size());
    IndexedMesh m;
    m.vertices.reserve(std::size_t(n) * slices);
    for (std::uint32_t k = 0; k < n; ++k)
        for (std::uint32_t s = 0; s < slices; ++s) {
            const double ph = 2 * std::numbers::pi * s / slices;
            m.vertices.push_back(axis + Vec3f{float(profile[k][0] * std::cos(ph)), profile[k][1], float(profile[k][0] * std::sin(ph))});
        }
    const std::uint32_t bands = closed ? n : n - 1;
    m.faces.reserve(2 * std::size_t(slices) * bands);
    for (std::uint32_t k = 0; k < bands; ++k) {
        const std::uint32_t lo = k * slices, hi = ((k + 1) % n) * slices;
        for (std::uint32_t s = 0; s < slices; ++s) {
            const std::uint32_t s1 = (s + 1) % slices;
            m.faces.push_back({lo + s, hi + s, hi + s1});
            m.faces.push_back({lo + s, hi + s1, lo + s1});
        }
    }
    return m;
}

/// Closed cylinder standing on `base` along +y: `slices` >= 3 around, `segments` >= 1 along the side;
/// 2*slices*(segments+1) triangles (caps are fans around a centre vertex).
inline IndexedMesh cylinder(Vec3f base, float radius, float height, std::uint32_t slices, std::uint32_t segments) {
    if (segments < 1) throw std::invalid_argument("dynbvh::scenes::cylinder: needs segments >= 1");
    std::vector<std::array<float, 2>> prof;
    for (std::uint32_t j = 0; j <= segments; ++j) prof.push_back({radius, height * float(j) / float(segments)});
    IndexedMesh m = revolve(base, prof, slices, false);
    const auto bottom = static_cast<std::uint32_t>(m.vertices.size());
    m.vertices.push_back(base);
    m.vertices.push_back(base + Vec3f{0, height, 0});
    const std::uint32_t top_ring = segments * slices;
    for (std::uint32_t s = 0; s < slices; ++s) {
        const std::uint32_t s1 = (s + 1) % slices;
        m.faces.push_back({bottom, s, s1});
        m.faces.push_back({bottom + 1, top_ring + s1, top_ring + s});
    }
    return m;
}

/// Signed volume enclosed by a closed mesh (positive when wound outward). O(n).
inline double signed_volume(const IndexedMesh& m) noexcept {
    double v = 0;
    for (const Face& f : m.faces) {
        const Vec3d a = Vec3d(m.vertices[f[0]]), b = Vec3d(m.vertices[f[1]]), c = Vec3d(m.vertices[f[2]]);
        v += dot(a, cross(b, c));
    }
    return v / 6;
}

} // namespace dynbvh::scenes
