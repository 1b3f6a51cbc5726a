#!/usr/bin/env bash
# The README's second command: installs what is missing, builds what is stale (library, tools
# and tests), and runs the whole test suite.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${PBDBENCH_BUILD_DIR:-$root/build}"
"$root/scripts/build.sh"
# The fuzz target's own build (clang, sanitizers) in build-fuzz/, for the short fuzzing test.
"$root/scripts/fuzz.sh" --build-only
jobs=$(nproc 2>/dev/null || echo 2)
ctest --test-dir "$build" -j "$jobs" --output-on-failure --timeout 900 "$@"
