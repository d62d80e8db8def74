#!/usr/bin/env bash
# Installs the Debian packages dynbvh's tests, benchmarks and study use, when missing.
# Usage: tools/deps.sh [extra packages...]   (needs root or sudo; does nothing when all are present)
set -euo pipefail
# clang + libomp-dev (clang's omp.h): the strict-warnings check compiles the headers with clang++ too.
pkgs=(g++ clang libomp-dev cmake make doctest-dev libtbb-dev libtinyobjloader-dev libbenchmark-dev libembree-dev libstb-dev libcli11-dev nlohmann-json3-dev doxygen "$@")
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "dynbvh: installing ${missing[*]}" >&2
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
