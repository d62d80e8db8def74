// The builder, traversal and validation instantiations most test files use, compiled once (tests/builds_*.cpp, in the test main
// library) instead of once per test file: each is a few seconds of compile time per executor at -O3 and
// tens of seconds under AddressSanitizer. A test that includes this header links those copies; other
// instantiations (other node types, configs with other template arguments) are compiled where used.
#pragma once

#include <dynbvh/binned_sah.hpp>
#include <dynbvh/executor.hpp>
#include <dynbvh/kbvh.hpp>
#include <dynbvh/lbvh.hpp>
#include <dynbvh/ploc.hpp>
#include <dynbvh/traverse.hpp>
#include <dynbvh/validate.hpp>

// X is `extern` (declaration) or empty (definition); E an executor type.
#define DYNBVH_TEST_BUILDS(X, E)                                                                                        \
    X template dynbvh::Bvh<dynbvh::Node<>, dynbvh::prim::indexed> dynbvh::lbvh::build<dynbvh::Node<>, dynbvh::prim::indexed, E>( \
        std::span<const dynbvh::Trianglef>, const dynbvh::lbvh::Config&, const E&);                                      \
    X template dynbvh::Bvh<dynbvh::Node<>, dynbvh::prim::copied>                                                   \
    dynbvh::lbvh::build<dynbvh::Node<>, dynbvh::prim::copied, E>(std::span<const dynbvh::Trianglef>,               \
                                                                       const dynbvh::lbvh::Config&, const E&);            \
    X template dynbvh::Bvh<dynbvh::Node<>, dynbvh::prim::indexed> dynbvh::ploc::build<dynbvh::Node<>, dynbvh::prim::indexed, E>( \
        std::span<const dynbvh::Trianglef>, const dynbvh::ploc::Config&, const E&);                                      \
    X template dynbvh::Bvh<dynbvh::Node<>, dynbvh::prim::copied>                                                   \
    dynbvh::ploc::build<dynbvh::Node<>, dynbvh::prim::copied, E>(std::span<const dynbvh::Trianglef>,               \
                                                                       const dynbvh::ploc::Config&, const E&);            \
    X template dynbvh::Bvh<dynbvh::Node<>, dynbvh::prim::indexed>                                                       \
    dynbvh::kbvh::build<dynbvh::Node<>, dynbvh::prim::indexed, dynbvh::kbvh::with_ploc, E>(                              \
        std::span<const dynbvh::Trianglef>, const dynbvh::kbvh::Config<dynbvh::kbvh::with_ploc>&, const E&);            \
    X template dynbvh::Bvh<dynbvh::Node<>, dynbvh::prim::indexed>                                                       \
    dynbvh::kbvh::build<dynbvh::Node<>, dynbvh::prim::indexed, dynbvh::kbvh::with_lbvh, E>(                              \
        std::span<const dynbvh::Trianglef>, const dynbvh::kbvh::Config<dynbvh::kbvh::with_lbvh>&, const E&);            \
    X template dynbvh::Bvh<dynbvh::Node<>, dynbvh::prim::indexed>                                                       \
    dynbvh::binned_sah::build<dynbvh::Node<>, dynbvh::prim::indexed, E>(std::span<const dynbvh::Trianglef>,             \
                                                                         const dynbvh::binned_sah::Config&, const E&);

DYNBVH_TEST_BUILDS(extern, dynbvh::exec::serial)
#if defined(_OPENMP)
DYNBVH_TEST_BUILDS(extern, dynbvh::exec::omp)
#endif
#if defined(DYNBVH_WITH_TBB)
DYNBVH_TEST_BUILDS(extern, dynbvh::exec::tbb)
#endif

namespace dynbvh::test_builds {
using fast_box_watertight = trace::policy<box::fast, tri::watertight>;
}

// Traversal with the three policies the tests compare, and validation, for both primitive policies.
#define DYNBVH_TEST_TRAVERSAL(X, P, Policy)                                                                            \
    X template dynbvh::Hit<float> dynbvh::intersect<Policy, dynbvh::Node<>, P>(                                         \
        const dynbvh::Bvh<dynbvh::Node<>, P>&, std::span<const dynbvh::Trianglef>, const dynbvh::Rayf&);                 \
    X template bool dynbvh::occluded<Policy, dynbvh::Node<>, P>(const dynbvh::Bvh<dynbvh::Node<>, P>&,                  \
                                                               std::span<const dynbvh::Trianglef>, const dynbvh::Rayf&);
#define DYNBVH_TEST_QUERIES(X, P)                                                                                       \
    DYNBVH_TEST_TRAVERSAL(X, P, dynbvh::trace::robust)                                                                  \
    DYNBVH_TEST_TRAVERSAL(X, P, dynbvh::trace::fast)                                                                    \
    DYNBVH_TEST_TRAVERSAL(X, P, dynbvh::test_builds::fast_box_watertight)       \
    X template dynbvh::ValidationReport dynbvh::validate<dynbvh::Node<>, P>(                                            \
        const dynbvh::Bvh<dynbvh::Node<>, P>&, std::span<const dynbvh::Trianglef>, const dynbvh::ValidateConfig&);

DYNBVH_TEST_QUERIES(extern, dynbvh::prim::indexed)
DYNBVH_TEST_QUERIES(extern, dynbvh::prim::copied)
