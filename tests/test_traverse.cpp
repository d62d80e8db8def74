// Traversal (traverse.hpp): closest hit equals brute force with the same triangle test (same t to the
// bit, same primitive or an exact tie), any hit agrees with closest hit, for both primitive policies
// and every policy bundle, on hand-made trees, a reference median-split tree and (when present) LBVH.
#include <doctest/doctest.h>

#include <dynbvh/traverse.hpp>
#include <dynbvh/validate.hpp>

#include "hit_compare.hpp"
#include "sanitized.hpp"
#include "simple_builder.hpp"

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <dynbvh/lbvh.hpp>

using namespace dynbvh;
using dynbvh::test::caterpillar_build;
using dynbvh::test::median_build;
using dynbvh::test::describe;
using dynbvh::test::same_bits;
using dynbvh::test::same_hit;

namespace {

template <class T>
constexpr T inf_v = std::numeric_limits<T>::infinity();

template <class T>
std::vector<Triangle<T>> random_soup(std::size_t n, std::uint32_t seed, T extent = T(10), T size = T(1)) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<T> c(0, extent), d(-size, size);
    std::vector<Triangle<T>> tris(n);
    for (auto& t : tris) {
        const Vec3<T> o{c(rng), c(rng), c(rng)};
        t = {o + Vec3<T>{d(rng), d(rng), d(rng)}, o + Vec3<T>{d(rng), d(rng), d(rng)}, o + Vec3<T>{d(rng), d(rng), d(rng)}};
    }
    // Exact duplicates (ties) and a few axis-aligned triangles (flat boxes).
    for (std::size_t i = 0; i + 7 < n; i += 37) tris[i + 7] = tris[i];
    for (std::size_t i = 3; i < n; i += 53) tris[i].p1.z = tris[i].p2.z = tris[i].p0.z;
    return tris;
}

enum class Kind { random, aimed_interior, aimed_vertex, axis, axis_through_vertex, clipped };
constexpr Kind all_kinds[] = {Kind::random, Kind::aimed_interior, Kind::aimed_vertex, Kind::axis, Kind::axis_through_vertex, Kind::clipped};

// A mix of ray kinds over the soup's bounds [lo, hi].
template <class T>
std::vector<Ray<T>> make_rays(const std::vector<Triangle<T>>& tris, std::size_t n, std::uint32_t seed,
                              std::vector<Kind>& kinds, bool grazing) {
    std::mt19937 rng(seed);
    AABB<T> b;
    for (const auto& t : tris)
        if (t.is_finite()) b.extend(t.bounds());
    const Vec3<T> lo = b.min - Vec3<T>{1, 1, 1}, hi = b.max + Vec3<T>{1, 1, 1};
    std::uniform_real_distribution<T> ux(lo.x, hi.x), uy(lo.y, hi.y), uz(lo.z, hi.z), u01(0, 1);
    std::normal_distribution<T> g(0, 1);
    std::uniform_int_distribution<std::size_t> pick(0, tris.size() - 1);
    std::uniform_int_distribution<int> axis(0, 2), coin(0, 1);
    auto point = [&] { return Vec3<T>{ux(rng), uy(rng), uz(rng)}; };
    std::vector<Ray<T>> rays;
    rays.reserve(n);
    kinds.clear();
    for (std::size_t i = 0; i < n; ++i) {
        Kind k = all_kinds[i % 6];
        if (!grazing && (k == Kind::aimed_vertex || k == Kind::axis_through_vertex)) k = Kind::aimed_interior;
        Ray<T> r;
        switch (k) {
        case Kind::random:
            r.org = point();
            r.dir = {g(rng), g(rng), g(rng)};
            break;
        case Kind::aimed_interior: {
            const auto& t = tris[pick(rng)];
            T a = u01(rng), c = u01(rng);
            if (a + c > 1) { a = 1 - a; c = 1 - c; }
            r.org = point();
            r.dir = (t.p0 * (1 - a - c) + t.p1 * a + t.p2 * c) - r.org;
            break;
        }
        case Kind::aimed_vertex: {
            const auto& t = tris[pick(rng)];
            r.org = point();
            r.dir = (i % 2 ? t.p1 : t.p2) - r.org;
            break;
        }
        case Kind::axis: {
            r.org = point();
            const int a = axis(rng);
            r.dir = {coin(rng) ? T(0) : -T(0), coin(rng) ? T(0) : -T(0), coin(rng) ? T(0) : -T(0)};
            r.dir[std::size_t(a)] = coin(rng) ? T(1) : T(-1);
            break;
        }
        case Kind::axis_through_vertex: {
            // Exactly through a vertex, parallel to an axis: the vertex lies on its leaf box's boundary.
            const auto& t = tris[pick(rng)];
            const int a = axis(rng);
            const T s = coin(rng) ? T(1) : T(-1);
            r.org = t.p0;
            r.org[std::size_t(a)] = s > 0 ? lo[std::size_t(a)] : hi[std::size_t(a)];
            r.dir = {coin(rng) ? T(0) : -T(0), coin(rng) ? T(0) : -T(0), coin(rng) ? T(0) : -T(0)};
            r.dir[std::size_t(a)] = s;
            break;
        }
        case Kind::clipped: {
            const auto& t = tris[pick(rng)];
            r.org = point();
            r.dir = t.centroid() - r.org;
            r.tmin = T(0.5) * u01(rng);
            r.tmax = r.tmin + T(1.2) * u01(rng);
            break;
        }
        }
        rays.push_back(r);
        kinds.push_back(k);
    }
    return rays;
}

