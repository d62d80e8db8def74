// 4-wide BVH (wide.hpp): the conversion keeps every reference exactly once with boxes that contain
// their subtrees and the binary tree's leaf SAH term; wide traversal returns exactly what brute force
// and the binary traversal return (t to the bit; an exact tie may name another triangle) on soups,
// a closed sphere, flat scenes, axis-parallel rays with +-0 components, rays through vertices and
// edges, grazing and clipped rays; the SIMD box test equals the scalar one bit for bit.
#include <doctest/doctest.h>

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/wide.hpp>

#include "simple_builder.hpp"
#include "hit_compare.hpp"
#include "support.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <dynbvh/io/ply.hpp>

using namespace dynbvh;
using dynbvh::test::Rng;
using dynbvh::test::describe;
using dynbvh::test::same_bits;
using dynbvh::test::same_hit;

namespace {


// ---- structure ------------------------------------------------------------------------------

/// Independent check of a wide tree against the binary tree it came from and the triangles.
/// Returns a description of every problem (empty when fine).
template <class NodeT, class Prim, int W>
std::string wide_problems(const Bvh<NodeT, Prim>& bvh, const wide_bvh_of<Bvh<NodeT, Prim>, W>& w,
                          std::span<const Triangle<typename NodeT::scalar_type>> tris) {
    using S = typename NodeT::scalar_type;
    std::ostringstream err;
    std::size_t problems = 0;
    auto fail = [&](const std::string& m) {
        if (problems++ < 10) err << m << "\n";
    };
    if (bvh.empty()) {
        if (!w.empty()) fail("wide tree of an empty tree is not empty");
        return err.str();
    }
    if (w.prim_ids != bvh.prim_ids) fail("prim_ids differ");
    if (w.leaf_triangles.size() != bvh.leaf_triangles.size()) fail("leaf_triangles differ");
    if (w.primitive_count != bvh.primitive_count || w.excluded != bvh.excluded) fail("counts differ");
    std::size_t binary_inner = 0;
    for (const auto& n : bvh.nodes) binary_inner += n.is_leaf() ? 0 : 1;
    if (w.nodes.size() > std::max<std::size_t>(binary_inner, 1)) fail("more wide nodes than binary inner nodes");

    std::vector<std::uint8_t> node_seen(w.nodes.size(), 0), slot_seen(w.prim_ids.size(), 0);
    std::vector<std::pair<std::size_t, std::uint32_t>> stack{{0, 0}};
    std::uint32_t depth = 0;
    double leaf_term = 0;
    while (!stack.empty()) {
        const auto [id, d] = stack.back();
        stack.pop_back();
        if (id >= w.nodes.size() || node_seen[id]++) {
            fail("node " + std::to_string(id) + " out of range or reached twice");
            continue;
        }
        depth = std::max(depth, d);
        const auto& n = w.nodes[id];
        int used = 0;
        bool all_leaves = true;
        for (int k = 0; k < W; ++k) {
            if (n.empty_slot(k)) {
                if (n.count[k] != 0) fail("empty slot with a count");
                continue;
            }
            if (k != used) fail("empty slot before a used one in node " + std::to_string(id));
            ++used;
            const AABB<S> box = n.bounds(k);
            if (n.is_leaf(k)) {
                leaf_term += detail::area(box) * double(n.count[k]);
                for (std::size_t s = n.child[k]; s < std::size_t(n.child[k]) + n.count[k]; ++s) {
                    if (s >= slot_seen.size() || slot_seen[s]++) {
                        fail("leaf slot " + std::to_string(s) + " out of range or referenced twice");
                        continue;
                    }
                    const AABB<S> tb = w.triangle(tris, s).bounds();
                    if (!box.contains(tb)) fail("leaf box does not contain its triangle, slot " + std::to_string(s));
                }
            } else {
                all_leaves = false;
                if (n.child[k] >= w.nodes.size()) {
                    fail("child out of range");
                    continue;
                }
                const AABB<S> cb = w.nodes[n.child[k]].bounds();
                if (!box.contains(cb)) fail("slot box does not contain child node " + std::to_string(n.child[k]));
                stack.push_back({n.child[k], d + 1});
            }
        }
        if (used < 2 && w.nodes.size() > 1) fail("inner node with fewer than two children");
        // Greedy collapse: a node is only left with fewer than W children when all of them are leaves.
        if (used < W && !all_leaves) fail("node " + std::to_string(id) + " has " + std::to_string(used) + " children, not all leaves");
    }
    for (std::size_t i = 0; i < node_seen.size(); ++i)
        if (!node_seen[i]) fail("node " + std::to_string(i) + " unreachable");
    for (std::size_t s = 0; s < slot_seen.size(); ++s)
        if (!slot_seen[s]) fail("leaf slot " + std::to_string(s) + " not referenced");
    if (depth != w.depth) fail("depth field " + std::to_string(w.depth) + " but measured " + std::to_string(depth));
    if (w.depth > bvh.depth) fail("wide tree deeper than the binary tree");
    // SAH: the same leaf term as the binary tree; a smaller (subset) inner term.
    double bin_leaf = 0;
    for (const auto& n : bvh.nodes)
        if (n.is_leaf()) bin_leaf += detail::area(n.bounds()) * double(n.count);
    if (!(std::abs(leaf_term - bin_leaf) <= 1e-9 * bin_leaf)) fail("leaf SAH term differs from the binary tree's");
    const double ws = sah_cost(w, {.ct = 3, .ci = 2}), bs = sah_cost(bvh, {.ct = 3, .ci = 2});
    // (a single-leaf binary tree has no inner node; its wide tree has one)
    if (!(ws <= bs * (1 + 1e-12)) && !bvh.nodes[0].is_leaf()) fail("wide SAH above binary SAH");
    const double wl = sah_cost(w, {.ct = 0, .ci = 2}), bl = sah_cost(bvh, {.ct = 0, .ci = 2});
    if (!(std::abs(wl - bl) <= 1e-9 * bl)) fail("SAH leaf parts differ");
    const AABB<S> wb = w.bounds(), bb = bvh.bounds();
    if (!(wb.min == bb.min && wb.max == bb.max)) fail("root bounds differ");
    if (problems > 10) err << "... " << problems << " problems in all\n";
    return err.str();
}

// ---- rays -----------------------------------------------------------------------------------

enum class Kind { random, interior, vertex, edge, axis, axis_vertex, clipped, grazing, tiny };
constexpr int kind_count = 9;

template <class T>
std::vector<Ray<T>> make_rays(const std::vector<Triangle<T>>& tris, std::size_t n, std::uint64_t seed) {
    Rng rng(seed);
    AABB<T> b;
    for (const auto& t : tris)
        if (t.is_finite()) b.extend(t.bounds());
    const Vec3<T> lo = b.min - Vec3<T>{1, 1, 1}, hi = b.max + Vec3<T>{1, 1, 1};
    auto u = [&](T a, T c) { return T(a + (c - a) * T(rng.uniform())); };
    auto point = [&] { return Vec3<T>{u(lo.x, hi.x), u(lo.y, hi.y), u(lo.z, hi.z)}; };
    auto pick = [&]() -> const Triangle<T>& { return tris[rng.next() % tris.size()]; };
    auto coin = [&] { return (rng.next() & 1) != 0; };
    auto signed_zero = [&] { return coin() ? T(0) : -T(0); };
    std::vector<Ray<T>> rays(n);
    for (std::size_t i = 0; i < n; ++i) {
        Ray<T>& r = rays[i];
        switch (Kind(i % kind_count)) {
        case Kind::random:
            r.org = point();
            r.dir = Vec3<T>{u(-1, 1), u(-1, 1), u(-1, 1)};
            break;
        case Kind::interior: {
            const auto& t = pick();
            T a = T(rng.uniform()), c = T(rng.uniform());
            if (a + c > 1) { a = 1 - a; c = 1 - c; }
            r.org = point();
            r.dir = (t.p0 * (1 - a - c) + t.p1 * a + t.p2 * c) - r.org;
            break;
        }
        case Kind::vertex: {
            const auto& t = pick();
            r.org = point();
            r.dir = (coin() ? t.p1 : t.p0) - r.org;
            break;
        }
        case Kind::edge: {
            const auto& t = pick();
            r.org = point();
            r.dir = (t.p0 + (t.p1 - t.p0) * T(0.5)) - r.org;
            break;
        }
        case Kind::axis: {
            r.org = point();
            r.dir = {signed_zero(), signed_zero(), signed_zero()};
            r.dir[rng.next() % 3] = coin() ? T(1) : T(-1);
            break;
        }
        case Kind::axis_vertex: {
            // Parallel to an axis exactly through a vertex: the vertex lies on its leaf box's faces.
            const auto& t = pick();
            const std::size_t a = rng.next() % 3;
            const bool up = coin();
            r.org = t.p2;
            r.org[a] = up ? lo[a] : hi[a];
            r.dir = {signed_zero(), signed_zero(), signed_zero()};
            r.dir[a] = up ? T(1) : T(-1);
            break;
        }
        case Kind::clipped: {
            const auto& t = pick();
            r.org = point();
            r.dir = t.centroid() - r.org;
            r.tmin = T(0.5) * T(rng.uniform());
            r.tmax = r.tmin + T(1.2) * T(rng.uniform());
            break;
        }
        case Kind::grazing: {
            // Nearly in the triangle's plane, aimed at a point of it.
            const auto& t = pick();
            const Vec3<T> p = t.p0 * T(0.25) + t.p1 * T(0.25) + t.p2 * T(0.5);
            const Vec3<T> nrm = cross(t.p1 - t.p0, t.p2 - t.p0);
            const Vec3<T> along = (t.p1 - t.p0) + nrm * T(1e-4 * rng.uniform());
            r.org = p - along * T(2);
            r.dir = along;
            break;
        }
        case Kind::tiny: {
            // A direction component so small (subnormal) that its reciprocal overflows: box::robust
            // scales such rays (t_scale != 1), and traversal must compare distances in its units.
            const auto& t = pick();
            r.org = point();
            r.dir = t.centroid() - r.org;
            r.dir[rng.next() % 3] = (coin() ? T(1) : T(-1)) * std::numeric_limits<T>::denorm_min() * T(3);
            if (coin()) r.dir = r.dir * T(1e-3);
            break;
        }
        }
    }
    return rays;
}

bool is_grazing(std::size_t i) {
    const Kind k = Kind(i % kind_count);
    return k == Kind::vertex || k == Kind::edge || k == Kind::axis_vertex || k == Kind::grazing;
}

/// Wide (robust and fast) against brute force and the binary traversal, both primitive policies.
/// Returns the number of disagreements of the robust policy (which must be 0); fast-policy
/// disagreements on non-grazing rays are counted in `fast_bad`.
template <class T, class Build>
std::size_t check_exact(const std::vector<Triangle<T>>& tris, std::size_t nrays, Build build, const std::string& what,
                        std::size_t& fast_bad) {
    const std::span<const Triangle<T>> ts(tris);
    const auto rays = make_rays(tris, test::sanitizer_scaled(nrays), 99);
    const auto bi = build.template operator()<prim::indexed>(ts);
    const auto bp = build.template operator()<prim::copied>(ts);
    const auto wi = make_wide(bi);   // one declaration each: the types differ (clang rejects a shared `auto`)
    const auto wp = make_wide(bp);
    const auto w8 = make_wide<8>(bi);
    const auto w8p = make_wide<8>(bp);
    CHECK_MESSAGE(wide_problems(bi, wi, ts) == "", what);
    CHECK_MESSAGE(wide_problems(bp, wp, ts) == "", what);
    CHECK_MESSAGE(wide_problems(bi, w8, ts) == "", what << " (8-wide)");
    CHECK_MESSAGE(wide_problems(bp, w8p, ts) == "", what << " (8-wide)");
    std::size_t bad = 0, hits = 0;
    fast_bad = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Ray<T>& r = rays[i];
        const Hit<T> e = brute_force_intersect<trace::robust, T>(ts, r);
        hits += e ? 1 : 0;
        for (const Hit<T>& h : {intersect(wi, ts, r), intersect(wp, ts, r), intersect(w8, ts, r), intersect(w8p, ts, r)}) {
            if (!same_hit<tri::watertight>(h, e, ts, r)) {
                if (bad++ < 5) MESSAGE(what << ": " << describe(r, h, e));
            }
        }
        // The binary traversal on the same tree: the same answer (its own exactness is test_traverse's).
        const Hit<T> hb = intersect(bi, ts, r), hw = intersect(wi, ts, r);
        if (!same_hit<tri::watertight>(hw, hb, ts, r)) {
            if (bad++ < 5) MESSAGE(what << " (vs binary): " << describe(r, hw, hb));
        }
        const bool occ = occluded(wi, ts, r), occ_p = occluded(wp, ts, r), occ8 = occluded(w8, ts, r);
        if (occ != bool(e) || occ_p != bool(e) || occ8 != bool(e) || occ != brute_force_occluded<trace::robust, T>(ts, r)) {
            if (bad++ < 5) MESSAGE(what << ": any hit disagrees: " << describe(r, hw, e));
        }
        if (!is_grazing(i)) {
            const Hit<T> ef = brute_force_intersect<trace::fast, T>(ts, r);
            fast_bad += same_hit<tri::moller_trumbore>(intersect<trace::fast>(wi, ts, r), ef, ts, r) ? 0 : 1;
            fast_bad += same_hit<tri::moller_trumbore>(intersect<trace::fast>(wp, ts, r), ef, ts, r) ? 0 : 1;
            fast_bad += same_hit<tri::moller_trumbore>(intersect<trace::fast>(w8, ts, r), ef, ts, r) ? 0 : 1;
            fast_bad += occluded<trace::fast>(wi, ts, r) == bool(ef) ? 0 : 1;
            fast_bad += occluded<trace::fast>(w8p, ts, r) == bool(ef) ? 0 : 1;
        }
    }
    MESSAGE(what << ": " << tris.size() << " triangles, " << rays.size() << " rays, " << hits << " hit, wide depth "
                 << wi.depth << ", " << wi.nodes.size() << " wide nodes; fast-policy disagreements " << fast_bad);
    CHECK(hits > rays.size() / 8);
    return bad;
}

