// Wide trees with SIMD triangle-block leaves (wide_blocks.hpp): for every builder, the 8-wide tree
// with 8-lane blocks, the 4-wide with 4-lane blocks and the 8-wide with 4-lane blocks hold exactly the
// wide tree's leaves (same nodes, each leaf's triangles in slot order with the user's indices), and
// trace exactly as it does: closest hit (t, u, v, prim) and any hit identical to the wide tree with
// index leaves, for trace::robust and trace::fast, and equal to brute force and to the binary
// traversal (exact ties aside) on adversarial rays over random soups (with duplicates and NaN/inf
// triangles), a closed sphere and a flat scene. Closed meshes traced through block trees from inside
// at every vertex and edge: no ray escapes.
#include <doctest/doctest.h>

#include <dynbvh/wide_blocks.hpp>

#include "robust_support.hpp"
#include "simple_builder.hpp"

#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

using namespace dynbvh;
using dynbvh::test::Rng;
using dynbvh::test::same_bits;

namespace {

bool identical(const Hitf& a, const Hitf& b) {
    return a.prim == b.prim && same_bits(a.t, b.t) && same_bits(a.u, b.u) && same_bits(a.v, b.v);
}

/// The block tree against the index-leaf wide tree of the same binary tree: same nodes but for leaf
/// children, each leaf's blocks holding the leaf's triangles in slot order. Empty when fine.
template <class B, class WB, class WI>
std::string block_problems(const B& bvh, const WB& wb, const WI& wi, std::span<const Trianglef> tris) {
    constexpr int L = WB::block_lanes;
    std::ostringstream err;
    std::size_t problems = 0;
    auto fail = [&](const std::string& m) {
        if (problems++ < 8) err << m << "\n";
    };
    if (wb.nodes.size() != wi.nodes.size() || wb.depth != wi.depth) fail("node count or depth differs from make_wide");
    if (wb.primitive_count != bvh.primitive_count || wb.excluded != bvh.excluded) fail("counts differ");
    if (!wb.prim_ids.empty() || !wb.leaf_triangles.empty()) fail("a block tree keeps prim_ids or leaf_triangles");
    if (problems) return err.str();
    std::size_t refs = 0, next_block = 0;
    for (std::size_t i = 0; i < wb.nodes.size(); ++i) {
        const auto& a = wb.nodes[i];
        const auto& b = wi.nodes[i];
        for (int k = 0; k < WB::width; ++k) {
            if (!same_bits(a.lo_x[k], b.lo_x[k]) || !same_bits(a.hi_x[k], b.hi_x[k]) || !same_bits(a.lo_y[k], b.lo_y[k]) ||
                !same_bits(a.hi_y[k], b.hi_y[k]) || !same_bits(a.lo_z[k], b.lo_z[k]) || !same_bits(a.hi_z[k], b.hi_z[k]) ||
                a.count[k] != b.count[k])
                fail("node " + std::to_string(i) + " slot " + std::to_string(k) + " differs");
            if (a.count[k] == 0) {
                if (a.child[k] != b.child[k]) fail("inner child differs");
                continue;
            }
            // leaves in node order, blocks contiguous
            if (a.child[k] != next_block) fail("leaf blocks not in node order at node " + std::to_string(i));
            next_block = a.child[k] + detail::blocks_for<L>(a.count[k]);
            if (next_block > wb.blocks.size()) {
                fail("blocks out of range");
                continue;
            }
            for (std::size_t s = 0; s < a.count[k]; ++s) {
                const auto& blk = wb.blocks[a.child[k] + s / L];
                const int lane = int(s % L);
                const std::size_t slot = b.child[k] + s;
                const Trianglef want = wi.triangle(tris, slot), got = blk.triangle(lane);
                if (std::memcmp(&want, &got, sizeof want) != 0 || blk.prim[lane] != wi.prim_ids[slot])
                    fail("leaf triangle differs at slot " + std::to_string(slot));
                ++refs;
            }
            const auto& last = wb.blocks[next_block - 1];
            if (last.count != (a.count[k] - 1) % L + 1) fail("last block's lane count wrong");
        }
    }
    if (next_block != wb.blocks.size()) fail("unused blocks");
    if (refs != wi.prim_ids.size()) fail("references lost or duplicated");
    return err.str();
}

struct Tally {
    std::size_t rays = 0, hits = 0, vs_wide = 0, vs_binary = 0, fast_vs_wide = 0;
    std::string first;
};

/// Robust and fast (when Fast) closest / any hit of the block tree == the index-leaf wide tree (all
/// bits), and == the binary tree (exact ties aside).
template <bool Fast = true, class B, class WB, class WI>
void compare_traversal(const B& bvh, const WB& wb, const WI& wi, std::span<const Trianglef> tris, std::span<const Rayf> rays, Tally& t) {
    for (const Rayf& r : rays) {
        ++t.rays;
        const Hitf h = intersect(wb, tris, r), w = intersect(wi, tris, r), b = intersect(bvh, tris, r);
        t.hits += h ? 1 : 0;
        if (!identical(h, w) || occluded(wb, tris, r) != occluded(wi, tris, r)) {
            if (t.vs_wide++ == 0) t.first = "robust vs wide: " + test::describe(r, h, w);
        }
        if (!test::same_hit<tri::watertight>(h, b, tris, r)) {
            if (t.vs_binary++ == 0 && t.first.empty()) t.first = "robust vs binary: " + test::describe(r, h, b);
        }
        if constexpr (Fast) {
            const Hitf hf = intersect<trace::fast>(wb, tris, r), wf = intersect<trace::fast>(wi, tris, r);
            if (!identical(hf, wf) || occluded<trace::fast>(wb, tris, r) != occluded<trace::fast>(wi, tris, r)) {
                if (t.fast_vs_wide++ == 0 && t.first.empty()) t.first = "fast vs wide: " + test::describe(r, hf, wf);
            }
        }
    }
}

/// Every builder, three block layouts, on one scene.
void check_scene(const std::string& name, std::span<const Trianglef> tris, std::size_t per_kind, std::uint64_t seed) {
    CAPTURE(name);
    const test::RaySet set = test::adversarial_rays(tris, test::sanitizer_scaled(per_kind), seed);
    const test::Reference ref = test::brute_force<trace::robust>(tris, set.rays);
    std::ostringstream line;
    line << name << " (" << tris.size() << " triangles, " << set.rays.size() << " rays):";
    test::for_each_builder(tris, exec::serial{}, [&](std::size_t bi, const auto& bvh, bool) {
        const std::string builder = test::builder_names[bi];
        CAPTURE(builder);
        // One declaration each: the types differ (clang rejects a shared `auto`).
        const auto w8 = make_wide<8>(bvh);
        const auto w4 = make_wide<4>(bvh);
        const auto b88 = make_wide_blocks<8, 8>(bvh, tris);
        const auto b44 = make_wide_blocks<4, 4>(bvh, tris);
        const auto b84 = make_wide_blocks<8, 4>(bvh, tris);
        CHECK(block_problems(bvh, b88, w8, tris) == "");
        CHECK(block_problems(bvh, b44, w4, tris) == "");
        CHECK(block_problems(bvh, b84, w8, tris) == "");
        // brute force, by ray kind (robust bundle)
        auto vs_brute_force = [&](const auto& tree) {
            const test::Disagreements r = test::compare_with<trace::robust>(tree, tris, set, ref);
            CHECK_MESSAGE(r.total == 0, r.total << " disagreements with brute force (" << test::by_kind(r) << "), first: " << r.first);
        };
        vs_brute_force(b88);
        vs_brute_force(b44);
        vs_brute_force(b84);
        Tally t;
        compare_traversal(bvh, b88, w8, tris, set.rays, t);
        // (sanitized builds: the fast policy on the 8/8 blocks only; its 4-lane block test is the same code)
        compare_traversal<!test::sanitized_build>(bvh, b44, w4, tris, set.rays, t);
        compare_traversal<!test::sanitized_build>(bvh, b84, w8, tris, set.rays, t);
        CHECK_MESSAGE(t.vs_wide == 0, t.first);
        CHECK_MESSAGE(t.vs_binary == 0, t.first);
        CHECK_MESSAGE(t.fast_vs_wide == 0, t.first);
        line << "\n    " << builder << ": " << b88.blocks.size() << " 8-lane / " << b44.blocks.size() << " 4-lane blocks, "
             << t.hits << " of " << t.rays << " traced rays hit; differences: vs wide " << t.vs_wide << ", vs binary "
             << t.vs_binary << ", fast vs wide " << t.fast_vs_wide;
    });
    MESSAGE(line.str());
}

} // namespace

