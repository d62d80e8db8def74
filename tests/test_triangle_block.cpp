// SIMD triangle blocks (detail/triangle_block.hpp): packing keeps every reference once in slot order;
// the block tests return exactly what the scalar per-triangle loop (traverse.hpp's test_leaf) returns -
// hit/miss, t, u, v to the bit, the user's triangle, the larger index at an exact tie, the first hit of
// an any-hit query - for tri::watertight and tri::moller_trumbore, 4- and 8-lane blocks, on adversarial
// triangles: rays through edges and vertices, zero-area and edge-on triangles, huge (1e30), tiny
// (1e-30) and subnormal coordinates, far from the origin (1e7), NaN / infinite vertices, partial
// blocks. The watertight filter is checked on its own too: a lane it rejects is missed by the scalar
// test with any interval and also under an FMA-contracted shear, and it rejects most lanes of
// ordinary rays (so it does filter). Built as test_triangle_block (SSE / AVX as compiled) and
// test_triangle_block_nosimd (-DDYNBVH_NO_SIMD).
#include <doctest/doctest.h>

#include <dynbvh/detail/triangle_block.hpp>
#include <dynbvh/traverse.hpp>

#include "hit_compare.hpp"
#include "support.hpp"

#include <cmath>
#include <cstdint>
#include <array>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

using namespace dynbvh;
using dynbvh::test::Rng;
using dynbvh::test::same_bits;

namespace {

constexpr float inf = std::numeric_limits<float>::infinity();
constexpr float qnan = std::numeric_limits<float>::quiet_NaN();

/// Triangles in slot order, the user's index of each slot, and their leaves.
struct Scene {
    std::string name;
    std::vector<Trianglef> tris;        // by slot
    std::vector<std::uint32_t> ids;     // slot -> user index
    std::vector<detail::LeafRange> leaves;
};

/// Leaves of random sizes 1 .. 2L + 3 over all slots (partial blocks, several blocks per leaf).
template <int L>
void make_leaves(Scene& s, Rng& rng) {
    s.leaves.clear();
    for (std::size_t first = 0; first < s.tris.size();) {
        const std::size_t n = std::min<std::size_t>(1 + rng.next() % (2 * L + 3), s.tris.size() - first);
        s.leaves.push_back({first, n});
        first += n;
    }
    s.ids.resize(s.tris.size());
    for (std::size_t i = 0; i < s.ids.size(); ++i) s.ids[i] = std::uint32_t(s.ids.size() - 1 - i) * 3 + 1;   // not the slot
}

/// A grid mesh of n x n quads (two triangles each, shared edges and vertices), z jittered, scaled by
/// `scale` about `offset`; duplicated triangles (exact ties), zero-area and edge-on ones mixed in.
Scene grid_scene(const std::string& name, int n, float scale, Vec3f offset, Rng& rng) {
    Scene s;
    s.name = name;
    auto vtx = [&](int i, int j) {
        const float z = float((i * 7 + j * 13) % 5) * 0.1f;
        return offset + Vec3f{float(i), float(j), z} * scale;
    };
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const Vec3f a = vtx(i, j), b = vtx(i + 1, j), c = vtx(i + 1, j + 1), d = vtx(i, j + 1);
            s.tris.push_back({a, b, c});
            s.tris.push_back({a, c, d});
            const std::uint64_t r = rng.next() % 16;
            if (r == 0) s.tris.push_back({a, b, c});                                  // exact duplicate: a tie
            if (r == 1) s.tris.push_back({a, c, c});                                  // zero area (a segment)
            if (r == 2) s.tris.push_back({a, a, a});                                  // a point
            if (r == 3) s.tris.push_back({a, b, a + (b - a) * 0.5f});                 // collinear
            if (r == 4) s.tris.push_back({a, b, a + Vec3f{0, 0, scale}});             // vertical: edge-on to some rays
        }
    return s;
}

