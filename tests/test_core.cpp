// Shared steps: executors, Morton codes, radix sort, emission (collapse + depth bound), refit.
#include "support.hpp"

#include <algorithm>
#include <numeric>

#include <dynbvh/detail/emit.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/detail/morton.hpp>
#include <dynbvh/detail/radix_sort.hpp>
#include <dynbvh/refit.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

TEST_CASE("executors: for_each, reduce and exclusive_scan agree with serial loops") {
    for_each_executor([](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        for (std::size_t n : {0u, 1u, 7u, 1000u, 100000u}) {
            std::vector<std::uint64_t> v(n), out(n), ref(n);
            ex.for_each(0, n, [&](std::size_t i) { v[i] = (i * 2654435761u) % 1000; });
            std::uint64_t sum = 0;
            for (std::size_t i = 0; i < n; ++i) { ref[i] = sum; sum += v[i]; }
            const auto total = ex.exclusive_scan(std::span<const std::uint64_t>(v), std::span<std::uint64_t>(out));
            CHECK(total == sum);
            CHECK(out == ref);
            // in place
            auto w = v;
            ex.exclusive_scan(std::span<const std::uint64_t>(w), std::span<std::uint64_t>(w));
            CHECK(w == ref);
            const auto r = ex.reduce(std::size_t(0), n, std::uint64_t(0), [&](std::size_t i) { return v[i]; },
                                     [](std::uint64_t a, std::uint64_t b) { return a + b; });
            CHECK(r == sum);
            std::vector<int> hits(n, 0);
            ex.for_blocks(0, n, [&](std::size_t lo, std::size_t hi) { for (auto i = lo; i < hi; ++i) ++hits[i]; });
            CHECK(std::all_of(hits.begin(), hits.end(), [](int h) { return h == 1; }));
        }
    });
}

TEST_CASE("morton: encodings equal a bit-by-bit interleave") {
    Rng r(7);
    for (int k = 0; k < 10000; ++k) {
        const std::uint32_t x = r.next() & 1023, y = r.next() & 1023, z = r.next() & 1023;
        std::uint32_t ref = 0;
        for (int b = 0; b < 10; ++b)
            ref |= ((x >> b & 1u) << (3 * b + 2)) | ((y >> b & 1u) << (3 * b + 1)) | ((z >> b & 1u) << (3 * b));
        REQUIRE(morton::encode30(x, y, z) == ref);
        const std::uint64_t X = r.next() & 0x1fffff, Y = r.next() & 0x1fffff, Z = r.next() & 0x1fffff;
        std::uint64_t ref64 = 0;
        for (int b = 0; b < 21; ++b)
            ref64 |= ((X >> b & 1ull) << (3 * b + 2)) | ((Y >> b & 1ull) << (3 * b + 1)) | ((Z >> b & 1ull) << (3 * b));
        REQUIRE(morton::encode63(X, Y, Z) == ref64);
    }
}

TEST_CASE("morton: quantisation survives flat, zero-size and non-finite bounds") {
    // flat in z: every code must have z bits 0, and x/y still spread over the grid
    AABBf flat{{0, 0, 5}, {1, 2, 5}};
    morton::Quantizer<float> q(flat, 10);
    CHECK(q.cell({1, 2, 5}, 0) == 1023);
    CHECK(q.cell({1, 2, 5}, 1) == 1023);
    CHECK(q.cell({1, 2, 5}, 2) == 0);
    CHECK(q.cell({0.5f, 1, 5}, 0) == 512);
    // a point-sized box quantises everything to cell 0
    morton::Quantizer<float> p(AABBf{{3, 3, 3}, {3, 3, 3}}, 21);
    CHECK(morton::encode<std::uint64_t>(p, Vec3f{3, 3, 3}) == 0);
    // NaN and out-of-range points clamp into the grid
    CHECK(q.cell({std::nanf(""), 0, 0}, 0) == 0);
    CHECK(q.cell({-7, 99, 5}, 0) == 0);
    CHECK(q.cell({-7, 99, 5}, 1) == 1023);
    // empty bounds
    morton::Quantizer<float> e(AABBf{}, 10);
    CHECK(e.cell({1, 1, 1}, 0) == 0);
}

