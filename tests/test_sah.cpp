// Tree quality metrics (sah.hpp): SAH cost and end-point overlap against hand-computed values on
// hand-built trees, every executor, degenerate scenes, and an independent Monte Carlo estimate of EPO.
#include <doctest/doctest.h>

#include <dynbvh/sah.hpp>
#include <dynbvh/validate.hpp>

#include "simple_builder.hpp"

#include <cmath>
#include <random>
#include <vector>

using namespace dynbvh;
using dynbvh::test::median_build;

namespace {

template <class Bvh>
void set_node(Bvh& bvh, std::size_t i, AABBf b, std::uint32_t index, std::uint32_t count) {
    bvh.nodes[i].set_bounds(b);
    bvh.nodes[i].index = index;
    bvh.nodes[i].count = count;
}

// root(0) = [0,4]x[0,2]x[0,1] -> leaf 1 [0,1]^3 {A, B}, inner 2 [2,4]x[0,2]x[0,1] -> leaf 3 {C}, leaf 4 {D}
struct HandTree {
    std::vector<Trianglef> tris = {
        {{0, 0, 0}, {1, 0, 0}, {0, 1, 1}},  // A: box [0,1]^3
        {{1, 1, 1}, {0, 1, 0}, {1, 0, 1}},  // B: box [0,1]^3
        {{2, 0, 0}, {3, 1, 0}, {2, 1, 1}},  // C: box [2,3]x[0,1]x[0,1]
        {{3, 1, 0}, {4, 2, 0}, {3, 2, 1}},  // D: box [3,4]x[1,2]x[0,1]
    };
    Bvh<> bvh;
    HandTree() {
        bvh.primitive_count = 4;
        bvh.nodes.resize(5);
        set_node(bvh, 0, {{0, 0, 0}, {4, 2, 1}}, 1, 0);
        set_node(bvh, 1, {{0, 0, 0}, {1, 1, 1}}, 0, 2);
        set_node(bvh, 2, {{2, 0, 0}, {4, 2, 1}}, 3, 0);
        set_node(bvh, 3, {{2, 0, 0}, {3, 1, 1}}, 2, 1);
        set_node(bvh, 4, {{3, 1, 0}, {4, 2, 1}}, 3, 1);
        bvh.prim_ids = {0, 1, 2, 3};
        bvh.depth = 2;
    }
};

// Flat (z = 0) tree with overlap between an inner node and a leaf:
// root(0) -> inner A(1) -> leaves a1(3), a2(4); leaf B(2).
struct OverlapTree {
    std::vector<Trianglef> tris = {
        {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}},  // a1, area 0.5, box [0,1]^2
        {{1, 1, 0}, {2, 1, 0}, {1, 2, 0}},  // a2, area 0.5, box [1,2]^2
        {{1, 0, 0}, {3, 0, 0}, {3, 2, 0}},  // B,  area 2,   box [1,3]x[0,2]
    };
    Bvh<> bvh;
    OverlapTree() {
        bvh.primitive_count = 3;
        bvh.nodes.resize(5);
        set_node(bvh, 0, {{0, 0, 0}, {3, 2, 0}}, 1, 0);
        set_node(bvh, 1, {{0, 0, 0}, {2, 2, 0}}, 3, 0);
        set_node(bvh, 2, {{1, 0, 0}, {3, 2, 0}}, 2, 1);
        set_node(bvh, 3, {{0, 0, 0}, {1, 1, 0}}, 0, 1);
        set_node(bvh, 4, {{1, 1, 0}, {2, 2, 0}}, 1, 1);
        bvh.prim_ids = {0, 1, 2};
        bvh.depth = 2;
    }
};

template <class F>
void for_each_executor(F&& f) {
    f(exec::serial{}, "serial");
#if defined(_OPENMP)
    f(exec::omp{2}, "omp");
#endif
#if defined(DYNBVH_WITH_TBB)
    f(exec::tbb{2}, "tbb");
#endif
}

