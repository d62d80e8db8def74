// Builds with exec::omp or exec::tbb (-DUSE_OMP / -DUSE_TBB). tests/compile_fail/check.cmake compiles it
// without the backend, where it must fail with the static_assert that says what to link, and with the
// backend, where it must compile (so the failure is the missing backend, not a mistake in this file).
#include <dynbvh/lbvh.hpp>

#include <vector>

int main() {
    const std::vector<dynbvh::Trianglef> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
#if defined(USE_OMP)
    const auto bvh = dynbvh::lbvh::build(tris, {}, dynbvh::exec::omp{2});
#elif defined(USE_TBB)
    const auto bvh = dynbvh::lbvh::build(tris, {}, dynbvh::exec::tbb{2});
#endif
    return bvh.nodes.empty() ? 1 : 0;
}