TEST_CASE("radix_sort: equals std::stable_sort on every executor, 32- and 64-bit keys") {
    for_each_executor([](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        for (std::size_t n : {0u, 1u, 2u, 1000u, 300000u}) {
            Rng r(n + 1);
            std::vector<std::uint32_t> k(n), v(n);
            std::vector<std::uint64_t> k64(n);
            for (std::size_t i = 0; i < n; ++i) {
                k[i] = std::uint32_t(r.next() & ((1u << 30) - 1)) & 0x3ff00fffu;   // some constant digits: skipped passes
                k64[i] = r.next() >> 1;
                v[i] = std::uint32_t(i);
            }
            std::vector<std::pair<std::uint32_t, std::uint32_t>> ref(n);
            for (std::size_t i = 0; i < n; ++i) ref[i] = {k[i], v[i]};
            std::stable_sort(ref.begin(), ref.end(), [](auto a, auto b) { return a.first < b.first; });
            auto v64 = v;
            std::vector<std::pair<std::uint64_t, std::uint32_t>> ref64(n);
            for (std::size_t i = 0; i < n; ++i) ref64[i] = {k64[i], v64[i]};
            std::stable_sort(ref64.begin(), ref64.end(), [](auto a, auto b) { return a.first < b.first; });
            radix_sort(k, v, ex, 30);
            radix_sort(k64, v64, ex, 63);
            bool ok = true, ok64 = true;
            for (std::size_t i = 0; i < n; ++i) {
                ok = ok && k[i] == ref[i].first && v[i] == ref[i].second;
                ok64 = ok64 && k64[i] == ref64[i].first && v64[i] == ref64[i].second;
            }
            CHECK(ok);
            CHECK(ok64);
        }
    });
}

namespace {
// A caterpillar: every inner node has one reference child, so the raw tree is n deep.
BinaryTree chain(std::uint32_t n) {
    BinaryTree t;
    for (std::uint32_t i = 0; i + 1 < n; ++i) {
        t.left.push_back(BinaryTree::leaf(i));
        t.right.push_back(i + 2 < n ? i + 1 : BinaryTree::leaf(n - 1));
    }
    t.root = 0;
    return t;
}
} // namespace

TEST_CASE("emit: a raw tree deeper than max_depth is rebalanced, not overflowed") {
    const auto tris = random_soup(5000, 11);
    for_each_executor([&](auto ex) {
        auto refs = make_references(std::span<const Trianglef>(tris), ex);
        const auto tree = chain(std::uint32_t(refs.size()));
        for (std::uint32_t leaf : {1u, 4u}) {
            const auto bvh = emit_bvh<Node<>, prim::indexed>(tree, refs, std::span<const Trianglef>(tris),
                                                             LeafConfig{.max_leaf_size = leaf}, ex);
            CHECK(bvh.depth <= max_depth);
            CHECK(structure_problems(bvh, tris) == "");
        }
    });
}

TEST_CASE("emit: leaves respect max_leaf_size and SAH decides the rest") {
    const auto tris = random_soup(20000, 5);
    for (std::uint32_t m : {1u, 2u, 8u, 32u}) {
        const auto bvh = lbvh::build(tris, {.leaves = {.max_leaf_size = m}}, exec::serial{});
        std::uint32_t largest = 0;
        for (const auto& n : bvh.nodes) if (n.is_leaf()) largest = std::max(largest, n.count);
        CHECK(largest <= m);
        CHECK(structure_problems(bvh, tris) == "");
    }
    // Huge intersection cost: collapsing never pays, every leaf holds one triangle.
    const auto fine = lbvh::build(tris, {.leaves = {.max_leaf_size = 8, .traversal_cost = 0.0f, .intersection_cost = 1e6f}});
    for (const auto& n : fine.nodes) if (n.is_leaf()) REQUIRE(n.count == 1);
    // Free intersections: everything that may collapse does (leaves hold max_leaf_size where possible).
    const auto coarse = lbvh::build(tris, {.leaves = {.max_leaf_size = 8, .traversal_cost = 1.0f, .intersection_cost = 0.0f}});
    CHECK(coarse.nodes.size() < fine.nodes.size() / 4);
}

