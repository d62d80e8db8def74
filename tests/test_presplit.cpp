// Presplitting (presplit.hpp) and KBVH (kbvh.hpp): fragments cover their triangle and stay inside it,
// boxes are tight, the whole budget is handed out, degenerate input is safe, every executor gives the
// same fragments, and presplitting lowers SAH on long thin triangles.
#include <doctest/doctest.h>

#include <dynbvh/kbvh.hpp>
#include <dynbvh/presplit.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/validate.hpp>
#include <dynbvh/wide_blocks.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "robust_support.hpp"
#include "support.hpp"

using namespace dynbvh;

namespace {

using Tri = Triangle<float>;

/// Long thin triangles along the (1, 1, 1) diagonal at random places: the worst case for plain boxes.
std::vector<Tri> diagonal_slivers(std::size_t n, std::uint32_t seed, float length = 0.5f, float width = 0.004f) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<Tri> tris(n);
    for (auto& t : tris) {
        const Vec3f o{u(rng), u(rng), u(rng)};
        const float len = length * (0.5f + u(rng));
        const Vec3f d = normalize(Vec3f{1.0f + 0.2f * u(rng), 1.0f - 0.2f * u(rng), 1.0f + 0.1f * u(rng)}) * len;
        const Vec3f side = Vec3f{width * u(rng), -width, width * u(rng)};
        t = {o, o + d, o + d * 0.5f + side};
    }
    return tris;
}

std::size_t expected_fragments(std::size_t m, float beta) {
    return m + static_cast<std::size_t>(std::floor(static_cast<double>(beta) * static_cast<double>(m)));
}

/// Checks every invariant of a split result against its input; returns fragments per reference.
/// Output order: each input reference's fragments are contiguous, in input order.
std::vector<std::size_t> check_fragments(const References<float>& in, const References<float>& out,
                                         std::span<const Tri> tris, std::uint32_t seed = 7) {
    REQUIRE(out.box.size() == out.prim.size());
    CHECK(out.primitive_count == in.primitive_count);
    CHECK(out.excluded == in.excluded);
    std::vector<std::size_t> per_ref(in.size(), 0);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    const Vec3f ext = in.bounds.diagonal();
    const float eps = 1e-6f * std::max(ext.x, std::max(ext.y, ext.z)) + 1e-30f;
    std::size_t f = 0, empty = 0, outside = 0, uncovered = 0, missed = 0;
    AABB<float> all, centres;
    for (std::size_t i = 0; i < in.size(); ++i) {
        const Tri& tri = tris[in.prim[i]];
        const AABB<float> tb = in.box[i];
        AABB<float> uni;
        const std::size_t first = f;
        while (f < out.size() && out.prim[f] == in.prim[i]) {   // callers use distinct triangles
            const AABB<float>& b = out.box[f];
            empty += b.is_empty() ? 1 : 0;
            outside += tb.contains(b) ? 0 : 1;
            uni.extend(b);
            all.extend(b);
            centres.extend(b.center());
            ++f;
        }
        per_ref[i] = f - first;
        REQUIRE_MESSAGE(per_ref[i] >= 1, "reference ", i, " has no fragment");
        uncovered += uni == tb ? 0 : 1;
        if (per_ref[i] > 1) {
            // Every point of the triangle lies in some fragment box (within rounding of the clip).
            for (int s = 0; s < 64; ++s) {
                float a = u(rng), b = u(rng);
                if (a + b > 1.0f) { a = 1.0f - a; b = 1.0f - b; }
                const Vec3f p = tri.p0 + (tri.p1 - tri.p0) * a + (tri.p2 - tri.p0) * b;
                bool inside = false;
                for (std::size_t k = first; k < f && !inside; ++k) {
                    AABB<float> g = out.box[k];
                    g.min -= Vec3f{eps, eps, eps};
                    g.max += Vec3f{eps, eps, eps};
                    inside = g.contains(p);
                }
                missed += inside ? 0 : 1;
            }
        }
    }
    CHECK_MESSAGE(empty == 0, empty, " empty fragment boxes");
    CHECK_MESSAGE(outside == 0, outside, " fragment boxes stick out of their triangle's box");
    CHECK_MESSAGE(uncovered == 0, uncovered, " triangles whose fragment boxes do not add up to the triangle's box");
    CHECK_MESSAGE(missed == 0, missed, " sampled triangle points lie in none of their triangle's fragments");
    CHECK(f == out.size());
    CHECK(out.bounds == all);
    CHECK(out.centroid_bounds == centres);
    return per_ref;
}

