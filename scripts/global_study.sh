#!/usr/bin/env bash
# The global study: how far PBD's sweeps are from the step that the global solvers solve to
# convergence, and what each costs.
#
#   (a) convergence of one step: `pbdbench converge` on hanging_cloth and cantilever_beam after 30
#       warm-up steps (0.5 s): results/global/converge-<scene>.h5 (and .txt, its table), drawn
#       into results/global/convergence.png (scripts/plot_convergence.py).
#   (b) cost against accuracy: xpbd at 1, 5, 20 and 100 sweeps (one substep) with a
#       global-cholmod shadow (the converged step from the run's own start, every step or every
#       k-th), and global-cholmod, global-cg and global-ceres alone, on hanging_chain,
#       cantilever_beam and hanging_cloth: results/global/<scene>/*.h5, and a Markdown table per
#       scene (scripts/summarize_global.py).
#
#   scripts/global_study.sh
#
# Files already complete are reused (delete one to redo it), so a second run costs only the
# tables. Two jobs run at a time. Where the study departs from a scene's own settings, and why:
#   hanging_cloth, converge: the warm-up runs the scene's xpbd with 10 substeps. After 30 steps of
#     its own single substep the cloth is in a state whose global step global-cholmod does not
#     solve in 200 Newton iterations, and without x* the distances from it mean nothing. The
#     matrix-free CG is left out there: with its Jacobi preconditioner a single step of the
#     64 x 64 cloth costs minutes.
#   hanging_cloth, cost table: 0.15 s (9 steps), the shadow every 2nd step: a global step of the
#     cloth costs seconds, global-ceres's tens of seconds after a few steps.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${PBDBENCH_BUILD_DIR:-$root/build}"
out="${PBDBENCH_GLOBAL_DIR:-$root/results/global}"
py=/usr/bin/python3

"$root/scripts/build.sh" pbdbench
bin="$build/pbdbench"
njobs=2
mkdir -p "$out"
timings="$out/timings.txt"
: >"$timings"
study_start=$EPOCHREALTIME

# Whether a run file is complete (status attribute).
complete() {
  [[ -f "$1" ]] && PYTHONPATH="$root/scripts" "$py" - "$1" <<'EOF' 2>/dev/null
import sys
import runfile
sys.exit(0 if runfile.status_of(sys.argv[1]) == "complete" else 1)
EOF
}

# Records "<name> <seconds> <what happened>" in the timings file.
timed() {
  local name=$1
  shift
  local t0=$EPOCHREALTIME rc=0
  "$@" || rc=$?
  echo "$name $(awk "BEGIN { print $EPOCHREALTIME - $t0 }") $([[ $rc -eq 0 ]] && echo ok || echo "exit $rc")" >>"$timings"
}

# converge SCENE WARMUP [ARGS...]: the convergence file and its table. The file is written at
# the command's end; the table is moved into place only when the command succeeded, so the table
# marks a complete pair.
converge() {
  local scene=$1 warmup=$2
  shift 2
  local stem="$out/converge-$scene"
  if [[ -f "$stem.h5" && -f "$stem.txt" ]]; then
    echo "converge-$scene reused" >>"$timings"
    return 0
  fi
  rm -f "$stem.txt"
  timed "converge-$scene" converge_job "$stem" "$scene" --warmup-steps "$warmup" "$@"
}
converge_job() {
  local stem=$1
  shift
  "$bin" converge "$@" --out "$stem.h5" --quiet >"$stem.txt.tmp" 2>"$stem.log" &&
    mv "$stem.txt.tmp" "$stem.txt"
}

# run SCENE NAME [ARGS...]: one run file, results/global/SCENE/NAME.h5.
run() {
  local scene=$1 name=$2
  shift 2
  local dir="$out/$scene"
  mkdir -p "$dir"
  if complete "$dir/$name.h5"; then
    echo "$scene/$name reused" >>"$timings"
    return 0
  fi
  timed "$scene/$name" "$bin" run "$scene" --out "$dir/$name.h5" --quiet "$@" >"$dir/$name.txt" 2>&1
}

# Starts a job once fewer than $njobs are running.
spawn() {
  while (($(jobs -rp | wc -l) >= njobs)); do wait -n || true; done
  "$@" &
}

# Per scene: simulated time and shadow spacing of the cost table.
declare -A duration=([hanging_chain]=0.5 [cantilever_beam]=0.5 [hanging_cloth]=0.15)
declare -A every=([hanging_chain]=1 [cantilever_beam]=1 [hanging_cloth]=2)

# The longest jobs first, so that the two slots end together.
for solver in global-ceres global-cholmod global-cg; do
  spawn run hanging_cloth "$solver" --solver "$solver" --set solver.substeps=1 \
    --set time.duration="${duration[hanging_cloth]}"
done
spawn converge hanging_cloth 30 --set solver.substeps=10 \
  --methods xpbd-sequential,xpbd-colored,xpbd-jacobi,global-cholmod,global-cg,global-ceres
spawn converge cantilever_beam 30
for scene in hanging_cloth cantilever_beam hanging_chain; do
  for it in 100 20 5 1; do
    spawn run "$scene" "xpbd-it$it" --solver xpbd --set solver.iterations="$it" \
      --set solver.substeps=1 --set solver.order=sequential --set time.duration="${duration[$scene]}" \
      --set shadow.solver=global-cholmod --set shadow.every="${every[$scene]}"
  done
  [[ $scene == hanging_cloth ]] && continue
  for solver in global-cholmod global-cg global-ceres; do
    spawn run "$scene" "$solver" --solver "$solver" --set solver.substeps=1 \
      --set time.duration="${duration[$scene]}"
  done
done
wait

for scene in hanging_cloth cantilever_beam; do
  if [[ -f "$out/converge-$scene.txt" ]]; then
    cat "$out/converge-$scene.txt"
  else
    echo "global_study.sh: converge $scene failed; see $out/converge-$scene.log" >&2
  fi
  echo
done
"$py" "$root/scripts/plot_convergence.py" "$out"/converge-hanging_cloth.h5 \
  "$out"/converge-cantilever_beam.h5 -o "$out/convergence.png"
echo
"$py" "$root/scripts/summarize_global.py" "$out/hanging_chain" "$out/cantilever_beam" "$out/hanging_cloth"
echo
echo "Wall time per job (s; 2 at a time on $(nproc) cores):"
sort "$timings" | awk '{ if ($2 == "reused") printf "  %-32s reused\n", $1; else printf "  %-32s %8.2f  %s\n", $1, $2, $3 ($4 != "" ? " " $4 : "") }'
awk "BEGIN { printf \"Study: %.1f s\\n\", $EPOCHREALTIME - $study_start }"
