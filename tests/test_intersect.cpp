// Ray-box and ray-triangle policies (intersect.hpp): exact hand cases, signed zeros, NaN, and
// watertightness on closed meshes.
#include <doctest/doctest.h>

#include <dynbvh/intersect.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

using namespace dynbvh;

namespace {

constexpr float inf = std::numeric_limits<float>::infinity();
constexpr float qnan = std::numeric_limits<float>::quiet_NaN();

template <class Tri, class T>
Hit<T> hit_of(const Triangle<T>& tri, Vec3<T> org, Vec3<T> dir, T tmin = 0, T tmax = std::numeric_limits<T>::infinity()) {
    return intersect_triangle<Tri>(tri, Ray<T>{org, dir, tmin, tmax});
}

template <class Box, class T>
bool box_hit(const AABB<T>& b, Vec3<T> org, Vec3<T> dir, T tmin = 0, T tmax = std::numeric_limits<T>::infinity()) {
    return intersect_box<Box>(b, Ray<T>{org, dir, tmin, tmax});
}

// A closed mesh as an indexed triangle list plus its edges.
struct Mesh {
    std::vector<Vec3f> v;
    std::vector<std::uint32_t> idx;
    std::vector<Trianglef> tris() const {
        std::vector<Trianglef> t;
        for (std::size_t i = 0; i < idx.size(); i += 3) t.push_back({v[idx[i]], v[idx[i + 1]], v[idx[i + 2]]});
        return t;
    }
    std::vector<std::pair<std::uint32_t, std::uint32_t>> edges() const {
        std::vector<std::pair<std::uint32_t, std::uint32_t>> e;
        for (std::size_t i = 0; i < idx.size(); i += 3)
            for (int k = 0; k < 3; ++k) {
                std::uint32_t a = idx[i + k], b = idx[i + (k + 1) % 3];
                if (a > b) std::swap(a, b);
                e.emplace_back(a, b);
            }
        std::sort(e.begin(), e.end());
        e.erase(std::unique(e.begin(), e.end()), e.end());
        return e;
    }
};

Mesh cube() {
    Mesh m;
    for (int i = 0; i < 8; ++i) m.v.push_back({i & 1 ? 1.f : -1.f, i & 2 ? 1.f : -1.f, i & 4 ? 1.f : -1.f});
    const std::uint32_t q[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    for (auto& f : q) m.idx.insert(m.idx.end(), {f[0], f[1], f[2], f[0], f[2], f[3]});
    return m;
}

Mesh octahedron() {
    Mesh m;
    m.v = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (std::uint32_t x : {0u, 1u})
        for (std::uint32_t y : {2u, 3u})
            for (std::uint32_t z : {4u, 5u}) m.idx.insert(m.idx.end(), {x, y, z});
    return m;
}

// UV sphere with radial jitter (closed, star-shaped around the origin), non-representable coordinates.
Mesh bumpy_sphere(int stacks, int slices, std::uint32_t seed) {
    Mesh m;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> jitter(0.85f, 1.15f);
    const float pi = 3.14159265358979f;
    m.v.push_back({0, 0, jitter(rng)});
    for (int i = 1; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const float th = pi * float(i) / float(stacks), ph = 2 * pi * float(j) / float(slices);
            const float r = jitter(rng);
            m.v.push_back({r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th)});
        }
    m.v.push_back({0, 0, -jitter(rng)});
    const auto ring = [&](int i, int j) { return std::uint32_t(1 + (i - 1) * slices + (j % slices)); };
    const std::uint32_t south = std::uint32_t(m.v.size() - 1);
    for (int j = 0; j < slices; ++j) {
        m.idx.insert(m.idx.end(), {0u, ring(1, j), ring(1, j + 1)});
        m.idx.insert(m.idx.end(), {south, ring(stacks - 1, j + 1), ring(stacks - 1, j)});
        for (int i = 1; i + 1 < stacks; ++i) {
            m.idx.insert(m.idx.end(), {ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
            m.idx.insert(m.idx.end(), {ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
        }
    }
    return m;
}

// Rays from points inside a closed mesh aimed exactly at its vertices and at points on its edges: every
// such ray must hit some triangle. Returns the number of rays that hit nothing.
template <class Tri>
std::size_t leaks(const Mesh& m, const std::vector<Vec3f>& origins, int points_per_edge, std::size_t& rays) {
    const auto tris = m.tris();
    std::vector<Vec3f> targets = m.v;
    for (auto [a, b] : m.edges())
        for (int k = 1; k <= points_per_edge; ++k) {
            const float s = float(k) / float(points_per_edge + 1);
            targets.push_back(m.v[a] + (m.v[b] - m.v[a]) * s);
        }
    std::size_t miss = 0;
    for (const Vec3f& o : origins)
        for (const Vec3f& p : targets) {
            const Rayf r{o, p - o, 0.0f, inf};
            const typename Tri::template prepared<float> pr(r);
            bool any = false;
            for (const auto& t : tris) {
                float tt, u, v;
                if (Tri::test(pr, t, inf, tt, u, v)) {
                    any = true;
                    break;
                }
            }
            miss += any ? 0 : 1;
            ++rays;
        }
    return miss;
}

std::vector<Vec3f> inner_origins(int n, float radius, std::uint32_t seed) {
    std::vector<Vec3f> o{{0, 0, 0}, {0.125f, -0.25f, 0.0625f}};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> d(-radius, radius);
    while (int(o.size()) < n) o.push_back({d(rng), d(rng), d(rng)});
    return o;
}

} // namespace

TEST_CASE_TEMPLATE("triangle hand cases: exact t, u, v, both faces", Tri, tri::watertight, tri::moller_trumbore) {
    const Trianglef tri{{0, 0, 0}, {4, 0, 0}, {0, 4, 0}};
    SUBCASE("front face") {
        const Hitf h = hit_of<Tri>(tri, Vec3f{1, 2, 3}, Vec3f{0, 0, -1});
        REQUIRE(h);
        CHECK(h.t == 3.0f);
        CHECK(h.u == 0.25f);
        CHECK(h.v == 0.5f);
    }
    SUBCASE("back face") {
        const Hitf h = hit_of<Tri>(tri, Vec3f{1, 2, -3}, Vec3f{0, 0, 1});
        REQUIRE(h);
        CHECK(h.t == 3.0f);
        CHECK(h.u == 0.25f);
        CHECK(h.v == 0.5f);
    }
    SUBCASE("unnormalised oblique direction: t in units of |dir|") {
        // From (1,2,3) towards (2,1,0) with dir = (1,-1,-3) * 0.5: t = 2.
        const Hitf h = hit_of<Tri>(tri, Vec3f{1, 2, 3}, Vec3f{0.5f, -0.5f, -1.5f});
        REQUIRE(h);
        CHECK(h.t == doctest::Approx(2.0f).epsilon(1e-6));
        CHECK(h.u == doctest::Approx(0.5f).epsilon(1e-6));
        CHECK(h.v == doctest::Approx(0.25f).epsilon(1e-6));
    }
    SUBCASE("the hit point is (1-u-v) p0 + u p1 + v p2 for a general triangle") {
        const Trianglef g{{0.3f, -1.2f, 0.7f}, {2.1f, 0.4f, -0.5f}, {-0.8f, 1.9f, 0.2f}};
        const float wu = 0.3f, wv = 0.45f;
        const Vec3f target = g.p0 * (1 - wu - wv) + g.p1 * wu + g.p2 * wv;
        const Vec3f org{0.2f, 0.1f, 5.0f};
        const Hitf h = hit_of<Tri>(g, org, target - org);
        REQUIRE(h);
        CHECK(h.t == doctest::Approx(1.0f).epsilon(1e-5));
        CHECK(h.u == doctest::Approx(wu).epsilon(1e-5));
        CHECK(h.v == doctest::Approx(wv).epsilon(1e-5));
    }
    SUBCASE("misses") {
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{3, 3, 1}, Vec3f{0, 0, -1}));            // outside the hypotenuse
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 1}, Vec3f{0, 0, 1}));             // triangle behind (t = -1)
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, 0.f, 2.9f)); // beyond tmax
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, 3.1f, inf)); // before tmin
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 0}, Vec3f{1, 0, 0}));             // in the plane: edge-on
    }
    SUBCASE("interval is closed: tmin == tmax == t hits") {
        CHECK(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, 3.0f, 3.0f));
        CHECK(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, 3.0f, inf));
        CHECK(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, 0.0f, 3.0f));
    }
    SUBCASE("signed zero direction components") {
        for (float sx : {0.0f, -0.0f})
            for (float sy : {0.0f, -0.0f}) {
                const Hitf h = hit_of<Tri>(tri, Vec3f{1, 2, 3}, Vec3f{sx, sy, -2});
                REQUIRE(h);
                CHECK(h.t == 1.5f);
                CHECK(h.u == 0.25f);
                CHECK(h.v == 0.5f);
            }
        // Along -x with y, z components +-0 through a triangle in the plane x = 0.
        const Trianglef yz{{0, 0, 0}, {0, 2, 0}, {0, 0, 2}};
        for (float s : {0.0f, -0.0f}) {
            const Hitf h = hit_of<Tri>(yz, Vec3f{5, 0.5f, 0.5f}, Vec3f{-1, s, -s});
            REQUIRE(h);
            CHECK(h.t == 5.0f);
            CHECK(h.u == 0.25f);
            CHECK(h.v == 0.25f);
        }
    }
    SUBCASE("NaN and infinity: no hit, no UB") {
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{qnan, 1, 3}, Vec3f{0, 0, -1}));
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, qnan, -1}));
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, inf}, Vec3f{0, 0, -1}));
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -inf}));
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, 0}));
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, qnan, inf));
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, 0.0f, qnan));
        CHECK_FALSE(hit_of<Tri>(tri, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}, 4.0f, 2.0f));  // empty interval
        // The prepared ray alone (without intersect_triangle's check) also misses.
        const typename Tri::template prepared<float> p(Rayf{{1, 1, 3}, {qnan, 0, -1}, 0, inf});
        float t = -1, u = -1, v = -1;
        CHECK_FALSE(Tri::test(p, tri, inf, t, u, v));
        // A triangle with a NaN or infinite vertex is never hit.
        const Trianglef bad{{0, 0, 0}, {qnan, 0, 0}, {0, 4, 0}};
        CHECK_FALSE(hit_of<Tri>(bad, Vec3f{1, 1, 3}, Vec3f{0, 0, -1}));
    }
    SUBCASE("degenerate triangles miss") {
        CHECK_FALSE(hit_of<Tri>(Trianglef{{0, 0, 0}, {1, 1, 0}, {2, 2, 0}}, Vec3f{1, 1, 1}, Vec3f{0, 0, -1}));
        CHECK_FALSE(hit_of<Tri>(Trianglef{{1, 1, 0}, {1, 1, 0}, {1, 1, 0}}, Vec3f{1, 1, 1}, Vec3f{0, 0, -1}));
    }
}