/// Ray origins around the scene's box (and far away), aimed at vertices, edge midpoints, interior
/// points or random directions; axis-parallel rays with +-0 components; clipped intervals.
std::vector<Rayf> make_rays(const Scene& s, std::size_t n, Rng& rng) {
    AABBf b;
    for (const auto& t : s.tris)
        if (t.is_finite()) b.extend(t.bounds());
    const Vec3f ext = b.max - b.min;
    const float size = std::max(ext.x, std::max(ext.y, ext.z));
    auto u = [&](float lo, float hi) { return lo + (hi - lo) * rng.uniform(); };
    auto point = [&] {
        const Vec3f c = (b.min + b.max) * 0.5f;
        return c + Vec3f{u(-1, 1), u(-1, 1), u(-1, 1)} * size;
    };
    auto pick = [&]() -> const Trianglef& {
        for (;;) {
            const Trianglef& t = s.tris[rng.next() % s.tris.size()];
            if (t.is_finite()) return t;
        }
    };
    std::vector<Rayf> rays(n);
    for (std::size_t i = 0; i < n; ++i) {
        Rayf& r = rays[i];
        r.org = point();
        if (i % 13 == 0) r.org = r.org + Vec3f{1, -2, 3} * (size * 1e7f);   // far away
        const Trianglef& t = pick();
        switch (i % 7) {
        case 0: r.dir = t.p0 - r.org; break;                                      // vertex
        case 1: r.dir = (t.p0 + (t.p1 - t.p0) * 0.5f) - r.org; break;              // edge
        case 2: r.dir = (t.p1 * 0.25f + t.p2 * 0.75f) - r.org; break;              // edge (another)
        case 3: r.dir = t.centroid() - r.org; break;                               // interior
        case 4: {                                                                  // axis-parallel through a vertex
            const std::size_t a = rng.next() % 3;
            r.org = t.p1;
            r.org[a] = (rng.next() & 1) ? b.min[a] - size : b.max[a] + size;
            r.dir = {(rng.next() & 1) ? 0.0f : -0.0f, (rng.next() & 1) ? 0.0f : -0.0f, (rng.next() & 1) ? 0.0f : -0.0f};
            r.dir[a] = r.org[a] < b.min[a] ? 1.0f : -1.0f;
            break;
        }
        case 5: {                                                                  // in the triangle's plane (edge-on)
            r.org = t.p0 - (t.p1 - t.p0);
            r.dir = t.p1 - t.p0;
            break;
        }
        default: r.dir = Vec3f{u(-1, 1), u(-1, 1), u(-1, 1)}; break;
        }
        if (!(r.dir.x != 0 || r.dir.y != 0 || r.dir.z != 0)) r.dir = {0, 0, 1};
        if (i % 5 == 0) {
            r.tmin = u(0.0f, 0.9f);
            r.tmax = r.tmin + u(0.0f, 0.5f);
        }
    }
    return rays;
}

/// Puts NaN / infinite coordinates into some triangles (blocks must treat them as the scalar test does).
void poison(Scene& s, Rng& rng) {
    for (std::size_t i = 3; i < s.tris.size(); i += 17) {
        Trianglef& t = s.tris[i];
        const float bad = (rng.next() & 1) ? qnan : ((rng.next() & 1) ? inf : -inf);
        switch (rng.next() % 3) {
        case 0: t.p0[rng.next() % 3] = bad; break;
        case 1: t.p1[rng.next() % 3] = bad; break;
        default: t.p2[rng.next() % 3] = bad; break;
        }
    }
}

template <int L>
struct Packed {
    scratch_vector<detail::TriangleBlock<L>> blocks;
    scratch_vector<std::size_t> first;
};

template <int L, class Exec = exec::serial>
Packed<L> pack(const Scene& s, const Exec& ex = {}) {
    Packed<L> p;
    detail::pack_triangle_blocks<L>(std::span<const detail::LeafRange>(s.leaves), std::span<const std::uint32_t>(s.ids),
                                    [&](std::size_t slot) -> const Trianglef& { return s.tris[slot]; }, p.blocks, p.first, ex);
    return p;
}