struct Median {
    template <class Prim, class T>
    Bvh<Node<T, std::conditional_t<std::is_same_v<T, float>, std::uint32_t, std::uint64_t>>, Prim>
    operator()(std::span<const Triangle<T>> tris) const {
        using NodeT = Node<T, std::conditional_t<std::is_same_v<T, float>, std::uint32_t, std::uint64_t>>;
        return test::median_build<NodeT, Prim>(tris, 3);
    }
};
struct Lbvh {
    template <class Prim> Bvh<Node<>, Prim> operator()(std::span<const Trianglef> t) const { return lbvh::build<Node<>, Prim>(t, {}, exec::serial{}); }
};
struct Ploc {
    template <class Prim> Bvh<Node<>, Prim> operator()(std::span<const Trianglef> t) const { return ploc::build<Node<>, Prim>(t, {.radius = 5}, exec::serial{}); }
};
struct Sah {
    template <class Prim> Bvh<Node<>, Prim> operator()(std::span<const Trianglef> t) const { return binned_sah::build<Node<>, Prim>(t, {}, exec::serial{}); }
};
/// One triangle per leaf: deep trees, many partly filled wide nodes.
struct LbvhLeaf1 {
    template <class Prim> Bvh<Node<>, Prim> operator()(std::span<const Trianglef> t) const {
        return lbvh::build<Node<>, Prim>(t, {.leaves = {.max_leaf_size = 1}}, exec::serial{});
    }
};

} // namespace