// Compares a BVH against precomputed brute-force results; `skip` masks ray kinds the policy is allowed
// to disagree on (grazing rays for the fast box test). Returns the number of mismatches.
template <class Policy, class B, class T>
std::size_t compare(const B& bvh, const std::vector<Triangle<T>>& tris, const std::vector<Ray<T>>& rays,
                    const std::vector<Hit<T>>& brute, const std::vector<Kind>& kinds, bool grazing_too,
                    std::size_t& compared) {
    using Tri = typename Policy::triangle_test;
    std::size_t bad = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (!grazing_too && (kinds[i] == Kind::aimed_vertex || kinds[i] == Kind::axis_through_vertex)) continue;
        ++compared;
        const Hit<T> h = intersect<Policy>(bvh, tris, rays[i]);
        const Hit<T>& e = brute[i];
        // an exact tie also needs the expected triangle hit at that t
        bool ok = same_hit<Tri>(h, e, std::span<const Triangle<T>>(tris), rays[i]) &&
                  (!h || h.prim == e.prim || same_bits(intersect_triangle<Tri>(tris[e.prim], rays[i]).t, e.t));
        const bool occ = occluded<Policy>(bvh, tris, rays[i]);
        if (occ != bool(h)) ok = false;
        if (!ok && bad++ < 5) MESSAGE("mismatch (occluded " << occ << "): " << describe(rays[i], h, e));
    }
    return bad;
}

template <class Policy, class T>
std::vector<Hit<T>> brute_all(const std::vector<Triangle<T>>& tris, const std::vector<Ray<T>>& rays) {
    std::vector<Hit<T>> out(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) out[i] = brute_force_intersect<Policy>(std::span<const Triangle<T>>(tris), rays[i]);
    return out;
}

