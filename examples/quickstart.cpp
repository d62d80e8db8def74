// The one-screen example of the README: build a BVH, trace a ray, measure its SAH.
#include <dynbvh/ploc.hpp>
#include <dynbvh/sah.hpp>
#include <dynbvh/traverse.hpp>

#include <cstdio>
#include <vector>

int main() {
    // Any triangles: here a 100 x 100 grid of quads in the plane z = 0 (20,000 triangles).
    std::vector<dynbvh::Trianglef> tris;
    for (int y = 0; y < 100; ++y)
        for (int x = 0; x < 100; ++x) {
            const dynbvh::Vec3f a{float(x), float(y), 0}, b{float(x + 1), float(y), 0};
            const dynbvh::Vec3f c{float(x + 1), float(y + 1), 0}, d{float(x), float(y + 1), 0};
            tris.push_back({a, b, c});
            tris.push_back({a, c, d});
        }

    auto bvh = dynbvh::ploc::build(tris, {.radius = 5}, dynbvh::exec::default_executor{});
    dynbvh::Rayf ray{.org = {50.5f, 50.25f, 10}, .dir = {0, 0, -1}};
    auto hit = dynbvh::intersect(bvh, tris, ray);          // closest hit
    bool occ = dynbvh::occluded(bvh, tris, ray);           // any hit
    double c = dynbvh::sah_cost(bvh, {.ct = 3, .ci = 2});  // tree quality

    std::printf("hit triangle %u at t = %g (occluded: %d), SAH %.2f, %zu nodes, depth %u\n",
                hit.prim, double(hit.t), int(occ), c, bvh.nodes.size(), bvh.depth);
    return hit && hit.t == 10.0f && occ ? 0 : 1;
}
