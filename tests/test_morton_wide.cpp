// morton_wide.hpp: the wide tree straight from the sorted Morton codes. Checked structurally (every
// finite triangle in exactly one leaf, leaves of at most max_leaf_size references that are runs of the
// Morton order, every slot box exactly the union of what it holds, depth as recorded), against brute
// force on adversarial rays (closest hit to the bit, any hit), the same tree on every executor, block
// leaves packed from it, its refit in place, and the errors for bad knobs. build_blocks (the traced
// layout in one step) is checked against make_wide_blocks of build, bit for bit, on every executor.
#include <doctest/doctest.h>

#include <dynbvh/morton_wide.hpp>
#include <dynbvh/refit.hpp>
#include <dynbvh/wide_blocks.hpp>

#include "robust_support.hpp"

#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

using namespace dynbvh;
using dynbvh::test::same_bits;
using dynbvh::test::block_difference;

namespace {

bool same_box(const AABB<float>& a, const AABB<float>& b) {
    return same_bits(a.min.x, b.min.x) && same_bits(a.min.y, b.min.y) && same_bits(a.min.z, b.min.z) &&
           same_bits(a.max.x, b.max.x) && same_bits(a.max.y, b.max.y) && same_bits(a.max.z, b.max.z);
}

/// Empty when `w` is a valid tree over `tris` with leaves of at most `max_leaf`, else the first problem.
template <class WB>
std::string problems(const WB& w, std::span<const Trianglef> tris, std::uint32_t max_leaf) {
    std::size_t finite = 0;
    for (const auto& t : tris) finite += t.is_finite();
    if (w.primitive_count != tris.size() || w.excluded != tris.size() - finite) return "counts wrong";
    if (finite == 0) return w.empty() && w.prim_ids.empty() ? "" : "a tree over no finite triangle";
    if (w.prim_ids.size() != finite) return "prim_ids has " + std::to_string(w.prim_ids.size()) + " slots for " + std::to_string(finite);
    std::vector<int> seen(tris.size(), 0), slot_used(w.prim_ids.size(), 0);
    std::vector<std::uint32_t> level(w.nodes.size(), 0);
    std::vector<int> reached(w.nodes.size(), 0);
    reached[0] = 1;
    std::uint32_t deepest = 0;
    for (std::size_t i = 0; i < w.nodes.size(); ++i) {   // children always follow their parent
        if (reached[i] != 1) return "node " + std::to_string(i) + " reached " + std::to_string(reached[i]) + " times";
        deepest = std::max(deepest, level[i]);
        const auto& n = w.nodes[i];
        int used = 0;
        for (int k = 0; k < WB::width; ++k) {
            if (n.empty_slot(k)) continue;
            ++used;
            AABB<float> want;
            if (n.is_leaf(k)) {
                if (n.count[k] > max_leaf) return "a leaf of " + std::to_string(n.count[k]) + " references";
                for (std::size_t s = n.child[k]; s < std::size_t(n.child[k]) + n.count[k]; ++s) {
                    if (s >= w.prim_ids.size() || slot_used[s]++) return "prim_ids slot used twice or out of range";
                    const std::uint32_t p = w.prim_ids[s];
                    if (p >= tris.size() || !tris[p].is_finite() || seen[p]++) return "bad or repeated reference";
                    want.extend(tris[p].bounds());
                }
            } else {
                const std::size_t c = n.child[k];
                if (c <= i || c >= w.nodes.size()) return "child index out of order";
                ++reached[c];
                level[c] = level[i] + 1;
                want = w.nodes[c].bounds();
            }
            if (!same_box(n.bounds(k), want)) return "node " + std::to_string(i) + " slot " + std::to_string(k) + " box is not the union of its contents";
        }
        if (used == 0) return "a node with no slot";
    }
    if (deepest != w.depth) return "depth " + std::to_string(w.depth) + " recorded, " + std::to_string(deepest) + " measured";
    return {};
}

template <class WB>
void check_rays(const WB& w, std::span<const Trianglef> tris, std::uint64_t seed) {
    const test::RaySet set = test::adversarial_rays(tris, test::sanitizer_scaled(80), seed);
    const test::Reference ref = test::brute_force<trace::robust>(tris, set.rays);
    const test::Disagreements r = test::compare_with<trace::robust>(w, tris, set, ref);
    CHECK_MESSAGE(r.total == 0, r.total << " disagreements with brute force (" << test::by_kind(r) << "), first: " << r.first);
}

template <class WA, class WB>
bool same_tree(const WA& a, const WB& b) {
    return a.nodes.size() == b.nodes.size() && a.prim_ids.size() == b.prim_ids.size() && a.depth == b.depth &&
           (a.nodes.empty() || std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(a.nodes[0])) == 0) &&
           std::equal(a.prim_ids.begin(), a.prim_ids.end(), b.prim_ids.begin());
}

