#!/usr/bin/env bash
# The installed pbdbench as a user gets it (cmake/Install.cmake): installed to a prefix, the prefix
# moved elsewhere, the command run from a folder of the user's with no PBDBENCH_* variable set
# (it finds its scenarios, regression cases, experiments and plot scripts beside itself, and
# writes where it is run), and a small outside C++ project (consumer/) built against the package with
# find_package(pbdbench) and run.
# Usage: test_package.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build=$1 source=$2 work=$3
rm -rf "$work"
mkdir -p "$work/home"
cmake --install "$build" --prefix "$work/prefix" >"$work/install.log"
mv "$work/prefix" "$work/moved"  # relocatable: nothing may point back to where it was installed
p="$work/moved"
unset PBDBENCH_DATA_DIR PBDBENCH_SCENARIOS PBDBENCH_CLAIMS

fail() { echo "test_package: $*" >&2; exit 1; }
if grep -q --binary-files=text -F "$source" "$p/bin/pbdbench"; then fail "the binary holds the source path $source"; fi
if grep -rq -F "$(cd "$build" && pwd)" "$p/lib/cmake/pbdbench"; then fail "the package files hold the build path"; fi

cd "$work/home"
"$p/bin/pbdbench" list >list.txt
grep -q -F "Scenarios ($p/share/pbdbench/scenarios)" list.txt || fail "list: $(head -1 list.txt)"
# A regression case against the installed baselines, with its plot (the installed scripts),
# written under this folder; the experiment catalogs load.
"$p/bin/pbdbench" regress spring_xpbd >regress.txt 2>&1 || { cat regress.txt >&2; fail "regress spring_xpbd failed"; }
grep -q "0 worse" regress.txt || fail "regress spring_xpbd: $(tail -3 regress.txt)"
test -f results/regress/quick/regress.png || fail "no results/regress/quick/regress.png (scripts/plot_regress.py)"
# The job scripts of an installed pbdbench call it where it is installed.
study="$p/share/pbdbench/studies/default/chain_iterations_vs_substeps.toml"
"$p/bin/pbdbench" sweep "$study" --slurm 2 --no-submit >slurm.txt 2>&1 || { cat slurm.txt >&2; fail "sweep --slurm 2 --no-submit"; }
grep -q "^bin=$p/bin/pbdbench$" results/sweeps/chain_iterations_vs_substeps/slurm/sweep.array.sbatch ||
  fail "the array script does not call $p/bin/pbdbench"
# The baselines of an installation are not rewritten by default.
set +e
"$p/bin/pbdbench" regress spring_xpbd --update --no-plot >update.txt 2>&1
rc=$?
set -e
[[ $rc -eq 2 ]] && grep -q "give --baselines FILE" update.txt || fail "regress --update on an installation: exit $rc"
# A wrong PBDBENCH_DATA_DIR is an error that says so.
set +e
PBDBENCH_DATA_DIR=/nonexistent "$p/bin/pbdbench" run free_fall --out x.h5 >bad.txt 2>&1
rc=$?
set -e
[[ $rc -eq 2 ]] && grep -q "PBDBENCH_DATA_DIR=/nonexistent holds no scenarios/" bad.txt || fail "bad PBDBENCH_DATA_DIR: exit $rc"

# An outside project on the package.
cmake -S "$source/tests/package/consumer" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$p" -DCMAKE_BUILD_TYPE=Release \
  >"$work/consumer-configure.log" 2>&1 || { cat "$work/consumer-configure.log" >&2; fail "consumer: configure"; }
cmake --build "$work/consumer" >"$work/consumer-build.log" 2>&1 || { cat "$work/consumer-build.log" >&2; fail "consumer: build"; }
"$work/consumer/consumer" "$work/home/consumer.h5"
echo "test_package: installed, moved, run and linked against: ok"
