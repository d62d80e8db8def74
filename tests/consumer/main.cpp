#include <dynbvh/lbvh.hpp>
#include <dynbvh/traverse.hpp>
#include <vector>
int main() {
    std::vector<dynbvh::Trianglef> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    auto bvh = dynbvh::lbvh::build(tris, {}, dynbvh::exec::serial{});
    auto hit = dynbvh::intersect(bvh, tris, dynbvh::Rayf{.org = {0.2f, 0.2f, 1}, .dir = {0, 0, -1}});
    return hit && hit.prim == 0 ? 0 : 1;
}
