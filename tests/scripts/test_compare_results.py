#!/usr/bin/python3
"""scripts/compare_results.py: two runs of the same experiments agree, or the differences are named
(what scripts/slurm_check.sh relies on to compare a Slurm job array with a local run).

Run by CTest with PBDBENCH_BIN and PBDBENCH_SCRIPTS set.
"""
import json
import os
import subprocess
import tempfile
import unittest

BIN = os.environ["PBDBENCH_BIN"]
SCRIPT = os.path.join(os.environ["PBDBENCH_SCRIPTS"], "compare_results.py")

EXPERIMENT = """id = "S9.8"
section = "9.8"
claim = "a chain holds, and more sweeps cost more"
experiment = "a short chain"
scenario = "hanging_chain"
[set]
"time.duration" = 0.05
[[run]]
name = "few"
set = { "solver.iterations" = 1 }
trials = 2
trial_key = "solver.shuffle_seed"
[[run]]
name = "many"
set = { "solver.iterations" = 30 }
[[measure]]
name = "err"
run = "few"
value = "final(constraint_error_max)"
doc = "final error"
[[measure]]
name = "time_few"
run = "few"
value = "mean(wall_step)"
doc = "s"
[[measure]]
name = "time_many"
run = "many"
value = "mean(wall_step)"
doc = "s"
[[measure]]
name = "cost"
value = "time_many / time_few"
doc = "ratio"
[[part]]
says = "held"
rule = "err < 1"
[[part]]
says = "costs more"
rule = "cost > 1"
timing = true
"""


def compare(*args):
    return subprocess.run(["/usr/bin/python3", SCRIPT, *args], capture_output=True, text=True)


class CompareResultsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_compare_results_")
        d = cls.dir = cls.tmp.name
        os.makedirs(os.path.join(d, "exp"))
        with open(os.path.join(d, "exp", "S9.8.toml"), "w") as f:
            f.write(EXPERIMENT)
        for name in ("a", "b"):
            r = subprocess.run([BIN, "claims", "--experiments", os.path.join(d, "exp"), "--runs", os.path.join(d, name, "runs"),
                                "--out", os.path.join(d, name), "--no-plots"], capture_output=True, text=True)
            assert r.returncode == 0, r.stdout + r.stderr

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def reports(self, other):
        d = self.dir
        return compare("reports", os.path.join(d, "a", "claims.json"), other, os.path.join(d, "exp"),
                       os.path.join(d, "a", "runs"))

    def edited(self, edit):
        with open(os.path.join(self.dir, "b", "claims.json")) as f:
            report = json.load(f)
        edit(report["claims"][0])
        path = os.path.join(self.dir, "edited.json")
        with open(path, "w") as f:
            json.dump(report, f)
        return path

    def test_two_runs_of_one_build_agree(self):
        r = self.reports(os.path.join(self.dir, "b", "claims.json"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("1 experiments, 2 parts (1 timing): the verdicts of the 1 others identical; "
                      "1 non-timing measures identical", r.stdout)
        self.assertIn("3 timing measures not compared", r.stdout)  # time_few, time_many, cost
        r = compare("runs", os.path.join(self.dir, "a", "runs", "S9.8"), os.path.join(self.dir, "b", "runs", "S9.8"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("3 run files", r.stdout)

    def test_a_changed_number_or_verdict_is_named(self):
        def trial(c):
            c["measures"][0]["trials"][1] *= 1 + 1e-15
        r = self.reports(self.edited(trial))
        self.assertEqual(r.returncode, 1, r.stdout)
        self.assertIn("DIFFERS: S9.8 measure err", r.stdout)

        def verdict(c):
            c["parts"][0]["verdict"] = "contradicted"
        r = self.reports(self.edited(verdict))
        self.assertEqual(r.returncode, 1, r.stdout)
        self.assertIn("DIFFERS: S9.8.1 (held): supported here, contradicted there", r.stdout)

    def test_a_timing_verdict_may_differ(self):
        def timing(c):
            c["parts"][1]["verdict"] = "contradicted" if c["parts"][1]["verdict"] == "supported" else "supported"
            c["measures"][3]["value"] = 123.0
        r = self.reports(self.edited(timing))
        self.assertEqual(r.returncode, 0, r.stdout)
        self.assertIn("1 timing verdicts differ", r.stdout)
        self.assertIn("timing part differs (wall clock, allowed): S9.8.2", r.stdout)

    def test_regress_results(self):
        d = self.dir
        registry = os.path.join(d, "cases.toml")
        with open(registry, "w") as f:
            f.write('[[metric]]\nname = "err"\n[[metric]]\nname = "wall"\ntiming = true\n')
        a = {"build": {"commit": "x"}, "c1": {"status": "complete", "hash": "ab", "err": 0.5, "wall": 1.0}}
        b = {"build": {"commit": "y"}, "c1": {"status": "complete", "hash": "ab", "err": 0.5, "wall": 2.0}}
        for name, value in (("a.json", a), ("b.json", b)):
            with open(os.path.join(d, name), "w") as f:
                json.dump(value, f)
        r = compare("regress", os.path.join(d, "a.json"), os.path.join(d, "b.json"), registry)
        self.assertEqual(r.returncode, 0, r.stdout)
        self.assertIn("1 cases: hashes and 3 non-timing values identical", r.stdout)
        b["c1"]["hash"] = "cd"
        with open(os.path.join(d, "b.json"), "w") as f:
            json.dump(b, f)
        r = compare("regress", os.path.join(d, "a.json"), os.path.join(d, "b.json"), registry)
        self.assertEqual(r.returncode, 1, r.stdout)
        self.assertIn("DIFFERS: c1 hash: ab here, cd there", r.stdout)


if __name__ == "__main__":
    unittest.main()