// Monte Carlo EPO: uniform points on every triangle; a point of triangle i counts for node n when it
// lies in n's box and i is not referenced in n's subtree. Independent of the clipping code.
template <class B>
double epo_monte_carlo(const B& bvh, const std::vector<Trianglef>& tris, const SahCost& cfg, int samples,
                       std::uint32_t seed) {
    // subtree membership by brute force
    const std::size_t nn = bvh.nodes.size();
    std::vector<std::vector<bool>> in(nn, std::vector<bool>(tris.size(), false));
    std::vector<std::vector<std::size_t>> below(nn);
    for (std::size_t n = nn; n-- > 0;) {
        const auto& node = bvh.nodes[n];
        if (node.is_leaf()) {
            for (std::size_t s = node.index; s < node.index + node.count; ++s) in[n][bvh.prim_ids[s]] = true;
        } else {
            for (std::size_t c : {std::size_t(node.index), std::size_t(node.index) + 1})
                for (std::size_t i = 0; i < tris.size(); ++i)
                    if (in[c][i]) in[n][i] = true;
        }
    }
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u01(0, 1);
    double sum = 0, total = 0;
    for (std::size_t i = 0; i < tris.size(); ++i) {
        const Vec3d a(tris[i].p0), b(tris[i].p1), c(tris[i].p2);
        const double area = 0.5 * length(cross(b - a, c - a));
        total += area;
        for (int k = 0; k < samples; ++k) {
            double s = u01(rng), t = u01(rng);
            if (s + t > 1) { s = 1 - s; t = 1 - t; }
            const Vec3d p = a + (b - a) * s + (c - a) * t;
            for (std::size_t n = 0; n < nn; ++n) {
                if (in[n][i]) continue;
                const auto& node = bvh.nodes[n];
                if (p.x >= node.min.x && p.x <= node.max.x && p.y >= node.min.y && p.y <= node.max.y &&
                    p.z >= node.min.z && p.z <= node.max.z)
                    sum += (node.is_leaf() ? cfg.ci : cfg.ct) * area / samples;
            }
        }
    }
    return sum / total;
}

} // namespace

TEST_CASE("SAH of a hand-built tree equals the hand-computed value") {
    const HandTree h;
    REQUIRE_MESSAGE(validate(h.bvh, h.tris).ok(), validate(h.bvh, h.tris).summary());
    // areas: root 2(4*2 + 2*1 + 1*4) = 28, inner 2: 2(2*2 + 2*1 + 1*2) = 16, leaves 6 each
    // (3 * (28 + 16) + 2 * (6 * 2 + 6 * 1 + 6 * 1)) / 28 = 180 / 28
    for_each_executor([&](const auto& ex, const char* name) {
        INFO(name);
        CHECK(sah_cost(h.bvh, {}, ex) == doctest::Approx(180.0 / 28.0).epsilon(1e-15));
        CHECK(sah_cost(h.bvh, {.ct = 1, .ci = 1}, ex) == doctest::Approx(68.0 / 28.0).epsilon(1e-15));
        CHECK(sah_cost(h.bvh, {.ct = 0, .ci = 1}, ex) == doctest::Approx(24.0 / 28.0).epsilon(1e-15));
    });
    CHECK(sah_cost(h.bvh) == doctest::Approx(180.0 / 28.0).epsilon(1e-15));  // default executor argument
    const OverlapTree o;
    REQUIRE(validate(o.bvh, o.tris).ok());
    // flat boxes: root 2*(3*2) = 12, A 8, a1 2, a2 2, B 8 -> (3 * 20 + 2 * 12) / 12 = 7
    CHECK(sah_cost(o.bvh) == doctest::Approx(7.0).epsilon(1e-15));
}

TEST_CASE("SAH of trivial and degenerate trees") {
    CHECK(sah_cost(Bvh<>{}) == 0.0);
    // One leaf of two triangles: its box is the root's, so the cost is Ci * 2.
    const std::vector<Trianglef> two = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}}};
    const auto one_leaf = median_build<Node<>, prim::indexed>(two, 8);
    REQUIRE(one_leaf.nodes.size() == 1);
    CHECK(sah_cost(one_leaf) == doctest::Approx(4.0));
    // All geometry at one point or on one line: root area 0, the formula's limit Ct * inner + Ci * refs.
    const std::vector<Trianglef> point(3, Trianglef{{1, 1, 1}, {1, 1, 1}, {1, 1, 1}});
    const auto p = median_build<Node<>, prim::indexed>(point, 1);
    REQUIRE(p.nodes.size() == 5);  // 2 inner, 3 leaves
    CHECK(sah_cost(p) == doctest::Approx(3.0 * 2 + 2.0 * 3));
    CHECK(std::isfinite(sah_cost(p)));
    const std::vector<Trianglef> line = {{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {{3, 0, 0}, {4, 0, 0}, {5, 0, 0}}};
    const auto l = median_build<Node<>, prim::indexed>(line, 1);
    CHECK(sah_cost(l) == doctest::Approx(3.0 * 1 + 2.0 * 2));
}

