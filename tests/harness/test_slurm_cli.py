#!/usr/bin/python3
"""`pbdbench paper|claims|regress|sweep ... --slurm N` end to end, with a stand-in for sbatch
(fake_sbatch.py: it runs each job at once, as one node would), and the merge of shards made
without Slurm. What a real Slurm does is checked by scripts/slurm_check.sh (docs/cluster.md).

Run by CTest with PBDBENCH_BIN (the executable) and PBDBENCH_SCENARIOS set.
"""
import json
import os
import shutil
import subprocess
import tempfile
import unittest

BIN = os.environ["PBDBENCH_BIN"]
HERE = os.path.dirname(os.path.abspath(__file__))

# A timing group of two runs (timed together, interleaved: they must share a task), and an
# untimed run of six seeded trials.
EXPERIMENT = """kind = "reproduction"
id = "chain_costs"
section = "1"
paper = "nobody 2026"
claim = "more sweeps cost more, and shuffled orders hold a chain"
experiment = "a short chain"
scenario = "hanging_chain"
[set]
"time.duration" = 0.1
[[setup]]
what = "chain"
value = "the catalog's"
from = "assumed"
why = "a test"
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
"""


def pbdbench(*args, cwd=None, env=None, timeout=300):
    return subprocess.run([BIN, *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=timeout)


class SlurmCliTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_slurm_cli_")
        self.dir = self.tmp.name
        self.bin = os.path.join(self.dir, "bin")
        self.state = os.path.join(self.dir, "sbatch-state")
        os.makedirs(self.bin)
        os.makedirs(self.state)
        shutil.copy(os.path.join(HERE, "fake_sbatch.py"), os.path.join(self.bin, "sbatch"))
        self.env = dict(os.environ, PATH=self.bin + os.pathsep + os.environ["PATH"], FAKE_SBATCH_DIR=self.state)
        os.makedirs(os.path.join(self.dir, "exp"))
        with open(os.path.join(self.dir, "exp", "chain_costs.toml"), "w") as f:
            f.write(EXPERIMENT)

    def tearDown(self):
        self.tmp.cleanup()

    def submissions(self):
        with open(os.path.join(self.state, "submissions.jsonl")) as f:
            return [json.loads(line) for line in f]

    def test_paper_array_with_a_cancelled_task_then_resubmitted(self):
        # Relative paths on purpose: the jobs run in the folder the command was typed in.
        args = ["paper", "--experiments", "exp", "--runs", "runs", "--out", "report", "--no-plots"]
        local = pbdbench("paper", "--experiments", "exp", "--runs", "local-runs", "--out", "local", "--no-plots",
                         cwd=self.dir)
        self.assertEqual(local.returncode, 0, local.stdout + local.stderr)

        env = dict(self.env, FAKE_SBATCH_SKIP="1")
        r = pbdbench(*args, "--slurm", "3", "--slurm-opt", "--time=00:10:00 -p short", cwd=self.dir, env=env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("7 of 7 runs and timing groups to make, in 3 of 3 shards", r.stdout)
        self.assertIn("submitted job array 100 (shards 0-2), and the merge, job 101, after it", r.stdout)
        array, merge = self.submissions()
        self.assertEqual(array["options"]["array"], "0-2")
        self.assertEqual(array["tasks"], {"0": 0, "1": "skipped", "2": 0})
        self.assertEqual(merge["options"]["dependency"], "afterany:100")
        self.assertEqual(merge["tasks"], {"None": 1})  # the merge failed, loudly
        slurm = os.path.join(self.dir, "runs", "slurm")
        with open(os.path.join(slurm, "paper.array.sbatch")) as f:
            script = f.read()
        # Every option is carried; the site's settings are there; the logs go beside the results.
        self.assertIn('"$bin" paper --experiments exp --runs runs --out report --no-plots '
                      '--shard "${SLURM_ARRAY_TASK_ID}/3"', script)
        self.assertIn("#SBATCH --time=00:10:00\n#SBATCH -p short\n", script)
        self.assertIn(f"#SBATCH --chdir={self.dir}\n", script)
        self.assertIn(f"#SBATCH --output={slurm}/paper-%A_%a.log\n", script)
        self.assertTrue(os.path.exists(os.path.join(slurm, "paper-100_0.log")))
        with open(os.path.join(slurm, "paper-merge-101.log")) as f:
            log = f.read()
        self.assertIn("of 1 shard (of 3, counted from 0: 0/3 to 2/3) are not finished; nothing was merged", log)
        self.assertIn("shard 1/3:", log)
        self.assertIn("missing (no run file: the task did not reach it)", log)
        self.assertIn(f"bash {slurm}/submit.sh", log)
        self.assertIn("--array=1 ", log)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "report", "README.md")))
        # The timing group was timed whole in one task (the largest unit: shard 0); task 1's
        # shuffled trials are missing.
        made = sorted(n for n in os.listdir(os.path.join(self.dir, "runs", "chain_costs")) if n.endswith(".h5"))
        self.assertEqual(made, ["shuffled-001.h5", "shuffled-003.h5", "shuffled-005.h5"])
        self.assertTrue(os.path.exists(os.path.join(self.dir, "runs", "chain_costs", "timing-cost.toml")))
        self.assertIn("chain_costs/shuffled-000: missing", log)

        # Resubmission: only the shard left, and a new merge, which writes the report.
        r = subprocess.run(["bash", os.path.join(slurm, "submit.sh")], capture_output=True, text=True, env=self.env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("in 1 of 3 shards", r.stdout)
        array, merge = self.submissions()[2:]
        self.assertEqual(array["options"]["array"], "1")
        self.assertEqual(merge["tasks"], {"None": 0})
        with open(os.path.join(self.dir, "runs", "index.json")) as f:
            self.assertEqual({x["status"] for x in json.load(f)["runs"]}, {"complete"})
        for i in range(3):
            self.assertTrue(os.path.exists(os.path.join(self.dir, "runs", f"index.shard-{i}-of-3.json")))

        # The same verdicts and the same non-timing numbers as the local run.
        with open(os.path.join(self.dir, "local", "reproductions.json")) as f:
            a = json.load(f)["claims"][0]
        with open(os.path.join(self.dir, "report", "reproductions.json")) as f:
            b = json.load(f)["claims"][0]
        # (A timing verdict may differ: its interval, from another moment of a shared machine.)
        self.assertEqual([p["verdict"] for p in a["parts"] if not p["timing"]],
                         [p["verdict"] for p in b["parts"] if not p["timing"]])
        err_a = next(m for m in a["measures"] if m["name"] == "err")
        err_b = next(m for m in b["measures"] if m["name"] == "err")
        self.assertEqual(err_a["trials"], err_b["trials"])

        # Everything finished: another --slurm submits only the merge.
        r = pbdbench(*args, "--slurm", "3", cwd=self.dir, env=self.env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("0 of 7 runs and timing groups to make, in 0 of 3 shards", r.stdout)
        self.assertIn("every run is finished: submitted only the merge", r.stdout)

    def test_merge_without_slurm_names_the_shards_to_make(self):
        args = ["paper", "--experiments", "exp", "--runs", "runs", "--out", "report", "--no-plots"]
        r = pbdbench(*args, "--shard", "0/3", cwd=self.dir, env=dict(self.env, SLURM_CPUS_PER_TASK="1"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("1 at a time", r.stderr)  # the allocation's cores, not the machine's
        r = pbdbench(*args, "--merge", "3", cwd=self.dir)
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("shard 1/3:", r.stderr)
        self.assertIn("shard 2/3:", r.stderr)
        self.assertNotIn("shard 0/3:", r.stderr)
        self.assertIn("--shard I/3", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "report")))

    def test_sweep_and_regress_arrays(self):
        sweep = os.path.join(self.dir, "s.toml")
        with open(sweep, "w") as f:
            f.write('scenario = "hanging_chain"\n[set]\n"time.duration" = 0.1\n[grid]\n"solver.iterations" = [1, 2, 3]\n')
        r = pbdbench("sweep", sweep, "--out", "sw", "--set", "solver.name=pbd", "--slurm", "2", cwd=self.dir,
                     env=self.env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("3 of 3 runs to make, in 2 of 2 shards", r.stdout)
        array, merge = self.submissions()
        self.assertEqual(array["tasks"], {"0": 0, "1": 0})
        self.assertEqual(merge["tasks"], {"None": 0})
        with open(os.path.join(self.dir, "sw", "index.json")) as f:
            runs = json.load(f)["runs"]
        self.assertEqual([x["status"] for x in runs], ["complete"] * 3)
        with open(os.path.join(self.dir, "sw", "slurm", "sweep.array.sbatch")) as f:
            self.assertIn("--set solver.name=pbd", f.read())
        with open(os.path.join(self.dir, "sw", "slurm", "sweep-merge-101.log")) as f:
            self.assertIn("solver.iterations=3", f.read())  # the summary table
        # --force redoes the runs in the tasks, never in the merge; submit.sh does not carry it.
        r = pbdbench("sweep", sweep, "--out", "sw", "--set", "solver.name=pbd", "--merge", "2", "--force", cwd=self.dir)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("3 runs, 0 not finished", r.stdout)
        r = pbdbench("sweep", sweep, "--out", "sw", "--set", "solver.name=pbd", "--slurm", "2", "--force", "--no-submit",
                     cwd=self.dir, env=self.env)
        self.assertIn("3 of 3 runs to make", r.stdout)
        with open(os.path.join(self.dir, "sw", "slurm", "submit.sh")) as f:
            self.assertNotIn("--force", f.read())

        base = os.path.join(self.dir, "base.toml")
        cases = ["spring_xpbd", "chain_pbd"]
        r = pbdbench("regress", *cases, "--baselines", base, "--update", "--no-plot", "--out", "rl", cwd=self.dir)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        r = pbdbench("regress", *cases, "--baselines", base, "--no-plot", "--out", "rs", "--slurm", "2", cwd=self.dir,
                     env=self.env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        array, merge = self.submissions()[2:]
        self.assertEqual(merge["tasks"], {"None": 0})
        with open(os.path.join(self.dir, "rs", "runs", "slurm", "regress-merge-103.log")) as f:
            self.assertIn("0 worse", f.read())
        with open(os.path.join(self.dir, "rl", "regress.json")) as f:
            local = json.load(f)
        with open(os.path.join(self.dir, "rs", "regress.json")) as f:
            sharded = json.load(f)
        # --repeat: both runs of every case made in the tasks, compared in the merge.
        r = pbdbench("regress", *cases, "--baselines", base, "--no-plot", "--out", "rr", "--repeat", "--slurm", "2",
                     cwd=self.dir, env=self.env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertEqual(self.submissions()[-1]["tasks"], {"None": 0})
        with open(os.path.join(self.dir, "rr", "regress.md")) as f:
            self.assertEqual(f.read().count("run twice, the same bits"), 2)
        for case in cases:  # the same bits; only the wall clock differs
            local[case].pop("wall_per_step")
            sharded[case].pop("wall_per_step")
            self.assertEqual(local[case], sharded[case])

    def test_bad_slurm_options_are_refused(self):
        args = ["paper", "--experiments", "exp", "--runs", "runs", "--no-plots"]
        r = pbdbench(*args, "--slurm", "2", "--slurm-opt", "--array=0-9", cwd=self.dir, env=self.env)
        self.assertEqual(r.returncode, 2)
        self.assertIn("which pbdbench sets itself", r.stderr)
        r = pbdbench(*args, "--shard", "0/2", "--merge", "2", cwd=self.dir)
        self.assertEqual(r.returncode, 2)
        self.assertIn("give one of --shard, --merge and --slurm", r.stderr)
        r = pbdbench(*args, "--no-submit", cwd=self.dir)
        self.assertEqual(r.returncode, 2)
        template = os.path.join(self.dir, "site.sh")
        with open(template, "w") as f:
            f.write("#SBATCH --account=proj42\nmodule load hdf5\n")
        r = pbdbench(*args, "--slurm", "2", "--slurm-template", template, "--no-submit", cwd=self.dir, env=self.env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("submit with:\n  jid=$(sbatch --parsable --array=0-1 ", r.stdout)
        self.assertFalse(os.path.exists(os.path.join(self.state, "submissions.jsonl")))
        with open(os.path.join(self.dir, "runs", "slurm", "paper.merge.sbatch")) as f:
            merge = f.read()
        self.assertIn("#SBATCH --account=proj42\n", merge)
        self.assertIn("module load hdf5\nset -euo pipefail\n", merge)
        # No sbatch on this machine: a clear failure, not a silent one.
        r = pbdbench(*args, "--slurm", "2", cwd=self.dir, env=dict(os.environ, PATH="/nonexistent"))
        self.assertEqual(r.returncode, 1)
        self.assertIn("cannot start sbatch", r.stderr)


if __name__ == "__main__":
    unittest.main()
