// Shared by the robustness tests (test_robust_rays.cpp, test_robust_geometry.cpp, test_watertight.cpp):
// closed indexed meshes with points known to lie inside them, the builder list, adversarial ray sets
// and the comparison of a BVH's answers with brute force.
#pragma once

#include "hit_compare.hpp"
#include "support.hpp"

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/io/ply.hpp>
#include <dynbvh/io/scene.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/traverse.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

namespace dynbvh::test {

inline constexpr float finf = std::numeric_limits<float>::infinity();
inline constexpr float fnan = std::numeric_limits<float>::quiet_NaN();

/// A count from the environment variable `name` (a positive integer), else `fallback`.
inline std::size_t env_count(const char* name, std::size_t fallback) {
    const char* s = std::getenv(name);
    if (!s || !*s) return fallback;
    char* end = nullptr;
    const unsigned long long v = std::strtoull(s, &end, 10);
    return (end && *end == '\0' && v > 0) ? std::size_t(v) : fallback;
}


// ---- closed meshes ---------------------------------------------------------------------------

/// How many faces use each undirected edge (key: lower index << 32 | higher index).
inline std::unordered_map<std::uint64_t, int> edge_uses(const io::Mesh& m) {
    std::unordered_map<std::uint64_t, int> uses;
    uses.reserve(m.faces.size() * 2);
    for (const auto& f : m.faces)
        for (int k = 0; k < 3; ++k) {
            std::uint64_t a = f[std::size_t(k)], b = f[std::size_t((k + 1) % 3)];
            if (a > b) std::swap(a, b);
            ++uses[a << 32 | b];
        }
    return uses;
}

/// Every edge shared by exactly two faces (and no face with a repeated vertex index).
inline bool is_closed(const io::Mesh& m) {
    for (const auto& f : m.faces)
        if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) return false;
    for (const auto& [e, n] : edge_uses(m))
        if (n != 2) return false;
    return !m.faces.empty();
}

/// The mesh's distinct edges as vertex index pairs.
inline std::vector<std::array<std::uint32_t, 2>> edges_of(const io::Mesh& m) {
    std::vector<std::array<std::uint32_t, 2>> e;
    for (const auto& [key, n] : edge_uses(m)) e.push_back({std::uint32_t(key >> 32), std::uint32_t(key)});
    std::sort(e.begin(), e.end());
    return e;
}

/// The surface of [-1, 1]^3 cut into k x k squares per face, two triangles each (k a power of two keeps
/// every coordinate exact). Vertices are shared between faces.
inline io::Mesh cube_mesh(int k) {
    io::Mesh m;
    std::map<std::array<int, 3>, std::uint32_t> ids;
    auto vertex = [&](std::array<int, 3> g) {
        const auto [it, fresh] = ids.emplace(g, std::uint32_t(m.vertices.size()));
        if (fresh)
            m.vertices.push_back({float(2.0 * g[0] / k - 1.0), float(2.0 * g[1] / k - 1.0), float(2.0 * g[2] / k - 1.0)});
        return it->second;
    };
    for (int a = 0; a < 3; ++a)
        for (int side : {0, k})
            for (int i = 0; i < k; ++i)
                for (int j = 0; j < k; ++j) {
                    auto g = [&](int di, int dj) {
                        std::array<int, 3> c{};
                        c[std::size_t(a)] = side;
                        c[std::size_t((a + 1) % 3)] = i + di;
                        c[std::size_t((a + 2) % 3)] = j + dj;
                        return vertex(c);
                    };
                    const auto v00 = g(0, 0), v10 = g(1, 0), v11 = g(1, 1), v01 = g(0, 1);
                    // Alternate the diagonal so that vertices of valence 4 and 8 both occur.
                    if ((i + j) % 2 == 0) {
                        m.faces.push_back({v00, v10, v11});
                        m.faces.push_back({v00, v11, v01});
                    } else {
                        m.faces.push_back({v00, v10, v01});
                        m.faces.push_back({v10, v11, v01});
                    }
                }
    return m;
}

