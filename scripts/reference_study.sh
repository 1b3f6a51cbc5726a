#!/usr/bin/env bash
# The reference study: every scene of studies/reference/*.toml run by its reference integrator
# (ref-bdf, or ref-dae for rigid links), by ref-be and by the PBD solvers, then each run compared
# with the reference (`pbdbench compare`): one compare file and one plot per run, and a table of
# the gaps. Runs and comparisons already made by the same build are reused.
#
#   scripts/reference_study.sh [STUDY ...]      (default: all; e.g. hanging_chain spring)
#
# Output: results/reference/<study>/ (run files, compare-*.h5, compare-*.png), and the table on
# the terminal. hanging_cloth's ref-bdf run costs a few minutes.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${PBDBENCH_BUILD_DIR:-$root/build}"
out="${PBDBENCH_REFERENCE_DIR:-$root/results/reference}"

"$root/scripts/build.sh" pbdbench
jobs=$(nproc 2>/dev/null || echo 2)

studies=("$@")
if [[ ${#studies[@]} -eq 0 ]]; then
  for f in "$root"/studies/reference/*.toml; do studies+=("$(basename "$f" .toml)"); done
fi

for name in "${studies[@]}"; do
  sweep="$root/studies/reference/$name.toml"
  [[ -f "$sweep" ]] || { echo "reference_study.sh: no study $sweep" >&2; exit 2; }
  dir="$out/$name"
  "$build/pbdbench" sweep "$sweep" --out "$dir" --jobs "$jobs" --quiet
  # The reference: the run of the study's first case (ref-bdf or ref-dae).
  ref=""
  for candidate in "$dir"/solver.name-ref-bdf.h5 "$dir"/solver.name-ref-dae.h5; do
    if [[ -f "$candidate" ]]; then ref=$candidate; break; fi
  done
  [[ -n "$ref" ]] || { echo "reference_study.sh: $name has no ref-bdf or ref-dae run" >&2; exit 1; }
  for run in "$dir"/solver.name-*.h5; do
    [[ "$run" == "$ref" ]] && continue
    stem=$(basename "$run" .h5)
    cmp="$dir/compare-$stem.h5"
    if [[ ! -f "$cmp" || "$cmp" -ot "$run" || "$cmp" -ot "$ref" ]]; then
      "$build/pbdbench" compare "$run" "$ref" --out "$cmp" --plot "$dir/compare-$stem.png" >"$dir/compare-$stem.txt"
    fi
  done
done

/usr/bin/python3 "$root/scripts/summarize_compare.py" "${studies[@]/#/$out/}"
