// detail/emit.hpp: emission of raw trees (depth bound, SAH leaf collapse, deduplicated fragments).
#include "support.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include <dynbvh/detail/emit.hpp>
#include <dynbvh/lbvh.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

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

TEST_CASE("emit: a 5000-deep raw chain is emitted valid within max_depth") {
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

TEST_CASE("emit: no leaf exceeds max_leaf_size; a huge Ci keeps one triangle per leaf, a zero Ci collapses to under a quarter of the nodes") {
    const auto tris = random_soup(20000, 5);
    for (std::uint32_t m : {1u, 2u, 8u, 32u}) {
        const auto bvh = lbvh::build(tris, {.leaves = {.max_leaf_size = m}}, exec::serial{});
        std::uint32_t largest = 0;
        for (const auto& n : bvh.nodes) if (n.is_leaf()) largest = std::max(largest, n.count);
        CHECK(largest <= m);
        CHECK(structure_problems(bvh, tris) == "");
    }
    // Huge intersection cost: collapsing never pays, every leaf holds one triangle.
    const auto fine = lbvh::build(tris, {.leaves = {.max_leaf_size = 8, .cost = {.ct = 0, .ci = 1e6}}});
    for (const auto& n : fine.nodes) if (n.is_leaf()) REQUIRE(n.count == 1);
    // Free intersections: everything that may collapse does (leaves hold max_leaf_size where possible).
    const auto coarse = lbvh::build(tris, {.leaves = {.max_leaf_size = 8, .cost = {.ct = 1, .ci = 0}}});
    CHECK(coarse.nodes.size() < fine.nodes.size() / 4);
}

TEST_CASE("emit: two fragments of one triangle in one leaf become one reference") {
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
    const auto bvh = emit_bvh<Node<>, prim::copied>(t, refs, std::span<const Trianglef>(tris),
                                                         LeafConfig{.cost = {.ct = 100}}, exec::serial{});
    REQUIRE(bvh.nodes.size() == 1);
    CHECK(bvh.nodes[0].count == 2);
    CHECK(bvh.prim_ids[0] == 0);
    CHECK(bvh.prim_ids[1] == 1);
    CHECK(bvh.leaf_triangles[1].p0 == tris[1].p0);
}

TEST_CASE("emit: BinaryTree::check_size throws std::length_error naming the builder from 2^31 references on") {
    CHECK_NOTHROW(BinaryTree::check_size(BinaryTree::leaf_flag - 1, "dynbvh::lbvh"));
    std::string what;
    try {
        BinaryTree::check_size(BinaryTree::leaf_flag, "dynbvh::ploc");
    } catch (const std::length_error& e) {
        what = e.what();
    }
    CHECK(what == "dynbvh::ploc: 2147483648 references exceed the limit of 2^31 - 1");
}