TEST_CASE("wide node layout") {
    CHECK(sizeof(WideNode<>) == 128);
    CHECK(alignof(WideNode<>) == 64);
    WideNode<> n;
    n.clear();
    for (int k = 0; k < 4; ++k) CHECK(n.empty_slot(k));
    CHECK(n.bounds().is_empty());
    // An empty slot is missed by every box test, whatever the ray.
    for (const Rayf& r : {Rayf{{0, 0, 0}, {1, 1, 1}}, Rayf{{0, 0, 0}, {-1, 0, 0}}, Rayf{{0, 0, 0}, {0, -0.0f, 1}},
                          Rayf{{0, 0, 0}, {1e-30f, 0, 0}, -std::numeric_limits<float>::infinity()}}) {
        float t[4];
        const box::robust::prepared<float> pr(r);
        const box::fast::prepared<float> pf(r);
        detail::dispatch_octant(pr.octant, [&](auto oct) {
            CHECK(detail::WideBoxTest<box::robust, float>(pr).test<decltype(oct)::value>(n, r.tmax, t) == 0u);
            CHECK(detail::WideBoxTest<box::fast, float>(pf).test<decltype(oct)::value>(n, r.tmax, t) == 0u);
            CHECK(detail::WideBoxTestScalar<box::robust, float>(pr).test<decltype(oct)::value>(n, r.tmax, t) == 0u);
            return 0;
        });
    }
}