template <class Exec>
References<float> split_with(const std::vector<Tri>& tris, float beta, const Exec& ex) {
    const auto refs = make_references(std::span<const Tri>(tris), ex);
    return presplit::split(refs, std::span<const Tri>(tris), {.beta = beta}, ex);
}

} // namespace

TEST_CASE("presplit: one right triangle, hand-computed tight fragments") {
    // Scene bounds [0,4]^2 x {0}: the most important plane is x = 2 (x beats y at equal level),
    // then inside [0,2]x[0,4] it is y = 2 (the finer x = 1 ranks below).
    const std::vector<Tri> tris{{{0, 0, 0}, {4, 0, 0}, {0, 4, 0}}};
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});

    const auto one = presplit::split(refs, std::span<const Tri>(tris), {.beta = 1.0f}, exec::serial{});
    REQUIRE(one.size() == 2);
    CHECK(one.box[0] == AABB<float>{{0, 0, 0}, {2, 4, 0}});
    CHECK(one.box[1] == AABB<float>{{2, 0, 0}, {4, 2, 0}});

    // Two splits: the left half (longest axis 4) gets the second one, (1 * 4 / 6 + 1/2) -> 1.
    const auto two = presplit::split(refs, std::span<const Tri>(tris), {.beta = 2.0f}, exec::serial{});
    REQUIRE(two.size() == 3);
    CHECK(two.box[0] == AABB<float>{{0, 0, 0}, {2, 2, 0}});
    CHECK(two.box[1] == AABB<float>{{0, 2, 0}, {2, 4, 0}});
    CHECK(two.box[2] == AABB<float>{{2, 0, 0}, {4, 2, 0}});
    for (auto p : two.prim) CHECK(p == 0);
    check_fragments(refs, two, tris);
}

TEST_CASE("presplit: the whole budget is handed out on long thin diagonal triangles") {
    const auto tris = diagonal_slivers(3001, 11);
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});
    for (float beta : {0.01f, 0.05f, 0.3f, 1.0f, 2.5f}) {
        CAPTURE(beta);
        const auto out = presplit::split(refs, std::span<const Tri>(tris), {.beta = beta}, exec::serial{});
        CHECK(out.size() == expected_fragments(tris.size(), beta));
        CHECK(presplit::budget(tris.size(), {.beta = beta}) == out.size() - tris.size());
        check_fragments(refs, out, tris);
    }
}

TEST_CASE("presplit: beta = 0 or a tiny scene gives no fragments") {
    const auto tris = diagonal_slivers(500, 3);
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});
    const auto out = presplit::split(refs, std::span<const Tri>(tris), {.beta = 0.0f}, exec::serial{});
    CHECK(out.box == refs.box);
    CHECK(out.prim == refs.prim);
    // floor(0.05 * 19) = 0
    const std::vector<Tri> few(tris.begin(), tris.begin() + 19);
    const auto r19 = make_references(std::span<const Tri>(few), exec::serial{});
    CHECK(presplit::split(r19, std::span<const Tri>(few), {}, exec::serial{}).size() == 19);
    // empty input
    const std::vector<Tri> none;
    const auto r0 = make_references(std::span<const Tri>(none), exec::serial{});
    CHECK(presplit::split(r0, std::span<const Tri>(none), {.beta = 1.0f}, exec::serial{}).size() == 0);
}

TEST_CASE("presplit: bad beta is refused with a clear error") {
    const auto tris = diagonal_slivers(100, 5);
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});
    CHECK_THROWS_AS(presplit::split(refs, std::span<const Tri>(tris), {.beta = -0.1f}, exec::serial{}), std::invalid_argument);
    CHECK_THROWS_AS(presplit::split(refs, std::span<const Tri>(tris), {.beta = std::numeric_limits<float>::quiet_NaN()},
                                    exec::serial{}),
                    std::invalid_argument);
    CHECK_THROWS_AS(presplit::split(refs, std::span<const Tri>(tris), {.beta = std::numeric_limits<float>::infinity()},
                                    exec::serial{}),
                    std::invalid_argument);
}

TEST_CASE("presplit: the budget goes to the triangles that fit their boxes worst") {
    // 1000 small triangles and one huge diagonal one: nearly all 50 splits go to the big one.
    auto tris = test::mt_soup(1000, 21, 0.001f);
    tris.push_back({{0, 0, 0}, {1, 1, 1}, {0.5f, 0.5f, 0.52f}});
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});
    const auto out = presplit::split(refs, std::span<const Tri>(tris), {.beta = 0.05f}, exec::serial{});
    REQUIRE(out.size() == 1001 + 50);
    const auto per_ref = check_fragments(refs, out, tris);
    CHECK(per_ref.back() > 25);
    // Its fragments together are far smaller than its box.
    double sum = 0;
    for (std::size_t i = 0; i < out.size(); ++i)
        if (out.prim[i] == 1000) sum += out.box[i].area();
    CHECK(sum < 0.25 * refs.box.back().area());
}

