#!/usr/bin/env bash
# The README's second command: installs what is missing, builds what is stale (library, tools
# and tests), and runs the test suite (docs/testing.md).
#
#   scripts/test.sh [CTEST ARGS...]          the fast suite: every test not labelled full (minutes)
#   scripts/test.sh --full [CTEST ARGS...]   every test: the fast suite and the full tier (the quick
#                                            tiers of claims and paper, the thorough Slurm check, ...)
#
# Further arguments go to ctest (-R NAME, -L LABEL, ...).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${PBDBENCH_BUILD_DIR:-$root/build}"
select=(-LE full)
if [[ ${1:-} == --full ]]; then
  select=()
  shift
fi
"$root/scripts/build.sh"
# The fuzz target's own build (clang, sanitizers) in build-fuzz/, for the short fuzzing test.
"$root/scripts/fuzz.sh" --build-only
jobs=$(nproc 2>/dev/null || echo 2)
ctest --test-dir "$build" -j "$jobs" --output-on-failure --timeout 900 "${select[@]}" "$@"
