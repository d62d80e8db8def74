// Whether the tests run under the sanitizers, and the smaller workloads they use there.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdlib>

namespace dynbvh::test {

/// True when compiled for the sanitizer runs (DYNBVH_TEST_SANITIZED_BUILD, set by tests/CMakeLists.txt):
/// such builds instantiate fewer combinations of the same code, each one at least once.
#if defined(DYNBVH_TEST_SANITIZED_BUILD)
inline constexpr bool sanitized_build = true;
#else
inline constexpr bool sanitized_build = false;
#endif

/// True in the sanitizer runs (tools/test.sh and tools/tsan.sh set DYNBVH_SANITIZED): use smaller counts.
inline bool sanitized() { return std::getenv("DYNBVH_SANITIZED") != nullptr; }

/// `n` in the optimised run; `n / div` (at least 1) under the sanitizers, whose unoptimised builds
/// check memory and undefined behaviour on fewer rays while the optimised run checks every answer.
inline std::size_t sanitizer_scaled(std::size_t n, std::size_t div = 4) { return sanitized() ? std::max<std::size_t>(n / div, 1) : n; }

} // namespace dynbvh::test