TEST_CASE("block trees: empty, one triangle, short spans, rays that cannot be traced") {
    const std::vector<Trianglef> none;
    const auto e = make_wide_blocks<8>(Bvh<>{}, none);
    CHECK(e.empty());
    CHECK(e.blocks.empty());
    CHECK_FALSE(intersect(e, none, Rayf{{0, 0, 0}, {0, 0, 1}}));
    CHECK_FALSE(occluded(e, none, Rayf{{0, 0, 0}, {0, 0, 1}}));

    const std::vector<Trianglef> one = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const auto b1 = lbvh::build(std::span<const Trianglef>(one));
    const auto w1 = make_wide_blocks<4>(b1, one);
    REQUIRE(w1.nodes.size() == 1);
    REQUIRE(w1.blocks.size() == 1);
    CHECK(w1.blocks[0].count == 1);
    const Hitf h = intersect(w1, one, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}});
    REQUIRE(h);
    CHECK(h.prim == 0);
    CHECK(h.t == 1.0f);
    CHECK(h.u == 0.25f);
    CHECK(h.v == 0.25f);
    CHECK_FALSE(intersect(w1, one, Rayf{{0.75f, 0.75f, 1}, {0, 0, -1}}));
    CHECK(intersect<trace::fast>(w1, one, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}}).prim == 0);
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    for (const Rayf& r : {Rayf{{nan, 0.25f, 1}, {0, 0, -1}}, Rayf{{0.25f, 0.25f, inf}, {0, 0, -1}}, Rayf{{0.25f, 0.25f, 1}, {0, 0, 0}},
                          Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}, 0, nan}, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}, 2, 1}}) {
        CHECK_FALSE(intersect(w1, one, r));
        CHECK_FALSE(occluded(w1, one, r));
        CHECK_FALSE(intersect<trace::fast>(w1, one, r));
        CHECK_FALSE(occluded<trace::fast>(w1, one, r));
    }
    // The span is checked as for every tree (blocks hold the vertices, but a call site must not pass
    // the wrong scene unnoticed).
    CHECK_THROWS_AS(intersect(w1, std::span<const Trianglef>(), Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}}), std::invalid_argument);
    CHECK_THROWS_AS(make_wide_blocks<8>(b1, std::span<const Trianglef>()), std::invalid_argument);
    // A prim::copied binary tree converts from its own leaf triangles (any span).
    const auto bp = lbvh::build<Node<>, prim::copied>(std::span<const Trianglef>(one));
    CHECK(make_wide_blocks<8>(bp, std::span<const Trianglef>()).blocks.size() == 1);
}