template <int W>
void check_simd_box_test() {
    // Random boxes (some flat, some empty) against random rays with +-0 components and origins on
    // box planes: the same hit mask and the same entry distances as box::robust's own test.
    Rng rng(3);
    std::size_t masks = 0, bad = 0;
    for (int i = 0; i < 20000; ++i) {
        WideNode<float, std::uint32_t, W> n;
        n.clear();
        const int used = 1 + int(rng.next() % W);
        for (int k = 0; k < used; ++k) {
            Vec3f a{rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-2, 2)};
            Vec3f b{rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-2, 2)};
            if (rng.next() % 5 == 0) b[rng.next() % 3] = a[rng.next() % 3];   // flat boxes
            n.set_bounds(k, AABBf{min(a, b), max(a, b)});
        }
        Rayf r;
        r.org = {rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)};
        if (rng.next() % 4 == 0) r.org[rng.next() % 3] = n.lo_x[0];   // on a plane
        r.dir = {rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
        for (int a = 0; a < 3; ++a)
            if (rng.next() % 4 == 0) r.dir[std::size_t(a)] = rng.next() % 2 ? 0.0f : -0.0f;
        if (r.dir.x == 0 && r.dir.y == 0 && r.dir.z == 0) r.dir.z = 1;
        r.tmin = rng.next() % 3 == 0 ? rng.uniform(-1, 1) : 0.0f;
        const float tmax = rng.next() % 2 ? std::numeric_limits<float>::infinity() : rng.uniform(0, 4);
        const box::robust::prepared<float> pr(r);
        detail::dispatch_octant(pr.octant, [&](auto oct) {
            constexpr int O = decltype(oct)::value;
            alignas(32) float ts[W], tv[W];
            const unsigned ms = detail::WideBoxTestScalar<box::robust, float>(pr).template test<O>(n, tmax, ts);
            const unsigned mv = detail::WideBoxTest<box::robust, float, W>(pr).template test<O>(n, tmax, tv);
            masks += ms != 0;
            bool ok = ms == mv;
            for (int k = 0; k < W; ++k)
                if (ms >> k & 1) ok = ok && same_bits(ts[k], tv[k]);
            // and each slot agrees with the one-box test the binary traversal uses
            for (int k = 0; k < used; ++k) {
                float t1;
                const bool h = box::robust::test_octant<O>(pr, n.bounds(k).min, n.bounds(k).max, tmax, t1);
                ok = ok && h == bool(mv >> k & 1) && (!h || same_bits(t1, tv[k]));
            }
#if !defined(__FMA__)
            // Without FMA the fast test is the same arithmetic as well.
            const box::fast::prepared<float> pf(r);
            const unsigned fs = detail::WideBoxTestScalar<box::fast, float>(pf).template test<O>(n, tmax, ts);
            const unsigned fv = detail::WideBoxTest<box::fast, float, W>(pf).template test<O>(n, tmax, tv);
            ok = ok && fs == fv;
#endif
            bad += ok ? 0 : 1;
            return 0;
        });
    }
    MESSAGE(W << "-wide: " << masks << " of 20000 nodes hit");
    CHECK(masks > 1000);
    CHECK(bad == 0);
}

