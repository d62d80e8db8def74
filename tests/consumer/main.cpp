// The core alone (dynbvh::dynbvh), or with the TBB backend (dynbvh::tbb, CONSUMER_TBB): one triangle, one ray.
#include <dynbvh/lbvh.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/version.hpp>

#include <cstdio>
#include <vector>

static_assert(DYNBVH_VERSION_MAJOR == EXPECT_MAJOR && DYNBVH_VERSION_MINOR == EXPECT_MINOR &&
                  DYNBVH_VERSION_PATCH == EXPECT_PATCH,
              "dynbvh/version.hpp differs from the package's version");

int main() {
    std::vector<dynbvh::Trianglef> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
#if defined(CONSUMER_TBB)
    const char* name = "consumer_tbb";
    auto bvh = dynbvh::lbvh::build(tris, {}, dynbvh::exec::tbb{2});
#else
    const char* name = "consumer";
    auto bvh = dynbvh::lbvh::build(tris, {}, dynbvh::exec::serial{});
#endif
    auto hit = dynbvh::intersect(bvh, tris, dynbvh::Rayf{.org = {0.2f, 0.2f, 1}, .dir = {0, 0, -1}});
    const bool ok = hit && hit.prim == 0 && hit.t == 1.0f;
    std::printf("%s: dynbvh %d.%d.%d, hit prim %u at t = %g: %s\n", name, DYNBVH_VERSION_MAJOR, DYNBVH_VERSION_MINOR,
                DYNBVH_VERSION_PATCH, hit.prim, double(hit.t), ok ? "ok" : "WRONG");
    return ok ? 0 : 1;
}
