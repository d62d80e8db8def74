// validate.hpp: valid trees pass, and every kind of broken tree built on purpose is caught with a
// message that says what is wrong.
#include <doctest/doctest.h>

#include <dynbvh/validate.hpp>

#include "simple_builder.hpp"

#include <limits>
#include <random>
#include <string>
#include <vector>

#include <dynbvh/lbvh.hpp>
#include <dynbvh/kbvh.hpp>

using namespace dynbvh;
using dynbvh::test::median_build;

namespace {

std::vector<Trianglef> soup(std::size_t n, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> c(0, 20), d(-1, 1);
    std::vector<Trianglef> tris(n);
    for (auto& t : tris) {
        const Vec3f o{c(rng), c(rng), c(rng)};
        t = {o + Vec3f{d(rng), d(rng), d(rng)}, o + Vec3f{d(rng), d(rng), d(rng)}, o + Vec3f{d(rng), d(rng), d(rng)}};
    }
    return tris;
}

bool mentions(const ValidationReport& r, const std::string& what) {
    return r.summary().find(what) != std::string::npos;
}

template <class B>
std::size_t first_leaf(const B& bvh) {
    for (std::size_t i = 0; i < bvh.nodes.size(); ++i)
        if (bvh.nodes[i].is_leaf()) return i;
    return 0;
}

} // namespace

TEST_CASE("valid trees pass") {
    const auto tris = soup(500, 1);
    const auto a = median_build<Node<>, prim::indexed>(tris, 4);
    const auto b = median_build<Node<>, prim::copied>(tris, 1);
    const auto ra = validate(a, tris), rb = validate(b, tris);
    CHECK_MESSAGE(ra.ok(), ra.summary());
    CHECK_MESSAGE(rb.ok(), rb.summary());
    CHECK(ra.references == 500);
    CHECK(rb.leaves == 500);
    CHECK(ra.depth == a.depth);
    CHECK(mentions(ra, "valid BVH"));
    // Non-finite triangles are excluded and counted.
    auto bad = tris;
    bad[7].p1.y = std::numeric_limits<float>::quiet_NaN();
    bad[9].p2.z = std::numeric_limits<float>::infinity();
    const auto c = median_build<Node<>, prim::indexed>(bad, 4);
    CHECK(c.excluded == 2);
    const auto rc = validate(c, bad);
    CHECK_MESSAGE(rc.ok(), rc.summary());
    // Double nodes, 64-bit indices.
    std::vector<Triangled> td;
    for (const auto& t : tris) td.push_back({Vec3d(t.p0), Vec3d(t.p1), Vec3d(t.p2)});
    const auto d = median_build<Node<double, std::uint64_t>, prim::copied>(td, 3);
    CHECK_MESSAGE(validate(d, td).ok(), validate(d, td).summary());
}

TEST_CASE("broken trees are caught, with the reason") {
    const auto tris = soup(200, 2);
    const auto good = median_build<Node<>, prim::copied>(tris, 2);
    REQUIRE(validate(good, tris).ok());

    SUBCASE("a child box sticking out of its parent") {
        auto b = good;
        b.nodes[b.nodes[0].index].max.x += 1.0f;
        const auto r = validate(b, tris);
        CHECK_FALSE(r.ok());
        CHECK(mentions(r, "is not inside its parent"));
    }
    SUBCASE("a leaf box that misses part of its triangle") {
        auto b = good;
        const std::size_t l = first_leaf(b);
        b.nodes[l].min.y += 0.25f;
        const auto r = validate(b, tris);
        CHECK_FALSE(r.ok());
        CHECK(mentions(r, "does not contain triangle"));
    }
    SUBCASE("a missing primitive (replaced by a duplicate of its leaf neighbour)") {
        auto b = good;
        std::size_t l = 0;
        while (l < b.nodes.size() && b.nodes[l].count != 2) ++l;
        REQUIRE(l < b.nodes.size());
        const std::size_t s = b.nodes[l].index;
        const auto lost = b.prim_ids[s + 1];
        b.prim_ids[s + 1] = b.prim_ids[s];
        b.leaf_triangles[s + 1] = b.leaf_triangles[s];
        const auto r = validate(b, tris);
        CHECK_FALSE(r.ok());
        CHECK(mentions(r, "triangle " + std::to_string(lost) + " is not referenced"));
        CHECK(mentions(r, "twice"));
    }
    SUBCASE("a primitive referenced from two leaves") {
        auto b = good;
        std::size_t l1 = first_leaf(b), l2 = l1 + 1;
        while (!b.nodes[l2].is_leaf()) ++l2;
        const std::size_t s1 = b.nodes[l1].index, s2 = b.nodes[l2].index;
        const auto lost = b.prim_ids[s2];
        b.prim_ids[s2] = b.prim_ids[s1];
        b.leaf_triangles[s2] = b.leaf_triangles[s1];
        const auto r = validate(b, tris);
        CHECK_FALSE(r.ok());
        CHECK(mentions(r, "referenced 2 times"));
        CHECK(mentions(r, "triangle " + std::to_string(lost) + " is not referenced"));
        // ... which presplit trees may do, but they must still cover every triangle.
        const auto rp = validate(b, tris, {.expect_single_reference = false});
        CHECK(mentions(rp, "triangle " + std::to_string(lost) + " is not referenced"));
        CHECK_FALSE(mentions(rp, "referenced 2 times"));
    }
    SUBCASE("children out of range") {
        auto b = good;
        b.nodes[1].index = std::uint32_t(b.nodes.size() - 1);
        b.nodes[1].count = 0;
        const auto r = validate(b, tris);
        CHECK_FALSE(r.ok());
        CHECK(mentions(r, "outside 1.."));
    }
    SUBCASE("a cycle back to an ancestor terminates and is reported") {
        auto b = good;
        const std::size_t c = b.nodes[0].index;  // an inner child of the root
        REQUIRE_FALSE(b.nodes[c].is_leaf());
        b.nodes[b.nodes[c].index].index = std::uint32_t(c);  // grandchild points back to c, c+1
        b.nodes[b.nodes[c].index].count = 0;
        const auto r = validate(b, tris);
        CHECK_FALSE(r.ok());
        CHECK(mentions(r, "reached more than once"));
    }
    SUBCASE("an unreachable node") {
        auto b = good;
        b.nodes.push_back(b.nodes.back());
        const auto r = validate(b, tris);
        CHECK(mentions(r, "not reachable from the root"));
    }
    SUBCASE("wrong depth") {
        auto b = good;
        b.depth += 1;
        CHECK(mentions(validate(b, tris), "the deepest leaf is at depth"));
    }
    SUBCASE("NaN box") {
        auto b = good;
        b.nodes[first_leaf(b)].max.z = std::numeric_limits<float>::quiet_NaN();
        CHECK(mentions(validate(b, tris), "invalid box"));
    }
    SUBCASE("precomputed copy differs from the input") {
        auto b = good;
        b.leaf_triangles[3].p0.x += 1e-3f;
        CHECK(mentions(validate(b, tris), "leaf_triangles[3] differs"));
        b.leaf_triangles.pop_back();
        CHECK(mentions(validate(b, tris), "leaf_triangles has"));
    }
    SUBCASE("bookkeeping: counts, out-of-range ids, overlapping leaf ranges") {
        auto b = good;
        b.excluded = 1;
        b.primitive_count = 5;
        const auto r = validate(b, tris);
        CHECK(mentions(r, "excluded is 1"));
        CHECK(mentions(r, "primitive_count is 5"));
        auto c = good;
        c.prim_ids[0] = 100000;
        CHECK(mentions(validate(c, tris), "references triangle 100000"));
        auto d = good;
        const std::size_t l = first_leaf(d);
        d.nodes[l].count += 1;  // now overlaps the next leaf's first slot
        CHECK(mentions(validate(d, tris), "belongs to leaves"));
    }
    SUBCASE("empty tree over finite triangles") {
        Bvh<Node<>, prim::copied> e;
        e.primitive_count = tris.size();
        CHECK(mentions(validate(e, tris), "empty tree but 200 triangles are finite"));
    }
    SUBCASE("messages are capped, the count is not") {
        auto b = good;
        for (auto& n : b.nodes) n.max.x = n.min.x - 1;  // every box inverted
        const auto r = validate(b, tris, {.max_messages = 4});
        CHECK(r.errors.size() == 4);
        CHECK(r.error_count > 100);
        CHECK(mentions(r, "more"));
    }
}

