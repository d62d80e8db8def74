// Adversarial geometry (issue 5): zero-area, collinear and repeated-vertex triangles, slivers, coordinates
// near 1e-30 and 1e30 (and both in one scene), subnormal and near-FLT_MAX coordinates, scenes far from the
// origin, flat scenes (one plane, one line, one point), a million triangles with the same centroid, NaN and
// infinite vertices. Every builder x every executor terminates, stays within max_depth, passes validate()
// and answers every adversarial ray exactly as brute force does with the same intersector.
#include "robust_support.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

using namespace dynbvh;
using namespace dynbvh::test;

namespace {

std::vector<Trianglef> scaled(std::vector<Trianglef> tris, float scale, Vec3f offset = {0, 0, 0}) {
    for (auto& t : tris)
        for (Vec3f* p : {&t.p0, &t.p1, &t.p2}) *p = *p * scale + offset;
    return tris;
}

/// A soup where every 2nd triangle is degenerate: a point, three collinear points, a repeated vertex
/// (both orders), or two equal vertices and the third on their line.
std::vector<Trianglef> degenerate_mix(std::size_t n) {
    auto tris = random_soup(n, 21, 0.05f);
    Rng rng(22);
    for (std::size_t i = 0; i < n; i += 2) {
        Trianglef& t = tris[i];
        switch ((i / 2) % 5) {
        case 0: t.p1 = t.p2 = t.p0; break;                                             // a point
        case 1: t.p2 = t.p0 + (t.p1 - t.p0) * rng.uniform(); break;                    // collinear, inside
        case 2: t.p2 = t.p0 + (t.p1 - t.p0) * 3.0f; break;                             // collinear, outside
        case 3: t.p1 = t.p0; break;                                                    // repeated vertex
        default: t.p2 = t.p1; t.p0 = t.p1 + (t.p1 - t.p0) * 0.5f; break;              // repeated, on a line
        }
    }
    return tris;
}

/// Slivers: needles of length ~1 and width 1e-4 .. 1e-7, and nearly collinear caps.
std::vector<Trianglef> slivers(std::size_t n) {
    Rng rng(23);
    std::vector<Trianglef> t(n);
    const float widths[] = {1e-4f, 1e-5f, 1e-6f, 1e-7f};
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3f a{rng.uniform(), rng.uniform(), rng.uniform()}, b{rng.uniform(), rng.uniform(), rng.uniform()};
        const Vec3f side = normalize(cross(b - a, Vec3f{rng.uniform(-1, 1), rng.uniform(-1, 1), 1}));
        const float w = widths[i % 4];
        t[i] = i % 2 ? Trianglef{a, b, b + side * w} : Trianglef{a, b, (a + b) * 0.5f + side * w};
    }
    return t;
}

/// Every vertex on one line (the diagonal of the unit cube): no triangle has any area.
std::vector<Trianglef> one_line(std::size_t n) {
    Rng rng(24);
    std::vector<Trianglef> t(n);
    auto on_line = [&] { const float s = rng.uniform(); return Vec3f{s, s, s}; };
    for (auto& tri : t) tri = {on_line(), on_line(), on_line()};
    return t;
}

/// NaN and infinite vertices in every position and coordinate, mixed into a soup; returns the count.
std::vector<Trianglef> with_non_finite(std::size_t n, std::size_t& bad) {
    auto tris = random_soup(n, 25);
    const float values[] = {fnan, finf, -finf, -fnan};
    bad = 0;
    for (std::size_t i = 3; i < n; i += 7) {
        Vec3f& p = i % 3 == 0 ? tris[i].p0 : (i % 3 == 1 ? tris[i].p1 : tris[i].p2);
        p[(i / 7) % 3] = values[(i / 21) % 4];
        if (i % 5 == 0) tris[i] = {{fnan, fnan, fnan}, {finf, finf, finf}, {-finf, 0, fnan}};
        ++bad;
    }
    return tris;
}

} // namespace

