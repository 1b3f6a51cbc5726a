#!/usr/bin/env bash
# pbdbench on a real Slurm: starts a single-node cluster on this machine (munged, slurmctld and
# slurmd from Debian's munge and slurm-wlm, on free localhost ports, every file in a temporary
# folder), runs commands through it as job arrays with their merge, compares each with the same
# command run locally (verdicts and non-timing numbers identical: scripts/compare_results.py),
# cancels a task of one array to check that the merge fails naming that shard and that
# resubmitting redoes only it, prints the times, and stops the daemons it started.
#
#   scripts/slurm_check.sh [--install] [--small] [--shards N] [--keep]
#
# What it runs through Slurm:
#   (default, the thorough check: the test suite's full tier, slurm_check_full)
#     the quick tiers of `paper` and `claims`, the quick regression and the default study's chain
#     sweep, each as a job array compared with a local run; the cancelled task on `claims`.
#   --small (the fast suite's slurm_check, seconds once the daemons are up)
#     one small experiment (a reproduction of three runs, one of six seeded trials, and a timing
#     group, on 0.1 s of the hanging chain, written here) and a small sweep (the default study's
#     chain sweep, 22 runs, shortened to 0.25 s), each as a job array compared with a local run;
#     the cancelled task on that experiment.
#
# --install: install munge and slurm-wlm with apt-get when missing (also PBDBENCH_SLURM_INSTALL=1);
# without it, a machine without them skips the check (exit 77). Needs root (slurmd runs the jobs).
# --shards N: tasks per array (default 4; 2 with --small). --keep: keep the work folder.
# PBDBENCH_BIN: the pbdbench to check (default: build/pbdbench, built first). Results and logs go
# to results/slurm_check/ (PBDBENCH_SLURM_CHECK_DIR). Exit 0 when everything agrees, 1 when not.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
install=${PBDBENCH_SLURM_INSTALL:-0} shards= keep=0 small=0
while [[ $# -gt 0 ]]; do
  case $1 in
    --install) install=1 ;;
    --small) small=1 ;;
    --shards) shards=$2; shift ;;
    --keep) keep=1 ;;
    *) echo "usage: $0 [--install] [--small] [--shards N] [--keep]" >&2; exit 2 ;;
  esac
  shift
done
if [[ -z $shards ]]; then if [[ $small == 1 ]]; then shards=2; else shards=4; fi; fi

