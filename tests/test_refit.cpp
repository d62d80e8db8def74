// refit.hpp: refitted boxes are tight after every vertex moves.
#include "hit_compare.hpp"
#include "support.hpp"

#include <dynbvh/lbvh.hpp>
#include <dynbvh/mesh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/refit.hpp>

using namespace dynbvh;
using namespace dynbvh::test;

TEST_CASE("refit: after every triangle moves, each box is the union of its triangles or children") {
    auto tris = sphere(32, 64);
    for_each_executor([&](auto ex) {
        auto bvh = lbvh::build<Node<>, prim::copied>(tris, {}, ex);
        auto moved = tris;
        Rng r(3);
        for (auto& t : moved) {
            const Vec3f d{r.uniform(-0.1f, 0.1f), r.uniform(-0.1f, 0.1f), r.uniform(-0.1f, 0.1f)};
            t.p0 += d; t.p1 += d; t.p2 += d;
        }
        refit(bvh, std::span<const Trianglef>(moved), ex);
        CHECK(structure_problems(bvh, moved) == "");
        // Boxes are tight: each leaf box equals the union of its triangles, each inner the union of its children.
        bool tight = true;
        for (const auto& n : bvh.nodes) {
            AABBf b;
            if (n.is_leaf()) for (auto s = n.index; s < n.index + n.count; ++s) b.extend(moved[bvh.prim_ids[s]].bounds());
            else b = merge(bvh.nodes[n.left()].bounds(), bvh.nodes[n.right()].bounds());
            tight = tight && b == n.bounds();
        }
        CHECK(tight);
    });
}

TEST_CASE("refit_sah: refit's boxes bit for bit, sah_cost's SAH to 1e-12, and the non-finite triangles it read") {
    // An indexed grid mesh, so the MeshView overload is checked against make_triangles' array too.
    std::vector<Vec3f> verts;
    std::vector<std::uint32_t> idx;
    const int n = 40;
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) verts.push_back({float(x), float(y), 0.05f * float((x * 7 + y * 3) % 5)});
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const std::uint32_t a = std::uint32_t(y * (n + 1) + x), b = a + 1, c = a + std::uint32_t(n + 1), d = c + 1;
            idx.insert(idx.end(), {a, b, d, a, d, c});
        }
    const SahCost cost{.ct = 3, .ci = 2};
    for_each_executor([&](auto ex) {
        CAPTURE(executor_name<decltype(ex)>());
        auto moved = verts;
        Rng r(5);
        for (auto& v : moved) v += Vec3f{r.uniform(-2.f, 2.f), r.uniform(-2.f, 2.f), r.uniform(-2.f, 2.f)};
        const auto tris = make_triangles(std::span<const Vec3f>(verts), std::span<const std::uint32_t>(idx)),
                   now = make_triangles(std::span<const Vec3f>(moved), std::span<const std::uint32_t>(idx));
        auto a = ploc::build<Node<>, prim::indexed>(std::span<const Trianglef>(tris), {}, ex);
        auto b = a, c = a;
        refit(a, std::span<const Trianglef>(now), ex);
        const RefitReport rb = refit_sah(b, std::span<const Trianglef>(now), cost, ex);
        const RefitReport rc = refit_sah(c, MeshView<float>(std::span<const Vec3f>(moved), std::span<const std::uint32_t>(idx)), cost, ex);
        bool same = a.nodes.size() == b.nodes.size();
        for (std::size_t i = 0; same && i < a.nodes.size(); ++i)
            same = a.nodes[i].bounds() == b.nodes[i].bounds() && a.nodes[i].bounds() == c.nodes[i].bounds();
        CHECK(same);
        const double want = sah_cost(a, cost, ex);
        CHECK(want > 0);
        CHECK(rb.sah == doctest::Approx(want).epsilon(1e-12));
        CHECK(same_bits(rb.sah, rc.sah));
        CHECK(rb.nonfinite == 0);
        // Two triangles turn non-finite (a NaN and an infinite vertex): counted, every other box still refitted.
        auto bad = now;
        bad[7].p1.x = std::numeric_limits<float>::quiet_NaN();
        bad[100].p2.z = std::numeric_limits<float>::infinity();
        CHECK(refit_sah(b, std::span<const Trianglef>(bad), cost, ex).nonfinite == 2);
        // Mismatched sizes throw and leave the tree as it was.
        const auto before = b.nodes;
        CHECK_THROWS_AS(refit_sah(b, std::span<const Trianglef>(now).first(now.size() - 1), cost, ex), std::invalid_argument);
        CHECK(b.nodes.size() == before.size());
    });
    // An empty tree: SAH 0.
    Bvh<> empty;
    CHECK(refit_sah(empty, std::span<const Trianglef>()).sah == 0);
}