TEST_CASE("adversarial geometry: every builder x executor terminates, is valid and == brute force") {
    const std::size_t n = sanitized() ? 300 : 800;
    const std::size_t per_kind = sanitized() ? 30 : 120;
    const float fmax = std::numeric_limits<float>::max();
    check_case("degenerate mix (points, collinear, repeated vertices)", degenerate_mix(n), per_kind, 31);
    check_case("slivers (width 1e-4 .. 1e-7)", slivers(n), per_kind, 32);
    check_case("scale 1e-30", scaled(random_soup(n, 33), 1e-30f), per_kind, 33);
    check_case("scale 1e30", scaled(random_soup(n, 34), 1e30f), per_kind, 34);
    {
        auto both = scaled(random_soup(n / 2, 35), 1e-30f);
        const auto big = scaled(random_soup(n / 2, 36), 1e30f);
        both.insert(both.end(), big.begin(), big.end());
        check_case("scales 1e-30 and 1e30 in one scene", both, per_kind, 35);
    }
    check_case("near FLT_MAX (box extents overflow)", scaled(random_soup(n, 38), 0.9f * fmax, {-0.45f * fmax, -0.45f * fmax, -0.45f * fmax}),
               per_kind, 38);
    // At 1e6 the float spacing is 1/16: a scene 1000 wide with triangles ~20 wide, and one whose
    // triangles are only a few ulps wide (heavily quantised, many degenerate).
    check_case("offset 1e6 (scene 1000 wide)", scaled(random_soup(n, 39), 1000.0f, {1e6f, 1e6f, 1e6f}), per_kind, 39);
    check_case("offset 1e6 (triangles a few ulps wide)", scaled(random_soup(n, 40), 10.0f, {1e6f, -1e6f, 1e6f}), per_kind, 40);
    check_case("flat: one plane (z = 0)", flat_scene(n), per_kind, 41);
    check_case("flat: one line", one_line(n), per_kind, 42);
    check_case("flat: one point", std::vector<Trianglef>(n, Trianglef{{0.5f, 0.25f, 0.125f}, {0.5f, 0.25f, 0.125f}, {0.5f, 0.25f, 0.125f}}),
               per_kind, 43);
    check_case("identical triangles", identical(n), per_kind, 44);
    std::size_t bad = 0;
    const auto nf = with_non_finite(n, bad);
    check_case("NaN and infinite vertices mixed in", nf, per_kind, 45);
    check_case("a single triangle", random_soup(1, 46, 0.3f), per_kind, 46);
}

// Directions near 1e-41 are subnormal: 1 / dir would overflow to infinity and the box tests would take
// every axis as parallel. The box tests scale such directions by a power of two (exact), so no hit the
// triangle test finds is lost.
TEST_CASE("subnormal coordinates (scale 1e-40): valid trees; rays with subnormal directions") {
    const auto tris = scaled(random_soup(sanitized() ? 300 : 800, 37), 1e-40f);
    for_each_executor([&](auto ex) {
        for_each_builder(tris, ex, [&](std::size_t b, const auto& bvh, bool single) {
            const std::string builder = builder_names[b];
            CAPTURE(builder);
            CHECK(structure_problems(bvh, tris, single) == "");
        });
    });
    check_case("subnormal coordinates (scale 1e-40)", tris, sanitized() ? 30 : 120, 37);
}

TEST_CASE("NaN and infinite vertices: excluded and counted in Bvh::excluded, never hit") {
    std::size_t bad = 0;
    const auto tris = with_non_finite(500, bad);
    REQUIRE(bad > 50);
    const std::vector<Trianglef> all_bad(40, Trianglef{{fnan, 0, 0}, {0, finf, 0}, {0, 0, -finf}});
    for_each_executor([&](auto ex) {
        const std::string executor = executor_name<decltype(ex)>();
        CAPTURE(executor);
        for_each_builder(tris, ex, [&](std::size_t b, const auto& bvh, bool) {
            const std::string builder = builder_names[b];
            CAPTURE(builder);
            CHECK(bvh.primitive_count == tris.size());
            CHECK(bvh.excluded == bad);
            for (auto id : bvh.prim_ids) CHECK(tris[id].is_finite());
        });
        for_each_builder(all_bad, ex, [&](std::size_t b, const auto& bvh, bool) {
            const std::string builder = builder_names[b];
            CAPTURE(builder);
            CHECK(bvh.empty());
            CHECK(bvh.excluded == all_bad.size());
            CHECK(bvh.primitive_count == all_bad.size());
            CHECK(bvh.depth == 0);
            CHECK_FALSE(intersect(bvh, all_bad, Rayf{{0, 0, -1}, {0, 0, 1}}));
            CHECK_FALSE(occluded(bvh, all_bad, Rayf{{0, 0, -1}, {0, 0, 1}}));
        });
    });
}