/// UV sphere of radius 1 with one vertex at each pole: 2 * slices * (stacks - 1) triangles.
inline io::Mesh sphere_mesh(int stacks, int slices) {
    io::Mesh m;
    const double pi = 3.14159265358979323846;
    m.vertices.push_back({0, 1, 0});
    for (int i = 1; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const double th = pi * i / stacks, ph = 2 * pi * j / slices;
            m.vertices.push_back({float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph))});
        }
    m.vertices.push_back({0, -1, 0});
    const auto south = std::uint32_t(m.vertices.size() - 1);
    auto ring = [&](int i, int j) { return std::uint32_t(1 + (i - 1) * slices + (j % slices)); };
    for (int j = 0; j < slices; ++j) {
        m.faces.push_back({0u, ring(1, j + 1), ring(1, j)});
        m.faces.push_back({south, ring(stacks - 1, j), ring(stacks - 1, j + 1)});
        for (int i = 1; i + 1 < stacks; ++i) {
            m.faces.push_back({ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)});
            m.faces.push_back({ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)});
        }
    }
    return m;
}

/// Torus around the z axis: ring radius R, tube radius r, nu x nv quads, two triangles each.
inline io::Mesh torus_mesh(double R, double r, int nu, int nv) {
    io::Mesh m;
    const double pi = 3.14159265358979323846;
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            const double u = 2 * pi * i / nu, v = 2 * pi * j / nv;
            m.vertices.push_back({float((R + r * std::cos(v)) * std::cos(u)), float((R + r * std::cos(v)) * std::sin(u)),
                                  float(r * std::sin(v))});
        }
    auto id = [&](int i, int j) { return std::uint32_t((i % nu) * nv + (j % nv)); };
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return m;
}

/// Closes the holes of an edge-manifold mesh by fanning every boundary loop from its centroid (a new
/// vertex), so that every edge is shared by exactly two faces. Faces with a repeated vertex index are
/// dropped first. nullopt when the boundary is not a set of simple loops.
inline std::optional<io::Mesh> close_holes(io::Mesh m) {
    std::erase_if(m.faces, [](const auto& f) { return f[0] == f[1] || f[1] == f[2] || f[0] == f[2]; });
    const auto uses = edge_uses(m);
    std::unordered_map<std::uint32_t, std::uint32_t> next;  // boundary edge a -> b as it runs in its face
    for (const auto& f : m.faces)
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t a = f[std::size_t(k)], b = f[std::size_t((k + 1) % 3)];
            const auto n = uses.at(std::uint64_t(std::min(a, b)) << 32 | std::max(a, b));
            if (n > 2) return std::nullopt;
            if (n == 1 && !next.emplace(a, b).second) return std::nullopt;  // two boundary edges leave a
        }
    while (!next.empty()) {
        std::vector<std::uint32_t> loop{next.begin()->first};
        for (;;) {
            const auto it = next.find(loop.back());
            if (it == next.end()) return std::nullopt;
            const std::uint32_t b = it->second;
            next.erase(it);
            if (b == loop.front()) break;
            loop.push_back(b);
        }
        double c[3] = {0, 0, 0};
        for (auto v : loop)
            for (std::size_t a = 0; a < 3; ++a) c[a] += m.vertices[v][a];
        const auto centre = std::uint32_t(m.vertices.size());
        const auto n = double(loop.size());
        m.vertices.push_back({float(c[0] / n), float(c[1] / n), float(c[2] / n)});
        for (std::size_t i = 0; i < loop.size(); ++i) m.faces.push_back({loop[(i + 1) % loop.size()], loop[i], centre});
    }
    return m;
}

