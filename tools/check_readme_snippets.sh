#!/usr/bin/env bash
# Fails when a ```cpp block of README.md is not in tests/readme_snippets.cpp verbatim, so the README's code
# is the code ctest compiles and runs (test `readme_snippets`). Lines are compared with leading and trailing
# blanks trimmed and blank lines skipped; a block's lines must be consecutive in the test file, except its
# `#include` lines, which may be anywhere in it (compared up to a trailing // comment).
# Usage: tools/check_readme_snippets.sh [README] [SNIPPETS_CPP]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
readme=${1:-$root/README.md}
cpp=${2:-$root/tests/readme_snippets.cpp}
awk -v readme="$readme" -v cpp="$cpp" '
function trim(s) { sub(/^[ \t\r]+/, "", s); sub(/[ \t\r]+$/, "", s); return s }
function include_of(s) { sub(/[ \t]*\/\/.*$/, "", s); return s }
function check_block(   i, k, best, bad) {
    blocks++
    for (k = 1; k <= ninc; k++)
        if (!(inc_block[k] in tu_inc)) {
            printf "%s:%d: %s is not in %s\n", readme, inc_line[k], inc_block[k], cpp; failed++
        }
    if (m == 0) return
    best = 0
    for (i = 1; i + m - 1 <= n; i++) {
        for (k = 1; k <= m && tu[i + k - 1] == sn[k]; k++) {}
        if (k - 1 > best) best = k - 1
        if (best == m) return
    }
    printf "%s:%d: the ```cpp block starting here is not in %s verbatim; first line not found after the lines before it:\n    %s\n", readme, start, cpp, sn[best + 1]
    failed++
}
FNR == NR {
    line = trim($0)
    if (line == "") next
    if (line ~ /^#include/) { tu_inc[include_of(line)] = 1; next }
    tu[++n] = line
    next
}
/^```cpp[ \t]*$/ { inblock = 1; m = 0; ninc = 0; start = FNR + 1; next }
inblock && /^```/ { inblock = 0; check_block(); next }
inblock {
    line = trim($0)
    if (line == "") next
    if (line ~ /^#include/) { inc_block[++ninc] = include_of(line); inc_line[ninc] = FNR; next }
    sn[++m] = line
}
END {
    if (blocks == 0) { printf "%s: no ```cpp block found\n", readme; exit 1 }
    if (failed) { printf "check_readme_snippets: %d of the README'"'"'s checks failed (copy the code from %s, or update it there)\n", failed, cpp; exit 1 }
    printf "check_readme_snippets: all %d ```cpp blocks of %s are in %s\n", blocks, readme, cpp
}' "$cpp" "$readme"
