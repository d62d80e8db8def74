// lbvh.hpp: structure on hard inputs and the same tree on every executor.
#include "support.hpp"

#include <algorithm>

#include <dynbvh/lbvh.hpp>

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
