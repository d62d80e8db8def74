// Explicit instantiations of tests/builds.hpp for exec::serial (one file per executor, so that they compile in parallel).
#include "builds.hpp"

DYNBVH_TEST_BUILDS(, dynbvh::exec::serial)

// the executor-independent ones live here too
DYNBVH_TEST_QUERIES(, dynbvh::prim::indexed)
DYNBVH_TEST_QUERIES(, dynbvh::prim::copied)