// All policy bundles and both primitive policies against brute force on one scene.
template <class NodeT, class BuildFn>
void check_scene(const std::vector<Triangle<typename NodeT::scalar_type>>& tris, std::size_t nrays, BuildFn build,
                 const std::string& what, bool fast_exact = true) {
    using T = typename NodeT::scalar_type;
    std::vector<Kind> kinds;
    const auto rays = make_rays<T>(tris, test::sanitizer_scaled(nrays), 1234, kinds, true);
    const auto brute_w = brute_all<trace::robust>(tris, rays);
    const auto brute_m = brute_all<trace::fast>(tris, rays);
    std::size_t hits = 0;
    for (const auto& h : brute_w) hits += h ? 1 : 0;
    MESSAGE(what << ": " << tris.size() << " triangles, " << rays.size() << " rays, " << hits << " hit (watertight)");
    CHECK(hits > rays.size() / 5);

    const auto bi = build.template operator()<NodeT, prim::indexed>(tris);
    const auto bp = build.template operator()<NodeT, prim::copied>(tris);
    const ValidateConfig vc{};
    const auto vi = validate(bi, tris, vc), vp = validate(bp, tris, vc);
    REQUIRE_MESSAGE(vi.ok(), vi.summary());
    REQUIRE_MESSAGE(vp.ok(), vp.summary());

    using mixed = trace::policy<box::fast, tri::watertight>;
    std::size_t n = 0;
    CHECK(compare<trace::robust>(bi, tris, rays, brute_w, kinds, true, n) == 0);
    CHECK(compare<trace::robust>(bp, tris, rays, brute_w, kinds, true, n) == 0);
    // box::fast may lose a box that a ray only grazes (through a vertex on the box boundary): compare
    // on the non-grazing rays.
    // In flat scenes every hit lies in a box face, so even ordinary rays graze: there the fast box test
    // is only reported, not required to agree.
    const std::size_t f1 = compare<mixed>(bi, tris, rays, brute_w, kinds, false, n);
    const std::size_t f2 = compare<trace::fast>(bi, tris, rays, brute_m, kinds, false, n);
    const std::size_t f3 = compare<trace::fast>(bp, tris, rays, brute_m, kinds, false, n);
    if (fast_exact) {
        CHECK(f1 == 0);
        CHECK(f2 == 0);
        CHECK(f3 == 0);
    } else {
        MESSAGE(what << ": box::fast disagreements with brute force (allowed here): " << f1 << ", " << f2 << ", " << f3);
    }
    // Any hit agrees with brute force for the robust bundle, including grazing rays.
    std::size_t occ_bad = 0;
    for (std::size_t i = 0; i < rays.size(); ++i)
        occ_bad += occluded(bp, tris, rays[i]) != brute_force_occluded(std::span<const Triangle<T>>(tris), rays[i]);
    CHECK(occ_bad == 0);
    MESSAGE(what << ": " << n << " (ray, bvh, policy) comparisons");
}

struct MedianBuilder {
    template <class NodeT, class Prim, class T>
    Bvh<NodeT, Prim> operator()(const std::vector<Triangle<T>>& tris) const {
        return median_build<NodeT, Prim>(tris, 4);
    }
};

} // namespace

