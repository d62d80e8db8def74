// Ray packets (packet.hpp): every active lane of intersect / occluded on a packet of 8 or 16 rays is,
// bit for bit, the single-ray query on the same wide tree (t, u, v, prim, hit/miss), and inactive lanes
// are misses; checked on every ray kind of the robustness suite (aimed at edges and vertices,
// axis-parallel with +-0, grazing, origins on surfaces, far origins, tmin == tmax, NaN / inf / empty
// rays) over the trees of every builder (8-wide with 8-lane blocks, 4-wide with 4-lane blocks, 8-wide
// with index or copied leaves), full, partial and random masks, incoherent packets (random rays, also
// sorted by octant so that they take the packet path) and coherent ones (tiles of camera rays), robust
// and Möller–Trumbore triangle tests, PacketConfig::min_rays from "always packets" to "always single
// rays" and the interval traversal on and off. Exact ties (duplicated triangles, shared edges hit
// exactly) equal brute force including the triangle index; occluded agrees with intersect; rays from
// inside closed meshes at every vertex and edge never escape through packets; trees deeper than the
// fixed stack. Built as test_packet (SSE / AVX as compiled: the sanitized build is the portable SSE one)
// and test_packet_nosimd (-DDYNBVH_NO_SIMD: the single-ray loop).
#include <doctest/doctest.h>

#include <dynbvh/packet.hpp>

#include "robust_support.hpp"
#include "simple_builder.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
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

struct Tally {
    std::size_t lanes = 0, hits = 0, bad = 0, bad_inactive = 0, bad_occluded = 0;
    std::string first;
    void fail(const std::string& what) {
        if (first.empty()) first = what;
    }
};

/// Packets of N consecutive rays of `rays` (the last one padded with copies) under mask `mask_of(i)`
/// against the single-ray queries, for Policy and one PacketConfig.
template <class Policy, int N, class WT, class MaskOf>
void check_packets(const WT& tree, std::span<const Trianglef> tris, std::span<const Rayf> rays, MaskOf&& mask_of,
                   const PacketConfig& cfg, Tally& t) {
    for (std::size_t i = 0; i < rays.size(); i += N) {
        RayPacket<float, N> p;
        for (int k = 0; k < N; ++k) p.set(k, rays[std::min(i + std::size_t(k), rays.size() - 1)]);
        const std::uint32_t active = mask_of(i) & all_lanes<N>;
        const HitPacket<float, N> hp = intersect<Policy>(tree, tris, p, active, cfg);
        const std::uint32_t occ = occluded<Policy>(tree, tris, p, active, cfg);
        for (int k = 0; k < N; ++k) {
            const Rayf r = p.ray(k);
            const Hitf got = hp.hit(k);
            if (!(active >> k & 1u)) {
                if (!identical(got, Hitf{}) || (occ >> k & 1u)) {
                    ++t.bad_inactive;
                    t.fail("inactive lane " + std::to_string(k) + " not a miss");
                }
                continue;
            }
            ++t.lanes;
            const Hitf want = intersect<Policy>(tree, tris, r);
            t.hits += want ? 1 : 0;
            if (!identical(got, want)) {
                ++t.bad;
                const Hitf bf = brute_force_intersect<Policy>(tris, r);
                t.fail("N=" + std::to_string(N) + " lane " + std::to_string(k) + ": " + test::describe(r, got, want) +
                       " (brute force prim " + std::to_string(bf.prim) + " t " + std::to_string(bf.t) + ")");
            }
            if (bool(occ >> k & 1u) != occluded<Policy>(tree, tris, r) || bool(occ >> k & 1u) != bool(want)) {
                ++t.bad_occluded;
                t.fail("occluded differs, lane " + std::to_string(k) + " ray " + test::describe(r));
            }
        }
    }
}