/// The sign decision of tri::watertight for a triangle, with the shear FMA-contracted (fmaf) or
/// not: +1 / -1 when two edge functions have strictly opposite signs (certain miss), 0 otherwise.
/// The scalar test's three edge functions (double products of the float-sheared vertices), with the
/// shear rounded as written or contracted to FMAs.
std::array<double, 3> scalar_edges(const tri::watertight::prepared<float>& p, const Trianglef& tri, bool contracted) {
    const std::size_t z = std::size_t(p.kz), x = (z + 1) % 3, y = (z + 2) % 3;
    auto shear = [&](const Vec3f& q, float& sx, float& sy) {
        const Vec3f a = q - p.org;
        if (contracted) {
            sx = std::fma(-p.sx, a[z], a[x]);
            sy = std::fma(-p.sy, a[z], a[y]);
        } else {
            const float mx = p.sx * a[z], my = p.sy * a[z];
            sx = a[x] - mx;
            sy = a[y] - my;
        }
    };
    float ax, ay, bx, by, cx, cy;
    shear(tri.p0, ax, ay);
    shear(tri.p1, bx, by);
    shear(tri.p2, cx, cy);
    return {double(cx) * double(by) - double(cy) * double(bx), double(ax) * double(cy) - double(ay) * double(cx),
            double(bx) * double(ay) - double(by) * double(ax)};
}

/// 1 when two of the scalar edge functions have strictly opposite signs, else 0.
int scalar_opposite_signs(const tri::watertight::prepared<float>& p, const Trianglef& tri, bool contracted) {
    bool pos = false, neg = false;
    for (double v : scalar_edges(p, tri, contracted)) {
        pos = pos || v > 0;
        neg = neg || v < 0;
    }
    return pos && neg ? 1 : 0;
}

/// +1 when all three scalar edge functions are > 0, -1 when all are < 0, else 0.
int scalar_common_sign(const tri::watertight::prepared<float>& p, const Trianglef& tri, bool contracted) {
    const auto e = scalar_edges(p, tri, contracted);
    if (e[0] > 0 && e[1] > 0 && e[2] > 0) return 1;
    if (e[0] < 0 && e[1] < 0 && e[2] < 0) return -1;
    return 0;
}

struct Counts {
    std::size_t rays = 0, hits = 0, lanes = 0, rejected = 0, inside = 0, bad = 0, unsound = 0;
};

