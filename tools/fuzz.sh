#!/usr/bin/env bash
# Fuzzes the PLY, OBJ and BART loaders with libFuzzer (Debian's clang, ASan + UBSan) for a bounded
# time per target, starting from fuzz/corpus/; installs clang and its runtime when missing.
# Usage: tools/fuzz.sh [seconds per target, default 60] [targets: ply obj bart]
# Exit status 1 when any target crashed (reproducers in build/fuzz/crashes/<format>/).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
need=()
command -v clang++ >/dev/null || command -v clang++-14 >/dev/null || need+=(clang)
dpkg-query -W -f='${Status}' libclang-rt-14-dev 2>/dev/null | grep -q "install ok installed" || need+=(libclang-rt-14-dev)
dpkg-query -W -f='${Status}' libtinyobjloader-dev 2>/dev/null | grep -q "install ok installed" || need+=(libtinyobjloader-dev)
if [ ${#need[@]} -gt 0 ]; then
  echo "dynbvh: installing ${need[*]}" >&2
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
exec bash "$root/fuzz/run.sh" "$@"