TEST_CASE("hand-made BVH: exact closest hit, any hit, interval, leaf order, prim ids") {
    // Three triangles facing +z at z = 1, 2, 3 over [0,1]^2, plus one off to the side.
    const std::vector<Trianglef> tris = {
        {{0, 0, 3}, {1, 0, 3}, {0, 1, 3}},   // 0
        {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}},   // 1
        {{5, 5, 0}, {6, 5, 0}, {5, 6, 0}},   // 2
        {{0, 0, 2}, {1, 0, 2}, {0, 1, 2}},   // 3
    };
    // root(0) -> [A(1): leaf {2}, B(2): inner -> C(3): leaf {0, 3}, D(4): leaf {1}]
    Bvh<Node<>, prim::indexed> bvh;
    bvh.primitive_count = 4;
    bvh.nodes.resize(5);
    auto set = [&](std::size_t i, AABBf b, std::uint32_t index, std::uint32_t count) {
        bvh.nodes[i].set_bounds(b);
        bvh.nodes[i].index = index;
        bvh.nodes[i].count = count;
    };
    set(0, {{0, 0, 0}, {6, 6, 3}}, 1, 0);
    set(1, tris[2].bounds(), 0, 1);
    set(2, {{0, 0, 1}, {1, 1, 3}}, 3, 0);
    set(3, {{0, 0, 2}, {1, 1, 3}}, 1, 2);
    set(4, tris[1].bounds(), 3, 1);
    bvh.prim_ids = {2, 0, 3, 1};
    bvh.depth = 2;
    REQUIRE_MESSAGE(validate(bvh, tris).ok(), validate(bvh, tris).summary());

    const std::span<const Trianglef> ts(tris);
    SUBCASE("closest from above is z = 3, from below z = 1") {
        const Hitf a = intersect(bvh, ts, Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}});
        REQUIRE(a);
        CHECK(a.prim == 0);
        CHECK(a.t == 7.0f);
        CHECK(a.u == 0.25f);
        CHECK(a.v == 0.5f);
        const Hitf b = intersect(bvh, ts, Rayf{{0.25f, 0.5f, -10}, {0, 0, 1}});
        REQUIRE(b);
        CHECK(b.prim == 1);
        CHECK(b.t == 11.0f);
    }
    SUBCASE("tmin and tmax select the middle triangle") {
        const Hitf h = intersect(bvh, ts, Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}, 7.5f, 8.5f});
        REQUIRE(h);
        CHECK(h.prim == 3);
        CHECK(h.t == 8.0f);
        CHECK_FALSE(intersect(bvh, ts, Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}, 7.1f, 7.9f}));
        CHECK(occluded(bvh, ts, Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}, 8.0f, 8.0f}));  // closed interval
        CHECK_FALSE(occluded(bvh, ts, Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}, 0.0f, 6.9f}));
    }
    SUBCASE("prim is the user's index in the other subtree too") {
        const Hitf h = intersect(bvh, ts, Rayf{{5.25f, 5.25f, 1}, {0, 0, -1}});
        REQUIRE(h);
        CHECK(h.prim == 2);
        CHECK(h.t == 1.0f);
    }
    SUBCASE("misses, NaN and infinite rays") {
        CHECK_FALSE(intersect(bvh, ts, Rayf{{3, 3, 10}, {0, 0, -1}}));
        CHECK_FALSE(occluded(bvh, ts, Rayf{{3, 3, 10}, {0, 0, -1}}));
        const float nan = std::numeric_limits<float>::quiet_NaN(), inf = inf_v<float>;
        for (const Rayf& r : {Rayf{{nan, 0.5f, 10}, {0, 0, -1}}, Rayf{{0.25f, 0.5f, 10}, {0, nan, -1}},
                              Rayf{{0.25f, 0.5f, inf}, {0, 0, -1}}, Rayf{{0.25f, 0.5f, 10}, {0, 0, -inf}},
                              Rayf{{0.25f, 0.5f, 10}, {0, 0, 0}}, Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}, nan, inf},
                              Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}, 0, nan}, Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}, 9, 8}}) {
            CHECK_FALSE(intersect(bvh, ts, r));
            CHECK_FALSE(occluded(bvh, ts, r));
            CHECK_FALSE(intersect<trace::fast>(bvh, ts, r));
            CHECK_FALSE(occluded<trace::fast>(bvh, ts, r));
        }
    }
    SUBCASE("a too short triangle span is refused for prim::indexed") {
        CHECK_THROWS_AS(intersect(bvh, ts.first(2), Rayf{{0.25f, 0.5f, 10}, {0, 0, -1}}), std::invalid_argument);
    }
}

TEST_CASE("empty BVH and empty input") {
    const std::vector<Trianglef> none;
    const Bvh<> empty;
    CHECK_FALSE(intersect(empty, none, Rayf{{0, 0, 0}, {0, 0, 1}}));
    CHECK_FALSE(occluded(empty, none, Rayf{{0, 0, 0}, {0, 0, 1}}));
    CHECK_FALSE(brute_force_intersect(std::span<const Trianglef>(none), Rayf{{0, 0, 0}, {0, 0, 1}}));
    // Only non-finite triangles: excluded, empty tree.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const std::vector<Trianglef> bad = {{{nan, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const auto b = median_build<Node<>, prim::indexed>(bad);
    CHECK(b.empty());
    CHECK(b.excluded == 1);
    CHECK(validate(b, bad).ok());
    CHECK_FALSE(intersect(b, bad, Rayf{{0.2f, 0.2f, 1}, {0, 0, -1}}));
}

TEST_CASE("single triangle and two triangles") {
    const std::vector<Trianglef> one = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const auto b1 = median_build<Node<>, prim::copied>(one);
    REQUIRE(b1.nodes.size() == 1);
    const Hitf h = intersect(b1, one, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}});
    REQUIRE(h);
    CHECK(h.prim == 0);
    CHECK(h.t == 1.0f);
    const std::vector<Trianglef> two = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, -1}, {1, 0, -1}, {0, 1, -1}}};
    const auto b2 = median_build<Node<>, prim::indexed>(two, 1);
    REQUIRE(b2.nodes.size() == 3);
    const Hitf h2 = intersect(b2, two, Rayf{{0.25f, 0.25f, -3}, {0, 0, 1}});
    REQUIRE(h2);
    CHECK(h2.prim == 1);
    CHECK(h2.t == 2.0f);
}