TEST_CASE("watertight: ray exactly through a shared edge or vertex is a hit with t and matching barycentrics") {
    // Two triangles sharing the edge (0,0,0)-(2,2,0).
    const Trianglef a{{0, 0, 0}, {2, 0, 0}, {2, 2, 0}}, b{{0, 0, 0}, {2, 2, 0}, {0, 2, 0}};
    const Hitf ha = hit_of<tri::watertight>(a, Vec3f{1, 1, 1}, Vec3f{0, 0, -1});
    const Hitf hb = hit_of<tri::watertight>(b, Vec3f{1, 1, 1}, Vec3f{0, 0, -1});
    REQUIRE(ha);
    REQUIRE(hb);
    CHECK(ha.t == 1.0f);
    CHECK(hb.t == 1.0f);
    CHECK(ha.u == 0.0f);   // on the edge p0-p2 of a: weight of p1 is 0
    CHECK(ha.v == 0.5f);
    CHECK(hb.u == 0.5f);   // on the edge p0-p1 of b
    CHECK(hb.v == 0.0f);
    // Through the shared vertex (2,2,0).
    const Hitf va = hit_of<tri::watertight>(a, Vec3f{2, 2, 7}, Vec3f{0, 0, -1});
    REQUIRE(va);
    CHECK(va.t == 7.0f);
    CHECK(va.u == 0.0f);
    CHECK(va.v == 1.0f);
}

