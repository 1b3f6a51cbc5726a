#!/usr/bin/env bash
# Installs what is missing (Debian packages only), configures build/ once, and builds what is
# stale. Arguments are CMake targets (default: everything). A second run costs a dpkg-query and
# a no-op build.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${PBDBENCH_BUILD_DIR:-$root/build}"

"$root/scripts/install_deps.sh"

if [[ ! -f "$build/CMakeCache.txt" ]]; then
  mkdir -p "$build"
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >"$build/configure.log" 2>&1 || {
    cat "$build/configure.log" >&2
    exit 1
  }
fi

jobs=$(nproc 2>/dev/null || echo 2)
targets=()
for t in "$@"; do targets+=(--target "$t"); done
# Show warnings and errors, not the progress lines.
set +e
cmake --build "$build" -j "$jobs" "${targets[@]}" 2>&1 |
  grep -Ev '^\[ *[0-9]+%\] (Built target|Building|Linking|Recording)|^-- |^Consolidate compiler'
status=${PIPESTATUS[0]}
set -e
exit "$status"