/// Whether `p` lies inside the closed triangle set: the number of watertight hits along three fixed
/// rays from p is odd for all three (rays through an edge or vertex would count twice; the three
/// must agree, else the point is rejected).
inline bool inside_by_parity(std::span<const Trianglef> tris, const Vec3f& p) {
    const Vec3f dirs[3] = {{0.5773f, 0.5779f, 0.5767f}, {-0.2672f, 0.8018f, -0.5345f}, {0.9058f, -0.3049f, 0.2944f}};
    for (const Vec3f& d : dirs) {
        const Rayf r{p, d};
        const tri::watertight::prepared<float> pr(r);
        std::size_t n = 0;
        for (const auto& t : tris) {
            float tt, u, v;
            n += tri::watertight::test(pr, t, finf, tt, u, v) ? 1 : 0;
        }
        if (n % 2 == 0) return false;
    }
    return true;
}

/// A closed mesh and points strictly inside it (a clear margin from the surface).
struct ClosedMesh {
    std::string name;
    io::Mesh mesh;
    std::vector<Vec3f> inside;
};

/// The watertightness probes of closed mesh `c`: from each of its first `origins` inside points, one
/// ray at every vertex, then one at every edge midpoint (a watertight traversal hits every one).
inline std::vector<Rayf> inside_rays(const ClosedMesh& c, std::size_t origins) {
    const auto edges = edges_of(c.mesh);
    std::vector<Rayf> rs;
    for (std::size_t o = 0; o < origins; ++o) {
        const Vec3f org = c.inside[o];
        for (const Vec3f& v : c.mesh.vertices) rs.push_back({org, v - org});
        for (const auto& e : edges) rs.push_back({org, (c.mesh.vertices[e[0]] + c.mesh.vertices[e[1]]) * 0.5f - org});
    }
    return rs;
}

inline ClosedMesh closed_cube(int k) {
    ClosedMesh c{"cube " + std::to_string(k) + "x" + std::to_string(k) + " per face", cube_mesh(k), {}};
    Rng rng(101);
    while (c.inside.size() < 64) c.inside.push_back({rng.uniform(-0.7f, 0.7f), rng.uniform(-0.7f, 0.7f), rng.uniform(-0.7f, 0.7f)});
    return c;
}

inline ClosedMesh closed_sphere(int stacks, int slices) {
    ClosedMesh c{"sphere " + std::to_string(stacks) + "x" + std::to_string(slices), sphere_mesh(stacks, slices), {}};
    Rng rng(102);
    while (c.inside.size() < 64) {
        const Vec3f p{rng.uniform(-0.6f, 0.6f), rng.uniform(-0.6f, 0.6f), rng.uniform(-0.6f, 0.6f)};
        if (dot(p, p) < 0.36f) c.inside.push_back(p);
    }
    return c;
}

inline ClosedMesh closed_torus(int nu, int nv) {
    const double R = 1.0, r = 0.4;
    ClosedMesh c{"torus " + std::to_string(nu) + "x" + std::to_string(nv), torus_mesh(R, r, nu, nv), {}};
    Rng rng(103);
    while (c.inside.size() < 64) {
        // within half the tube radius of the core circle
        const double u = 6.283185307179586 * rng.uniform(), w = 6.283185307179586 * rng.uniform(), d = 0.5 * r * rng.uniform();
        c.inside.push_back({float((R + d * std::cos(w)) * std::cos(u)), float((R + d * std::cos(w)) * std::sin(u)),
                            float(d * std::sin(w))});
    }
    return c;
}

/// The Stanford bunny with its holes closed (nullopt when the file is absent or cannot be closed);
/// inside points are found by parity and kept only when they are far from every vertex.
inline std::optional<ClosedMesh> closed_bunny() {
    if (!have_data("meshes/bun_zipper.ply")) return std::nullopt;
    auto closed = close_holes(io::read_ply(data_path("meshes/bun_zipper.ply")));
    if (!closed) return std::nullopt;
    ClosedMesh c{"bunny (holes closed)", std::move(*closed), {}};
    const auto tris = c.mesh.triangles();
    const AABBf b = c.mesh.bounds();
    const float margin = 0.05f * length(b.diagonal());
    Rng rng(104);
    for (int tries = 0; tries < 400 && c.inside.size() < 24; ++tries) {
        const Vec3f p = b.min + b.diagonal() * Vec3f{rng.uniform(0.2f, 0.8f), rng.uniform(0.2f, 0.8f), rng.uniform(0.2f, 0.8f)};
        bool far = true;
        for (const auto& v : c.mesh.vertices)
            if (dot(v - p, v - p) < margin * margin) { far = false; break; }
        if (far && inside_by_parity(tris, p)) c.inside.push_back(p);
    }
    return c;
}