TEST_CASE("double precision triangles") {
    const Triangled tri{{0, 0, 0}, {4, 0, 0}, {0, 4, 0}};
    const Hit<double> w = hit_of<tri::watertight>(tri, Vec3d{1, 2, 3}, Vec3d{0, 0, -1});
    const Hit<double> m = hit_of<tri::moller_trumbore>(tri, Vec3d{1, 2, 3}, Vec3d{-0.0, 0, -1});
    REQUIRE(w);
    REQUIRE(m);
    CHECK(w.t == 3.0);
    CHECK(w.u == 0.25);
    CHECK(w.v == 0.5);
    CHECK(m.t == 3.0);
    CHECK(m.u == 0.25);
    CHECK(m.v == 0.5);
    // Shared edge in double, ray exactly on it: both neighbours hit.
    const Triangled a{{0.1, 0.3, 0}, {2.7, 0.1, 0}, {2.3, 2.9, 0}}, b{{0.1, 0.3, 0}, {2.3, 2.9, 0}, {0.2, 2.5, 0}};
    const double s = 0.37;
    const Vec3d onedge = a.p0 + (a.p2 - a.p0) * s, org{onedge.x, onedge.y, 1.5};
    const bool ha = bool(hit_of<tri::watertight>(a, org, Vec3d{0, 0, -1}));
    const bool hb = bool(hit_of<tri::watertight>(b, org, Vec3d{0, 0, -1}));
    CHECK((ha || hb));
}