TEST_CASE("random soup, median tree: closest hit == brute force to the bit, any hit agrees (float)") {
    const auto tris = random_soup<float>(256, 42);
    check_scene<Node<>>(tris, 40000, MedianBuilder{}, "soup/median");
}

TEST_CASE("random soup with non-finite triangles mixed in") {
    auto tris = random_soup<float>(300, 5);
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = inf_v<float>;
    tris[10].p1.x = nan;
    tris[20].p2.y = inf;
    tris[30].p0.z = -inf;
    check_scene<Node<>>(tris, 8000, MedianBuilder{}, "soup with NaN/inf triangles");
}

TEST_CASE("double-precision nodes with 64-bit indices") {
    const auto tris = random_soup<double>(300, 9);
    check_scene<Node<double, std::uint64_t>>(tris, 8000, MedianBuilder{}, "soup/median double");
}

TEST_CASE("flat scene (all z = 0) with axis-parallel rays") {
    auto tris = random_soup<float>(400, 3);
    for (auto& t : tris) t.p0.z = t.p1.z = t.p2.z = 0;
    check_scene<Node<>>(tris, 12000, MedianBuilder{}, "flat soup", false);
}

TEST_CASE("coplanar overlapping triangles, grazing rays, far from the origin: still bit-exact") {
    // Many triangles in one plane overlapping each other, hit at grazing angles: the computed t of
    // neighbouring triangles differ in the last bits, and the box test must never cull a box whose
    // triangle's computed t is smaller than the best so far (see tri::watertight's t).
    for (const float offset : {0.0f, 1000.0f, 1.0e6f}) {
        std::mt19937 rng(5);
        std::uniform_real_distribution<float> c(0, 10), d(-2, 2), u01(0, 1);
        std::normal_distribution<float> g(0, 1);
        std::vector<Trianglef> tris(300);
        for (auto& t : tris) {
            const Vec3f o{c(rng) + offset, c(rng) + offset, offset};
            t = {o + Vec3f{d(rng), d(rng), 0}, o + Vec3f{d(rng), d(rng), 0}, o + Vec3f{d(rng), d(rng), 0}};
        }
        for (std::size_t i = 0; i < tris.size(); i += 3) tris[i].p1.z += 0.5f;  // some tilted ones
        const auto bvh = median_build<Node<>, prim::indexed>(tris, 4);
        std::size_t bad = 0, hits = 0;
        const std::size_t n = 12000;
        for (std::size_t i = 0; i < n; ++i) {
            const auto& t = tris[rng() % tris.size()];
            float a = u01(rng), b = u01(rng);
            if (a + b > 1) { a = 1 - a; b = 1 - b; }
            const Vec3f p = t.p0 * (1 - a - b) + t.p1 * a + t.p2 * b;
            const float grazing = i % 3 == 0 ? 0.1f : (i % 3 == 1 ? 1e-3f : 1e-5f);
            const Vec3f dir{g(rng), g(rng), (rng() % 2 ? 1.f : -1.f) * grazing * u01(rng)};
            const Rayf r{p - dir * (1 + 10 * u01(rng)), dir};
            const Hitf h = intersect(bvh, tris, r);
            const Hitf e = brute_force_intersect(std::span<const Trianglef>(tris), r);
            hits += e ? 1 : 0;
            if (bool(h) != bool(e) || (h && !same_bits(h.t, e.t))) {
                if (bad++ < 5) MESSAGE("offset " << offset << ": " << describe(r, h, e));
            }
        }
        MESSAGE("offset " << offset << ": " << n << " grazing rays, " << hits << " hits, " << bad << " mismatches");
        CHECK(bad == 0);
    }
}

