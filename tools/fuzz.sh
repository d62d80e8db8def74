#!/usr/bin/env bash
# Fuzzes the PLY, OBJ and BART loaders with libFuzzer (Debian's clang, ASan + UBSan) for a bounded
# time per target, starting from fuzz/corpus/; installs clang and its runtime when missing.
# Usage: tools/fuzz.sh [seconds per target, default 60] [targets: ply obj bart]
# Exit status 1 when any target crashed (reproducers in build/fuzz/crashes/<format>/).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
# clang and its fuzzer runtime, with what the tests need (tinyobjloader for the OBJ target)
bash "$root/tools/deps.sh" clang libclang-rt-14-dev
exec bash "$root/fuzz/run.sh" "$@"
