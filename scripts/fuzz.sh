#!/usr/bin/env bash
# Fuzzes the scenario loader, the mesh readers and the rule language of experiment files
# (tests/fuzz/fuzz_loader.cpp), or whole experiment files (tests/fuzz/fuzz_experiment.cpp, with
# --experiments), with libFuzzer, AddressSanitizer and UndefinedBehaviorSanitizer, built by
# Debian's clang 14 in build-fuzz/.
#
#   scripts/fuzz.sh [SECONDS] [libFuzzer options...]                 # default 60 s
#   scripts/fuzz.sh --build-only                                     # configure and build, do not run
#   scripts/fuzz.sh --experiments [SECONDS | --build-only] [...]     # experiment files
#
# Seeds of fuzz_loader: the catalog (scenarios/, its meshes), the bad-input corpus
# (tests/bad_input/) and the rules of tests/fuzz/make_seeds.py, each file prefixed with the byte
# that selects its reader. Seeds of fuzz_experiment: the experiment files of claims/ and
# reproductions/, and make_seeds.py's (the rules that crashed, endless trial counts). What the
# fuzzer adds to the corpus stays in build-fuzz/corpus/ (corpus-experiments/ for the second), so
# that a second run goes on from there; a crash leaves its input in build-fuzz/ (crash-*, leak-*,
# timeout-*) and the script exits non-zero. fuzz_experiment links the whole experiment engine
# (HDF5, the reference solvers): its first build takes much longer than fuzz_loader's.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${PBDBENCH_FUZZ_BUILD_DIR:-$root/build-fuzz}"
target=fuzz_loader
if [[ "${1:-}" == "--experiments" ]]; then
  target=fuzz_experiment
  shift
fi
"$root/scripts/install_deps.sh"

if [[ ! -f "$build/CMakeCache.txt" ]]; then
  mkdir -p "$build"
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DPBDBENCH_FUZZ=ON -DPBDBENCH_BUILD_TESTS=OFF -DPBDBENCH_BUILD_BENCHMARKS=OFF \
    "-DPBDBENCH_SANITIZE=fuzzer-no-link;address;undefined" >"$build/configure.log" 2>&1 || {
    cat "$build/configure.log" >&2
    exit 1
  }
fi
jobs=$(nproc 2>/dev/null || echo 2)
set +e
cmake --build "$build" -j "$jobs" --target "$target" 2>&1 |
  grep -Ev '^\[ *[0-9]+%\] (Built target|Building|Linking)|^-- |^Consolidate compiler'
status=${PIPESTATUS[0]}
set -e
[[ $status -eq 0 ]] || exit "$status"
[[ "${1:-}" == "--build-only" ]] && exit 0

seconds=60
if [[ $# -gt 0 && "$1" =~ ^[0-9]+$ ]]; then
  seconds=$1
  shift
fi

# A refused input returns at once; 10 s for one input is a hang. Memory: 2 GB at most.
limits=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1)

if [[ "$target" == fuzz_experiment ]]; then
  seeds="$build/seeds-experiments"
  rm -rf "$seeds"
  mkdir -p "$seeds" "$build/corpus-experiments"
  /usr/bin/python3 "$root/tests/fuzz/make_seeds.py" experiments "$seeds"
  find "$root/claims/experiments" "$root/reproductions/experiments" -name '*.toml' -exec cp -t "$seeds" {} +
  cd "$build"
  exec ./tests/fuzz/fuzz_experiment "${limits[@]}" "$@" "$build/corpus-experiments" "$seeds"
fi

# Seeds: one file per catalog file, its first byte the reader (0 scenario, 1 OBJ, 2 TetGen
# .node NUL .ele, 3 Gmsh), and the rules of make_seeds.py (4).
seeds="$build/seeds"
rm -rf "$seeds"
mkdir -p "$seeds" "$build/corpus"
/usr/bin/python3 "$root/tests/fuzz/make_seeds.py" rules "$seeds"
k=0
seed() {  # seed MODE FILE...
  local mode=$1
  shift
  { printf "\\x0$mode"; cat "$@"; } >"$seeds/seed-$k" 2>/dev/null || true
  k=$((k + 1))
}
while IFS= read -r -d '' f; do seed 0 "$f"; done < <(find "$root/scenarios" "$root/tests/bad_input" -name '*.toml' -print0)
while IFS= read -r -d '' f; do seed 1 "$f"; done < <(find "$root/scenarios" "$root/tests/bad_input" -name '*.obj' -print0)
while IFS= read -r -d '' f; do seed 3 "$f"; done < <(find "$root/scenarios" "$root/tests/bad_input" -name '*.msh' -print0)
while IFS= read -r -d '' f; do
  ele="${f%.node}.ele"
  [[ -f "$ele" ]] || continue
  { printf '\x02'; cat "$f"; printf '\x00'; cat "$ele"; } >"$seeds/seed-$k"
  k=$((k + 1))
done < <(find "$root/scenarios" "$root/tests/bad_input" -name '*.node' -print0)

cd "$build"
exec ./tests/fuzz/fuzz_loader "${limits[@]}" "$@" "$build/corpus" "$seeds"
