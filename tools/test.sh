#!/usr/bin/env bash
# Runs every dynbvh test: a -Werror build with all backends (serial, OpenMP, TBB), then the
# same tests under AddressSanitizer + UndefinedBehaviorSanitizer. Installs what it needs.
# Usage: tools/test.sh            (from anywhere; build trees go to build/test and build/asan)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
bash tools/deps.sh
jobs=$(nproc)
common=(-DDYNBVH_BUILD_TESTS=ON -DDYNBVH_BUILD_BENCH=ON -DDYNBVH_BUILD_EXAMPLES=ON -DDYNBVH_WERROR=ON)

echo "== dynbvh tests (Release, -Werror) =="
# -O2, not -O3: the warnings that need optimisation (uninitialised use, bounds) come from -O2 on (the
# examples are built so); the tests themselves are built at -O1 (DYNBVH_TEST_OPT), and the bench
# executables and the study, which this build only compiles and runs on tiny scenes, at -O0
# (DYNBVH_BENCH_OPT: CI time). Timings come from tools/study.sh's -O3 build, never from this one.
# -march=native: the AVX 8-wide node test where this CPU has AVX; the sanitizer build below is portable
# (SSE), so both paths are tested.
cmake -S . -B build/test -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O2 -DNDEBUG" -DDYNBVH_NATIVE=ON -DDYNBVH_BENCH_OPT=-O0 \
  "${common[@]}" >/dev/null
cmake --build build/test -j"$jobs"
(cd build/test && ctest --output-on-failure -j"$jobs")

echo "== dynbvh tests under AddressSanitizer + UndefinedBehaviorSanitizer =="
cmake -S . -B build/asan -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O0 -g1" -DDYNBVH_SANITIZE=ON \
  -DDYNBVH_BUILD_TESTS=ON -DDYNBVH_BUILD_BENCH=OFF -DDYNBVH_BUILD_EXAMPLES=OFF -DDYNBVH_WERROR=ON >/dev/null
cmake --build build/asan -j"$jobs"
(cd build/asan && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  DYNBVH_SANITIZED=1 ctest --output-on-failure -j"$jobs")