TEST_CASE("block trees: the same blocks on every executor") {
    const auto tris = test::random_soup(30000, 21, 0.01f);
    const std::span<const Trianglef> ts(tris);
    const auto bvh = ploc::build(ts);
    const auto ref = make_wide_blocks<8>(bvh, ts, exec::serial{});
    CHECK(block_problems(bvh, ref, make_wide<8>(bvh), ts) == "");
    CHECK(sah_cost(ref, {.ct = 3, .ci = 2}) == sah_cost(make_wide<8>(bvh), {.ct = 3, .ci = 2}));
    test::for_each_executor([&](auto ex) {
        const auto w = make_wide_blocks<8>(bvh, ts, ex);
        REQUIRE(w.nodes.size() == ref.nodes.size());
        CHECK(std::memcmp(w.nodes.data(), ref.nodes.data(), w.nodes.size() * sizeof(w.nodes[0])) == 0);
        REQUIRE(w.blocks.size() == ref.blocks.size());
        std::size_t diff = 0;
        for (std::size_t i = 0; i < w.blocks.size(); ++i)
            diff += std::memcmp(w.blocks[i].v, ref.blocks[i].v, sizeof w.blocks[i].v) == 0 &&
                            std::memcmp(w.blocks[i].prim, ref.blocks[i].prim, sizeof w.blocks[i].prim) == 0 &&
                            w.blocks[i].count == ref.blocks[i].count
                        ? 0
                        : 1;
        CHECK(diff == 0);
    });
}

TEST_CASE("block trees of every builder: == wide tree bit for bit, == brute force, == binary (soups)") {
    auto soup = test::random_soup(500, 5, 0.08f);
    for (std::size_t i = 0; i + 5 < soup.size(); i += 29) soup[i + 5] = soup[i];   // exact ties
    soup[7].p1.x = std::numeric_limits<float>::quiet_NaN();
    soup[11].p2.z = std::numeric_limits<float>::infinity();
    check_scene("soup with ties and NaN/inf", soup, 250, 31);
}