// ---- builders ----------------------------------------------------------------------------------

inline constexpr const char* builder_names[] = {"lbvh", "lbvh-63", "ploc", "kbvh", "kbvh-lbvh", "binned-sah"};
inline constexpr std::size_t builder_count = std::size(builder_names);

/// Runs f(builder index, bvh, single_reference) for every builder on executor `ex`. The presplit ones
/// split heavily (beta 0.5 and 0.3) so that presplitting meets every case too.
template <class Exec, class F>
void for_each_builder(std::span<const Trianglef> tris, const Exec& ex, F&& f) {
    f(std::size_t(0), lbvh::build(tris, {}, ex), true);
    f(std::size_t(1), lbvh::build<Node<>, prim::copied>(tris, {.morton_bits = 63}, ex), true);
    f(std::size_t(2), ploc::build(tris, {.radius = 5}, ex), true);
    f(std::size_t(3), kbvh::build(tris, {.split = {.beta = 0.5f}}, ex), false);
    f(std::size_t(4), kbvh::build<Node<>, prim::indexed, kbvh::with_lbvh>(tris, {.split = {.beta = 0.3f}}, ex), false);
    f(std::size_t(5), binned_sah::build(tris, {}, ex), true);
}

// ---- rays --------------------------------------------------------------------------------------

/// Kinds of adversarial rays (names in ray_kind_names).
enum RayKind : std::uint8_t {
    aimed_point,        ///< from around the scene (or near the target) to a random point of a triangle
    aimed_vertex,       ///< ... exactly at a vertex
    aimed_edge,         ///< ... at a point a + t (b - a) of an edge
    axis_signed_zero,   ///< parallel to an axis, the other components +0 or -0
    axis_vertex,        ///< parallel to an axis exactly through a vertex
    axis_box_plane,     ///< parallel to an axis, lying exactly in a plane (or edge line) of a triangle's box
    grazing,            ///< nearly parallel to a triangle's plane (angles 1e-3 .. 0) towards its interior
    origin_box_face,    ///< origin exactly on a face of a triangle's box, random direction
    origin_vertex,      ///< origin exactly at a vertex, random direction
    origin_surface,     ///< origin at a point of a triangle (interior or edge), random direction
    tmin_is_tmax,       ///< tmin == tmax, half of them equal to the hit distance of the unclipped ray
    huge_tmax,          ///< tmax 1e30, FLT_MAX or inf; some with tmin = -FLT_MAX or -inf
    tiny_tmax,          ///< tmax 0, denorm_min, 1e-30 or 1e-7 (origins on the surface)
    not_traceable,      ///< NaN / inf origin or direction, zero direction, NaN or empty interval
    ray_kind_count
};
inline constexpr const char* ray_kind_names[] = {
    "aimed point", "aimed vertex", "aimed edge", "axis +-0", "axis through vertex", "axis in box plane", "grazing",
    "origin on box face", "origin at vertex", "origin on surface", "tmin == tmax", "huge tmax", "tiny tmax", "NaN/inf/empty"};
static_assert(std::size(ray_kind_names) == ray_kind_count);

struct RaySet {
    std::vector<Rayf> rays;
    std::vector<RayKind> kind;
};