TEST_CASE("SIMD box test (SSE; AVX for 8-wide nodes where compiled in) equals the scalar box test bit for bit") {
    check_simd_box_test<4>();
    check_simd_box_test<8>();
#if defined(DYNBVH_AVX)
    MESSAGE("8-wide nodes tested with AVX");
#endif
}

#if defined(DYNBVH_SSE)
TEST_CASE("SSE ray setup gives box::robust::prepared's values, or declines") {
    // Random rays with +-0, subnormal, huge, NaN and infinite components and empty intervals: where the
    // direct setup accepts a ray, the ray is traceable, unscaled, the octant matches and every box test
    // agrees bit for bit with the one built from box::robust::prepared.
    Rng rng(17);
    const float specials[] = {0.0f, -0.0f, 1e-40f, -1e-40f, std::numeric_limits<float>::min(), 1e30f, -3.0f,
                              std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN()};
    std::size_t accepted = 0, declined = 0, bad = 0;
    for (int i = 0; i < 20000; ++i) {
        Rayf r{{rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)}, {rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)}};
        for (int k = 0; k < 2; ++k)
            if (rng.next() % 3 == 0) {
                const float v = specials[rng.next() % std::size(specials)];
                if (rng.next() % 4 == 0) r.org[rng.next() % 3] = v;
                else r.dir[rng.next() % 3] = v;
            }
        if (rng.next() % 10 == 0) r.tmin = rng.uniform(-1, 2);
        if (rng.next() % 10 == 0) r.tmax = rng.uniform(-1, 2);
        bool ok = false;
        int octant = -1;
        const detail::WideBoxTest<box::robust, float> direct(r, ok, octant);
        if (!ok) {
            ++declined;
            continue;
        }
        ++accepted;
        const box::robust::prepared<float> p(r);
        bool good = traceable(r) && p.t_scale == 1.0f && p.octant == octant;
        const detail::WideBoxTest<box::robust, float> via(p);
        for (int b = 0; b < 8 && good; ++b) {
            WideNode<> n;
            n.clear();
            for (int k = 0; k < 4; ++k) {
                const Vec3f a{rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-2, 2)};
                const Vec3f c{rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-2, 2)};
                n.set_bounds(k, AABBf{min(a, c), max(a, c)});
            }
            detail::dispatch_octant(octant, [&](auto oct) {
                float t1[4], t2[4];
                const unsigned m1 = direct.test<decltype(oct)::value>(n, r.tmax, t1);
                const unsigned m2 = via.test<decltype(oct)::value>(n, r.tmax, t2);
                good = good && m1 == m2;
                for (int k = 0; k < 4; ++k)
                    if (m1 >> k & 1) good = good && same_bits(t1[k], t2[k]);
                return 0;
            });
        }
        bad += good ? 0 : 1;
    }
    MESSAGE(accepted << " rays set up directly, " << declined << " declined");
    CHECK(accepted > 10000);
    CHECK(declined > 1000);
    CHECK(bad == 0);
}
#endif