TEST_CASE("presplit: degenerate and axis-aligned triangles") {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<Tri> tris;
    for (int i = 0; i < 400; ++i) {
        const Vec3f a{u(rng), u(rng), u(rng)}, b{u(rng), u(rng), u(rng)};
        switch (i % 5) {
        case 0: tris.push_back({a, b, a + (b - a) * 0.25f}); break;                 // collinear: a segment
        case 1: tris.push_back({a, a, a}); break;                                    // a point
        case 2: tris.push_back({a, b, b}); break;                                    // repeated vertex
        case 3: tris.push_back({{a.x, a.y, 0.5f}, {b.x, a.y, 0.5f}, {a.x, b.y, 0.5f}}); break;  // axis-aligned (z)
        default: tris.push_back({{a.x, 0.25f, a.z}, {b.x, 0.25f, a.z}, {a.x, 0.25f, a.x}}); break;  // in y = 0.25
        }
    }
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});
    for (float beta : {0.05f, 0.5f, 4.0f}) {
        CAPTURE(beta);
        const auto out = presplit::split(refs, std::span<const Tri>(tris), {.beta = beta}, exec::serial{});
        CHECK(out.size() == expected_fragments(tris.size(), beta));
        const auto per_ref = check_fragments(refs, out, tris);
        for (std::size_t i = 1; i < tris.size(); i += 5) CHECK(per_ref[i] == 1);   // points are never split
    }

    // Only points and segments along one axis: nothing can be split, no fragments appear.
    std::vector<Tri> flat;
    for (int i = 0; i < 200; ++i) {
        const Vec3f a{u(rng), u(rng), u(rng)};
        flat.push_back(i % 2 ? Tri{a, a, a} : Tri{a, a + Vec3f{0.3f, 0, 0}, a + Vec3f{0.1f, 0, 0}});
    }
    const auto fr = make_references(std::span<const Tri>(flat), exec::serial{});
    CHECK(presplit::split(fr, std::span<const Tri>(flat), {.beta = 0.5f}, exec::serial{}).size() == flat.size());

    // A flat scene (all z = 0) of big triangles: still splits, boxes stay flat.
    auto plane = diagonal_slivers(300, 8);
    for (auto& t : plane) t.p0.z = t.p1.z = t.p2.z = 0.0f;
    const auto pr = make_references(std::span<const Tri>(plane), exec::serial{});
    const auto po = presplit::split(pr, std::span<const Tri>(plane), {.beta = 0.5f}, exec::serial{});
    CHECK(po.size() == expected_fragments(plane.size(), 0.5f));
    check_fragments(pr, po, plane);
    CHECK(std::all_of(po.box.begin(), po.box.end(), [](const AABB<float>& b) { return b.min.z == 0.0f && b.max.z == 0.0f; }));
}

TEST_CASE("presplit: non-finite triangles stay excluded, counts are carried over") {
    auto tris = diagonal_slivers(400, 9);
    tris[3].p1.x = std::numeric_limits<float>::quiet_NaN();
    tris[77].p2.z = std::numeric_limits<float>::infinity();
    const auto refs = make_references(std::span<const Tri>(tris), exec::serial{});
    REQUIRE(refs.size() == 398);
    const auto out = presplit::split(refs, std::span<const Tri>(tris), {.beta = 0.25f}, exec::serial{});
    CHECK(out.size() == expected_fragments(398, 0.25f));
    CHECK(out.excluded == 2);
    CHECK(out.primitive_count == 400);
    CHECK(std::none_of(out.prim.begin(), out.prim.end(), [](std::uint32_t p) { return p == 3 || p == 77; }));
    check_fragments(refs, out, tris);
}

