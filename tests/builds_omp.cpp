// Explicit instantiations of tests/builds.hpp for exec::omp (one file per executor, so that they compile in parallel).
#include "builds.hpp"

#if defined(_OPENMP)
DYNBVH_TEST_BUILDS(, dynbvh::exec::omp)
#endif
