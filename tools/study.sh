#!/usr/bin/env bash
# The README's main command: installs what the study needs, builds dynbvh-study (Release) and runs the
# quick study on every built-in scene beside Embree (a few minutes at most on 2 cores).
# Usage: tools/study.sh [dynbvh-study options]     e.g. tools/study.sh --full, tools/study.sh --scenes my.ply
#        (with no options: --quick --out out/study)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
bash tools/deps.sh
# -march=native (DYNBVH_NATIVE): the study measures this machine, beside Embree, which picks its AVX2
# kernels at run time; our 8-wide node test needs AVX at compile time.
cmake -S . -B build/release -DCMAKE_BUILD_TYPE=Release -DDYNBVH_BUILD_BENCH=ON -DDYNBVH_NATIVE=ON >/dev/null
cmake --build build/release --target dynbvh-study -j"$(nproc)"
args=("$@")
[ ${#args[@]} -eq 0 ] && args=(--quick --out out/study)
out=out/study
for ((i = 0; i < ${#args[@]}; i++)); do
  case "${args[$i]}" in
    --out) out="${args[$((i + 1))]:-$out}" ;;
    --out=*) out="${args[$i]#--out=}" ;;
  esac
done
has_out=0
for a in "${args[@]}"; do case "$a" in --out|--out=*) has_out=1 ;; esac; done
[ $has_out -eq 0 ] && args+=(--out "$out")
./build/release/bench/study/dynbvh-study "${args[@]}"
case " ${args[*]} " in
  *" --info "*|*" --help "*) ;;
  *) echo "The report is $root/$out/report.md (data: $out/study.json, $out/study.csv)" ;;
esac