/// Every mask kind, N = 8, 16 and 32 (16 only when !Both), several min_rays, interval traversal on and off, for Policy.
template <class Policy, bool Both = true, class WT>
void check_all_masks(const WT& tree, std::span<const Trianglef> tris, std::span<const Rayf> rays, std::uint64_t seed, Tally& t) {
    Rng rng(seed);
    // (the sanitized build checks memory and UB on two of the five min_rays values; the optimised one all)
    const std::vector<unsigned> min_rays_values = test::sanitized() ? std::vector<unsigned>{0u, 3u} : std::vector<unsigned>{0u, 2u, 3u, 6u, 17u};
    for (const unsigned min_rays : min_rays_values)
      for (const bool interval : {true, false}) {
        const PacketConfig cfg{.min_rays = min_rays, .interval = interval};
        check_packets<Policy, 16>(tree, tris, rays, [](std::size_t) { return ~std::uint32_t(0); }, cfg, t);
        check_packets<Policy, 16>(tree, tris, rays, [&](std::size_t) { return std::uint32_t(rng.next()); }, cfg, t);
        check_packets<Policy, 16>(tree, tris, rays, [](std::size_t i) { return i % 32 == 0 ? 0x00ffu : 0x0001u; }, cfg, t);
        if constexpr (Both) {
            check_packets<Policy, 8>(tree, tris, rays, [](std::size_t) { return ~std::uint32_t(0); }, cfg, t);
            check_packets<Policy, 8>(tree, tris, rays, [&](std::size_t) { return std::uint32_t(rng.next()); }, cfg, t);
            check_packets<Policy, 8>(tree, tris, rays, [](std::size_t) { return 0u; }, cfg, t);
            // 32 (two 16-lane halves): all lanes, and a random mask (lanes 16-31 too)
            check_packets<Policy, 32>(tree, tris, rays, [](std::size_t) { return ~std::uint32_t(0); }, cfg, t);
            if (!test::sanitized())   // (CI time: the sanitized build checks the full mask)
                check_packets<Policy, 32>(tree, tris, rays, [&](std::size_t) { return std::uint32_t(rng.next()); }, cfg, t);
        }
    }
}

/// Tiles of camera rays (coherent packets): a pinhole at `eye` looking at `at`, w x h pixels, in tiles of
/// tw x th pixels, tile after tile (so packets of tw * th rays are tiles).
std::vector<Rayf> camera_tiles(Vec3f eye, Vec3f at, float fov, int w, int h, int tw, int th) {
    const Vec3f f = normalize(at - eye);
    const Vec3f up = std::abs(f.y) < 0.9f ? Vec3f{0, 1, 0} : Vec3f{1, 0, 0};
    const Vec3f r = normalize(cross(f, up)), u = cross(r, f);
    std::vector<Rayf> rays;
    for (int ty = 0; ty < h; ty += th)
        for (int tx = 0; tx < w; tx += tw)
            for (int y = ty; y < ty + th; ++y)
                for (int x = tx; x < tx + tw; ++x) {
                    const float sx = (2.0f * (float(x) + 0.5f) / float(w) - 1.0f) * fov, sy = (2.0f * (float(y) + 0.5f) / float(h) - 1.0f) * fov;
                    rays.push_back({eye, f + r * sx + u * sy});
                }
    return rays;
}

/// The robustness suite's rays, rays from far away (1e6 .. 1e7 scene sizes) and camera tiles.
std::vector<Rayf> all_rays(std::span<const Trianglef> tris, std::size_t per_kind, std::uint64_t seed) {
    const test::RaySet set = test::adversarial_rays(tris, test::sanitizer_scaled(per_kind), seed);
    std::vector<Rayf> rays = set.rays;
    AABBf b;
    for (const auto& t : tris)
        if (t.is_finite()) b.extend(t.bounds());
    const Vec3f c = (b.min + b.max) * 0.5f, e = b.max - b.min;
    const float size = std::max(e.x, std::max(e.y, e.z));
    Rng rng(seed + 7);
    // far origins: packets of rays from one far point (1e2 .. 1e4 scene sizes) to targets in the scene.
    // (Within tri::watertight's documented limit for these triangles, about 1e6 triangle sizes: beyond
    // it hits can lie outside their boxes by rounding, so even the single-ray answer depends on the
    // visit order and differs from brute force; packets then differ as a binary and a wide tree can.)
    for (int g = 0; g < 8; ++g) {
        const Vec3f dir0 = normalize(Vec3f{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)});
        const Vec3f eye = c + dir0 * (size * (g % 2 ? 1e2f : 1e4f));
        for (int k = 0; k < 16; ++k) {
            const Trianglef& t = tris[std::size_t(rng.next() % tris.size())];
            if (!t.is_finite()) continue;
            rays.push_back({eye, (k % 3 == 0 ? t.p0 : (t.p0 + t.p1) * 0.5f) - eye});
        }
    }
    // the suite's rays again, sorted by direction octant and dominant axis: incoherent packets whose
    // rays all take the packet path (the unsorted ones mostly split into groups too small for it)
    {
        std::vector<Rayf> sorted = set.rays;
        auto key = [](const Rayf& r) {
            const int oct = (std::signbit(r.dir.x) ? 1 : 0) | (std::signbit(r.dir.y) ? 2 : 0) | (std::signbit(r.dir.z) ? 4 : 0);
            return oct | largest_axis(Vec3f{std::abs(r.dir.x), std::abs(r.dir.y), std::abs(r.dir.z)}) << 3;
        };
        std::stable_sort(sorted.begin(), sorted.end(), [&](const Rayf& a, const Rayf& b) { return key(a) < key(b); });
        rays.insert(rays.end(), sorted.begin(), sorted.end());
    }
    const Vec3f eye = c + Vec3f{0.3f, 0.2f, 1.0f} * (1.5f * size);
    for (const Rayf& r : camera_tiles(eye, c, 0.45f, 32, 16, 4, 4)) rays.push_back(r);
    for (const Rayf& r : camera_tiles(eye, c, 0.45f, 32, 16, 4, 2)) rays.push_back(r);
    for (const Rayf& r : camera_tiles(eye, c, 0.45f, 32, 16, 8, 4)) rays.push_back(r);
    return rays;
}