TEST_CASE_TEMPLATE("box tests: hits, misses, signed zeros, origins on faces, NaN", Box, box::robust, box::fast) {
    const AABBf b{{0, 0, 0}, {1, 1, 1}};
    CHECK(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{0, 0, -1}));
    CHECK(box_hit<Box>(b, Vec3f{-1, -1, -1}, Vec3f{1, 1, 1}));
    CHECK(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 0.5f}, Vec3f{0.3f, -0.2f, 0.1f}));  // origin inside
    CHECK_FALSE(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{0, 0, 1}));          // box behind
    CHECK_FALSE(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{0, 0, -1}, 0.f, 0.5f));  // tmax before entry
    CHECK_FALSE(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{0, 0, -1}, 3.5f, inf));  // tmin after exit
    CHECK_FALSE(box_hit<Box>(b, Vec3f{2, 2, 2}, Vec3f{1, 0, 0}));
    for (float z0 : {0.0f, -0.0f})
        for (float z1 : {0.0f, -0.0f}) {
            // parallel to x and y (components +-0), inside both slabs
            CHECK(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{z0, z1, -1}));
            // parallel, outside the x slab: a miss whatever the sign of zero
            CHECK_FALSE(box_hit<Box>(b, Vec3f{1.5f, 0.5f, 2}, Vec3f{z0, z1, -1}));
            CHECK_FALSE(box_hit<Box>(b, Vec3f{-0.5f, 0.5f, 2}, Vec3f{z0, z1, -1}));
            // parallel and lying exactly in a face plane of the closed box: a hit for the robust test
            // (box::fast replaces a zero component by a tiny one of the same sign, so it counts a ray in
            // the max face with +0, or in the min face with -0, as leaving: documented, not tested)
            if constexpr (std::is_same_v<Box, box::robust>) {
                CHECK(box_hit<Box>(b, Vec3f{1, 0.5f, 2}, Vec3f{z0, z1, -1}));
                CHECK(box_hit<Box>(b, Vec3f{0, 0, 2}, Vec3f{z0, z1, -1}));
                CHECK(box_hit<Box>(b, Vec3f{1, 1, 2}, Vec3f{z0, z1, -1}));
            }
        }
    // Degenerate (flat) box, as a leaf holding one axis-aligned triangle has.
    const AABBf flat{{0, 0, 0.5f}, {1, 1, 0.5f}};
    CHECK(box_hit<Box>(flat, Vec3f{0.5f, 0.5f, 2}, Vec3f{0, 0, -1}));
    CHECK(box_hit<Box>(flat, Vec3f{0.25f, 0.5f, 0.5f}, Vec3f{1, 0, 0}));   // in the plane
    CHECK(box_hit<Box>(flat, Vec3f{0.25f, 0.5f, 0.5f}, Vec3f{1, -0.0f, 0}));
    CHECK_FALSE(box_hit<Box>(flat, Vec3f{0.25f, 0.5f, 0.6f}, Vec3f{1, 0, 0}));
    // Origin on a face, leaving or entering.
    CHECK(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 1}, Vec3f{0, 0, 1}));
    CHECK(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 1}, Vec3f{0, 0, -1}));
    // NaN / inf / zero rays miss.
    CHECK_FALSE(box_hit<Box>(b, Vec3f{qnan, 0.5f, 2}, Vec3f{0, 0, -1}));
    CHECK_FALSE(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{qnan, 0, -1}));
    CHECK_FALSE(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{0, 0, 0}));
    CHECK_FALSE(box_hit<Box>(b, Vec3f{0.5f, 0.5f, inf}, Vec3f{0, 0, -1}));
    CHECK_FALSE(box_hit<Box>(b, Vec3f{0.5f, 0.5f, 2}, Vec3f{0, 0, -1}, qnan, inf));
    const typename Box::template prepared<float> p(Rayf{{0.5f, 0.5f, 2}, {qnan, qnan, qnan}, 0, inf});
    float te;
    CHECK_FALSE(Box::test(p, b.min, b.max, inf, te));
    // Entry distance.
    const typename Box::template prepared<float> q(Rayf{{0.5f, 0.5f, 3}, {0, 0, -1}, 0, inf});
    REQUIRE(Box::test(q, b.min, b.max, inf, te));
    CHECK(te == 2.0f);
    // Normal directions are not scaled.
    CHECK(q.t_scale == 1.0f);
    if constexpr (!std::is_same_v<Box, box::robust>) return;  // box::fast replaces components below 1e-30
    // Subnormal direction components (1 / dir overflows): the ray is not taken as parallel to the axes.
    const AABBf tiny{{1e-40f, 1e-40f, 1e-40f}, {2e-40f, 2e-40f, 2e-40f}};
    const Rayf sub{{0, 0, 0}, {1e-41f, 1e-41f, 1e-41f}, 0, inf};
    const typename Box::template prepared<float> s(sub);
    CHECK(s.t_scale < 1.0f);
    REQUIRE(Box::test(s, tiny.min, tiny.max, inf, te));
    CHECK(te == doctest::Approx(1e-40f / 1e-41f).epsilon(1e-3));
    CHECK_FALSE(Box::test(s, tiny.min, tiny.max, 9.0f, te));  // the box starts at t ~ 10
    CHECK_FALSE(box_hit<Box>(tiny, Vec3f{0, 0, 0}, Vec3f{-1e-41f, 1e-41f, 1e-41f}));
    // One subnormal component beside normal ones: the ray climbs 1e-41 per unit of t.
    const AABBf slab{{0.5f, 0.5f, 0.9e-40f}, {1.5f, 1.5f, 1.1e-40f}};
    CHECK(box_hit<Box>(slab, Vec3f{0, 0, 0}, Vec3f{0.1f, 0.1f, 1e-41f}));
    CHECK_FALSE(box_hit<Box>(slab, Vec3f{0, 0, 0}, Vec3f{0.1f, 0.1f, 4e-41f}));
}

