#!/usr/bin/env bash
# One command to watch a scene: runs it (with its own solver, or with each solver named) and
# animates the runs side by side (scripts/animate.py), with a summary that names any failure by
# its symptom (metrics/health.hpp, docs/failures.md).
#
#   scripts/watch.sh SCENARIO [SOLVER ...] [-- --set KEY=VALUE ...]
#   scripts/watch.sh --failures          every scene of scenarios/failures/, one video each, then
#                                        what the summary named for each
#
# Output in ${PBDBENCH_WATCH_DIR:-results/watch}/<scene>/: the run files, their ParaView
# files (RUN.xdmf: open in ParaView) and <scene>.mp4 (or .gif when ffmpeg is missing).
# pbdbench is $PBDBENCH_BIN, or build/pbdbench, or the one on the PATH.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bin="${PBDBENCH_BIN:-}"
[[ -z "$bin" && -x "$root/build/pbdbench" ]] && bin="$root/build/pbdbench"
[[ -z "$bin" ]] && bin=$(command -v pbdbench || true)
[[ -n "$bin" ]] || { echo "watch.sh: no pbdbench (build it with scripts/build.sh, or set PBDBENCH_BIN)" >&2; exit 2; }
out_root="${PBDBENCH_WATCH_DIR:-results/watch}"
ext=mp4
command -v ffmpeg >/dev/null || ext=gif

if [[ "${1:-}" == "--failures" ]]; then
  # Each scene, then what the summary named for each (docs/failures.md: the detector each scene
  # trips, or why its failure is not one a run's summary can see).
  status=0
  named=""
  for f in "$root"/scenarios/failures/*.toml; do
    name=$(basename "$f" .toml)
    log=$(mktemp)
    "$0" "$f" | tee "$log" || status=1
    seen=$(sed -n 's/^  run: seen: //p' "$log")
    named+=$(printf '%-24s %s' "$name" "${seen:-no failure named (docs/failures.md says why)}")$'\n'
    rm -f "$log"
  done
  echo
  echo "What the summary named (docs/failures.md):"
  printf '%s' "$named"
  exit $status
fi
[[ $# -ge 1 ]] || { sed -n 2,12p "$0" >&2; exit 2; }

scenario=$1; shift
solvers=(); extra=()
while [[ $# -gt 0 ]]; do
  if [[ "$1" == "--" ]]; then shift; extra=("$@"); break; fi
  solvers+=("$1"); shift
done
name=$(basename "$scenario" .toml)
dir="$out_root/$name"
mkdir -p "$dir"
runs=()
if [[ ${#solvers[@]} -eq 0 ]]; then
  "$bin" run "$scenario" --out "$dir/run.h5" --quiet "${extra[@]}" || true
  runs+=("$dir/run.h5")
else
  for s in "${solvers[@]}"; do
    "$bin" run "$scenario" --solver "$s" --out "$dir/$s.h5" --quiet "${extra[@]}" || true
    runs+=("$dir/$s.h5")
  done
fi
"$bin" summary "${runs[@]}"
PBDBENCH_BIN="$bin" /usr/bin/python3 "$root/scripts/animate.py" "${runs[@]}" -o "$dir/$name.$ext"
