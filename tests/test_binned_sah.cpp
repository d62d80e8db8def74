// Binned SAH builder (binned_sah.hpp): raw topology is a valid binary tree over every reference,
// edge cases (identical centroids, 1 and 2 triangles, flat scene, adversarial spacing) stay shallow,
// the result does not depend on the executor, and its SAH beats LBVH's.
#include <doctest/doctest.h>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/validate.hpp>

#include <algorithm>
#include <chrono>
#include <random>
#include <vector>

#include "support.hpp"

using namespace dynbvh;

namespace {

/// Raw binned-SAH trees must themselves stay within max_depth.
std::size_t check_topology(const BinaryTree& tree, std::size_t n) { return test::check_topology(tree, n, max_depth); }

using Tri = Triangle<float>;

template <class Exec = exec::serial>
BinaryTree tree_of(const std::vector<Tri>& tris, const binned_sah::Config& cfg = {}, const Exec& ex = {}) {
    const auto refs = make_references(std::span<const Tri>(tris), ex);
    auto tree = binned_sah::build_tree(refs, cfg, ex);
    check_topology(tree, refs.size());
    return tree;
}

double sah(const Bvh<>& bvh) { return sah_cost(bvh, {.ct = 3, .ci = 2}); }

void check_bvh(const Bvh<>& bvh, const std::vector<Tri>& tris) {
    const auto rep = validate(bvh, std::span<const Tri>(tris));
    CHECK_MESSAGE(rep.ok(), rep.summary());
}

} // namespace

TEST_CASE("binned_sah: random soup, valid topology and final tree") {
    const auto tris = test::mt_soup(20000, 1);
    tree_of(tris);
    check_bvh(binned_sah::build(tris, {}, exec::serial{}), tris);
    check_bvh(binned_sah::build(tris, {.bins = 2}, exec::serial{}), tris);
    check_bvh(binned_sah::build(tris, {.bins = 256}, exec::serial{}), tris);
#if defined(_OPENMP)
    check_bvh(binned_sah::build(tris, {}, exec::omp{2}), tris);
#endif
#if defined(DYNBVH_WITH_TBB)
    check_bvh(binned_sah::build(tris, {}, exec::tbb{2}), tris);
#endif
    const auto pre = binned_sah::build<Node<>, prim::copied>(tris, {}, exec::serial{});
    const auto rep = validate(pre, std::span<const Tri>(tris));
    CHECK_MESSAGE(rep.ok(), rep.summary());
}

TEST_CASE("binned_sah: two clusters are separated at the root") {
    // Four triangles: two near x = 0, two near x = 100. The cheapest root split separates the clusters.
    const std::vector<Tri> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}},
                                {{100, 0, 0}, {101, 0, 0}, {100, 1, 0}},
                                {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}},
                                {{100, 0, 1}, {101, 0, 1}, {100, 1, 1}}};
    const auto tree = tree_of(tris);
    const auto side = [&](std::uint32_t id) {
        std::vector<std::uint32_t> refs, st{id};
        while (!st.empty()) {
            const auto x = st.back();
            st.pop_back();
            if (BinaryTree::is_leaf(x)) refs.push_back(BinaryTree::ref_of(x));
            else { st.push_back(tree.left[x]); st.push_back(tree.right[x]); }
        }
        std::sort(refs.begin(), refs.end());
        return refs;
    };
    const auto l = side(tree.left[tree.root]), r = side(tree.right[tree.root]);
    CHECK(((l == std::vector<std::uint32_t>{0, 2} && r == std::vector<std::uint32_t>{1, 3}) ||
           (l == std::vector<std::uint32_t>{1, 3} && r == std::vector<std::uint32_t>{0, 2})));
}

TEST_CASE("binned_sah: empty, one and two triangles") {
    const std::vector<Tri> none;
    CHECK(tree_of(none).inner_count() == 0);
    CHECK(binned_sah::build(none, {}, exec::serial{}).empty());
    const std::vector<Tri> one{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    CHECK(tree_of(one).root == BinaryTree::leaf(0));
    check_bvh(binned_sah::build(one, {}, exec::serial{}), one);
    const std::vector<Tri> two{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{5, 5, 5}, {6, 5, 5}, {5, 6, 5}}};
    const auto t2 = tree_of(two);
    CHECK(BinaryTree::is_leaf(t2.left[t2.root]));
    CHECK(BinaryTree::is_leaf(t2.right[t2.root]));
    check_bvh(binned_sah::build(two, {}, exec::serial{}), two);
    const std::vector<Tri> same2(2, one[0]);
    tree_of(same2);
}

