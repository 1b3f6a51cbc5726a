#!/usr/bin/env bash
# The README's first command: installs what is missing, builds what is stale, runs the default
# study (studies/default/*.toml) on small scenes, writes one HDF5 file per run under
# results/study/, draws the plots as PNG, and prints a table of what was measured.
# Then the seed article's claims, quick tier (claims/: every part's runs with its counterfactual
# variants, each timing group in 3 processes: minutes on two cores, not seconds): their verdicts
# are printed and their report and figures written to results/claims/quick/.
# A second run reuses every run file made by the same build with the same configuration.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${PBDBENCH_BUILD_DIR:-$root/build}"
out="${PBDBENCH_STUDY_DIR:-$root/results/study}"

"$root/scripts/build.sh" pbdbench
jobs=$(nproc 2>/dev/null || echo 2)

for sweep in "$root"/studies/default/*.toml; do
  name=$(basename "$sweep" .toml)
  "$build/pbdbench" sweep "$sweep" --out "$out/$name" --jobs "$jobs"
  echo
done

/usr/bin/python3 "$root/scripts/plot_default_study.py" "$out"

echo
echo "The seed article's claims (quick tier; the full report: build/pbdbench claims -> paper/claims/):"
"$build/pbdbench" claims --tier quick --out "$root/results/claims/quick" 2>/dev/null