/// Every policy and width on `tree`; AllWidths = false: 8- and 32-ray packets left out, AllPolicies =
/// false: the robust policy only.
template <bool AllWidths = true, bool AllPolicies = true, class WT>
std::string run_tree(const std::string& label, const WT& tree, std::span<const Trianglef> tris, std::span<const Rayf> rays,
                     std::uint64_t seed, std::size_t& lanes) {
    Tally t;
    check_all_masks<trace::robust, AllWidths>(tree, tris, rays, seed, t);
    if constexpr (AllPolicies) {
        // (Moller-Trumbore's leaf test through 16-ray packets only: the packet width's code is the robust
        // policy's, checked at both widths; CI time)
        check_all_masks<trace::policy<box::robust, tri::moller_trumbore>, false>(tree, tris, rays, seed + 1, t);
        check_packets<trace::fast, 16>(tree, tris, rays, [](std::size_t) { return ~std::uint32_t(0); }, PacketConfig{}, t);
    }
    lanes += t.lanes;
    if (t.bad + t.bad_inactive + t.bad_occluded == 0) return "";
    std::ostringstream s;
    s << label << ": " << t.bad << " lanes differ, " << t.bad_inactive << " inactive lanes not misses, " << t.bad_occluded
      << " occluded differences; first: " << t.first;
    return s.str();
}

/// Every builder's trees on one scene: 8/8 and 4/4 block trees, 8-wide index (or copied) leaves.
void check_scene(const std::string& name, std::span<const Trianglef> tris, std::size_t per_kind, std::uint64_t seed) {
    CAPTURE(name);
    const std::vector<Rayf> rays = all_rays(tris, per_kind, seed);
    std::size_t lanes = 0;
    test::for_each_builder(tris, exec::serial{}, [&](std::size_t bi, const auto& bvh, bool) {
        const std::string builder = test::builder_names[bi];
        CAPTURE(builder);
        const auto b88 = make_wide_blocks<8, 8>(bvh, tris);
        const auto b44 = make_wide_blocks<4, 4>(bvh, tris);
        const auto w8 = make_wide<8>(bvh);
        CHECK(run_tree(builder + " w8 blk8", b88, tris, rays, seed, lanes) == "");
        // (sanitized builds: the trees after the first through 16-ray packets and the robust policy only,
        // the first has run every policy and width there. Index and copied leaves at 16 rays in every
        // build: their leaf loop is the per-triangle test that the block trees check at every width; CI time)
        CHECK(run_tree<!test::sanitized_build, !test::sanitized_build>(builder + " w4 blk4", b44, tris, rays, seed + 2, lanes) == "");
        CHECK(run_tree<false, !test::sanitized_build>(builder + " w8 leaves", w8, tris, rays, seed + 4, lanes) == "");
    });
    MESSAGE(name << ": " << rays.size() << " rays, " << lanes << " active lanes compared");
}

} // namespace