TEST_CASE("presplit-style fragments: coverage of each triangle by its leaves' boxes") {
    // One long triangle split by hand into two leaves whose boxes each cover half of it.
    const std::vector<Trianglef> tris = {{{0, 0, 0}, {8, 0, 0}, {0, 1, 0}}};
    Bvh<> b;
    b.primitive_count = 1;
    b.nodes.resize(3);
    b.nodes[0].set_bounds({{0, 0, 0}, {8, 1, 0}});
    b.nodes[0].index = 1;
    b.nodes[1].set_bounds({{0, 0, 0}, {4, 1, 0}});  // left half: x in [0, 4]
    b.nodes[1].index = 0;
    b.nodes[1].count = 1;
    b.nodes[2].set_bounds({{4, 0, 0}, {8, 0.5f, 0}});  // right half: x in [4, 8], y <= 0.5
    b.nodes[2].index = 1;
    b.nodes[2].count = 1;
    b.prim_ids = {0, 0};
    b.depth = 1;
    const auto single = validate(b, tris);
    CHECK_FALSE(single.ok());  // two references where one is expected
    const auto frag = validate(b, tris, {.expect_single_reference = false});
    CHECK_MESSAGE(frag.ok(), frag.summary());
    // Shrink the right fragment so that the vertex (8,0,0) is no longer covered.
    b.nodes[2].max.x = 7.5f;
    b.nodes[0].max.x = 8;  // root unchanged
    const auto hole = validate(b, tris, {.expect_single_reference = false});
    CHECK_FALSE(hole.ok());
    CHECK(mentions(hole, "not covered"));
}

TEST_CASE("LBVH trees validate") {
    const auto tris = soup(3000, 4);
    const auto a = lbvh::build<Node<>, prim::indexed>(std::span<const Trianglef>(tris), {}, exec::serial{});
    const auto b = lbvh::build<Node<>, prim::copied>(std::span<const Trianglef>(tris), {}, exec::serial{});
    CHECK_MESSAGE(validate(a, tris).ok(), validate(a, tris).summary());
    CHECK_MESSAGE(validate(b, tris).ok(), validate(b, tris).summary());
}

TEST_CASE("presplit KBVH trees validate with fragment coverage") {
    // Long thin triangles, so that presplitting actually splits.
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> c(0, 20), d(-8, 8), e(-0.2f, 0.2f);
    std::vector<Trianglef> tris(2000);
    for (auto& t : tris) {
        const Vec3f o{c(rng), c(rng), c(rng)};
        const Vec3f along{d(rng), d(rng), d(rng)};
        t = {o, o + along, o + along * 0.5f + Vec3f{e(rng), e(rng), e(rng)}};
    }
    const auto b = kbvh::build<Node<>, prim::copied>(std::span<const Trianglef>(tris), {}, exec::serial{});
    const auto r = validate(b, tris, {.expect_single_reference = false});
    CHECK_MESSAGE(r.ok(), r.summary());
    MESSAGE("kbvh: " << r.references << " references for " << tris.size() << " triangles");
}