TEST_CASE("closed mesh through a BVH: rays from inside aimed at edges and vertices never escape") {
    // A subdivided cube surface (closed, 6 * 2 * k^2 triangles), traced through a median tree.
    const int k = 8;
    std::vector<Trianglef> tris;
    auto face = [&](int axis, float side) {
        for (int i = 0; i < k; ++i)
            for (int j = 0; j < k; ++j) {
                auto p = [&](int a, int b) {
                    Vec3f v;
                    v[std::size_t(axis)] = side;
                    v[std::size_t((axis + 1) % 3)] = -1.0f + 2.0f * float(a) / float(k);
                    v[std::size_t((axis + 2) % 3)] = -1.0f + 2.0f * float(b) / float(k);
                    return v;
                };
                tris.push_back({p(i, j), p(i + 1, j), p(i + 1, j + 1)});
                tris.push_back({p(i, j), p(i + 1, j + 1), p(i, j + 1)});
            }
    };
    for (int a = 0; a < 3; ++a) {
        face(a, -1);
        face(a, 1);
    }
    const auto bvh = median_build<Node<>, prim::copied>(tris, 2);
    REQUIRE(validate(bvh, tris).ok());
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> d(-0.9f, 0.9f), s(0, 1);
    std::size_t rays = 0, escaped = 0, escaped_fast = 0;
    for (int o = 0; o < 40; ++o) {
        const Vec3f org{d(rng), d(rng), d(rng)};
        for (const auto& t : tris)
            for (const Vec3f& target : {t.p0, t.p0 + (t.p1 - t.p0) * s(rng), t.p1 + (t.p2 - t.p1) * 0.5f}) {
                const Rayf r{org, target - org};
                ++rays;
                escaped += intersect(bvh, tris, r) ? 0 : 1;
                escaped_fast += intersect<trace::fast>(bvh, tris, r) ? 0 : 1;
            }
    }
    MESSAGE(rays << " rays from inside a closed cube at edges/vertices: escaped robust " << escaped << ", fast "
                 << escaped_fast);
    CHECK(escaped == 0);
}

TEST_CASE("trees deeper than max_depth use a heap stack; a wrong depth field cannot overflow it") {
    // 150 triangles stacked along z, each fully covering the others' footprint: every ray down the
    // z axis hits all of them, so traversal pushes at every level of a 149-deep caterpillar.
    std::vector<Trianglef> tris;
    for (int i = 0; i < 150; ++i) {
        const float z = float(i);
        tris.push_back({{-1, -1, z}, {3, -1, z}, {-1, 3, z}});
    }
    auto deep = caterpillar_build<Node<>, prim::indexed>(tris);
    REQUIRE(deep.depth == 149);
    const auto rep = validate(deep, tris);
    CHECK_FALSE(rep.ok());  // depth > max_depth is reported ...
    CHECK(rep.error_count == 2);
    const Rayf down{{0.1f, 0.1f, 1000}, {0, 0, -1}}, up{{0.1f, 0.1f, -1000}, {0, 0, 1}};
    // ... but tracing still works.
    const Hitf a = intersect(deep, tris, down), b = intersect(deep, tris, up);
    REQUIRE(a);
    REQUIRE(b);
    CHECK(a.prim == 149);
    CHECK(a.t == 1000.0f - 149.0f);
    CHECK(b.prim == 0);
    CHECK(b.t == 1000.0f);
    CHECK(occluded(deep, tris, down));
    // A tree that lies about its depth: the stack grows instead of overflowing (ASan would catch it).
    deep.depth = 3;
    const Hitf c = intersect(deep, tris, down);
    REQUIRE(c);
    CHECK(c.prim == 149);
    CHECK(c.t == 1000.0f - 149.0f);
}

struct LbvhBuilder {
    template <class NodeT, class Prim, class T>
    Bvh<NodeT, Prim> operator()(const std::vector<Triangle<T>>& tris) const {
        return lbvh::build<NodeT, Prim>(std::span<const Triangle<T>>(tris), {}, exec::serial{});
    }
};

TEST_CASE("random soup, LBVH: closest hit == brute force to the bit, any hit agrees") {
    const auto tris = random_soup<float>(200, 77);
    check_scene<Node<>>(tris, 100000, LbvhBuilder{}, "soup/lbvh");
    auto flat = random_soup<float>(200, 78);
    for (auto& t : flat) t.p0.z = t.p1.z = t.p2.z = 0;
    check_scene<Node<>>(flat, 12000, LbvhBuilder{}, "flat/lbvh", false);
}