/// Every ray through every leaf in order (tmax carried across leaves as in traversal), and each leaf
/// alone with a tmax set to a hit's t (ties), closest and any hit: block test == test_leaf.
template <class Tri, int L>
void compare(const Scene& s, const Packed<L>& p, const std::vector<Rayf>& rays, Counts& c) {
    const Trianglef* tris = s.tris.data();
    const std::uint32_t* ids = s.ids.data();
    for (const Rayf& ray : rays) {
        ++c.rays;
        const typename Tri::template prepared<float> pt(ray);
        const detail::BlockTest<Tri, L> bt(ray);
        auto fail = [&](const std::string& what) {
            if (c.bad++ < 8) MESSAGE(s.name << " L=" << L << ": " << what << " for ray " << test::describe(ray));
        };
        // closest hit over all leaves
        float tmax_s = ray.tmax, tbox_s = ray.tmax, tmax_b = ray.tmax, tbox_b = ray.tmax;
        std::uint32_t want = invalid_prim;   // test_leaf's closest triangle
        std::uint32_t best_prim = invalid_prim;
        Hitf hs, hb;
        for (std::size_t j = 0; j < s.leaves.size(); ++j) {
            const auto& leaf = s.leaves[j];
            detail::test_leaf<Tri, false, true>(pt, tris, ids, leaf.first, leaf.first + leaf.count, 1.0f, tmax_s, tbox_s, want, hs);
            bt.template test<false>(p.blocks.data(), p.first[j], p.first[j + 1], 1.0f, tmax_b, tbox_b, best_prim, hb);
        }
        if (want != best_prim || !same_bits(tmax_s, tmax_b) || !same_bits(tbox_s, tbox_b) ||
            (want != invalid_prim && (!same_bits(hs.t, hb.t) || !same_bits(hs.u, hb.u) || !same_bits(hs.v, hb.v))))
            fail("closest hit differs: prim " + std::to_string(best_prim) + " vs " + std::to_string(want));
        c.hits += want != invalid_prim;
        // any hit over all leaves: the same first hit
        {
            Hitf as, ab;
            float t1 = ray.tmax, b1 = ray.tmax, t2 = ray.tmax, b2 = ray.tmax;
            std::uint32_t bs = 0;
            std::uint32_t bp = 0;
            bool rs = false, rb = false;
            for (std::size_t j = 0; j < s.leaves.size() && !rs; ++j)
                rs = detail::test_leaf<Tri, true, true>(pt, tris, ids, s.leaves[j].first, s.leaves[j].first + s.leaves[j].count, 1.0f, t1, b1, bs, as);
            for (std::size_t j = 0; j < s.leaves.size() && !rb; ++j)
                rb = bt.template test<true>(p.blocks.data(), p.first[j], p.first[j + 1], 1.0f, t2, b2, bp, ab);
            if (rs != rb || (rs && (as.prim != ab.prim || !same_bits(as.t, ab.t) || !same_bits(as.u, ab.u) || !same_bits(as.v, ab.v))))
                fail("any hit differs");
        }
        // each leaf alone with tmax = the closest hit's t (ties at exactly that t: the larger index wins)
        if (want != invalid_prim)
            for (std::size_t j = 0; j < s.leaves.size(); ++j) {
                const auto& leaf = s.leaves[j];
                float ts = hs.t, bs = hs.t, tb = hs.t, bb = hs.t;
                std::uint32_t w = invalid_prim;
                std::uint32_t prim = invalid_prim;
                Hitf h1, h2;
                detail::test_leaf<Tri, false, true>(pt, tris, ids, leaf.first, leaf.first + leaf.count, 0.5f, ts, bs, w, h1);
                bt.template test<false>(p.blocks.data(), p.first[j], p.first[j + 1], 0.5f, tb, bb, prim, h2);
                if (w != prim || !same_bits(ts, tb) || !same_bits(bs, bb) ||
                    (w != invalid_prim && (!same_bits(h1.u, h2.u) || !same_bits(h1.v, h2.v))))
                    fail("leaf " + std::to_string(j) + " at tmax = closest t differs");
            }
        // the watertight filter alone: rejected lanes are certain misses (also with a contracted shear)
        if constexpr (std::is_same_v<Tri, tri::watertight>) {
            Rayf open = ray;
            open.tmin = -inf;
            open.tmax = inf;
            for (const auto& b : p.blocks) {
                unsigned pos = 0, neg = 0;
                const unsigned cand = bt.candidates(b, pos, neg);
                if ((cand & ~b.valid_mask()) != 0) fail("a padding lane is a candidate");
                if ((pos & neg) != 0 || ((pos | neg) & ~cand) != 0) fail("inside lanes are not disjoint candidates");
                for (int k = 0; k < int(b.count); ++k) {
                    ++c.lanes;
                    // lanes proved inside: the scalar edge functions share that sign (either shear rounding)
                    if ((pos | neg) >> k & 1) {
                        ++c.inside;
                        const int sign = (pos >> k & 1) ? 1 : -1;
                        const Trianglef t = b.triangle(k);
                        if (scalar_common_sign(pt, t, false) != sign || scalar_common_sign(pt, t, true) != sign) ++c.unsound;
                    }
                    if (cand >> k & 1) continue;
                    ++c.rejected;
                    const Trianglef t = b.triangle(k);
                    if (intersect_triangle(t, open) || scalar_opposite_signs(pt, t, false) == 0 || scalar_opposite_signs(pt, t, true) == 0)
                        ++c.unsound;
                }
            }
        }
    }
}

template <class Tri, int L>
Counts check_scene(Scene s, std::size_t nrays, std::uint64_t seed) {
    Rng rng(seed);
    make_leaves<L>(s, rng);
    const Packed<L> p = pack<L>(s);
    const auto rays = make_rays(s, test::sanitizer_scaled(nrays), rng);
    Counts c;
    compare<Tri, L>(s, p, rays, c);
    MESSAGE(s.name << " L=" << L << std::string(std::is_same_v<Tri, tri::watertight> ? " watertight" : " moller-trumbore") << ": "
                   << s.tris.size() << " triangles in " << p.blocks.size() << " blocks, " << c.rays << " rays, " << c.hits
                   << " hit; filter rejected " << c.rejected << " and proved inside " << c.inside << " of " << c.lanes << " lanes");
    CHECK(c.bad == 0);
    CHECK(c.unsound == 0);
    return c;
}