TEST_CASE("child order: the sorting networks sort every 0/1 input; keys order as (distance, slot)") {
    // Zero-one principle: a comparator network that sorts every 0/1 sequence sorts every sequence.
    auto sorts_all = [](auto sort, int n) {
        for (unsigned bits = 0; bits < (1u << n); ++bits) {
            std::uint64_t k[8];
            for (int i = 0; i < n; ++i) k[i] = bits >> i & 1u;
            sort(k);
            for (int i = 1; i < n; ++i)
                if (k[i - 1] > k[i]) return false;
        }
        return true;
    };
    CHECK(sorts_all([](std::uint64_t* k) { detail::sort4(k); }, 4));
    CHECK(sorts_all([](std::uint64_t* k) { detail::sort8(k); }, 8));
    // order_by_distance: every count 0..8 (4- and 8-wide), ties by index, signed zeros and infinities
    Rng r(5);
    const float values[] = {-std::numeric_limits<float>::infinity(), -2.5f, -0.0f, 0.0f, 1e-30f, 1.0f, 1.0f, 3e38f,
                            std::numeric_limits<float>::infinity()};
    for (int trial = 0; trial < 2000; ++trial) {
        const int w = trial % 2 ? 8 : 4;
        const int n = int(r.next() % std::uint64_t(w + 1));
        float d[8];
        for (int i = 0; i < n; ++i) d[i] = values[r.next() % std::size(values)];
        int order[8];
        if (w == 8) detail::order_by_distance<8>(d, n, order);
        else detail::order_by_distance<4>(d, n, order);
        std::vector<int> want(static_cast<std::size_t>(n));
        for (int i = 0; i < n; ++i) want[std::size_t(i)] = i;
        // (-0 before +0: the keys order the float bits)
        std::stable_sort(want.begin(), want.end(), [&](int a, int b) {
            return d[a] < d[b] || (d[a] == d[b] && std::signbit(d[a]) && !std::signbit(d[b]));
        });
        CHECK(std::equal(want.begin(), want.end(), order));
    }
}

TEST_CASE("conversion: empty tree, one triangle, one leaf, moved tree") {
    const std::vector<Trianglef> none;
    const auto e = make_wide(Bvh<>{});
    CHECK(e.empty());
    CHECK_FALSE(intersect(e, none, Rayf{{0, 0, 0}, {0, 0, 1}}));
    CHECK_FALSE(occluded(e, none, Rayf{{0, 0, 0}, {0, 0, 1}}));
    CHECK(sah_cost(e) == 0.0);

    const std::vector<Trianglef> one = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const auto b1 = lbvh::build(std::span<const Trianglef>(one));
    const auto w1 = make_wide(b1);
    REQUIRE(w1.nodes.size() == 1);
    CHECK(w1.depth == 0);
    CHECK(wide_problems(b1, w1, std::span<const Trianglef>(one)) == "");
    const Hitf h = intersect(w1, one, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}});
    REQUIRE(h);
    CHECK(h.prim == 0);
    CHECK(h.t == 1.0f);
    CHECK(h.u == 0.25f);
    CHECK(h.v == 0.25f);
    CHECK_FALSE(intersect(w1, one, Rayf{{0.75f, 0.75f, 1}, {0, 0, -1}}));
    // Rays that are not traceable hit nothing, with every policy.
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    for (const Rayf& r : {Rayf{{nan, 0.25f, 1}, {0, 0, -1}}, Rayf{{0.25f, 0.25f, 1}, {0, nan, -1}},
                          Rayf{{0.25f, 0.25f, inf}, {0, 0, -1}}, Rayf{{0.25f, 0.25f, 1}, {0, 0, -inf}},
                          Rayf{{0.25f, 0.25f, 1}, {0, 0, 0}}, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}, nan, inf},
                          Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}, 0, nan}, Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}, 2, 1}}) {
        CHECK_FALSE(intersect(w1, one, r));
        CHECK_FALSE(occluded(w1, one, r));
        CHECK_FALSE(intersect<trace::fast>(w1, one, r));
        CHECK_FALSE(occluded<trace::fast>(w1, one, r));
        CHECK_FALSE(intersect<trace::policy<box::fast, tri::watertight>>(w1, one, r));
    }
    CHECK_THROWS_AS(intersect(w1, std::span<const Trianglef>(), Rayf{{0.25f, 0.25f, 1}, {0, 0, -1}}), std::invalid_argument);

    const auto soup = test::random_soup(3000, 8);
    auto b = lbvh::build<Node<>, prim::copied>(std::span<const Trianglef>(soup));
    const auto copied = make_wide(b);
    const auto moved = make_wide(std::move(b));
    CHECK(b.empty());
    REQUIRE(moved.nodes.size() == copied.nodes.size());
    CHECK(std::memcmp(moved.nodes.data(), copied.nodes.data(), moved.nodes.size() * sizeof(WideNode<>)) == 0);
    CHECK(moved.prim_ids == copied.prim_ids);
    CHECK(moved.leaf_triangles.size() == soup.size());
}