TEST_CASE("robust box never loses a triangle the watertight test hits (rays aimed at vertices)") {
    // For each triangle, a ray aimed exactly at a vertex hits the triangle's own bounding box (the vertex
    // lies on the box boundary) whenever the watertight test hits the triangle; this is what makes
    // traversal agree with brute force. The fast box test is allowed to lose some: count them.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> d(-100.f, 100.f), small(-1.f, 1.f);
    std::size_t rays = 0, tri_hits = 0, robust_lost = 0, fast_lost = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec3f c{d(rng), d(rng), d(rng)};
        const Trianglef t{c + Vec3f{small(rng), small(rng), small(rng)}, c + Vec3f{small(rng), small(rng), small(rng)},
                          c + Vec3f{small(rng), small(rng), small(rng)}};
        const AABBf bb = t.bounds();
        for (const Vec3f& target : {t.p0, t.p1, t.p2, (t.p0 + t.p1) * 0.5f}) {
            const Vec3f org{d(rng), d(rng), d(rng)};
            const Rayf r{org, target - org, 0.0f, inf};
            ++rays;
            const Hitf h = intersect_triangle<tri::watertight>(t, r);
            if (!h) continue;
            ++tri_hits;
            Rayf clipped = r;
            clipped.tmax = h.t;  // the box must also be found when the ray is clipped at this very hit
            robust_lost += intersect_box<box::robust>(bb, clipped) ? 0 : 1;
            fast_lost += intersect_box<box::fast>(bb, clipped) ? 0 : 1;
        }
    }
    MESSAGE("vertex-aimed rays: " << rays << ", watertight hits: " << tri_hits << ", boxes lost: robust " << robust_lost
                                  << ", fast " << fast_lost);
    CHECK(tri_hits > rays / 4);
    CHECK(robust_lost == 0);
}