TEST_CASE("a million triangles with the same centroid: valid trees, rays == brute force") {
    // Different sizes and orientations, one box centre: p0 = a, p1 = -a, p2 = b with |b| <= |a| per
    // axis, so every box is symmetric about the origin. Morton codes and centroid bounds collapse.
    const std::size_t n = sanitized() ? 100000 : 1000000;
    Rng rng(51);
    std::vector<Trianglef> tris(n);
    for (auto& t : tris) {
        const Vec3f a{rng.uniform(0.01f, 1), rng.uniform(0.01f, 1), rng.uniform(0.01f, 1)};
        const Vec3f b{a.x * rng.uniform(-1, 1), a.y * rng.uniform(-1, 1), a.z * rng.uniform(-1, 1)};
        t = {a, -a, b};
    }
    for (const auto& t : tris) REQUIRE(t.bounds().center() == Vec3f{0, 0, 0});
    // A handful of rays (brute force costs n per ray): through the common centre, aimed at vertices,
    // axis-parallel with signed zeros.
    std::vector<Rayf> rays;
    for (int i = 0; i < 24; ++i) {
        const Vec3f o{rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)};
        const Trianglef& t = tris[rng.next() % n];
        const Vec3f targets[] = {Vec3f{0, 0, 0}, t.p2, t.p0 * rng.uniform()};
        rays.push_back({o, targets[i % 3] - o});
    }
    rays.push_back({{0, 0, -5}, {0.0f, -0.0f, 1}});
    rays.push_back({{0.5f, 0.5f, 5}, {-0.0f, 0.0f, -1}});
    rays.push_back({{0, 0, 0}, {1, 0, 0}});
    rays.push_back({{-5, 0, 0}, {1, 0, 0}, 0, 4.5f});
    RaySet set{rays, std::vector<RayKind>(rays.size(), aimed_point)};
    const Reference ref = brute_force<trace::robust>(tris, set.rays);

    // Builds of a million triangles take seconds each, so this case runs on one executor: the first
    // parallel one selected (serial when there is none).
    std::size_t parallel = 0, runs = 0;
    for_each_executor([&](auto ex) { parallel += std::is_same_v<decltype(ex), exec::serial> ? 0 : 1; });
    for_each_executor([&](auto ex) {
        if (parallel > 0 && std::is_same_v<decltype(ex), exec::serial>) return;
        if (runs++ > 0) return;
        const std::string executor = executor_name<decltype(ex)>();
        CAPTURE(executor);
        auto check = [&](const char* name, const auto& bvh) {
            CAPTURE(name);
            CHECK(structure_problems(bvh, tris) == "");
            CHECK(bvh.depth <= max_depth);
            const Disagreements d = compare_with<trace::robust>(bvh, tris, set, ref);
            CHECK_MESSAGE(d.total == 0, d.first);
        };
        const auto t0 = std::chrono::steady_clock::now();
        check("lbvh", lbvh::build(tris, {}, ex));
        check("ploc", ploc::build(tris, {}, ex));
        check("binned-sah", binned_sah::build(tris, {}, ex));
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        MESSAGE("[robustness] " << n << " triangles with one centroid on " << std::string(executor_name<decltype(ex)>())
                                << ": lbvh, ploc, binned-sah built and checked in " << s << " s");
    });
}