TEST_CASE("block trees of binary trees built with block_leaves: == brute force, == wide tree") {
    const auto soup = test::random_soup(3000, 9, 0.03f);
    const std::span<const Trianglef> ts(soup);
    const test::RaySet set = test::adversarial_rays(ts, test::sanitizer_scaled(150), 34);
    const test::Reference ref = test::brute_force<trace::robust>(ts, set.rays);
    const auto bvh = ploc::build(ts, {.radius = 5, .leaves = block_leaves});
    std::size_t refs = 0, leaves = 0;
    for (const auto& n : bvh.nodes)
        if (n.is_leaf()) {
            ++leaves;
            refs += n.count;
        }
    MESSAGE("block_leaves: " << double(refs) / double(leaves) << " references per leaf");
    CHECK(double(refs) / double(leaves) > 3.0);   // fuller leaves than the default collapse
    const auto b8 = make_wide_blocks<8>(bvh, ts);
    const auto b4 = make_wide_blocks<8, 4>(bvh, ts);
    const auto w8 = make_wide<8>(bvh);
    CHECK(block_problems(bvh, b8, w8, ts) == "");
    CHECK(block_problems(bvh, b4, w8, ts) == "");
    const test::Disagreements r = test::compare_with<trace::robust>(b8, ts, set, ref);
    CHECK_MESSAGE(r.total == 0, r.total << " disagreements with brute force (" << test::by_kind(r) << "), first: " << r.first);
    Tally t;
    compare_traversal(bvh, b8, w8, ts, set.rays, t);
    compare_traversal(bvh, b4, w8, ts, set.rays, t);
    CHECK_MESSAGE(t.vs_wide + t.vs_binary + t.fast_vs_wide == 0, t.first);
}

TEST_CASE("block trees of every builder: closed sphere and flat scene") {
    check_scene("sphere", test::sphere(24, 48), 200, 32);
    check_scene("flat", test::flat_scene(400), 200, 33);
}

TEST_CASE("watertightness through block trees: rays from inside closed meshes at every vertex and edge") {
    for (const test::ClosedMesh& c : {test::closed_sphere(20, 40), test::closed_cube(6), test::closed_torus(24, 12)}) {
        const auto tris = c.mesh.triangles();
        const std::span<const Trianglef> ts(tris);
        std::size_t rays = 0, escaped = 0;
        const std::vector<Rayf> probes = test::inside_rays(c, test::sanitized() ? 2 : 6);
        test::for_each_builder(ts, exec::serial{}, [&](std::size_t, const auto& bvh, bool) {
            const auto b8 = make_wide_blocks<8>(bvh, ts);
            const auto b4 = make_wide_blocks<4>(bvh, ts);
            for (const Rayf& r : probes) {
                rays += 2;
                escaped += intersect(b8, ts, r) ? 0 : 1;
                escaped += occluded(b4, ts, r) ? 0 : 1;
            }
        });
        MESSAGE(c.name << ": " << rays << " rays from inside at vertices and edge midpoints, " << escaped << " escaped");
        CHECK(rays > 0);
        CHECK(escaped == 0);
    }
}

TEST_CASE("block trees deeper than max_depth: heap stack, same answers") {
    const int levels = 600;
    const std::vector<Trianglef> tris = test::stacked_triangles(levels);
    const std::span<const Trianglef> ts(tris);
    const auto deep = test::caterpillar_build<Node<>, prim::indexed>(ts);
    const auto w = make_wide_blocks<8>(deep, ts);
    CHECK(w.depth >= max_depth);
    const Rayf down{{0.1f, 0.1f, 1000}, {0, 0, -1}}, up{{0.1f, 0.1f, -1000}, {0, 0, 1}};
    const Hitf a = intersect(w, ts, down), b = intersect(w, ts, up);
    REQUIRE(a);
    REQUIRE(b);
    CHECK(a.prim == std::uint32_t(levels - 1));
    CHECK(a.t == 1000.0f - float(levels - 1));
    CHECK(b.prim == 0);
    CHECK(b.t == 1000.0f);
    CHECK(occluded(w, ts, down));
    CHECK(intersect<trace::fast>(w, ts, down).prim == std::uint32_t(levels - 1));
}

namespace {

/// Empty when the two block trees are the same bit for bit (nodes, blocks' vertices, indices, counts).
template <class WB>
std::string block_tree_difference(const WB& a, const WB& b) {
    if (a.nodes.size() != b.nodes.size() || a.blocks.size() != b.blocks.size() || a.depth != b.depth ||
        a.primitive_count != b.primitive_count || a.excluded != b.excluded)
        return "sizes or counts differ";
    if (!a.nodes.empty() && std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(a.nodes[0])) != 0) return "nodes differ";
    for (std::size_t i = 0; i < a.blocks.size(); ++i)
        if (std::memcmp(a.blocks[i].v, b.blocks[i].v, sizeof a.blocks[i].v) != 0 ||
            std::memcmp(a.blocks[i].prim, b.blocks[i].prim, sizeof a.blocks[i].prim) != 0 || a.blocks[i].count != b.blocks[i].count)
            return "block " + std::to_string(i) + " differs";
    return {};
}