TEST_CASE("conversion is the same tree on every executor, and keeps every reference once") {
    const auto tris = test::random_soup(40000, 21, 0.01f);
    const std::span<const Trianglef> ts(tris);
    for (const auto& bvh : {lbvh::build(ts), ploc::build(ts), binned_sah::build(ts), lbvh::build(ts, {.leaves = {.max_leaf_size = 1}})}) {
        const auto ref = make_wide(bvh, exec::serial{});
        CHECK(wide_problems(bvh, ref, ts) == "");
        CHECK(ref.depth < bvh.depth);
        const double bs = sah_cost(bvh, {.ct = 3, .ci = 2}), ws = sah_cost(ref, {.ct = 3, .ci = 2});
        MESSAGE("binary SAH " << bs << " (" << bvh.nodes.size() << " nodes, depth " << bvh.depth << "), wide SAH " << ws
                              << " (" << ref.nodes.size() << " nodes, depth " << ref.depth << ")");
        CHECK(ws < bs);
        const auto ref8 = make_wide<8>(bvh, exec::serial{});
        CHECK(wide_problems(bvh, ref8, ts) == "");
        CHECK(ref8.depth <= ref.depth);
        CHECK(sah_cost(ref8, {.ct = 3, .ci = 2}) < ws);
        test::for_each_executor([&](auto ex) {
            const auto w = make_wide(bvh, ex);
            REQUIRE(w.nodes.size() == ref.nodes.size());
            CHECK(w.depth == ref.depth);
            CHECK(std::memcmp(w.nodes.data(), ref.nodes.data(), w.nodes.size() * sizeof(WideNode<>)) == 0);
            const auto w8 = make_wide<8>(bvh, ex);
            REQUIRE(w8.nodes.size() == ref8.nodes.size());
            CHECK(w8.depth == ref8.depth);
            CHECK(std::memcmp(w8.nodes.data(), ref8.nodes.data(), w8.nodes.size() * sizeof(w8.nodes[0])) == 0);
        });
    }
}

TEST_CASE("random soups: wide closest hit == brute force == binary to the bit, any hit agrees") {
    std::size_t fast_bad = 0;
    const auto soup = test::random_soup(400, 5, 0.08f);
    CHECK(check_exact(soup, 12000, Lbvh{}, "soup/lbvh", fast_bad) == 0);
    CHECK(fast_bad == 0);
    CHECK(check_exact(soup, 6000, Ploc{}, "soup/ploc", fast_bad) == 0);
    CHECK(fast_bad == 0);
    CHECK(check_exact(soup, 6000, Sah{}, "soup/binned-sah", fast_bad) == 0);
    CHECK(fast_bad == 0);
    CHECK(check_exact(soup, 6000, LbvhLeaf1{}, "soup/lbvh leaf=1", fast_bad) == 0);
    CHECK(fast_bad == 0);
    // Duplicates (exact ties) and non-finite triangles mixed in.
    auto dup = test::random_soup(300, 6, 0.1f);
    for (std::size_t i = 0; i + 5 < dup.size(); i += 29) dup[i + 5] = dup[i];
    dup[7].p1.x = std::numeric_limits<float>::quiet_NaN();
    dup[11].p2.z = std::numeric_limits<float>::infinity();
    CHECK(check_exact(dup, 6000, Median{}, "soup with ties and NaN/inf/median", fast_bad) == 0);
    const auto dsoup = [] {
        std::vector<Triangle<double>> t;
        for (const auto& f : test::random_soup(300, 7, 0.08f))
            t.push_back({Vec3d(f.p0) * 10.0, Vec3d(f.p1) * 10.0, Vec3d(f.p2) * 10.0});
        return t;
    }();
    CHECK(check_exact(dsoup, 4000, Median{}, "double soup/median (scalar wide path)", fast_bad) == 0);
}

TEST_CASE("closed sphere and flat scene: exact, and no ray escapes the sphere") {
    std::size_t fast_bad = 0;
    const auto sph = test::sphere(24, 48);
    CHECK(check_exact(sph, 8000, Ploc{}, "sphere/ploc", fast_bad) == 0);
    CHECK(fast_bad == 0);
    const auto flat = test::flat_scene(400);
    CHECK(check_exact(flat, 8000, Lbvh{}, "flat/lbvh", fast_bad) == 0);   // box::fast may lose grazed boxes here
    CHECK(check_exact(flat, 4000, Sah{}, "flat/binned-sah", fast_bad) == 0);
    // Rays from inside the closed sphere aimed at its vertices and edge midpoints always hit it.
    const auto w = make_wide(lbvh::build(std::span<const Trianglef>(sph), {.leaves = {.max_leaf_size = 2}}));
    std::size_t escaped = 0, rays = 0;
    Rng rng(4);
    for (int o = 0; o < 10; ++o) {
        const Vec3f org{rng.uniform(-0.5f, 0.5f), rng.uniform(-0.5f, 0.5f), rng.uniform(-0.5f, 0.5f)};
        for (const auto& t : sph)
            for (const Vec3f& target : {t.p0, (t.p0 + t.p1) * 0.5f, (t.p1 + t.p2) * 0.5f}) {
                ++rays;
                escaped += intersect(w, sph, Rayf{org, target - org}) ? 0 : 1;
            }
    }
    MESSAGE(rays << " rays from inside the sphere at vertices and edges, " << escaped << " escaped");
    CHECK(escaped == 0);
}

