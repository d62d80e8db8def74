// Every public function that takes a tree and the user's triangles checks that the span is the array
// the tree was built over (issue 16.3; detail/check_triangles.hpp): refit, intersect, occluded, epo
// throw std::invalid_argument naming the function and both counts, and leave the tree unchanged;
// validate reports the same message. Covers binary trees (indexed and precomputed) and wide trees
// (4 and 8 wide), spans shorter and longer than the tree's, empty spans and empty trees.
#include <doctest/doctest.h>

#include <dynbvh/lbvh.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/validate.hpp>
#include <dynbvh/wide.hpp>

#include <algorithm>
#include <cstring>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "builds.hpp"
#include "support.hpp"

using namespace dynbvh;

namespace {

template <class F>
std::string thrown(F&& f) {
    try {
        f();
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return {};
}

/// The expected message parts for function `fn`, `given` triangles, a tree over `built`.
void check_message(const std::string& what, const char* fn, std::size_t given, std::size_t built) {
    INFO(what);
    CHECK(what.find(std::string("dynbvh::") + fn + ":") == 0);
    CHECK(what.find(": " + std::to_string(given) + " triangles were passed") != std::string::npos);
    CHECK(what.find("primitive_count is " + std::to_string(built)) != std::string::npos);
}

template <class B>
std::vector<char> bytes_of(const B& b) {
    std::vector<char> out(b.nodes.size() * sizeof(b.nodes[0]) + b.leaf_triangles.size() * sizeof(Trianglef));
    std::memcpy(out.data(), b.nodes.data(), b.nodes.size() * sizeof(b.nodes[0]));
    if (!b.leaf_triangles.empty())
        std::memcpy(out.data() + b.nodes.size() * sizeof(b.nodes[0]), b.leaf_triangles.data(), b.leaf_triangles.size() * sizeof(Trianglef));
    return out;
}

/// Spans of other sizes than `n` over a buffer of 2n + 1 valid triangles (so that a missing check
/// reads garbage in bounds rather than crashing, and the test still fails).
std::vector<std::size_t> wrong_sizes(std::size_t n) {
    std::vector<std::size_t> out;
    for (const std::size_t m : {std::size_t(0), std::size_t(1), n / 2, n - 1, n + 1, 2 * n + 1})
        if (m != n && std::find(out.begin(), out.end(), m) == out.end()) out.push_back(m);
    return out;
}

template <class B>
void check_binary(const char* label, std::size_t n) {
    INFO(label);
    const auto all = test::random_soup(2 * n + 1, 21);
    const std::span<const Trianglef> tris(all.data(), n);
    B bvh = lbvh::build<typename B::node_type, typename B::prim_policy>(tris);
    REQUIRE(validate(bvh, tris).ok());
    const Rayf ray{{0.5f, 0.5f, -1}, {0, 0, 1}};
    const auto before = bytes_of(bvh);
    for (const std::size_t m : wrong_sizes(n)) {
        CAPTURE(m);
        const std::span<const Trianglef> other(all.data(), m);
        check_message(thrown([&] { refit(bvh, other); }), "refit", m, n);
        CHECK(bytes_of(bvh) == before);   // nothing refitted before the throw
        check_message(thrown([&] { (void)epo(bvh, other); }), "epo", m, n);
        const auto rep = validate(bvh, other);
        CHECK(!rep.ok());
        bool named = false;
        for (const auto& e : rep.errors) named = named || e.find("primitive_count is " + std::to_string(n)) != std::string::npos;
        CHECK(named);
        if constexpr (!B::precomputed) {
            check_message(thrown([&] { (void)intersect(bvh, other, ray); }), "intersect", m, n);
            check_message(thrown([&] { (void)occluded(bvh, other, ray); }), "occluded", m, n);
        } else {  // traversal of precomputed trees does not read `tris`: any span is accepted
            CHECK(intersect(bvh, other, ray).prim == intersect(bvh, tris, ray).prim);
            CHECK(occluded(bvh, other, ray) == occluded(bvh, tris, ray));
        }
    }
    // The right span passes everywhere.
    CHECK_NOTHROW(refit(bvh, tris));
    CHECK_NOTHROW((void)epo(bvh, tris));
    CHECK(validate(bvh, tris).ok());
    CHECK(intersect(bvh, tris, ray).prim == brute_force_intersect(tris, ray).prim);

    // Wide trees: the same check in their traversal.
    auto check_wide = [&](auto wide) {
        for (const std::size_t m : wrong_sizes(n)) {
            const std::span<const Trianglef> other(all.data(), m);
            if constexpr (!decltype(wide)::precomputed) {
                check_message(thrown([&] { (void)intersect(wide, other, ray); }), "intersect", m, n);
                check_message(thrown([&] { (void)occluded(wide, other, ray); }), "occluded", m, n);
            } else {
                CHECK(intersect(wide, other, ray).prim == intersect(wide, tris, ray).prim);
            }
        }
        CHECK(intersect(wide, tris, ray).prim == brute_force_intersect(tris, ray).prim);
    };
    check_wide(make_wide<4>(bvh));
    check_wide(make_wide<8>(bvh));
}

} // namespace

TEST_CASE("input checks: tree and triangle span must match (binary and wide, indexed and precomputed)") {
    for (const std::size_t n : {1u, 2u, 7u, 1000u}) {
        CAPTURE(n);
        check_binary<Bvh<Node<>, prim::indexed>>("indexed", n);
        check_binary<Bvh<Node<>, prim::copied>>("precomputed", n);
    }
}

TEST_CASE("input checks: an empty tree takes only an empty span") {
    const std::vector<Trianglef> none;
    Bvh<> empty = lbvh::build(std::span<const Trianglef>(none));
    REQUIRE(empty.empty());
    const auto tris = test::random_soup(3, 2);
    CHECK_NOTHROW(refit(empty, none));
    check_message(thrown([&] { refit(empty, tris); }), "refit", 3, 0);
    check_message(thrown([&] { (void)intersect(empty, tris, Rayf{{0, 0, 0}, {1, 0, 0}}); }), "intersect", 3, 0);
    // Non-finite triangles still count: a tree over 3 triangles of which none is finite wants 3.
    std::vector<Trianglef> nan_tris(3, Trianglef{{std::numeric_limits<float>::quiet_NaN(), 0, 0}, {1, 0, 0}, {0, 1, 0}});
    Bvh<> none_finite = lbvh::build(std::span<const Trianglef>(nan_tris));
    CHECK(none_finite.primitive_count == 3);
    CHECK_NOTHROW(refit(none_finite, nan_tris));
    check_message(thrown([&] { refit(none_finite, none); }), "refit", 0, 3);
}
