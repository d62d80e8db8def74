// lbvh.hpp: structure on hard inputs and the same tree on every executor.
#include "support.hpp"

#include <algorithm>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/sah.hpp>

#include <stdexcept>
#include <string>
#include <type_traits>

using namespace dynbvh;
using namespace dynbvh::test;

TEST_CASE("lbvh: valid structure on soup, sphere, flat, identical centroids, 0-2 and non-finite triangles; every executor, 30- and 63-bit keys, both node layouts") {
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
    for (const auto& entry : cases) {
        // Not a structured binding: clang 14 (the TSan + OpenMP build) cannot capture one in a lambda.
        const char* const name = entry.first;
        const std::vector<Trianglef>& tris = entry.second;
        CAPTURE(name);
        for_each_executor([&](auto ex) {
            CAPTURE(executor_name<decltype(ex)>());
            for (int bits : {30, 63}) {
                CAPTURE(bits);
                const auto a = lbvh::build(tris, {.morton_bits = bits}, ex);
                CHECK(structure_problems(a, tris) == "");
                const auto b = lbvh::build<Node<double, std::uint64_t>, prim::copied>(
                    std::span<const Triangle<double>>(), {.morton_bits = bits}, ex);
                CHECK(b.empty());
                const auto c = lbvh::build<Node<>, prim::copied>(tris, {.morton_bits = bits}, ex);
                CHECK(structure_problems(c, tris) == "");
            }
        });
    }
    CHECK(lbvh::build(with_nan).excluded == 2);
}

TEST_CASE("lbvh: every executor builds the serial tree node for node") {
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

TEST_CASE("lbvh: a std::vector of double triangles builds a Bvh<Node<double>> with the float tree's topology") {
    const auto tris = random_soup(3000, 4);
    std::vector<Triangled> dtris;
    for (const auto& t : tris) dtris.push_back({Vec3d(t.p0), Vec3d(t.p1), Vec3d(t.p2)});
    const auto d = lbvh::build(dtris);
    static_assert(std::is_same_v<std::remove_const_t<decltype(d)>, Bvh<Node<double>>>);
    const auto f = lbvh::build(tris);
    static_assert(std::is_same_v<std::remove_const_t<decltype(f)>, Bvh<Node<>>>);
    REQUIRE(d.nodes.size() == f.nodes.size());
    CHECK(d.primitive_count == dtris.size());
    bool boxes_hold = true;
    for (const auto& n : d.nodes)
        if (n.is_leaf())
            for (auto s = n.index; s < n.index + n.count; ++s) boxes_hold = boxes_hold && n.bounds().contains(dtris[d.prim_ids[s]].bounds());
    CHECK(boxes_hold);
    // The other builders deduce the node type the same way.
    static_assert(std::is_same_v<decltype(ploc::build(dtris)), Bvh<Node<double>>>);
    static_assert(std::is_same_v<decltype(binned_sah::build(dtris)), Bvh<Node<double>>>);
    static_assert(std::is_same_v<decltype(kbvh::build(dtris)), Bvh<Node<double>>>);
}

TEST_CASE("lbvh: morton_bits other than 30 or 63 throws std::invalid_argument naming lbvh and morton_bits") {
    const auto tris = random_soup(100, 2);
    for (int bits : {0, 29, 31, 32, 62, 64}) {
        CAPTURE(bits);
        std::string what;
        try {
            (void)lbvh::build(tris, {.morton_bits = bits});
        } catch (const std::invalid_argument& e) {
            what = e.what();
        }
        CHECK(what == "dynbvh::lbvh: morton_bits must be 30 or 63, got " + std::to_string(bits));
    }
    CHECK_NOTHROW((void)lbvh::build(tris, {.morton_bits = 63}));
}

TEST_CASE("prim::precomputed is still accepted as the deprecated name of prim::copied") {
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#endif
    static_assert(std::is_same_v<prim::precomputed, prim::copied>);
    const auto tris = random_soup(200, 3);
    const auto old = lbvh::build<Node<>, prim::precomputed>(tris);
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
    const auto now = lbvh::build<Node<>, prim::copied>(tris);
    CHECK(old.leaf_triangles.size() == now.leaf_triangles.size());
    CHECK(structure_problems(old, tris) == "");
}

TEST_CASE("lbvh sah_top (HLBVH): a lower SAH than the plain LBVH; sah_top at or above the reference count leaves the plain tree") {
    std::vector<std::pair<const char*, std::vector<Trianglef>>> cases;
    cases.emplace_back("random soup", random_soup(30000, 4));
    cases.emplace_back("long thin", long_thin(20000));
    cases.emplace_back("sphere", sphere(48, 96));
    cases.emplace_back("flat", flat_scene(20000));
    for (const auto& entry : cases) {
        const std::string name = entry.first;
        const std::vector<Trianglef>& tris = entry.second;
        CAPTURE(name);
        const auto plain = lbvh::build(tris);
        const auto top = lbvh::build(tris, {.sah_top = 32});
        CHECK(structure_problems(top, tris) == "");
        const double a = sah_cost(plain), b = sah_cost(top);
        MESSAGE(name << ": SAH lbvh " << a << ", sah_top 32 " << b);
        CHECK(b < a);
        // The root is a cluster itself: nothing rebuilt, the plain tree node for node.
        const auto same = lbvh::build(tris, {.sah_top = std::uint32_t(tris.size())});
        REQUIRE(same.nodes.size() == plain.nodes.size());
        bool equal = std::equal(same.prim_ids.begin(), same.prim_ids.end(), plain.prim_ids.begin());
        for (std::size_t i = 0; i < same.nodes.size(); ++i)
            equal = equal && same.nodes[i].index == plain.nodes[i].index && same.nodes[i].count == plain.nodes[i].count &&
                    same.nodes[i].bounds() == plain.nodes[i].bounds();
        CHECK(equal);
    }
}