TEST_CASE("axis-parallel rays with +-0 components through vertices, from everywhere") {
    // A grid of axis-aligned triangles whose vertices share coordinates with many box faces.
    std::vector<Trianglef> tris;
    for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) {
            const float x = float(i), y = float(j), z = float((i * 7 + j * 3) % 5);
            tris.push_back({{x, y, z}, {x + 1, y, z}, {x, y + 1, z}});
            tris.push_back({{x, y, z}, {x, y, z + 1}, {x + 1, y, z + 1}});
        }
    const std::span<const Trianglef> ts(tris);
    const auto w = make_wide(binned_sah::build(ts, {.leaves = {.max_leaf_size = 2}}));
    const auto b = binned_sah::build(ts, {.leaves = {.max_leaf_size = 2}});
    std::size_t bad = 0, hits = 0, n = 0;
    for (const auto& t : tris)
        for (const Vec3f& v : {t.p0, t.p1, t.p2, (t.p0 + t.p1) * 0.5f})
            for (int a = 0; a < 3; ++a)
                for (const float s : {1.0f, -1.0f})
                    for (const float z : {0.0f, -0.0f}) {
                        Rayf r;
                        r.org = v;
                        r.org[std::size_t(a)] = s > 0 ? -5.0f : 20.0f;
                        r.dir = {z, z, z};
                        r.dir[std::size_t(a)] = s;
                        const Hitf h = intersect(w, ts, r), e = brute_force_intersect(ts, r), hb = intersect(b, ts, r);
                        ++n;
                        hits += e ? 1 : 0;
                        if (!same_hit<tri::watertight>(h, e, ts, r) || !same_hit<tri::watertight>(h, hb, ts, r) ||
                            occluded(w, ts, r) != bool(e)) {
                            if (bad++ < 5) MESSAGE(describe(r, h, e));
                        }
                    }
    MESSAGE(n << " axis rays through vertices and edges, " << hits << " hit");
    CHECK(hits > n / 2);
    CHECK(bad == 0);
}

TEST_CASE("trees deeper than max_depth and a wrong depth field: heap stack, same answers") {
    const int levels = 600;
    const std::vector<Trianglef> tris = test::stacked_triangles(levels);
    const std::span<const Trianglef> ts(tris);
    const auto deep = test::caterpillar_build<Node<>, prim::indexed>(ts);
    auto check = [&](auto w) {
        CHECK(wide_problems(deep, w, ts) == "");
        MESSAGE("caterpillar: binary depth " << deep.depth << ", " << w.width << "-wide depth " << w.depth);
        CHECK(w.depth >= max_depth);
        const Rayf down{{0.1f, 0.1f, 1000}, {0, 0, -1}}, up{{0.1f, 0.1f, -1000}, {0, 0, 1}};
        for (int lie = 0; lie < 2; ++lie) {
            if (lie) w.depth = 2;   // a wrong depth field: the fixed stack overflows into the heap retry
            const Hitf a = intersect(w, ts, down), b = intersect(w, ts, up);
            REQUIRE(a);
            REQUIRE(b);
            CHECK(a.prim == std::uint32_t(levels - 1));
            CHECK(a.t == 1000.0f - float(levels - 1));
            CHECK(b.prim == 0);
            CHECK(b.t == 1000.0f);
            CHECK(occluded(w, ts, down));
        }
    };
    check(make_wide(deep));
    check(make_wide<8>(deep));
}

TEST_CASE("real data: cloth-ball frame, wide == binary on camera rays") {
    const std::string path = test::data_path("unc/cloth_ball92.ply");
    if (!test::have_data("unc/cloth_ball92.ply")) {
        MESSAGE("skipped: " << path << " not found");
        return;
    }
    const auto mesh = io::read_ply(path);
    const auto tris = mesh.triangles();
    const std::span<const Trianglef> ts(tris);
    const auto bvh = ploc::build(ts);
    const auto w = make_wide(bvh, exec::default_executor{});
    CHECK(wide_problems(bvh, w, ts) == "");
    const AABBf bb = bvh.bounds();
    Rng rng(11);
    std::size_t bad = 0, hits = 0;
    const std::size_t n = 20000;
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3f org = bb.center() + (bb.max - bb.min) * Vec3f{rng.uniform(-1, 1), rng.uniform(0.5f, 1), rng.uniform(-1, 1)};
        const Vec3f to{rng.uniform(bb.min.x, bb.max.x), rng.uniform(bb.min.y, bb.max.y), rng.uniform(bb.min.z, bb.max.z)};
        const Rayf r{org, to - org};
        const Hitf h = intersect(w, ts, r), e = intersect(bvh, ts, r);
        hits += e ? 1 : 0;
        if (!same_hit<tri::watertight>(h, e, ts, r) || occluded(w, ts, r) != bool(e)) {
            if (bad++ < 5) MESSAGE(describe(r, h, e));
        }
    }
    MESSAGE(n << " rays, " << hits << " hit");
    CHECK(hits > n / 10);
    CHECK(bad == 0);
}
