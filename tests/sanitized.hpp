// Whether the tests run under the sanitizers, and the smaller workloads they use there.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdlib>

namespace dynbvh::test {

/// True in the sanitizer runs (tools/test.sh and tools/tsan.sh set DYNBVH_SANITIZED): use smaller counts.
inline bool sanitized() { return std::getenv("DYNBVH_SANITIZED") != nullptr; }

/// `n` in the optimised run; `n / div` (at least 1) under the sanitizers, whose unoptimised builds
/// check memory and undefined behaviour on fewer rays while the optimised run checks every answer.
inline std::size_t sanitizer_scaled(std::size_t n, std::size_t div = 4) { return sanitized() ? std::max<std::size_t>(n / div, 1) : n; }

} // namespace dynbvh::test