/// Moves every vertex by up to `amount` (soups: each triangle on its own).
std::vector<Trianglef> jiggled(std::vector<Trianglef> tris, float amount, std::uint64_t seed) {
    Rng r(seed);
    for (auto& t : tris)
        for (Vec3f* p : {&t.p0, &t.p1, &t.p2}) *p = *p + Vec3f{r.uniform(-amount, amount), r.uniform(-amount, amount), r.uniform(-amount, amount)};
    return tris;
}

} // namespace

TEST_CASE("block trees packed from a builder's direct wide tree == packed from its binary tree, every builder") {
    auto soup = test::random_soup(test::sanitizer_scaled(4000), 41, 0.03f);
    soup[3].p0.y = std::numeric_limits<float>::quiet_NaN();
    const std::span<const Trianglef> ts(soup);
    test::for_each_executor([&](auto ex) {
        const ploc::Config pc{.radius = 5, .leaves = block_leaves};
        CHECK(block_tree_difference(make_wide_blocks(ploc::build_wide<8>(ts, pc, ex), ts, ex), make_wide_blocks<8>(ploc::build(ts, pc, ex), ts, ex)) == "");
        CHECK(block_tree_difference(make_wide_blocks(lbvh::build_wide<4>(ts, {}, ex), ts, ex), make_wide_blocks<4>(lbvh::build(ts, {}, ex), ts, ex)) == "");
        CHECK(block_tree_difference(make_wide_blocks<4>(binned_sah::build_wide<8>(ts, {}, ex), ts, ex),
                                    make_wide_blocks<8, 4>(binned_sah::build(ts, {}, ex), ts, ex)) == "");
        const kbvh::Config<> kc{.split = {.beta = 0.3f}};
        CHECK(block_tree_difference(make_wide_blocks(kbvh::build_wide<8>(ts, kc, ex), ts, ex), make_wide_blocks<8>(kbvh::build(ts, kc, ex), ts, ex)) == "");
        // prim::copied wide trees pack from their own leaf triangles
        const auto copied = lbvh::build_wide<8, Node<>, prim::copied>(ts, {}, ex);
        CHECK(block_tree_difference(make_wide_blocks(copied, std::span<const Trianglef>(), ex), make_wide_blocks<8>(lbvh::build(ts, {}, ex), ts, ex)) == "");
    });
    CHECK_THROWS_AS(make_wide_blocks(lbvh::build_wide<8>(ts), ts.first(10)), std::invalid_argument);
}

TEST_CASE("refit of a block tree in place == packing the refitted wide tree; exact hits; wrong spans throw") {
    const auto soup = test::random_soup(test::sanitizer_scaled(3000), 43, 0.03f);
    const std::span<const Trianglef> ts(soup);
    test::for_each_executor([&](auto ex) {
        for (const float amount : {0.01f, 0.3f}) {
            CAPTURE(amount);
            auto wide = kbvh::build_wide<8>(ts, {.split = {.beta = 0.3f}}, ex);   // fragments: triangles in several leaves
            auto blk = make_wide_blocks(wide, ts, ex);
            auto blk4 = make_wide_blocks<4>(wide, ts, ex);
            const auto now = jiggled(soup, amount, 44);
            const std::span<const Trianglef> tn(now);
            refit(wide, tn, ex);
            refit(blk, tn, ex);
            refit(blk4, tn, ex);
            CHECK(block_tree_difference(blk, make_wide_blocks(wide, tn, ex)) == "");
            CHECK(block_tree_difference(blk4, make_wide_blocks<4>(wide, tn, ex)) == "");
            const test::RaySet set = test::adversarial_rays(tn, test::sanitizer_scaled(60), 45);
            const test::Reference ref = test::brute_force<trace::robust>(tn, set.rays);
            const test::Disagreements r = test::compare_with<trace::robust>(blk, tn, set, ref);
            CHECK_MESSAGE(r.total == 0, r.total << " disagreements with brute force (" << test::by_kind(r) << "), first: " << r.first);
        }
    });
    auto blk = make_wide_blocks(lbvh::build_wide<8>(ts), ts);
    const auto before = blk;
    for (const auto bad : {ts.first(ts.size() - 1), ts.first(0)}) {
        try {
            refit(blk, bad);
            FAIL("no exception for " << bad.size() << " triangles");
        } catch (const std::invalid_argument& e) {
            CHECK(std::string(e.what()).find("dynbvh::refit") == 0);
        }
        CHECK(block_tree_difference(blk, before) == "");
    }
}
