#!/usr/bin/env bash
# Fails when a public name in include/dynbvh/ (outside detail/ and namespaces named detail) has no ///
# comment, or a comment Doxygen cannot parse: runs docs/Doxyfile with the warnings to a log and fails on
# any. Usage: tools/check_api_docs.sh [OUT_DIR]   (default build/docs-check; needs doxygen, tools/deps.sh)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/build/docs-check}
mkdir -p "$out"
log=$out/doxygen-warnings.log
rm -f "$log"
cd "$root"
# The README is the reference's main page for users; the check concerns the headers alone.
{ cat docs/Doxyfile
  echo "OUTPUT_DIRECTORY = $out"
  echo "INPUT = include/dynbvh"
  echo "USE_MDFILE_AS_MAINPAGE ="
  echo "WARN_LOGFILE = $log"
} | doxygen - >"$out/doxygen.out" 2>&1 || { cat "$out/doxygen.out"; echo "check_api_docs: doxygen failed" >&2; exit 1; }
if [ -s "$log" ]; then
  sed "s|$root/||" "$log"
  echo "check_api_docs: $(grep -c 'warning:' "$log") Doxygen warning(s) (undocumented public names above); add a short /// comment to each" >&2
  exit 1
fi
echo "check_api_docs: every public name in include/dynbvh is documented"
