#!/usr/bin/env bash
# Builds the libFuzzer targets for the PLY, OBJ and BART loaders with Debian's clang (ASan + UBSan)
# and runs each for a bounded time, starting from the seed corpus in fuzz/corpus/<format>/ (which is
# never modified: new inputs go to build/fuzz/corpus/<format>/).
#
# Usage: fuzz/run.sh [seconds per target, default 60] [targets: ply obj bart]
#   env: CXX_FUZZ    clang++ to use (default: clang++, else clang++-14)
#        FUZZ_JOBS   parallel fuzzing processes per target (default 1)
#        FUZZ_TINYOBJ_SOURCE=1  compile tinyobjloader's implementation into the OBJ fuzzer (instrumented)
#                   instead of linking Debian's -ltinyobjloader
# Prints, per target, the executions and the crashes (reproducers in build/fuzz/crashes/<format>/);
# exits 1 when any target crashed. Reproduce one with: build/fuzz/fuzz_<format> <file>.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(ply obj bart)
cxx=${CXX_FUZZ:-}
if [ -z "$cxx" ]; then
  if command -v clang++ >/dev/null; then cxx=clang++; elif command -v clang++-14 >/dev/null; then cxx=clang++-14; else
    echo "fuzz: clang++ not found (apt-get install clang libclang-rt-14-dev)" >&2; exit 2; fi
fi
out=$root/build/fuzz
mkdir -p "$out"
flags=(-std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined -I "$root/include")

build() {
  local t=$1 src=$root/fuzz/fuzz_$1.cpp bin=$out/fuzz_$1 extra=()
  if [ "$t" = obj ]; then
    if [ "${FUZZ_TINYOBJ_SOURCE:-0}" = 1 ]; then
      printf '#define TINYOBJLOADER_IMPLEMENTATION\n#include <tiny_obj_loader.h>\n' > "$out/tinyobj_impl.cpp"
      extra=("$out/tinyobj_impl.cpp")
    else
      extra=(-ltinyobjloader)
    fi
  fi
  # Rebuilt when the source or a header it includes (listed in $bin.d by -MMD) is newer.
  local stale=1
  if [ -x "$bin" ] && [ -f "$bin.d" ]; then
    stale=0
    for f in $(sed -e 's/^[^:]*://' -e 's/\\$//' "$bin.d"); do
      if [ "$f" -nt "$bin" ]; then stale=1; break; fi
    done
  fi
  if [ $stale = 1 ]; then
    echo "fuzz: building $bin" >&2
    "$cxx" "${flags[@]}" -MMD -MF "$bin.d" "$src" "${extra[@]}" -o "$bin"
  fi
}

# The targets compile in parallel (each takes tens of seconds), then fuzz one after another.
pids=()
for t in "${targets[@]}"; do build "$t" & pids+=($!); done
for p in "${pids[@]}"; do wait "$p"; done

status=0
summary=()
for t in "${targets[@]}"; do
  work=$out/corpus/$t crashes=$out/crashes/$t log=$out/fuzz_$t.log
  mkdir -p "$work" "$crashes"
  dict=()
  [ -f "$root/fuzz/$t.dict" ] && dict=(-dict="$root/fuzz/$t.dict")
  jobs=()
  # several processes: their logs go to fuzz-<n>.log in the current directory (build/fuzz)
  [ "${FUZZ_JOBS:-1}" -gt 1 ] && jobs=(-jobs="$FUZZ_JOBS" -workers="$FUZZ_JOBS") && rm -f "$out"/fuzz-*.log
  before=$(find "$crashes" -type f | wc -l)
  start=$(date +%s)
  # -rss_limit_mb / -malloc_limit_mb: an input that allocates gigabytes is a bug too.
  set +e
  cd "$out"
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$out/fuzz_$t" "$work" "$root/fuzz/corpus/$t" "${dict[@]}" -max_total_time="$seconds" -timeout=10 \
      -rss_limit_mb=2048 -malloc_limit_mb=1024 -max_len=16384 -print_final_stats=1 "${jobs[@]}" \
      -artifact_prefix="$crashes/" >"$log" 2>&1
  rc=$?
  cd "$root"
  set -e
  wall=$(( $(date +%s) - start ))
  logs=("$log")
  [ ${#jobs[@]} -gt 0 ] && logs+=("$out"/fuzz-*.log)
  execs=$(cat "${logs[@]}" 2>/dev/null | awk '/stat::number_of_executed_units/ {s += $2} END {print s + 0}')
  after=$(find "$crashes" -type f | wc -l)
  new=$((after - before))
  if [ $rc -ne 0 ] || [ $new -gt 0 ]; then
    status=1
    echo "fuzz: $t FAILED (exit $rc): see $log and $crashes/" >&2
    grep -m 5 -E 'ERROR|runtime error|==[0-9]+==|SUMMARY|Test unit written' "$log" >&2 || true
  fi
  summary+=("$(printf '%-5s %9s executions in %4ss, crashes: %s (corpus: %s inputs)' "$t" "$execs" "$wall" "$new" "$(find "$work" -type f | wc -l)")")
done
echo "== fuzzing summary (${seconds}s per target) =="
printf '%s\n' "${summary[@]}"
exit $status