say() { echo "slurm_check: $*"; }
if [[ $(id -u) -ne 0 ]]; then say "skipped: needs root to run slurmd"; exit 77; fi
missing=()
for cmd in munged slurmctld slurmd sbatch; do command -v $cmd >/dev/null || missing+=("$cmd"); done
if [[ ${#missing[@]} -gt 0 ]]; then
  if [[ $install != 1 ]]; then say "skipped: ${missing[*]} not installed (--install installs munge and slurm-wlm)"; exit 77; fi
  say "installing munge and slurm-wlm"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq && apt-get install -y -qq --no-install-recommends munge slurm-wlm >/dev/null
fi

if [[ -z ${PBDBENCH_BIN:-} ]]; then
  "$root/scripts/build.sh" pbdbench >/dev/null
  PBDBENCH_BIN=$root/build/pbdbench
fi
bin=$PBDBENCH_BIN
work=${PBDBENCH_SLURM_CHECK_DIR:-$root/results/slurm_check}
rm -rf "$work"
mkdir -p "$work"
cd "$work"

# --- A one-node cluster, all of it under $cluster --------------------------------------------
cluster=$(mktemp -d /tmp/pbdbench-slurm.XXXXXX)
chmod 755 "$cluster"
mkdir -p "$cluster"/{munge,state,spool,log}
chmod 700 "$cluster/munge"
started=()
stop() {
  local f
  for f in "${started[@]}"; do
    [[ -f $f ]] && kill "$(cat "$f")" 2>/dev/null || true
  done
  sleep 1
  for f in "${started[@]}"; do
    [[ -f $f ]] && kill -9 "$(cat "$f")" 2>/dev/null || true
  done
  if [[ $keep == 1 ]]; then say "cluster files kept in $cluster"; else rm -rf "$cluster"; fi
}
trap stop EXIT
trap 'exit 143' TERM INT
# Should this script be killed outright (SIGKILL: no trap runs), a watchdog stops the daemons
# once it is gone.
(
  while kill -0 $$ 2>/dev/null; do sleep 2; done
  for f in "$cluster/slurmd.pid" "$cluster/slurmctld.pid" "$cluster/munge/munged.pid"; do
    [[ -f $f ]] && kill -9 "$(cat "$f")" 2>/dev/null || true
  done
) </dev/null >/dev/null 2>&1 &

mungekey -c -k "$cluster/munge/munge.key" 2>/dev/null || dd if=/dev/urandom of="$cluster/munge/munge.key" bs=128 count=1 2>/dev/null
chmod 600 "$cluster/munge/munge.key"
munged --force --socket="$cluster/munge/munge.sock" --key-file="$cluster/munge/munge.key" \
  --pid-file="$cluster/munge/munged.pid" --log-file="$cluster/munge/munged.log" --seed-file="$cluster/munge/munged.seed"
started+=("$cluster/munge/munged.pid")
read -r port_ctld port_d < <(/usr/bin/python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
host=$(hostname -s)
cpus=$(nproc)
cat >"$cluster/slurm.conf" <<CONF
ClusterName=pbdbenchcheck
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port_ctld
SlurmdPort=$port_d
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$cluster/munge/munge.sock
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$cluster/state
SlurmdSpoolDir=$cluster/spool/slurmd-%n
SlurmctldPidFile=$cluster/slurmctld.pid
SlurmdPidFile=$cluster/slurmd.pid
SlurmctldLogFile=$cluster/log/slurmctld.log
SlurmdLogFile=$cluster/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/affinity
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MinJobAge=3600
InactiveLimit=0
KillWait=5
NodeName=pbdnode NodeAddr=127.0.0.1 NodeHostname=$host CPUs=$cpus State=UNKNOWN
PartitionName=check Nodes=pbdnode Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$cluster/slurm.conf
slurmctld -f "$SLURM_CONF"
started+=("$cluster/slurmctld.pid")
slurmd -f "$SLURM_CONF" -N pbdnode
started+=("$cluster/slurmd.pid")
# (No `cmd | grep -q` or `| head` in this script: with pipefail, the writer's SIGPIPE fails it.)
for _ in $(seq 60); do
  [[ $(sinfo -h -o %T 2>/dev/null) == *idle* ]] && break
  sleep 1
done
[[ $(sinfo -h -o %T 2>/dev/null) == *idle* ]] || { say "the node did not come up"; tail "$cluster"/log/*.log >&2; exit 1; }
say "cluster up: $(sinfo -V), one node of $cpus cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')), ports $port_ctld/$port_d"

# --- Helpers ---------------------------------------------------------------------------------
now() { date +%s.%N; }
elapsed() { /usr/bin/python3 -c "print(f'{$2 - $1:.1f}')"; }
job_state() { scontrol show job "$1" 2>/dev/null | awk 'match($0, /JobState=[A-Z_]+/) && !s { s = substr($0, RSTART + 9, RLENGTH - 9) } END { print s }'; }
wait_job() {  # until the job (and, for an array, every task) has ended; prints its state
  local id=$1 state
  for _ in $(seq 1800); do
    [[ -z $(squeue -h -j "$id" 2>/dev/null) ]] && break
    sleep 1
  done
  state=$(job_state "$id")
  echo "${state:-UNKNOWN}"
}
submitted() { awk -v key="$1" 'i = index($0, key) { split(substr($0, i + length(key) + 1), w, /[^0-9]/); if (!n++) print w[1] }' "$2"; }
failures=0
summary=()
check() {  # check NAME COMMAND...: counts a failure when the command fails
  local name=$1
  shift
  if "$@"; then return 0; fi
  say "FAILED: $name"
  failures=$((failures + 1))
}
record() { summary+=("$*"); }
compare() {  # compare OUT ARGS...: scripts/compare_results.py ARGS, its output to OUT and here
  local out=$1 rc=0
  shift
  /usr/bin/python3 "$data/scripts/compare_results.py" "$@" >"$out" 2>&1 || rc=$?
  cat "$out"
  return $rc
}

# submit NAME LOG CMD...: submits (CMD has --slurm); prints the merge job's id, or says why not.
submit() {
  local name=$1 log=$2
  shift 2
  if ! "$@" >"$log" 2>&1; then
    say "FAILED: $name: the submission failed: $(tail -n 3 "$log" | tr '\n' ' ')" >&2
    return 1
  fi
  submitted "the merge, job" "$log"
}
# local_run NAME LOG CMD...: the same command without Slurm; a refusal (exit 2) is a failure.
local_run() {
  local name=$1 log=$2 rc=0
  shift 2
  "$@" >"$log" 2>&1 || rc=$?
  if [[ $rc -eq 2 ]]; then
    say "FAILED: $name: the local run was refused: $(tail -n 3 "$log" | tr '\n' ' ')"
    failures=$((failures + 1))
  fi
}
# through_slurm NAME T0 T1 CMD...: submits CMD, waits for its merge, records the times.
through_slurm() {
  local name=$1 t0=$2 t1=$3 merge state=NOT_SUBMITTED t2
  shift 3
  if merge=$(submit "$name" "$work/$name.submit.log" "$@"); then state=$(wait_job "$merge"); fi
  t2=$(now)
  check "$name: the merge job ${merge:-} ended $state" test "$state" = COMPLETED
  record "$(printf '%-9s local %6ss   slurm %6ss (%s tasks and the merge, merge %s)' "$name" "$(elapsed "$t0" "$t1")" "$(elapsed "$t1" "$t2")" "$shards" "$state")"
}
# run_pair NAME CMD ARGS...: CMD ARGS locally (1 process) and as --slurm $shards.
run_pair() {
  local name=$1 t0 t1
  shift
  t0=$(now)
  local_run "$name" "$work/$name.local.log" "$bin" "$@" --out "$work/local/$name" --no-plots $(extra_local "$name")
  t1=$(now)
  through_slurm "$name" "$t0" "$t1" "$bin" "$@" --out "$work/slurm/$name" --no-plots $(extra_slurm "$name") --slurm "$shards"
}
extra_local() { case $1 in paper|claims|experiment) echo "--runs $work/local/$1/runs" ;; esac; }
extra_slurm() { case $1 in paper|claims|experiment) echo "--runs $work/slurm/$1/runs" ;; esac; }

# A cancelled task: the merge fails naming it; resubmitting redoes only that shard.
# cancel_check NAME REPORT EXPERIMENTS ARGS...: `pbdbench ARGS` (an experiment command) as a held
# array (--slurm-opt=--hold, carried into both jobs and into submit.sh) so that task 1 can be
# cancelled before it starts; its final report is compared with the local run NAME's REPORT (a
# file name: claims.json or reproductions.json) of the experiments in EXPERIMENTS.
cancel_check() {
  local name=$1 report=$2 experiments=$3
  shift 3
  local runs=$work/cancel/runs command=$1 array merge array2 merge2 state log before after
  submit cancel "$work/cancel.submit.log" "$bin" "$@" --no-plots --runs "$runs" \
    --out "$work/cancel/report" --slurm "$shards" --slurm-opt=--hold >/dev/null || return 1
  array=$(submitted "submitted job array" "$work/cancel.submit.log")
  merge=$(submitted "the merge, job" "$work/cancel.submit.log")
  scancel "${array}_1"
  scontrol release "$array,$merge"
  state=$(wait_job "$merge")
  check "cancel: the merge fails when a task was cancelled (it ended $state)" test "$state" = FAILED
  log=$runs/slurm/$command-merge-$merge.log
  check "cancel: the merge names shard 1" grep -q "shard 1/$shards:" "$log"
  check "cancel: the merge says how to resubmit" grep -q "bash $runs/slurm/submit.sh" "$log"
  check "cancel: no report after a failed merge" test ! -e "$work/cancel/report/README.md"
  before=$(find "$runs" -name '*.h5' | wc -l)
  submit cancel "$work/cancel.resubmit.log" bash "$runs/slurm/submit.sh" >/dev/null || return 1
  array2=$(submitted "submitted job array" "$work/cancel.resubmit.log")
  merge2=$(submitted "the merge, job" "$work/cancel.resubmit.log")
  check "cancel: resubmission runs shard 1 only" grep -q "(shards 1)" "$work/cancel.resubmit.log"
  scontrol release "$array2,$merge2"
  state=$(wait_job "$merge2")
  after=$(find "$runs" -name '*.h5' | wc -l)
  check "cancel: the second merge writes the report (it ended $state)" test "$state" = COMPLETED -a -f "$work/cancel/report/README.md"
  record "cancel    $command: task 1 of $shards cancelled: merge $merge FAILED naming shard 1; resubmitted shard 1 only ($before -> $after run files), merge $merge2 $state"
  check "cancel: the resubmitted report agrees with the local run" compare "$work/cancel.compare.txt" reports \
    "$work/local/$name/$report" "$work/cancel/report/$report" "$experiments" "$work/local/$name/runs" \
    >/dev/null
}

data=$("$bin" list | sed -n -e '1s/^Scenarios (\(.*\)\/scenarios):$/\1/p')
sweep=$data/studies/default/chain_iterations_vs_substeps.toml
if [[ $small == 1 ]]; then
  # --- One small experiment, and a small sweep --------------------------------------------------
  # A reproduction written here, so that what the catalog's experiments become does not change
  # what this check costs: three runs (one of six seeded trials) on 0.1 s of the hanging chain,
  # a [[timing]] group of two of them (timed together: they must share a task), a measure and a
  # part on each.
  mkdir -p "$work/experiments"
  cat >"$work/experiments/chain_small.toml" <<'TOML'
kind = "reproduction"
id = "chain_small"
section = "1"
paper = "slurm_check.sh"
claim = "more sweeps cost more, and shuffled orders hold a chain"
experiment = "a short chain through Slurm"
scenario = "hanging_chain"
[set]
"time.duration" = 0.1
[[setup]]
what = "chain"
value = "the catalog's"
from = "assumed"
why = "a check of the job array, not of the chain"
[[run]]
name = "few"
set = { "solver.iterations" = 1 }
[[run]]
name = "shuffled"
set = { "solver.order" = "shuffled" }
trials = 6
trial_key = "solver.shuffle_seed"
[[run]]
name = "many"
set = { "solver.iterations" = 40 }
[[timing]]
name = "cost"
runs = ["few", "many"]
repeats = 7
[[measure]]
name = "cost"
timing = "cost"
value = "many / few"
doc = "cost ratio"
[[measure]]
name = "err"
run = "shuffled"
value = "final(constraint_error_max)"
doc = "final error"
[[part]]
says = "held"
rule = "err < 0.1"
published = "held"
source = "nowhere"
[[part]]
says = "forty sweeps cost more than one"
rule = "cost > 1"
published = "more"
source = "nowhere"
TOML
  run_pair experiment paper --experiments "$work/experiments"
  check "experiment: local and Slurm agree" compare "$work/experiment.compare.txt" reports \
    "$work/local/experiment/reproductions.json" "$work/slurm/experiment/reproductions.json" "$work/experiments" \
    "$work/local/experiment/runs"

  t0=$(now)
  local_run sweep "$work/sweep.local.log" "$bin" sweep "$sweep" --set time.duration=0.25 --out "$work/local/sweep" --jobs 1 --quiet
  t1=$(now)
  through_slurm sweep "$t0" "$t1" "$bin" sweep "$sweep" --set time.duration=0.25 --out "$work/slurm/sweep" --quiet --slurm "$shards"
  check "sweep: local and Slurm agree" compare "$work/sweep.compare.txt" runs "$work/local/sweep" "$work/slurm/sweep"

  cancel_check experiment reproductions.json "$work/experiments" paper --experiments "$work/experiments" \
    || failures=$((failures + 1))
  checked="experiment sweep cancel"
else
  # --- paper, claims: quick tiers --------------------------------------------------------------
  run_pair paper paper --tier quick
  check "paper: local and Slurm agree" compare "$work/paper.compare.txt" reports \
    "$work/local/paper/reproductions.json" "$work/slurm/paper/reproductions.json" "$data/reproductions/experiments" \
    "$work/local/paper/runs"
  run_pair claims claims --tier quick
  check "claims: local and Slurm agree" compare "$work/claims.compare.txt" reports \
    "$work/local/claims/claims.json" "$work/slurm/claims/claims.json" "$data/claims/experiments" \
    "$work/local/claims/runs"

  # --- the regression's quick tier, and a sweep ------------------------------------------------
  t0=$(now)
  local_run regress "$work/regress.local.log" "$bin" regress --tier quick --no-plot --out "$work/local/regress"
  t1=$(now)
  through_slurm regress "$t0" "$t1" "$bin" regress --tier quick --no-plot --out "$work/slurm/regress" --slurm "$shards"
  check "regress: local and Slurm agree" compare "$work/regress.compare.txt" regress \
    "$work/local/regress/regress.json" "$work/slurm/regress/regress.json" "$data/regress/cases.toml"

  t0=$(now)
  local_run sweep "$work/sweep.local.log" "$bin" sweep "$sweep" --out "$work/local/sweep" --jobs 1 --quiet
  t1=$(now)
  through_slurm sweep "$t0" "$t1" "$bin" sweep "$sweep" --out "$work/slurm/sweep" --quiet --slurm "$shards"
  check "sweep: local and Slurm agree" compare "$work/sweep.compare.txt" runs "$work/local/sweep" "$work/slurm/sweep"

  cancel_check claims claims.json "$data/claims/experiments" claims --tier quick || failures=$((failures + 1))
  checked="paper claims regress sweep cancel"
fi

echo
say "pbdbench $("$bin" --version) on $(sinfo -V), $cpus cores, $shards tasks per array$([[ $small == 1 ]] && echo ", the small check"):"
for line in "${summary[@]}"; do echo "  $line"; done
for f in $checked; do
  if [[ -f $work/$f.compare.txt ]]; then echo "  $f: $(head -1 "$work/$f.compare.txt")"; fi
done
if [[ $failures -gt 0 ]]; then say "$failures check(s) failed; logs in $work"; exit 1; fi
say "every check passed; logs in $work"