std::vector<std::pair<std::string, std::vector<Trianglef>>> scenes() {
    auto soup = test::random_soup(test::sanitizer_scaled(5000), 51, 0.02f);
    for (std::size_t i = 0; i + 7 < soup.size(); i += 37) soup[i + 7] = soup[i];   // exact ties
    soup[5].p1.x = std::numeric_limits<float>::quiet_NaN();
    soup[9].p2.z = std::numeric_limits<float>::infinity();
    const auto one = test::random_soup(1, 52);
    return {{"soup with ties and NaN/inf", soup},
            {"sphere", test::sphere(24, 48)},
            {"flat", test::flat_scene(600)},
            {"identical", test::identical(300)},   // equal keys everywhere: middle splits
            {"one", one},
            {"eight", test::random_soup(8, 53)},
            {"nine", test::random_soup(9, 54)},
            {"none finite", {{{std::numeric_limits<float>::quiet_NaN(), 0, 0}, {1, 0, 0}, {0, 1, 0}}}},
            {"empty", {}}};
}

} // namespace

TEST_CASE("morton_wide: valid trees, exact hits, the same tree on every executor (4/8 wide, 30/63 bits, leaf sizes)") {
    for (const auto& [name, tris] : scenes()) {
        CAPTURE(name);
        const std::span<const Trianglef> ts(tris);
        for (const int bits : {30, 63})
            for (const std::uint32_t leaf : {1u, 4u, 8u}) {
                CAPTURE(bits);
                CAPTURE(leaf);
                const morton_wide::Config cfg{.morton_bits = bits, .max_leaf_size = leaf};
                const auto w8 = morton_wide::build<8>(ts, cfg, exec::serial{});
                const auto w4 = morton_wide::build<4>(ts, cfg, exec::serial{});
                CHECK(problems(w8, ts, leaf) == "");
                CHECK(problems(w4, ts, leaf) == "");
                if (leaf == 8) {
                    check_rays(w8, ts, 61);
                    check_rays(w4, ts, 62);
                }
                test::for_each_executor([&](auto ex) {
                    CHECK(same_tree(morton_wide::build<8>(ts, cfg, ex), w8));
                    CHECK(same_tree(morton_wide::build<4>(ts, cfg, ex), w4));
                });
            }
    }
}

TEST_CASE("morton_wide: a large scene takes the parallel path; prim::copied; block leaves; refit in place") {
    const auto soup = test::random_soup(test::sanitizer_scaled(60000), 55, 0.01f);
    const std::span<const Trianglef> ts(soup);
    const auto ref = morton_wide::build<8>(ts, {}, exec::serial{});
    CHECK(problems(ref, ts, 8) == "");
    CHECK(ref.nodes.size() > 300);   // more than the 256 subtrees of the top
    test::for_each_executor([&](auto ex) { CHECK(same_tree(morton_wide::build<8>(ts, {}, ex), ref)); });
    const auto copied = morton_wide::build<8, Node<>, prim::copied>(ts);
    CHECK(same_tree(copied, ref));
    std::size_t wrong = 0;
    for (std::size_t s = 0; s < copied.prim_ids.size(); ++s) wrong += std::memcmp(&copied.leaf_triangles[s], &soup[copied.prim_ids[s]], sizeof(Trianglef)) != 0;
    CHECK(wrong == 0);
    check_rays(ref, ts, 63);
    const auto blocks = make_wide_blocks(ref, ts);
    check_rays(blocks, ts, 64);
    // refit after motion keeps every box the union of its contents and the hits exact
    auto moved = soup;
    test::Rng r(56);
    for (auto& t : moved)
        for (Vec3f* p : {&t.p0, &t.p1, &t.p2}) *p = *p + Vec3f{r.uniform(-0.05f, 0.05f), r.uniform(-0.05f, 0.05f), r.uniform(-0.05f, 0.05f)};
    auto tree = ref;
    refit(tree, std::span<const Trianglef>(moved));
    CHECK(problems(tree, std::span<const Trianglef>(moved), 8) == "");
    check_rays(tree, std::span<const Trianglef>(moved), 65);
}