TEST_CASE("packets: empty tree, one triangle, wrong span, inactive and untraceable lanes") {
    const std::vector<Trianglef> none;
    const auto e = make_wide_blocks<8>(Bvh<>{}, none);
    RayPacket<float, 8> p;
    const HitPacket<float, 8> he = intersect(e, none, p);
    CHECK(he.hit_mask() == 0u);
    CHECK(occluded(e, none, p) == 0u);

    const std::vector<Trianglef> one = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const auto w = make_wide_blocks<8>(lbvh::build(std::span<const Trianglef>(one)), one);
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    const Rayf good{{0.25f, 0.25f, 1}, {0, 0, -1}};
    const Rayf lanes[8] = {good, Rayf{{nan, 0.25f, 1}, {0, 0, -1}}, Rayf{{0.25f, 0.25f, inf}, {0, 0, -1}}, Rayf{{0.25f, 0.25f, 1}, {0, 0, 0}},
                           Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}, 0, nan}, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}, 2, 1},
                           Rayf{{0.75f, 0.75f, 1}, {0, 0, -1}}, good};
    for (int k = 0; k < 8; ++k) p.set(k, lanes[k]);
    const HitPacket<float, 8> h = intersect(w, one, p);
    CHECK(h.hit_mask() == 0x81u);
    CHECK(h.prim[0] == 0u);
    CHECK(h.t[0] == 1.0f);
    CHECK(h.u[0] == 0.25f);
    CHECK(h.v[0] == 0.25f);
    CHECK(occluded(w, one, p) == 0x81u);
    CHECK(intersect(w, one, p, 0x80u).hit_mask() == 0x80u);
    CHECK(intersect(w, one, p, 0u).hit_mask() == 0u);
    CHECK(occluded(w, one, p, 0x01u) == 0x01u);
    CHECK(std::isinf(intersect(w, one, p, 0x80u).t[0]));
    CHECK_THROWS_AS(intersect(w, std::span<const Trianglef>(), p), std::invalid_argument);
    CHECK_THROWS_AS(occluded(w, std::span<const Trianglef>(), p), std::invalid_argument);
    // lane round trip
    const Rayf back = p.ray(5);
    CHECK(back.tmin == 2.0f);
    CHECK(back.tmax == 1.0f);
}

TEST_CASE("packets == single rays bit for bit: soup with ties and NaN/inf, every builder") {
    auto soup = test::random_soup(400, 5, 0.08f);
    for (std::size_t i = 0; i + 5 < soup.size(); i += 29) soup[i + 5] = soup[i];   // exact ties
    soup[7].p1.x = std::numeric_limits<float>::quiet_NaN();
    soup[11].p2.z = std::numeric_limits<float>::infinity();
    check_scene("soup with ties and NaN/inf", soup, 40, 41);
}

TEST_CASE("packets == single rays bit for bit: closed sphere and flat scene, every builder") {
    check_scene("sphere", test::sphere(16, 32), 30, 42);
    check_scene("flat", test::flat_scene(300), 30, 43);
}

TEST_CASE("packets: exact ties equal brute force including the triangle (larger index wins)") {
    // every triangle three times, and a grid of squares whose shared edges camera rays hit exactly
    std::vector<Trianglef> tris;
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            const float x0 = float(x) * 0.125f, y0 = float(y) * 0.125f, x1 = x0 + 0.125f, y1 = y0 + 0.125f;
            const Trianglef a{{x0, y0, 0}, {x1, y0, 0}, {x1, y1, 0}}, b{{x0, y0, 0}, {x1, y1, 0}, {x0, y1, 0}};
            for (int d = 0; d < 3; ++d) {
                tris.push_back(a);
                tris.push_back(b);
            }
        }
    const std::span<const Trianglef> ts(tris);
    std::vector<Rayf> rays;
    for (int y = 0; y <= 32; ++y)   // origins above grid points and edges: exact edge and vertex hits
        for (int x = 0; x <= 32; ++x) rays.push_back({{float(x) / 32.0f, float(y) / 32.0f, 1}, {0, 0, -1}});
    for (int k = 0; k < 64; ++k) rays.push_back({{float(k % 8) / 8.0f, float(k / 8) / 8.0f, 2}, {0.001f * float(k % 3), 0.0f, -1}});
    std::size_t bad = 0, ties = 0, hits = 0;
    std::string first;
    test::for_each_builder(ts, exec::serial{}, [&](std::size_t, const auto& bvh, bool) {
        const auto b88 = make_wide_blocks<8, 8>(bvh, ts);
        const auto b44 = make_wide_blocks<4, 4>(bvh, ts);
        auto check = [&](const auto& tree) {
            for (std::size_t i = 0; i < rays.size(); i += 16) {
                RayPacket<float, 16> p;
                for (int k = 0; k < 16; ++k) p.set(k, rays[std::min(i + std::size_t(k), rays.size() - 1)]);
                for (const unsigned min_rays : {0u, 3u}) {
                    const HitPacket<float, 16> hp = intersect(tree, ts, p, all_lanes<16>, {.min_rays = min_rays, .interval = min_rays == 0});
                    for (int k = 0; k < 16; ++k) {
                        const Hitf want = brute_force_intersect<trace::robust>(ts, p.ray(k));
                        const Hitf got = hp.hit(k);
                        hits += want ? 1 : 0;
                        if (want) {   // a tie: the duplicates (index - 2, index - 4) are hit at the same t
                            Rayf probe = p.ray(k);
                            probe.tmax = want.t;
                            ties += brute_force_intersect<trace::robust>(std::span<const Trianglef>(&tris[want.prim - 2], 1), probe) ? 1 : 0;
                        }
                        if (!identical(got, want)) {
                            if (bad++ == 0) first = test::describe(p.ray(k), got, want);
                        }
                        if (!identical(got, intersect(tree, ts, p.ray(k)))) {
                            if (bad++ == 0) first = "vs single ray: " + test::describe(p.ray(k), got, intersect(tree, ts, p.ray(k)));
                        }
                    }
                }
            }
        };
        check(b88);
        check(b44);
        check(make_wide<8>(bvh));
    });
    MESSAGE(hits << " hits, " << ties << " of them exact ties");
    CHECK(hits > 0);
    CHECK(ties == hits);   // every hit is a tie of three duplicates
    CHECK_MESSAGE(bad == 0, first);
}

