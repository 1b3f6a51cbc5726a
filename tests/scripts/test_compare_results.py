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

EXPERIMENT = """kind = "reproduction"
id = "chain_check"
section = "1"
paper = "nobody 2026"
claim = "a chain holds, and more sweeps cost more"
experiment = "a short chain"
scenario = "hanging_chain"
[set]
"time.duration" = 0.05
[[setup]]
what = "chain"
value = "the catalog's"
from = "assumed"
why = "a test"
[[run]]
name = "few"
set = { "solver.iterations" = 1 }
trials = 2
trial_key = "solver.shuffle_seed"
[[run]]
name = "many"
set = { "solver.iterations" = 30 }
[[timing]]
name = "cost"
runs = ["few", "many"]
repeats = 7
[[measure]]
name = "err"
run = "few"
value = "final(constraint_error_max)"
doc = "final error"
[[measure]]
name = "cost"
timing = "cost"
value = "many / few"
doc = "ratio"
[[measure]]
name = "cost_2"
value = "2 * cost"
doc = "twice"
[[part]]
says = "held"
rule = "err < 1"
published = "held"
source = "nowhere"
[[part]]
says = "costs more"
rule = "cost_2 > 2"
published = "more"
source = "nowhere"
"""


def compare(*args):
    return subprocess.run(["/usr/bin/python3", SCRIPT, *args], capture_output=True, text=True)


class CompareResultsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_compare_results_")
        d = cls.dir = cls.tmp.name
        os.makedirs(os.path.join(d, "exp"))
        with open(os.path.join(d, "exp", "chain_check.toml"), "w") as f:
            f.write(EXPERIMENT)
        for name in ("a", "b"):
            r = subprocess.run([BIN, "paper", "--experiments", os.path.join(d, "exp"), "--runs", os.path.join(d, name, "runs"),
                                "--out", os.path.join(d, name), "--no-plots"], capture_output=True, text=True)
            assert r.returncode == 0, r.stdout + r.stderr

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def reports(self, other):
        d = self.dir
        return compare("reports", os.path.join(d, "a", "reproductions.json"), other, os.path.join(d, "exp"),
                       os.path.join(d, "a", "runs"))

    def edited(self, edit):
        with open(os.path.join(self.dir, "b", "reproductions.json")) as f:
            report = json.load(f)
        edit(report["claims"][0])
        path = os.path.join(self.dir, "edited.json")
        with open(path, "w") as f:
            json.dump(report, f)
        return path

    def test_two_runs_of_one_build_agree(self):
        r = self.reports(os.path.join(self.dir, "b", "reproductions.json"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("1 experiments, 2 parts (1 timing): the verdicts of the 1 others identical; "
                      "1 non-timing measures identical", r.stdout)
        self.assertIn("2 timing measures not compared", r.stdout)  # cost, cost_2
        r = compare("runs", os.path.join(self.dir, "a", "runs", "chain_check"),
                    os.path.join(self.dir, "b", "runs", "chain_check"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("2 run files", r.stdout)

    def test_a_changed_number_or_verdict_is_named(self):
        def trial(c):
            c["measures"][0]["trials"][1] *= 1 + 1e-15
        r = self.reports(self.edited(trial))
        self.assertEqual(r.returncode, 1, r.stdout)
        self.assertIn("DIFFERS: chain_check measure err", r.stdout)

        def verdict(c):
            c["parts"][0]["verdict"] = "contradicted"
        r = self.reports(self.edited(verdict))
        self.assertEqual(r.returncode, 1, r.stdout)
        # The fixture's parts have no counterfactual, so here they are "not shown able to fail":
        # what matters is that the changed verdict is named with both readings.
        self.assertIn("DIFFERS: chain_check.1 (held): not shown able to fail here, contradicted there", r.stdout)

    def test_a_timing_verdict_may_differ(self):
        def timing(c):
            c["parts"][1]["verdict"] = "other"
            c["measures"][2]["value"] = 123.0
        r = self.reports(self.edited(timing))
        self.assertEqual(r.returncode, 0, r.stdout)
        self.assertIn("1 timing verdicts differ", r.stdout)
        self.assertIn("timing part differs (wall clock, allowed): chain_check.2", r.stdout)

    def test_a_missing_report_is_a_difference(self):
        r = compare("reports", os.path.join(self.dir, "nothing.json"), os.path.join(self.dir, "b", "reproductions.json"),
                    os.path.join(self.dir, "exp"), os.path.join(self.dir, "a", "runs"))
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("nothing to compare: " + os.path.join(self.dir, "nothing.json") + " not found", r.stdout)

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
