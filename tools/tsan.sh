#!/usr/bin/env bash
# Runs the dynbvh test suite under ThreadSanitizer.
#
#  1. serial + TBB backends (g++): OpenMP is left out of this build (GCC's libgomp is not instrumented,
#     so TSan reports false races inside every parallel region). Debian's libtbb is not instrumented
#     either, and TSan cannot see the synchronisation inside it (it reports races between tasks of
#     consecutive parallel_for calls), so oneTBB is built once from Debian's source package with
#     -fsanitize=thread into build/tsan-tbb (a few minutes; needs deb-src, which this script adds as
#     /etc/apt/sources.list.d/dynbvh-deb-src.sources) and the tests link that one.
#  2. OpenMP backend (--omp, clang): LLVM's libomp with the Archer OMPT tool (libarcher.so from
#     libomp-14-dev), which tells TSan about OpenMP's synchronisation; only exec::omp is run
#     (DYNBVH_TEST_EXECUTORS=omp).
#
# Usage: tools/tsan.sh [--no-tbb] [--omp] [ctest -R regex]
#   --no-tbb   skip building the instrumented oneTBB: phase 1 runs the serial backend only
#   --omp      also run phase 2
# Counts are the sanitizer ones (DYNBVH_SANITIZED=1). Build trees: build/tsan, build/tsan-omp.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
with_tbb=1 with_omp=0 regex=""
for a in "$@"; do
  case "$a" in
    --no-tbb) with_tbb=0 ;;
    --omp) with_omp=1 ;;
    *) regex=$a ;;
  esac
done
bash tools/deps.sh
jobs=$(nproc)
ctest_args=(--output-on-failure -j"$jobs" -E install_and_find_package)
[ -n "$regex" ] && ctest_args+=(-R "$regex")
export DYNBVH_SANITIZED=1

# --- oneTBB built with -fsanitize=thread ---------------------------------------------------------------
tbb_prefix=$root/build/tsan-tbb/install
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
build_tbb() {
  [ -f "$tbb_prefix/lib/cmake/TBB/TBBConfig.cmake" ] && return 0
  local src=$root/build/tsan-tbb/src
  mkdir -p "$src"
  if ! ls -d "$src"/onetbb-*/ >/dev/null 2>&1; then
    if ! grep -rqs "deb-src" /etc/apt/sources.list /etc/apt/sources.list.d/; then
      echo "tsan: adding Debian's deb-src entries to fetch oneTBB's source" >&2
      sed 's/^Types: deb$/Types: deb-src/' /etc/apt/sources.list.d/debian.sources | $SUDO tee /etc/apt/sources.list.d/dynbvh-deb-src.sources >/dev/null
    fi
    $SUDO apt-get update -qq
    (cd "$src" && apt-get source -qq --download-only onetbb >/dev/null && dpkg-source -x onetbb_*.dsc >/dev/null)
  fi
  local dir
  dir=$(ls -d "$src"/onetbb-*/ | head -1)
  cmake -S "$dir" -B "$root/build/tsan-tbb/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTBB_TEST=OFF -DTBB_EXAMPLES=OFF \
    -DTBB_STRICT=OFF -DTBBMALLOC_BUILD=OFF -DTBB_SANITIZE=thread -DCMAKE_INSTALL_PREFIX="$tbb_prefix" >/dev/null
  cmake --build "$root/build/tsan-tbb/build" -j"$jobs" >/dev/null
  cmake --install "$root/build/tsan-tbb/build" >/dev/null
}

echo "== dynbvh tests under ThreadSanitizer: serial$([ $with_tbb = 1 ] && echo ' + TBB') backends (g++) =="
cfg=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DDYNBVH_TSAN=ON -DCMAKE_DISABLE_FIND_PACKAGE_OpenMP=ON -DDYNBVH_BUILD_TESTS=ON
     -DDYNBVH_BUILD_BENCH=OFF -DDYNBVH_BUILD_EXAMPLES=OFF -DDYNBVH_WERROR=ON)
if [ $with_tbb = 1 ]; then
  build_tbb
  cfg+=(-DTBB_DIR="$tbb_prefix/lib/cmake/TBB")
  executors=serial,tbb
  ldpath=$tbb_prefix/lib
else
  cfg+=(-DCMAKE_DISABLE_FIND_PACKAGE_TBB=ON)
  executors=serial
  ldpath=
fi
cmake -S . -B build/tsan "${cfg[@]}" >/dev/null
cmake --build build/tsan -j"$jobs"
(cd build/tsan && LD_LIBRARY_PATH=$ldpath${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH} DYNBVH_TEST_EXECUTORS=$executors \
  TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" ctest "${ctest_args[@]}")

if [ $with_omp = 1 ]; then
  echo "== dynbvh tests under ThreadSanitizer: OpenMP backend (clang, libomp + Archer) =="
  archer=$(ls /usr/lib/llvm-*/lib/libarcher.so 2>/dev/null | head -1)
  [ -n "$archer" ] || { echo "tsan: libarcher.so not found (apt-get install libomp-14-dev)" >&2; exit 2; }
  cmake -S . -B build/tsan-omp -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDYNBVH_TSAN=ON \
    -DCMAKE_DISABLE_FIND_PACKAGE_TBB=ON -DDYNBVH_BUILD_TESTS=ON -DDYNBVH_BUILD_BENCH=OFF -DDYNBVH_BUILD_EXAMPLES=OFF \
    -DDYNBVH_WERROR=OFF >/dev/null
  cmake --build build/tsan-omp -j"$jobs"
  (cd build/tsan-omp && DYNBVH_TEST_EXECUTORS=omp OMP_TOOL_LIBRARIES=$archer \
    TSAN_OPTIONS="halt_on_error=1 ignore_noninstrumented_modules=1" ctest "${ctest_args[@]}")
fi