/// `per_kind` rays of every kind against the finite triangles of `tris` (at least one finite triangle).
/// Origins alternate between a sphere around the scene and a shell around the target whose size is the
/// target triangle's, so that tiny triangles in a huge scene are aimed at from close by too.
inline RaySet adversarial_rays(std::span<const Trianglef> tris, std::size_t per_kind, std::uint64_t seed) {
    std::vector<std::uint32_t> finite;
    AABBf bounds;
    for (std::size_t i = 0; i < tris.size(); ++i)
        if (tris[i].is_finite()) {
            finite.push_back(std::uint32_t(i));
            bounds.extend(tris[i].bounds());
        }
    RaySet set;
    if (finite.empty()) return set;
    Rng rng(seed);
    // Extents are computed in double: for scenes near FLT_MAX the float diagonal overflows.
    auto clamp_f = [](double x) { return float(std::clamp(x, -3.0e38, 3.0e38)); };
    const Vec3d lo{bounds.min.x, bounds.min.y, bounds.min.z}, hi{bounds.max.x, bounds.max.y, bounds.max.z};
    const Vec3d centre = (lo + hi) * 0.5;
    const double radius = std::max(length(hi - lo), std::max(1e-30, 1e-6 * length(centre)));
    auto unit = [&] {
        for (;;) {
            const Vec3f d{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
            if (dot(d, d) > 0.01f && dot(d, d) <= 1) return normalize(d);
        }
    };
    auto tri = [&]() -> const Trianglef& { return tris[finite[rng.next() % finite.size()]]; };
    auto size_of = [](const Trianglef& t) {
        const Vec3f d = t.bounds().diagonal();
        const double s = std::sqrt(double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z);
        return s > 0 ? s : std::max(1e-30, 1e-6 * std::abs(double(t.p0.x)) + 1e-6 * std::abs(double(t.p0.y)));
    };
    auto origin_for = [&](const Vec3f& target, const Trianglef& t, std::size_t i) {
        const Vec3f u = unit();
        if (i % 2 == 0)
            return Vec3f{clamp_f(centre.x + u.x * radius), clamp_f(centre.y + u.y * radius), clamp_f(centre.z + u.z * radius)};
        const double s = size_of(t) * (1 + 9 * rng.uniform());
        return Vec3f{clamp_f(target.x + u.x * s), clamp_f(target.y + u.y * s), clamp_f(target.z + u.z * s)};
    };
    auto interior = [&](const Trianglef& t) {
        float a = rng.uniform(), b = rng.uniform();
        if (a + b > 1) { a = 1 - a; b = 1 - b; }
        return t.p0 * (1 - a - b) + t.p1 * a + t.p2 * b;
    };
    auto vertex = [&](const Trianglef& t) { const auto k = rng.next() % 3; return k == 0 ? t.p0 : (k == 1 ? t.p1 : t.p2); };
    auto edge_point = [&](const Trianglef& t) {
        const auto k = rng.next() % 3;
        const Vec3f a = k == 0 ? t.p0 : (k == 1 ? t.p1 : t.p2), b = k == 0 ? t.p1 : (k == 1 ? t.p2 : t.p0);
        return a + (b - a) * rng.uniform();
    };
    auto signed_zero = [&] { return rng.next() % 2 ? 0.0f : -0.0f; };
    auto axis_dir = [&](std::size_t a, float s) {
        Vec3f d{signed_zero(), signed_zero(), signed_zero()};
        d[a] = s;
        return d;
    };
    auto push = [&](Rayf r, RayKind k) {
        set.rays.push_back(r);
        set.kind.push_back(k);
    };
    const float outside_lo[3] = {clamp_f(lo.x - radius), clamp_f(lo.y - radius), clamp_f(lo.z - radius)};
    const float outside_hi[3] = {clamp_f(hi.x + radius), clamp_f(hi.y + radius), clamp_f(hi.z + radius)};

    for (std::size_t i = 0; i < per_kind; ++i) {
        {   // aimed point / vertex / edge
            const auto& t = tri();
            const Vec3f p = interior(t), o = origin_for(p, t, i);
            push({o, p - o}, aimed_point);
            const auto& t2 = tri();
            const Vec3f v = vertex(t2), o2 = origin_for(v, t2, i);
            push({o2, v - o2}, aimed_vertex);
            const auto& t3 = tri();
            const Vec3f e = edge_point(t3), o3 = origin_for(e, t3, i);
            push({o3, e - o3}, aimed_edge);
        }
        {   // axis-parallel rays with signed zeros: random origin in the bounds, or an origin on a triangle
            const auto& t = tri();
            const std::size_t a = rng.next() % 3;
            Vec3f o = i % 2 ? interior(t) : Vec3f{clamp_f(lo.x + (hi.x - lo.x) * rng.uniform()),
                                                   clamp_f(lo.y + (hi.y - lo.y) * rng.uniform()),
                                                   clamp_f(lo.z + (hi.z - lo.z) * rng.uniform())};
            const float s = rng.next() % 2 ? 1.0f : -1.0f;
            o[a] = s > 0 ? outside_lo[a] : outside_hi[a];
            push({o, axis_dir(a, s)}, axis_signed_zero);
        }
        {   // exactly through a vertex, parallel to an axis
            const auto& t = tri();
            const std::size_t a = rng.next() % 3;
            Vec3f o = vertex(t);
            const float s = rng.next() % 2 ? 1.0f : -1.0f;
            o[a] = s > 0 ? outside_lo[a] : outside_hi[a];
            push({o, axis_dir(a, s)}, axis_vertex);
        }
        {   // lying in a plane of a triangle's box (or on an edge line of it), parallel to an axis
            const auto& t = tri();
            const AABBf tb = t.bounds();
            const std::size_t a = rng.next() % 3, b = (a + 1 + rng.next() % 2) % 3, c = 3 - a - b;
            Vec3f o;
            o[b] = rng.next() % 2 ? tb.min[b] : tb.max[b];
            o[c] = rng.next() % 3 == 0 ? (rng.next() % 2 ? tb.min[c] : tb.max[c]) : tb.min[c] + (tb.max[c] - tb.min[c]) * rng.uniform();
            const float s = rng.next() % 2 ? 1.0f : -1.0f;
            o[a] = s > 0 ? outside_lo[a] : outside_hi[a];
            push({o, axis_dir(a, s)}, axis_box_plane);
        }
        {   // grazing: nearly in the triangle's plane, towards an interior point
            const auto& t = tri();
            const Vec3f n = t.normal();
            const Vec3f p = interior(t);
            if (is_finite(n) && dot(n, n) > 0 && std::isfinite(dot(n, n))) {
                const Vec3f nh = normalize(n);
                Vec3f in_plane = cross(nh, unit());
                if (!(dot(in_plane, in_plane) > 0)) in_plane = cross(nh, Vec3f{1, 0, 0});
                const float tilt[] = {1e-3f, 1e-5f, 1e-7f, 0.0f, -1e-6f};
                const Vec3f d = normalize(in_plane) + nh * tilt[i % 5];
                const float s = float(size_of(t) * (0.5 + 4 * rng.uniform()));
                push({p - d * s, d}, grazing);
            } else {
                const Vec3f o = origin_for(p, t, i);
                push({o, p - o}, grazing);
            }
        }
        {   // origin on a face of a triangle's box
            const auto& t = tri();
            const AABBf tb = t.bounds();
            Vec3f o = tb.min + tb.diagonal() * Vec3f{rng.uniform(), rng.uniform(), rng.uniform()};
            const std::size_t a = rng.next() % 3;
            o[a] = rng.next() % 2 ? tb.min[a] : tb.max[a];
            push({o, unit()}, origin_box_face);
        }
        {   // origin at a vertex or on a triangle
            const auto& t = tri();
            push({vertex(t), unit()}, origin_vertex);
            const auto& t2 = tri();
            push({i % 2 ? interior(t2) : edge_point(t2), unit()}, origin_surface);
        }
        {   // tmin == tmax: the exact hit distance of the unclipped ray (when it hits), or a random value
            const auto& t = tri();
            const Vec3f p = interior(t), o = origin_for(p, t, i);
            Rayf r{o, p - o};
            const Hitf h = brute_force_intersect(tris, r);
            r.tmin = r.tmax = (h && i % 2 == 0) ? h.t : rng.uniform(0.5f, 1.5f);
            push(r, tmin_is_tmax);
        }
        {   // huge tmax (and very negative tmin)
            const auto& t = tri();
            const Vec3f p = interior(t), o = origin_for(p, t, i);
            Rayf r{o, p - o};
            const float tmax[] = {1e30f, std::numeric_limits<float>::max(), finf};
            r.tmax = tmax[i % 3];
            if (i % 4 == 3) r.tmin = i % 8 == 3 ? -std::numeric_limits<float>::max() : -finf;
            push(r, huge_tmax);
        }
        {   // tiny tmax from a surface point
            const auto& t = tri();
            const float tmax[] = {0.0f, std::numeric_limits<float>::denorm_min(), 1e-30f, 1e-7f};
            push({i % 2 ? interior(t) : vertex(t), unit(), 0.0f, tmax[i % 4]}, tiny_tmax);
        }
        {   // rays that cannot be traced
            const auto& t = tri();
            const Vec3f p = interior(t), o = origin_for(p, t, i);
            Rayf r{o, p - o};
            switch (i % 10) {
            case 0: r.org[rng.next() % 3] = fnan; break;
            case 1: r.org[rng.next() % 3] = rng.next() % 2 ? finf : -finf; break;
            case 2: r.dir[rng.next() % 3] = fnan; break;
            case 3: r.dir[rng.next() % 3] = rng.next() % 2 ? finf : -finf; break;
            case 4: r.dir = {signed_zero(), signed_zero(), signed_zero()}; break;
            case 5: r.tmin = fnan; break;
            case 6: r.tmax = fnan; break;
            case 7: r.tmin = 2; r.tmax = 1; break;
            case 8: r.tmin = finf; r.tmax = finf; break;
            default: r.org = {fnan, fnan, fnan}; r.dir = {fnan, fnan, fnan}; break;
            }
            push(r, not_traceable);
        }
    }
    return set;
}

// ---- comparison with brute force ----------------------------------------------------------------

struct Reference {
    std::vector<Hitf> hits;
    std::vector<char> occluded;
};

/// Brute-force answers of every ray with `Policy`'s triangle test (parallel).
template <class Policy>
Reference brute_force(std::span<const Trianglef> tris, std::span<const Rayf> rays) {
    Reference ref;
    ref.hits.resize(rays.size());
    ref.occluded.resize(rays.size());
    exec::default_executor{}.for_each(0, rays.size(), [&](std::size_t i) {
        ref.hits[i] = brute_force_intersect<Policy>(tris, rays[i]);
        ref.occluded[i] = brute_force_occluded<Policy>(tris, rays[i]) ? 1 : 0;
    }, 16);
    return ref;
}

/// Disagreements of a BVH with brute force: closest hit (hit or miss, t to the bit, the same triangle
/// or an exact tie, u and v to the bit), any hit (occluded == brute-force occluded). Per ray kind.
struct Disagreements {
    std::array<std::size_t, ray_kind_count> by_kind{};
    std::size_t total = 0;
    std::string first;   ///< the first one, described
};

template <class Policy, class B>
Disagreements compare_with(const B& bvh, std::span<const Trianglef> tris, const RaySet& set, const Reference& ref) {
    using Tri = typename Policy::triangle_test;
    Disagreements d;
    for (std::size_t i = 0; i < set.rays.size(); ++i) {
        const Rayf& ray = set.rays[i];
        const Hitf h = intersect<Policy>(bvh, tris, ray);
        const Hitf& e = ref.hits[i];
        bool ok = same_hit<Tri>(h, e, tris, ray);
        const bool occ = occluded<Policy>(bvh, tris, ray);
        if (occ != bool(ref.occluded[i])) ok = false;
        if (!ok) {
            ++d.total;
            ++d.by_kind[set.kind[i]];
            if (d.first.empty()) {
                std::ostringstream s;
                s.precision(9);
                s << ray_kind_names[set.kind[i]] << " ray " << describe(ray) << ": bvh prim " << h.prim << " t " << h.t
                  << " occluded " << occ << " / brute force prim " << e.prim << " t " << e.t << " occluded "
                  << int(ref.occluded[i]);
                d.first = s.str();
            }
        }
    }
    return d;
}

/// "kind: n, kind: n" for the kinds with disagreements.
inline std::string by_kind(const Disagreements& d) {
    std::string s;
    for (std::size_t k = 0; k < ray_kind_count; ++k)
        if (d.by_kind[k]) s += (s.empty() ? "" : ", ") + std::string(ray_kind_names[k]) + ": " + std::to_string(d.by_kind[k]);
    return s;
}

} // namespace dynbvh::test