TEST_CASE("watertight: rays from inside closed meshes through their edges and vertices never escape") {
    struct Case {
        std::string name;
        Mesh mesh;
        float radius;  // origins are drawn in [-radius, radius]^3 (inside the mesh)
    };
    const Case cases[] = {{"cube (12 triangles)", cube(), 0.9f},
                          {"octahedron", octahedron(), 0.3f},
                          {"bumpy sphere 10x14", bumpy_sphere(10, 14, 1), 0.4f},
                          {"bumpy sphere 16x24", bumpy_sphere(16, 24, 2), 0.4f}};
    std::size_t total_rays = 0, total_mt = 0;
    for (const Case& c : cases) {
        const auto origins = inner_origins(c.mesh.v.size() > 100 ? 10 : 24, c.radius, 11);
        std::size_t rays_w = 0, rays_m = 0;
        const std::size_t w = leaks<tri::watertight>(c.mesh, origins, 5, rays_w);
        const std::size_t m = leaks<tri::moller_trumbore>(c.mesh, origins, 5, rays_m);
        MESSAGE(c.name << ": " << rays_w << " rays at edges and vertices; escaped: watertight " << w
                       << ", moller_trumbore " << m);
        CHECK_MESSAGE(w == 0, c.name);
        total_rays += rays_w;
        total_mt += m;
    }
    MESSAGE("total " << total_rays << " rays; Möller–Trumbore let " << total_mt << " through");
    // The harness can fail: the non-watertight test leaks on this very set of rays.
    CHECK(total_mt > 0);
}
