// refit.hpp: refitted boxes are tight after every vertex moves.
#include "support.hpp"

#include <dynbvh/lbvh.hpp>
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