template <class Tri, int L>
void check_adversarial() {
    Rng rng(7);
    struct Case {
        const char* name;
        float scale;
        Vec3f offset;
    };
    const Case cases[] = {
        {"unit grid", 1.0f, {0, 0, 0}},
        {"huge (1e30)", 1e30f, {0, 0, 0}},
        {"near the no-overflow limit (1e17)", 1e17f, {0, 0, 0}},
        {"tiny (1e-30)", 1e-30f, {0, 0, 0}},
        {"subnormal (1e-41)", 1e-41f, {0, 0, 0}},
        {"far from the origin (1e7)", 1.0f, {1e7f, -3e7f, 2e7f}},
        {"small at 1e4", 1e-3f, {1e4f, 1e4f, -1e4f}},
    };
    std::size_t rejected = 0, inside = 0, lanes = 0;
    for (const Case& k : cases) {
        Scene s = grid_scene(k.name, 9, k.scale, k.offset, rng);
        const Counts c = check_scene<Tri, L>(s, 1500, rng.next());
        if (std::string(k.name) == "unit grid") {
            rejected += c.rejected;
            inside += c.inside;
            lanes += c.lanes;
        }
        Scene bad = grid_scene(std::string(k.name) + " with NaN/inf vertices", 6, k.scale, k.offset, rng);
        poison(bad, rng);
        check_scene<Tri, L>(bad, 600, rng.next());
    }
    // random soups (long thin and ordinary), with duplicates
    {
        Scene s;
        s.name = "soup";
        s.tris = test::random_soup(400, 3, 0.1f);
        for (std::size_t i = 0; i + 1 < s.tris.size(); i += 37) s.tris[i + 1] = s.tris[i];
        check_scene<Tri, L>(s, 1500, 11);
        Scene t;
        t.name = "long thin";
        t.tris = test::long_thin(300, 4);
        check_scene<Tri, L>(t, 1500, 12);
    }
#if defined(DYNBVH_SSE)
    if constexpr (std::is_same_v<Tri, tri::watertight>) {
        // The filter must do its job: most lanes of ordinary rays are rejected in SIMD, and the
        // lanes of hit triangles are mostly proved inside (the sign-test shortcut is taken).
        MESSAGE("unit grid: filter rejected " << rejected << ", proved inside " << inside << " of " << lanes << " lanes");
        CHECK(rejected * 2 > lanes);
        CHECK(inside > 0);
    }
#else
    (void)rejected;
    (void)inside;
    (void)lanes;
#endif
}

} // namespace