TEST_CASE("presplit: references already cut to part of their triangle are split inside that part") {
    const std::vector<Tri> tris{{{0, 0, 0}, {4, 0, 0}, {0, 4, 0}}};
    References<float> refs;
    refs.box = {AABB<float>{{0, 0, 0}, {2, 4, 0}}, AABB<float>{{2, 0, 0}, {4, 2, 0}}};
    refs.prim = {0, 0};
    refs.primitive_count = 1;
    update_reference_bounds(refs, exec::serial{});
    const auto out = presplit::split(refs, std::span<const Tri>(tris), {.beta = 1.0f}, exec::serial{});
    REQUIRE(out.size() == 4);
    for (std::size_t i = 0; i < 2; ++i) CHECK(refs.box[0].contains(out.box[i]));
    for (std::size_t i = 2; i < 4; ++i) CHECK(refs.box[1].contains(out.box[i]));
    CHECK(merge(out.box[0], out.box[1]) == refs.box[0]);
    CHECK(merge(out.box[2], out.box[3]) == refs.box[1]);
}

TEST_CASE("presplit: every executor produces identical fragments") {
    // Large enough for the parallel paths (blocked scan from 2^14 elements, loops from 1024).
    auto tris = diagonal_slivers(14000, 17);
    const auto more = test::mt_soup(6000, 18, 0.05f);
    tris.insert(tris.end(), more.begin(), more.end());
    const auto ref = split_with(tris, 0.05f, exec::serial{});
    CHECK(ref.size() == expected_fragments(tris.size(), 0.05f));
#if defined(_OPENMP)
    for (int threads : {1, 2, 3}) {
        CAPTURE(threads);
        const auto o = split_with(tris, 0.05f, exec::omp{threads});
        CHECK(o.box == ref.box);
        CHECK(o.prim == ref.prim);
        CHECK(o.bounds == ref.bounds);
        CHECK(o.centroid_bounds == ref.centroid_bounds);
    }
#endif
#if defined(DYNBVH_WITH_TBB)
    for (int threads : {0, 2}) {
        CAPTURE(threads);
        const auto t = split_with(tris, 0.05f, exec::tbb{threads});
        CHECK(t.box == ref.box);
        CHECK(t.prim == ref.prim);
    }
#endif
}

namespace {
template <class Builder>
double kbvh_sah(const std::vector<Tri>& tris, float beta) {
    const kbvh::Config<Builder> cfg{.split = {.beta = beta}};
    const auto bvh = kbvh::build(std::span<const Tri>(tris), cfg, exec::serial{});
    const auto rep = validate(bvh, std::span<const Tri>(tris), {.expect_single_reference = beta == 0.0f});
    CHECK_MESSAGE(rep.ok(), rep.summary());
    return sah_cost(bvh, {.ct = 3, .ci = 2});
}
} // namespace

TEST_CASE("kbvh: valid trees with every builder and executor, one-line use") {
    const auto tris = diagonal_slivers(4000, 31);
    const auto check = [&](const auto& bvh) {
        const auto rep = validate(bvh, std::span<const Tri>(tris), {.expect_single_reference = false});
        CHECK_MESSAGE(rep.ok(), rep.summary());
        CHECK(bvh.primitive_count == tris.size());
    };
    check(kbvh::build(tris, {.split = {.beta = 0.05f}}, exec::serial{}));
    check(kbvh::build<Node<>, prim::copied, kbvh::with_lbvh>(tris, {.split = {.beta = 0.2f}}, exec::serial{}));
    check(kbvh::build(tris, kbvh::Config<kbvh::with_binned_sah>{.split = {.beta = 0.1f}}, exec::serial{}));
#if defined(_OPENMP)
    check(kbvh::build(tris, {.split = {.beta = 0.05f}}, exec::omp{2}));
#endif
#if defined(DYNBVH_WITH_TBB)
    check(kbvh::build(tris, kbvh::Config<kbvh::with_lbvh>{}, exec::tbb{2}));
#endif
    // Edge cases: nothing, one and two triangles, all identical.
    const std::vector<Tri> none, one(tris.begin(), tris.begin() + 1), two(tris.begin(), tris.begin() + 2),
        same(1000, tris[0]);
    CHECK(kbvh::build(none, {.split = {.beta = 1.0f}}, exec::serial{}).empty());
    for (const auto* s : {&one, &two, &same}) {
        const auto bvh = kbvh::build(*s, {.split = {.beta = 1.0f}}, exec::serial{});
        const auto rep = validate(bvh, std::span<const Tri>(*s), {.expect_single_reference = false});
        CHECK_MESSAGE(rep.ok(), rep.summary());
    }
}

