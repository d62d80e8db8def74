// Direct wide emission (detail/emit_wide.hpp, <builder>::build_wide<W>): the same tree, bit for bit, as
// the binary build followed by make_wide<W> (nodes in the same order, boxes, children, counts, prim_ids,
// leaf triangles, depth), on every builder x executor x test scene, W = 4 and 8, both primitive policies;
// the too-deep raw tree (rebalanced by the binary emission) too; and hits equal to brute force.
#include "builds.hpp"
#include "hit_compare.hpp"
#include "support.hpp"

#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <dynbvh/detail/emit_wide.hpp>
#include <dynbvh/wide.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

namespace {

/// Empty when `a` and `b` are the same wide tree to the bit, else the first difference.
template <class WB>
std::string difference(const WB& a, const WB& b) {
    if (a.nodes.size() != b.nodes.size())
        return "node counts " + std::to_string(a.nodes.size()) + " and " + std::to_string(b.nodes.size());
    for (std::size_t i = 0; i < a.nodes.size(); ++i)
        if (std::memcmp(&a.nodes[i], &b.nodes[i], sizeof(a.nodes[i])) != 0) return "node " + std::to_string(i) + " differs";
    if (a.prim_ids.size() != b.prim_ids.size()) return "prim_ids sizes differ";
    for (std::size_t s = 0; s < a.prim_ids.size(); ++s)
        if (a.prim_ids[s] != b.prim_ids[s]) return "prim_ids[" + std::to_string(s) + "] differs";
    if (a.leaf_triangles.size() != b.leaf_triangles.size()) return "leaf_triangles sizes differ";
    for (std::size_t s = 0; s < a.leaf_triangles.size(); ++s)
        if (std::memcmp(&a.leaf_triangles[s], &b.leaf_triangles[s], sizeof(Trianglef)) != 0) return "leaf triangle " + std::to_string(s) + " differs";
    if (a.depth != b.depth) return "depth " + std::to_string(a.depth) + " and " + std::to_string(b.depth);
    if (a.primitive_count != b.primitive_count || a.excluded != b.excluded) return "counts differ";
    return {};
}

std::vector<std::pair<std::string, std::vector<Trianglef>>> scenes() {
    std::vector<std::pair<std::string, std::vector<Trianglef>>> s;
    s.push_back({"empty", {}});
    s.push_back({"one", random_soup(1, 3)});
    s.push_back({"two", random_soup(2, 4)});
    s.push_back({"soup 3000", random_soup(3000, 7)});
    s.push_back({"soup 20000", random_soup(sanitizer_scaled(20000), 8)});
    s.push_back({"sphere", sphere(24, 48)});
    s.push_back({"flat", flat_scene(2000)});
    s.push_back({"identical", identical(300)});
    s.push_back({"long thin", long_thin(2000)});
    auto with_nan = random_soup(500, 9);
    with_nan[17].p1.y = std::numeric_limits<float>::quiet_NaN();
    with_nan[300].p0.x = std::numeric_limits<float>::infinity();
    s.push_back({"non-finite", with_nan});
    return s;
}

/// Checks build_wide<W> against make_wide<W>(build) for one builder (`direct`, `binary` callables).
template <int W, class Direct, class Binary, class Ex>
void check_same(const char* builder, Direct&& direct, Binary&& binary, const Ex& ex) {
    for (const auto& [name, tris] : scenes()) {
        CAPTURE(builder);
        CAPTURE(name);
        CAPTURE(W);
        CAPTURE(executor_name<Ex>());
        const std::span<const Trianglef> t(tris);
        const auto want = make_wide<W>(binary(t, ex), ex);
        const auto got = direct(t, ex);
        CHECK(difference(got, want) == "");
    }
}

template <int W, class Prim, class Ex>
void check_all_builders(const Ex& ex) {
    using NodeT = Node<>;
    check_same<W>("lbvh", [](auto t, const auto& e) { return lbvh::build_wide<W, NodeT, Prim>(t, {}, e); },
                  [](auto t, const auto& e) { return lbvh::build<NodeT, Prim>(t, {}, e); }, ex);
    check_same<W>("lbvh63 leaf 8", [](auto t, const auto& e) { return lbvh::build_wide<W, NodeT, Prim>(t, {.morton_bits = 63, .leaves = {.max_leaf_size = 8}}, e); },
                  [](auto t, const auto& e) { return lbvh::build<NodeT, Prim>(t, {.morton_bits = 63, .leaves = {.max_leaf_size = 8}}, e); }, ex);
    check_same<W>("hlbvh 16", [](auto t, const auto& e) { return lbvh::build_wide<W, NodeT, Prim>(t, {.sah_top = 16}, e); },
                  [](auto t, const auto& e) { return lbvh::build<NodeT, Prim>(t, {.sah_top = 16}, e); }, ex);
    check_same<W>("ploc r5", [](auto t, const auto& e) { return ploc::build_wide<W, NodeT, Prim>(t, {.radius = 5}, e); },
                  [](auto t, const auto& e) { return ploc::build<NodeT, Prim>(t, {.radius = 5}, e); }, ex);
    check_same<W>("kbvh", [](auto t, const auto& e) { return kbvh::build_wide<W, NodeT, Prim>(t, {.split = {.beta = 0.3f}}, e); },
                  [](auto t, const auto& e) { return kbvh::build<NodeT, Prim>(t, {.split = {.beta = 0.3f}}, e); }, ex);
    check_same<W>("kbvh lbvh", [](auto t, const auto& e) { return kbvh::build_wide<W, NodeT, Prim, kbvh::with_lbvh>(t, {.split = {.beta = 0.3f}}, e); },
                  [](auto t, const auto& e) { return kbvh::build<NodeT, Prim, kbvh::with_lbvh>(t, {.split = {.beta = 0.3f}}, e); }, ex);
    check_same<W>("binned sah", [](auto t, const auto& e) { return binned_sah::build_wide<W, NodeT, Prim>(t, {}, e); },
                  [](auto t, const auto& e) { return binned_sah::build<NodeT, Prim>(t, {}, e); }, ex);
}

// A caterpillar raw tree (every inner node has one reference child): n deep, so the binary emission
// rebalances it and the direct emission must take the same path.
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

TEST_CASE("emit_wide: build_wide<8> equals make_wide<8>(build) bit for bit, every builder x executor x scene") {
    for_each_executor([&](auto ex) { check_all_builders<8, prim::indexed>(ex); });
}

TEST_CASE("emit_wide: build_wide<4> and prim::copied equal the two-step path bit for bit") {
    for_each_executor([&](auto ex) {
        check_all_builders<4, prim::indexed>(ex);
        check_all_builders<8, prim::copied>(ex);
    });
}

TEST_CASE("emit_wide: a raw tree too deep for max_depth gives the two-step (rebalanced) tree, within max_depth") {
    const auto tris = random_soup(3000, 11);
    for_each_executor([&](auto ex) {
        auto refs = make_references(std::span<const Trianglef>(tris), ex);
        const auto tree = chain(std::uint32_t(refs.size()));
        for (std::uint32_t leaf : {1u, 4u}) {
            const LeafConfig cfg{.max_leaf_size = leaf};
            const auto want = make_wide<8>(emit_bvh<Node<>, prim::indexed>(tree, refs, std::span<const Trianglef>(tris), cfg, ex), ex);
            const auto got = emit_wide_bvh<8, Node<>, prim::indexed>(tree, refs, std::span<const Trianglef>(tris), cfg, ex);
            CHECK(difference(got, want) == "");
            CHECK(got.depth <= max_depth);
        }
    });
}

TEST_CASE("emit_wide: hits on directly emitted trees equal brute force (t to the bit, or an exact tie)") {
    const auto tris = random_soup(sanitizer_scaled(4000), 21, 0.05f);
    const std::span<const Trianglef> t(tris);
    const auto w_lbvh = lbvh::build_wide<8>(t, {}, exec::serial{});
    const auto w_kbvh = kbvh::build_wide<4>(t, {.split = {.beta = 0.3f}}, exec::serial{});
    Rng rng(5);
    std::size_t bad = 0;
    const std::size_t rays = sanitizer_scaled(400);
    for (std::size_t i = 0; i < rays; ++i) {
        const Vec3f org{rng.uniform(-0.5f, 1.5f), rng.uniform(-0.5f, 1.5f), rng.uniform(-0.5f, 1.5f)};
        const Vec3f target{rng.uniform(), rng.uniform(), rng.uniform()};
        const Rayf ray{.org = org, .dir = target - org};
        const Hitf want = brute_force_intersect(t, ray);
        for (const Hitf got : {intersect(w_lbvh, t, ray), intersect(w_kbvh, t, ray)})
            if (!same_hit<tri::watertight>(got, want, t, ray)) {
                if (bad++ < 5) MESSAGE(describe(ray, got, want));
            }
    }
    CHECK(bad == 0);
}
