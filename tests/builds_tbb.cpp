// Explicit instantiations of tests/builds.hpp for exec::tbb (one file per executor, so that they compile in parallel).
#include "builds.hpp"

#if defined(DYNBVH_WITH_TBB)
DYNBVH_TEST_BUILDS(, dynbvh::exec::tbb)
#endif