TEST_CASE("binned_sah: identical centroids split by index, balanced and fast") {
    // 100k copies of one triangle, and 20k triangles of different sizes around one centre.
    const std::vector<Tri> same(100000, Tri{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    const auto depth = check_topology(tree_of(same), same.size());
    CHECK(depth == 17);   // ceil(log2(100000)): median splits by index
    std::vector<Tri> nested;
    for (int i = 1; i <= 20000; ++i) {
        const float s = 1e-3f * static_cast<float>(i);
        nested.push_back({{-s, -s, -s}, {s, s, s}, {s, -s, s}});
    }
    const auto rn = make_references(std::span<const Tri>(nested), exec::serial{});
    const auto tn = binned_sah::build_tree(rn, {}, exec::serial{});
    check_topology(tn, nested.size());
#if defined(_OPENMP)
    const auto to = binned_sah::build_tree(make_references(std::span<const Tri>(same), exec::omp{2}), {}, exec::omp{2});
    check_topology(to, same.size());
#endif
    check_bvh(binned_sah::build(nested, {}, exec::serial{}), nested);
}

TEST_CASE("binned_sah: flat scene and exponentially spaced triangles stay within max_depth") {
    auto flat = test::mt_soup(10000, 3, 0.01f);
    for (auto& t : flat) t.p0.z = t.p1.z = t.p2.z = 0.0f;
    tree_of(flat);
    check_bvh(binned_sah::build(flat, {}, exec::serial{}), flat);

    // Centres at 1.5^i: every SAH split peels off the far end, which alone would be 179 levels deep.
    std::vector<Tri> chain;
    float x = 1.0f;
    for (int i = 0; i < 180; ++i, x *= 1.5f) chain.push_back({{x, 0, 0}, {x * 1.01f, 0, 0}, {x, 1, 0}});
    const auto depth = check_topology(tree_of(chain), chain.size());
    CHECK(depth <= max_depth);
    check_bvh(binned_sah::build(chain, {}, exec::serial{}), chain);
}

TEST_CASE("binned_sah: every executor builds the same tree") {
    // Large enough for many data-parallel top nodes (above max(4096, n / 128) references).
    auto tris = test::mt_soup(40000, 7);
    const std::vector<Tri> same(5000, tris[5]);
    tris.insert(tris.end(), same.begin(), same.end());
    const auto ref = tree_of(tris);
#if defined(_OPENMP)
    for (int threads : {1, 2, 3}) {
        CAPTURE(threads);
        const auto t = tree_of(tris, {}, exec::omp{threads});
        CHECK(t.root == ref.root);
        CHECK(t.left == ref.left);
        CHECK(t.right == ref.right);
    }
#endif
#if defined(DYNBVH_WITH_TBB)
    const auto t = tree_of(tris, {}, exec::tbb{2});
    CHECK(t.root == ref.root);
    CHECK(t.left == ref.left);
    CHECK(t.right == ref.right);
#endif
}

TEST_CASE("binned_sah: bad config is refused") {
    const auto tris = test::mt_soup(10, 2);
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});
    CHECK_THROWS_AS(binned_sah::build_tree(refs, {.bins = 1}, exec::serial{}), std::invalid_argument);
    CHECK_THROWS_AS(binned_sah::build_tree(refs, {.bins = 0}, exec::serial{}), std::invalid_argument);
}

TEST_CASE("binned_sah: SAH at most LBVH's (and PLOC's ratio reported) on a random soup") {
    const auto tris = test::mt_soup(50000, 13, 0.03f);
    const double b = sah(binned_sah::build(tris, {}, exec::serial{}));
    const double l = sah(lbvh::build(tris, {}, exec::serial{}));
    const double p5 = sah(ploc::build(tris, {.radius = 5}, exec::serial{}));
    MESSAGE("SAH binned ", b, ", LBVH ", l, " (", l / b, "x), PLOC r=5 ", p5, " (", p5 / b, "x)");
    CHECK(b <= l);
}