TEST_CASE("emit: fragments of one triangle in one leaf are tested once") {
    // Two references to the same triangle and one to another: one leaf, two distinct ids.
    std::vector<Trianglef> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}}};
    References<float> refs;
    refs.box = {AABBf{{0, 0, 0}, {0.5f, 1, 0}}, AABBf{{0.5f, 0, 0}, {1, 0.5f, 0}}, tris[1].bounds()};
    refs.prim = {0, 0, 1};
    refs.primitive_count = 2;
    refs.repeats = true;
    BinaryTree t;
    t.left = {1, BinaryTree::leaf(0)};
    t.right = {BinaryTree::leaf(2), BinaryTree::leaf(1)};
    t.root = 0;
    // Traversal made expensive so the SAH collapses everything into one leaf.
    const auto bvh = emit_bvh<Node<>, prim::precomputed>(t, refs, std::span<const Trianglef>(tris),
                                                         LeafConfig{.traversal_cost = 100.0f}, exec::serial{});
    REQUIRE(bvh.nodes.size() == 1);
    CHECK(bvh.nodes[0].count == 2);
    CHECK(bvh.prim_ids[0] == 0);
    CHECK(bvh.prim_ids[1] == 1);
    CHECK(bvh.leaf_triangles[1].p0 == tris[1].p0);
}

TEST_CASE("lbvh: structure on hard inputs, every executor, both key widths and node layouts") {
    std::vector<std::pair<const char*, std::vector<Trianglef>>> cases;
    cases.emplace_back("random soup", random_soup(30000));
    cases.emplace_back("sphere", sphere(48, 96));
    cases.emplace_back("flat", flat_scene(20000));
    cases.emplace_back("identical centroids", identical(20000));
    cases.emplace_back("one", random_soup(1));
    cases.emplace_back("two", random_soup(2));
    cases.emplace_back("none", std::vector<Trianglef>{});
    auto with_nan = random_soup(1000, 9);
    with_nan[3].p1.x = std::nanf("");
    with_nan[500].p2.y = std::numeric_limits<float>::infinity();
    cases.emplace_back("non-finite vertices", with_nan);
    for (const auto& [name, tris] : cases) {
        CAPTURE(name);
        for_each_executor([&](auto ex) {
            CAPTURE(executor_name<decltype(ex)>());
            for (int bits : {30, 63}) {
                CAPTURE(bits);
                const auto a = lbvh::build(tris, {.morton_bits = bits}, ex);
                CHECK(structure_problems(a, tris) == "");
                const auto b = lbvh::build<Node<double, std::uint64_t>, prim::precomputed>(
                    std::span<const Triangle<double>>(), {.morton_bits = bits}, ex);
                CHECK(b.empty());
                const auto c = lbvh::build<Node<>, prim::precomputed>(tris, {.morton_bits = bits}, ex);
                CHECK(structure_problems(c, tris) == "");
            }
        });
    }
    CHECK(lbvh::build(with_nan).excluded == 2);
}

TEST_CASE("lbvh: every executor builds the identical tree") {
    const auto tris = random_soup(50000, 21);
    const auto ref = lbvh::build(tris, {}, exec::serial{});
    for_each_executor([&](auto ex) {
        const auto b = lbvh::build(tris, {}, ex);
        REQUIRE(b.nodes.size() == ref.nodes.size());
        CHECK(std::equal(b.prim_ids.begin(), b.prim_ids.end(), ref.prim_ids.begin()));
        bool same = true;
        for (std::size_t i = 0; i < b.nodes.size(); ++i)
            same = same && b.nodes[i].index == ref.nodes[i].index && b.nodes[i].count == ref.nodes[i].count &&
                   b.nodes[i].bounds() == ref.nodes[i].bounds();
        CHECK(same);
    });
}

TEST_CASE("refit: boxes after moving every vertex equal the boxes recomputed from scratch") {
    auto tris = sphere(32, 64);
    for_each_executor([&](auto ex) {
        auto bvh = lbvh::build<Node<>, prim::precomputed>(tris, {}, ex);
        auto moved = tris;
        Rng r(3);
        for (auto& t : moved) {
            const Vec3f d{r.uniform(-0.1f, 0.1f), r.uniform(-0.1f, 0.1f), r.uniform(-0.1f, 0.1f)};
            t.p0 += d; t.p1 += d; t.p2 += d;
        }
        refit(bvh, std::span<const Trianglef>(moved), ex);
        CHECK(structure_problems(bvh, moved) == "");
        // Boxes are tight: each leaf box equals the union of its triangles, each inner the union of its children.
        bool tight = true;
        for (const auto& n : bvh.nodes) {
            AABBf b;
            if (n.is_leaf()) for (auto s = n.index; s < n.index + n.count; ++s) b.extend(moved[bvh.prim_ids[s]].bounds());
            else b = merge(bvh.nodes[n.left()].bounds(), bvh.nodes[n.right()].bounds());
            tight = tight && b == n.bounds();
        }
        CHECK(tight);
    });
}