TEST_CASE("SAH on a random tree: every executor agrees with a direct sum") {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> c(0, 100), d(-2, 2);
    std::vector<Trianglef> tris(20000);
    for (auto& t : tris) {
        const Vec3f o{c(rng), c(rng), c(rng)};
        t = {o + Vec3f{d(rng), d(rng), d(rng)}, o + Vec3f{d(rng), d(rng), d(rng)}, o + Vec3f{d(rng), d(rng), d(rng)}};
    }
    const auto bvh = median_build<Node<>, prim::indexed>(tris, 4);
    double inner = 0, leaf = 0;
    for (const auto& n : bvh.nodes) {
        const Vec3d e = Vec3d(n.max) - Vec3d(n.min);
        const double a = 2 * (e.x * e.y + e.y * e.z + e.z * e.x);
        if (n.is_leaf()) leaf += a * n.count;
        else inner += a;
    }
    const Vec3d r = Vec3d(bvh.nodes[0].max) - Vec3d(bvh.nodes[0].min);
    const double expected = (3 * inner + 2 * leaf) / (2 * (r.x * r.y + r.y * r.z + r.z * r.x));
    for_each_executor([&](const auto& ex, const char* name) {
        INFO(name);
        CHECK(sah_cost(bvh, {}, ex) == doctest::Approx(expected).epsilon(1e-12));
    });
    // Sanity: a better split cannot be worse than a useless one. One leaf of everything costs Ci * n.
    CHECK(sah_cost(bvh) < 2.0 * 20000);
}

TEST_CASE("EPO of hand-built trees equals the hand-computed value") {
    SUBCASE("disjoint leaves: no overlap") {
        const std::vector<Trianglef> tris = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{5, 5, 0}, {6, 5, 0}, {5, 6, 0}}};
        const auto bvh = median_build<Node<>, prim::indexed>(tris, 1);
        REQUIRE(bvh.nodes.size() == 3);
        CHECK(epo(bvh, tris) == 0.0);
    }
    SUBCASE("a small triangle inside a big one's leaf box") {
        // big (area 8) in leaf 1, small (area 0.5) in leaf 2. Leaf 1's box holds all of small (0.5),
        // leaf 2's box [1,2]^2 cuts a unit square out of big: EPO = Ci (0.5 + 1) / 8.5.
        const std::vector<Trianglef> tris = {{{0, 0, 0}, {4, 0, 0}, {0, 4, 0}}, {{1, 1, 0}, {2, 1, 0}, {1, 2, 0}}};
        const auto bvh = median_build<Node<>, prim::indexed>(tris, 1);
        REQUIRE(bvh.nodes.size() == 3);
        for_each_executor([&](const auto& ex, const char* name) {
            INFO(name);
            CHECK(epo(bvh, tris, {}, ex) == doctest::Approx(2.0 * 1.5 / 8.5).epsilon(1e-14));
        });
        CHECK(epo(bvh, tris, {.ct = 3, .ci = 1}) == doctest::Approx(1.5 / 8.5).epsilon(1e-14));
    }
    SUBCASE("overlap between an inner node and a leaf") {
        // A (inner, box [0,2]^2) holds 0.5 of B; B's leaf box [1,3]x[0,2] holds all of a2 (0.5); the
        // remaining contacts are single points. EPO = (Ct 0.5 + Ci 0.5) / 3.
        const OverlapTree o;
        for_each_executor([&](const auto& ex, const char* name) {
            INFO(name);
            CHECK(epo(o.bvh, o.tris, {}, ex) == doctest::Approx(2.5 / 3.0).epsilon(1e-14));
        });
        CHECK(epo(o.bvh, o.tris, {.ct = 1, .ci = 0}) == doctest::Approx(0.5 / 3.0).epsilon(1e-14));
    }
    SUBCASE("empty tree") {
        CHECK(epo(Bvh<>{}, std::span<const Trianglef>{}) == 0.0);
    }
}

TEST_CASE("EPO agrees with an independent Monte Carlo estimate on a random tree") {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> c(0, 6), d(-1.5f, 1.5f);
    std::vector<Trianglef> tris(40);
    for (auto& t : tris) {
        const Vec3f o{c(rng), c(rng), c(rng)};
        t = {o + Vec3f{d(rng), d(rng), d(rng)}, o + Vec3f{d(rng), d(rng), d(rng)}, o + Vec3f{d(rng), d(rng), d(rng)}};
    }
    const auto bvh = median_build<Node<>, prim::copied>(tris, 2);
    const double exact = epo(bvh, tris);
    const double mc = epo_monte_carlo(bvh, tris, {}, 3000, 5);
    MESSAGE("EPO " << exact << ", Monte Carlo " << mc);
    CHECK(exact > 0.5);  // overlapping random soup: plenty of overlap
    CHECK(mc == doctest::Approx(exact).epsilon(0.03));
    for_each_executor([&](const auto& ex, const char* name) {
        INFO(name);
        CHECK(epo(bvh, tris, {}, ex) == doctest::Approx(exact).epsilon(1e-12));
    });
}