TEST_CASE("morton_wide: build_blocks is make_wide_blocks of build, bit for bit, on every executor (4/8 wide, 4/8 lanes)") {
    for (const auto& [name, tris] : scenes()) {
        CAPTURE(name);
        const std::span<const Trianglef> ts(tris);
        for (const int bits : {30, 63})
            for (const std::uint32_t leaf : {1u, 5u, 8u}) {
                CAPTURE(bits);
                CAPTURE(leaf);
                const morton_wide::Config cfg{.morton_bits = bits, .max_leaf_size = leaf};
                const exec::serial s;
                const auto w8 = morton_wide::build<8>(ts, cfg, s);
                const auto w4 = morton_wide::build<4>(ts, cfg, s);
                const auto b88 = make_wide_blocks(w8, ts, s);
                const auto b84 = make_wide_blocks<4>(w8, ts, s);
                const auto b44 = make_wide_blocks(w4, ts, s);
                const auto b48 = make_wide_blocks<8>(w4, ts, s);
                test::for_each_executor([&](auto ex) {
                    CHECK(block_difference(morton_wide::build_blocks(ts, cfg, ex), b88) == "");
                    CHECK(block_difference(morton_wide::build_blocks<8, 4>(ts, cfg, ex), b84) == "");
                    CHECK(block_difference(morton_wide::build_blocks<4>(ts, cfg, ex), b44) == "");
                    CHECK(block_difference(morton_wide::build_blocks<4, 8>(ts, cfg, ex), b48) == "");
                });
                if (leaf == 8) {
                    check_rays(morton_wide::build_blocks(ts, cfg), ts, 66);
                    check_rays(morton_wide::build_blocks<4>(ts, cfg), ts, 67);
                }
            }
    }
    // the parallel path (more than 256 subtrees), with non-finite triangles spread through the input
    auto soup = test::random_soup(test::sanitizer_scaled(60000), 58, 0.01f);
    for (std::size_t i = 11; i < soup.size(); i += 997) soup[i].p0.y = std::numeric_limits<float>::quiet_NaN();
    const std::span<const Trianglef> ts(soup);
    const auto ref = make_wide_blocks(morton_wide::build<8>(ts, {}, exec::serial{}), ts, exec::serial{});
    REQUIRE(ref.nodes.size() > 300);
    CHECK(ref.excluded == (soup.size() - 11 + 996) / 997);
    test::for_each_executor([&](auto ex) { CHECK(block_difference(morton_wide::build_blocks(ts, {}, ex), ref) == ""); });
    check_rays(morton_wide::build_blocks(ts), ts, 68);
}

TEST_CASE("morton_wide: bad knobs throw std::invalid_argument naming the function and the value") {
    const auto soup = test::random_soup(100, 57);
    const std::span<const Trianglef> ts(soup);
    for (const morton_wide::Config bad : {morton_wide::Config{.morton_bits = 31}, morton_wide::Config{.max_leaf_size = 0},
                                          morton_wide::Config{.max_leaf_size = 256}}) {
        try {
            (void)morton_wide::build<8>(ts, bad);
            FAIL("no exception");
        } catch (const std::invalid_argument& e) {
            const std::string m = e.what();
            CHECK(m.find("dynbvh::morton_wide::build") != std::string::npos);
            CHECK((m.find("31") != std::string::npos || m.find("max_leaf_size") != std::string::npos));
        }
    }
}