TEST_CASE("kbvh: presplitting lowers SAH on long thin diagonal triangles") {
    const auto tris = diagonal_slivers(20000, 41);
    const double ploc0 = kbvh_sah<kbvh::with_ploc>(tris, 0.0f), ploc5 = kbvh_sah<kbvh::with_ploc>(tris, 0.05f),
                 ploc30 = kbvh_sah<kbvh::with_ploc>(tris, 0.3f);
    const double lbvh0 = kbvh_sah<kbvh::with_lbvh>(tris, 0.0f), lbvh5 = kbvh_sah<kbvh::with_lbvh>(tris, 0.05f),
                 lbvh30 = kbvh_sah<kbvh::with_lbvh>(tris, 0.3f);
    MESSAGE("SAH ploc beta 0/0.05/0.3: ", ploc0, " ", ploc5, " ", ploc30, "; lbvh: ", lbvh0, " ", lbvh5, " ", lbvh30);
    CHECK(ploc5 < ploc0);
    CHECK(ploc30 < ploc5);
    CHECK(lbvh5 < lbvh0);
    CHECK(lbvh30 < lbvh5);
    // beta = 0 is exactly the plain builder.
    CHECK(ploc0 == sah_cost(ploc::build(std::span<const Tri>(tris), {}, exec::serial{}), {.ct = 3, .ci = 2}));
}

TEST_CASE("kbvh: build, build_wide and build_blocks give the tree of the plain path (split, build_tree, emission), bit for bit") {
    // kbvh's builds take the builder's node facts as it makes them (PLOC) and pack the blocks during the
    // wide emission: the trees of make_references + presplit::split + build_tree + emit_bvh /
    // emit_wide_bvh / make_wide_blocks, on every executor, and exact against brute force.
    auto tris = diagonal_slivers(3000, 57);
    tris[17].p1.x = std::numeric_limits<float>::quiet_NaN();   // left out and counted, as in the plain path
    const std::span<const Tri> ts(tris);
    const auto plain = [&]<class Builder>(const kbvh::Config<Builder>& cfg) {
        const exec::serial s;
        auto refs = make_references(ts, s);
        refs = presplit::split(refs, ts, cfg.split, s);
        const BinaryTree tree = Builder::build_tree(refs, cfg.builder, s);
        auto w8 = emit_wide_bvh<8, Node<>, prim::indexed>(tree, refs, ts, cfg.builder.leaves, s);
        return std::pair{emit_bvh<Node<>, prim::indexed>(tree, refs, ts, cfg.builder.leaves, s), std::move(w8)};
    };
    const auto check_all = [&](const auto& cfg) {
        const auto [bin, w8] = plain(cfg);
        const auto b88 = make_wide_blocks(w8, ts, exec::serial{});
        REQUIRE(b88.nodes.size() > 50);
        CHECK(bin.excluded == 1);
        test::for_each_executor([&](const auto& ex) {
            CAPTURE(test::executor_name<std::remove_cvref_t<decltype(ex)>>());
            const auto b = kbvh::build(ts, cfg, ex);
            CHECK((b.nodes.size() == bin.nodes.size() && b.prim_ids == bin.prim_ids && b.depth == bin.depth && b.excluded == bin.excluded &&
                   std::memcmp(b.nodes.data(), bin.nodes.data(), b.nodes.size() * sizeof(b.nodes[0])) == 0));
            const auto w = kbvh::build_wide<8>(ts, cfg, ex);
            CHECK((w.nodes.size() == w8.nodes.size() && w.prim_ids == w8.prim_ids && w.depth == w8.depth &&
                   std::memcmp(w.nodes.data(), w8.nodes.data(), w.nodes.size() * sizeof(w.nodes[0])) == 0));
            const auto k = kbvh::build_blocks(ts, cfg, ex);
            CHECK(test::block_difference(k, b88) == "");
            CHECK(test::block_difference(kbvh::build_blocks<8, 4>(ts, cfg, ex), make_wide_blocks<4>(w8, ts, exec::serial{})) == "");
        });
        const auto k = kbvh::build_blocks(ts, cfg);
        const test::RaySet set = test::adversarial_rays(ts, test::sanitizer_scaled(60), 23);
        const test::Reference ref = test::brute_force<trace::robust>(ts, set.rays);
        const test::Disagreements r = test::compare_with<trace::robust>(k, ts, set, ref);
        CHECK_MESSAGE(r.total == 0, r.total << " disagreements with brute force (" << test::by_kind(r) << "), first: " << r.first);
    };
    SUBCASE("PLOC underneath (facts made while clustering)") {
        kbvh::Config<kbvh::with_ploc> cfg{.split = {.beta = 0.3f}};
        cfg.builder.leaves = block_leaves;
        check_all(cfg);
    }
    SUBCASE("LBVH underneath (facts from compute_node_info)") {
        check_all(kbvh::Config<kbvh::with_lbvh>{.split = {.beta = 0.1f}});
    }
}