TEST_CASE("watertightness through packets: rays from inside closed meshes at every vertex and edge") {
    for (const test::ClosedMesh& c : {test::closed_sphere(20, 40), test::closed_cube(6), test::closed_torus(24, 12)}) {
        const auto tris = c.mesh.triangles();
        const std::span<const Trianglef> ts(tris);
        std::size_t rays = 0, escaped = 0;
        // per origin, as packets of 16 (the last of each origin partial)
        const std::size_t per_origin = test::inside_rays(c, 1).size();
        const std::vector<Rayf> all = test::inside_rays(c, test::sanitized() ? 1 : 3);
        test::for_each_builder(ts, exec::serial{}, [&](std::size_t, const auto& bvh, bool) {
            const auto b8 = make_wide_blocks<8>(bvh, ts);
            const auto b4 = make_wide_blocks<4>(bvh, ts);
            for (std::size_t first = 0; first < all.size(); first += per_origin) {
                const std::span<const Rayf> rs(all.data() + first, per_origin);
                for (std::size_t i = 0; i < rs.size(); i += 16) {
                    RayPacket<float, 16> p;
                    const std::uint32_t n = std::uint32_t(std::min<std::size_t>(16, rs.size() - i));
                    for (std::uint32_t k = 0; k < n; ++k) p.set(int(k), rs[i + k]);
                    const std::uint32_t active = n == 16 ? all_lanes<16> : (1u << n) - 1u;
                    rays += 2 * n;
                    escaped += n - unsigned(std::popcount(intersect(b8, ts, p, active).hit_mask()));
                    escaped += n - unsigned(std::popcount(occluded(b4, ts, p, active)));
                }
            }
        });
        MESSAGE(c.name << ": " << rays << " packet lanes from inside at vertices and edge midpoints, " << escaped << " escaped");
        CHECK(rays > 0);
        CHECK(escaped == 0);
    }
}

TEST_CASE("packets on trees deeper than the fixed stack: heap stack, same answers") {
    const int levels = 600;
    const std::vector<Trianglef> tris = test::stacked_triangles(levels);
    const std::span<const Trianglef> ts(tris);
    const auto deep = test::caterpillar_build<Node<>, prim::indexed>(ts);
    const auto w = make_wide_blocks<8>(deep, ts);
    const auto wi = make_wide<8>(deep);
    CHECK(w.depth >= max_depth);
    RayPacket<float, 8> p;
    for (int k = 0; k < 8; ++k)
        p.set(k, k % 2 ? Rayf{{0.1f + 0.01f * float(k), 0.1f, 1000}, {0, 0, -1}} : Rayf{{0.1f, 0.1f + 0.01f * float(k), -1000}, {0, 0, 1}});
    for (const unsigned min_rays : {0u, 3u}) {
        const HitPacket<float, 8> a = intersect(w, ts, p, all_lanes<8>, {.min_rays = min_rays});
        const HitPacket<float, 8> b = intersect(wi, ts, p, all_lanes<8>, {.min_rays = min_rays});
        for (int k = 0; k < 8; ++k) {
            CHECK(a.prim[k] == (k % 2 ? std::uint32_t(levels - 1) : 0u));
            CHECK(identical(a.hit(k), intersect(w, ts, p.ray(k))));
            CHECK(identical(b.hit(k), intersect(wi, ts, p.ray(k))));
        }
        CHECK(occluded(w, ts, p, all_lanes<8>, {.min_rays = min_rays}) == all_lanes<8>);
    }
}