namespace dynbvh::test {

/// One scene through every builder x every executor: a valid tree within max_depth, and the robust
/// bundle's answers equal to brute force (to the bit) on `per_kind` rays of every adversarial kind.
/// The fast box test (with the watertight triangle test) and the fast bundle are compared too and
/// only reported: they may lose grazing hits by design. Prints one line per builder.
inline void check_case(const std::string& name, std::span<const Trianglef> tris, std::size_t per_kind, std::uint64_t seed) {
    CAPTURE(name);
    const RaySet set = adversarial_rays(tris, per_kind, seed);
    const Reference robust = brute_force<trace::robust>(tris, set.rays);
    const Reference fast = brute_force<trace::fast>(tris, set.rays);
    using fast_box = trace::policy<box::fast, tri::watertight>;
    std::size_t hits = 0;
    for (const auto& h : robust.hits) hits += h ? 1 : 0;
    for (std::size_t i = 0; i < set.rays.size(); ++i)
        if (set.kind[i] == not_traceable) CHECK_FALSE((robust.hits[i] || robust.occluded[i] || fast.hits[i] || fast.occluded[i]));

    struct Row {
        std::size_t builds = 0, invalid = 0, robust = 0, fast_box = 0, fast = 0;
        std::uint32_t depth = 0;
        std::string fast_kinds;
    };
    std::array<Row, builder_count> rows{};
    for_each_executor([&](auto ex) {
        const std::string executor = executor_name<decltype(ex)>();
        CAPTURE(executor);
        for_each_builder(tris, ex, [&](std::size_t b, const auto& bvh, bool single) {
            const std::string builder = builder_names[b];
            CAPTURE(builder);
            Row& row = rows[b];
            ++row.builds;
            const std::string problems = structure_problems(bvh, tris, single);
            CHECK(problems == "");
            row.invalid += problems.empty() ? 0 : 1;
            CHECK(bvh.depth <= max_depth);
            row.depth = std::max(row.depth, bvh.depth);
            const Disagreements r = compare_with<trace::robust>(bvh, tris, set, robust);
            CHECK_MESSAGE(r.total == 0, r.total << " disagreements (" << by_kind(r) << "), first: " << r.first);
            row.robust += r.total;
            const Disagreements fb = compare_with<fast_box>(bvh, tris, set, robust);
            const Disagreements f = compare_with<trace::fast>(bvh, tris, set, fast);
            row.fast_box += fb.total;
            row.fast += f.total;
            if (row.fast_kinds.empty()) row.fast_kinds = by_kind(fb);
        });
    });
    std::ostringstream s;
    s << "[robustness] " << name << " (" << tris.size() << " triangles, " << set.rays.size() << " rays, " << hits
      << " hit) x " << rows[0].builds << " executors:";
    for (std::size_t b = 0; b < builder_count; ++b) {
        const Row& r = rows[b];
        s << "\n    " << builder_names[b] << ": " << (r.invalid ? "INVALID" : "valid") << ", depth <= " << r.depth
          << ", robust != brute force: " << r.robust << "; reported only: box::fast+watertight " << r.fast_box
          << ", trace::fast " << r.fast;
        if (!r.fast_kinds.empty()) s << " (box::fast misses by kind: " << r.fast_kinds << ")";
    }
    MESSAGE(s.str());
}

} // namespace dynbvh::test