TEST_CASE("packing: every reference once, in slot order, padded blocks, the same on every executor") {
    Rng rng(1);
    Scene s;
    s.tris = test::random_soup(1000, 5);
    auto check = [&](auto lanes) {
        constexpr int L = decltype(lanes)::value;
        make_leaves<L>(s, rng);
        s.leaves.insert(s.leaves.begin() + 3, detail::LeafRange{0, 0});   // an empty range packs to no block
        const Packed<L> p = pack<L>(s);
        REQUIRE(p.first.size() == s.leaves.size() + 1);
        std::size_t total = 0, bad = 0;
        for (std::size_t j = 0; j < s.leaves.size(); ++j) {
            const auto& leaf = s.leaves[j];
            if (p.first[j] != total) ++bad;
            total += (leaf.count + L - 1) / L;
            for (std::size_t i = 0; i < leaf.count; ++i) {
                const auto& b = p.blocks[p.first[j] + i / L];
                const int k = int(i % L);
                const Trianglef t = b.triangle(k), want = s.tris[leaf.first + i];
                bad += (std::memcmp(&t, &want, sizeof t) == 0 && b.prim[k] == s.ids[leaf.first + i]) ? 0 : 1;
            }
            for (std::size_t bi = p.first[j]; bi < p.first[j + 1]; ++bi) {
                const auto& b = p.blocks[bi];
                const std::size_t expect = std::min<std::size_t>(L, leaf.count - (bi - p.first[j]) * L);
                bad += b.count == expect ? 0 : 1;
                bad += b.valid_mask() == (1u << expect) - 1 ? 0 : 1;
                for (int k = int(b.count); k < L; ++k) bad += (b.prim[k] == invalid_prim && std::isnan(b.v[0][0][k])) ? 0 : 1;
            }
        }
        CHECK(p.first.back() == total);
        CHECK(p.blocks.size() == total);
        CHECK(bad == 0);
        CHECK(reinterpret_cast<std::uintptr_t>(p.blocks.data()) % 64 == 0);
        test::for_each_executor([&](auto ex) {
            const Packed<L> q = pack<L>(s, ex);
            REQUIRE(q.blocks.size() == p.blocks.size());
            CHECK(q.first == p.first);
            std::size_t diff = 0;
            for (std::size_t i = 0; i < q.blocks.size(); ++i)
                diff += (std::memcmp(q.blocks[i].v, p.blocks[i].v, sizeof p.blocks[i].v) == 0 &&
                         std::memcmp(q.blocks[i].prim, p.blocks[i].prim, sizeof p.blocks[i].prim) == 0 && q.blocks[i].count == p.blocks[i].count)
                            ? 0
                            : 1;
            CHECK(diff == 0);
        });
    };
    check(std::integral_constant<int, 4>{});
    check(std::integral_constant<int, 8>{});
}

TEST_CASE("watertight block test == scalar loop bit for bit on adversarial triangles (4 lanes)") {
    check_adversarial<tri::watertight, 4>();
}
TEST_CASE("watertight block test == scalar loop bit for bit on adversarial triangles (8 lanes)") {
#if defined(DYNBVH_AVX)
    MESSAGE("8-lane blocks tested with AVX");
#elif defined(DYNBVH_SSE)
    MESSAGE("8-lane blocks tested in two SSE steps");
#else
    MESSAGE("no SIMD: the scalar block loop");
#endif
    check_adversarial<tri::watertight, 8>();
}
TEST_CASE("Moller-Trumbore block test == scalar loop bit for bit (4 and 8 lanes)") {
    check_adversarial<tri::moller_trumbore, 4>();
    check_adversarial<tri::moller_trumbore, 8>();
}

TEST_CASE("closed sphere through blocks: no ray from inside escapes through an edge or a vertex") {
    const auto sph = test::sphere(24, 48);
    for (int lanes : {4, 8}) {
        Rng rng(4);
        Scene s;
        s.tris = sph;
        std::size_t escaped = 0, rays = 0;
        auto run = [&](auto lc) {
            constexpr int L = decltype(lc)::value;
            make_leaves<L>(s, rng);
            const Packed<L> p = pack<L>(s);
            for (int o = 0; o < (test::sanitized() ? 1 : 6); ++o) {
                const Vec3f org{rng.uniform(-0.5f, 0.5f), rng.uniform(-0.5f, 0.5f), rng.uniform(-0.5f, 0.5f)};
                for (const auto& t : sph)
                    for (const Vec3f& target : {t.p0, (t.p0 + t.p1) * 0.5f, (t.p1 + t.p2) * 0.5f}) {
                        ++rays;
                        const Rayf r{org, target - org};
                        const detail::BlockTest<tri::watertight, L> bt(r);
                        float tmax = r.tmax, tbox = r.tmax;
                        std::uint32_t prim = invalid_prim;
                        Hitf h;
                        bt.template test<false>(p.blocks.data(), 0, p.blocks.size(), 1.0f, tmax, tbox, prim, h);
                        escaped += prim == invalid_prim;
                    }
            }
        };
        if (lanes == 4) run(std::integral_constant<int, 4>{});
        else run(std::integral_constant<int, 8>{});
        MESSAGE(lanes << " lanes: " << rays << " rays from inside at vertices and edges, " << escaped << " escaped");
        CHECK(escaped == 0);
    }
}
