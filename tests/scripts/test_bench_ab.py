#!/usr/bin/python3
"""Tests of scripts/bench_ab.py: two builds (here one bench_solvers binary under two labels)
alternated, every process's JSON kept, the ratios against the first build and the thread-count
ratios within one process.

Environment (set by benchmarks/CMakeLists.txt):
    PBDBENCH_BENCH     the bench_solvers executable
    PBDBENCH_SCRIPTS   the scripts/ folder
    PBDBENCH_TEST_TMP  a folder for the files the tests write
"""
import json
import os
import shutil
import subprocess
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(HERE, "..", "..", "scripts"))
BENCH = os.environ.get("PBDBENCH_BENCH", os.path.join(HERE, "..", "..", "build", "benchmarks", "bench_solvers"))
TMP = os.path.join(os.environ.get("PBDBENCH_TEST_TMP", os.path.join(HERE, "tmp")), "bench_ab")
PYTHON = "/usr/bin/python3"
CASES = "^solver/cloth64_distance/pbd/colored/double/t[12]/"


def bench_ab(*args):
    return subprocess.run([PYTHON, os.path.join(SCRIPTS, "bench_ab.py"), *args], capture_output=True,
                          text=True, timeout=600)


class BenchAb(unittest.TestCase):
    def setUp(self):
        shutil.rmtree(TMP, ignore_errors=True)
        os.makedirs(TMP)

    def test_two_builds_alternated_with_thread_ratios(self):
        out = os.path.join(TMP, "ab")
        r = bench_ab("--build", f"one={BENCH}", "--build", f"two={BENCH}", "--filter", CASES,
                     "--reps", "2", "--rounds", "2", "--min-time", "0.01", "--out", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(os.listdir(out)),
                         ["one_r1.json", "one_r2.json", "summary.json", "two_r1.json", "two_r2.json"])
        with open(os.path.join(out, "summary.json")) as f:
            s = json.load(f)
        # The order rotates: round 1 starts with the first build, round 2 with the second.
        self.assertEqual([(x["round"], x["build"]) for x in s["runs"]],
                         [(1, "one"), (1, "two"), (2, "two"), (2, "one")])
        # Every repetition of every round is in the rates: 2 rounds x 2 repetitions.
        rates = {(x["case"], x["build"]): x for x in s["rates"]}
        t1 = "solver/cloth64_distance/pbd/colored/double/t1/real_time"
        t2 = "solver/cloth64_distance/pbd/colored/double/t2/real_time"
        for case in (t1, t2):
            for build in ("one", "two"):
                x = rates[(case, build)]
                self.assertEqual(x["n"], 4)
                self.assertGreater(x["min"], 0.0)
                self.assertLessEqual(x["min"], x["median"])
                self.assertLessEqual(x["median"], x["max"])
        # The ratio to the first build, per round, and t2 / t1 within each process.
        ratio = [x for x in s["ratios"] if x["case"] == t1][0]
        self.assertEqual((ratio["build"], ratio["baseline"], ratio["n"]), ("two", "one", 2))
        scaling = {x["build"]: x for x in s["scaling"]}
        self.assertEqual(sorted(scaling), ["one", "two"])
        for build, x in scaling.items():
            self.assertEqual(x["threads"], 2)
            self.assertEqual(len(x["per_round"]), 2)
            # Recomputed from the kept files: the medians of the two cases in each process.
            for rnd, value in zip((1, 2), x["per_round"]):
                with open(os.path.join(out, f"{build}_r{rnd}.json")) as f:
                    reps = [b for b in json.load(f)["benchmarks"] if b.get("run_type") == "iteration"]
                med = {c: sorted(b["Mproj_per_s"] for b in reps if b["run_name"] == c) for c in (t1, t2)}
                expect = (sum(med[t2]) / 2) / (sum(med[t1]) / 2)
                self.assertAlmostEqual(value, expect, places=12)
        self.assertIn("| tN / t1 in one process (per round) |", r.stdout)
        self.assertIn(f"| {t2} | two |", r.stdout)

    def test_busy_processes_beside_and_gone_after(self):
        out = os.path.join(TMP, "load")
        r = bench_ab("--build", f"one={BENCH}", "--filter", CASES, "--reps", "1", "--rounds", "1",
                     "--min-time", "0.01", "--load", "2", "--out", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(out, "summary.json")) as f:
            s = json.load(f)
        self.assertEqual(s["load_processes"], 2)
        self.assertEqual(len(s["load_pids"]), 2)
        for pid in s["load_pids"]:  # killed and reaped: no such process now
            self.assertFalse(os.path.exists(f"/proc/{pid}"), pid)
        self.assertIn("2 busy processes beside", r.stdout)

    def test_refusals(self):
        out = os.path.join(TMP, "exists")
        os.makedirs(out)
        r = bench_ab("--build", f"a={BENCH}", "--filter", CASES, "--out", out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("not overwriting", r.stderr)
        self.assertEqual(os.listdir(out), [])
        r = bench_ab("--build", "nolabel", "--filter", CASES, "--out", os.path.join(TMP, "x"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("LABEL=BINARY", r.stderr)
        r = bench_ab("--build", f"a={BENCH}", "--build", f"a={BENCH}", "--filter", CASES,
                     "--out", os.path.join(TMP, "y"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("one label", r.stderr)
        r = bench_ab("--build", f"a={BENCH}", "--filter", "^no_such_case$", "--rounds", "1",
                     "--out", os.path.join(TMP, "z"))
        self.assertEqual(r.returncode, 1)
        self.assertIn("no case matches", r.stderr)


if __name__ == "__main__":
    unittest.main()
