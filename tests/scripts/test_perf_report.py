#!/usr/bin/python3
"""Tests of scripts/perf_report.py: the tables of docs/performance.md from a benchmark JSON written
here (medians, spreads, ratios, lines met or missed, cases not measured), the block replaced
between its markers and nothing else, and, when PBDBENCH_BENCH names bench_solvers, one real run
of a tiny filter with one repetition into a temporary page (times are not asserted)."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(HERE, "..", "..", "scripts"))
sys.path.insert(0, SCRIPTS)
import perf_report  # noqa: E402

SCRIPT = os.path.join(SCRIPTS, "perf_report.py")


def rep(name, suffix="/real_time", **counters):
    return dict(run_name=name + suffix, run_type="iteration", **counters)


BENCH = {
    "context": {"pbdbench_version": "9.9", "git_commit": "0123456789abcdef", "compiler": "GNU 1.0",
                "build_type": "Release", "cxx_flags": "-O3 ", "library_build_type": "release",
                "cpu_model": "Test CPU", "available_cores": "3"},
    "benchmarks": (
        [rep("solver/cloth64_distance/pbd/colored/double/t1", Mproj_per_s=v) for v in (190.0, 210.0, 230.0)]
        + [rep("solver/cloth64_distance/pbd/sequential/double/t1", Mproj_per_s=v) for v in (150.0, 160.0, 170.0)]
        + [rep("plain/cloth64_distance/pbd", Mproj_per_s=v) for v in (40.0, 50.0, 60.0)]
        + [rep("solver/cloth256_distance/xpbd/colored/double/t1", Mproj_per_s=v) for v in (100.0, 100.0)]
        + [rep("solver/cloth256_distance/xpbd/colored/double/t2", Mproj_per_s=v) for v in (150.0, 150.0)]
        + [rep("harness/cloth64/inline", suffix="/iterations:1/real_time", logging_pct=v, overhead_pct=9.0,
               run_s=1.5) for v in (7.0, 8.0, 9.0)]
        + [dict(run_name="solver/cloth64_distance/pbd/colored/double/t1/real_time", run_type="aggregate",
                Mproj_per_s=1.0)]),
}


class PerfReport(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="perf_report_")
        self.page = os.path.join(self.tmp, "performance.md")
        with open(self.page, "w") as f:
            f.write("# Perf\n\nbefore\n\n" + perf_report.BEGIN + "\nold\n" + perf_report.END + "\n\nafter\n")
        self.json = os.path.join(self.tmp, "bench.json")
        with open(self.json, "w") as f:
            json.dump(BENCH, f)

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def run_script(self, *args):
        return subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True)

    def test_tables_from_a_json(self):
        proc = self.run_script("--from-json", self.json, "--out", self.page, "--machine", "Test machine")
        self.assertEqual(proc.returncode, 0, proc.stderr)
        with open(self.page) as f:
            text = f.read()
        self.assertTrue(text.startswith("# Perf\n\nbefore\n\n" + perf_report.BEGIN))
        self.assertTrue(text.endswith(perf_report.END + "\n\nafter\n"))
        self.assertNotIn("\nold\n", text)
        self.assertIn("- Machine: Test machine", text)
        self.assertIn("commit 0123456789;", text)
        self.assertIn("Repetitions: 3 a case", text)
        # Medians (the aggregate row is not a repetition), the spread, the line at 200 M/s.
        self.assertIn("| colored, double, one thread ≥ 200 M/s | pbd, cloth64_distance | 210.0 [190.0, 230.0] | met |", text)
        self.assertIn("| colored, double, one thread ≥ 200 M/s | xpbd, cloth256_distance | 100.0 [100.0, 100.0] | **missed** |", text)
        self.assertIn("| sequential ≥ 1.5× the plain loop | pbd, cloth64_distance | 3.20× | met |", text)
        self.assertIn("| two threads ≥ 1.7× one | xpbd, cloth256_distance, colored | 1.50× | **missed** |", text)
        self.assertIn("2 s cloth64 run, logging on the run's thread | 8.00 [7.00, 9.00] % | **missed** |", text)
        self.assertNotIn("| pbd, cloth256_distance |", text)  # a line not measured has no row
        self.assertIn("| `hanging_cloth` 64×64, distance only (16,002 constraints) | 160.0 / 210.0 / – | – / – / – | 50.0 / – |", text)
        self.assertNotIn("`cantilever_fem`", text)  # a scene with no case measured has no row
        self.assertIn("| `harness/cloth64/inline` | 8.00 [7.00, 9.00] | 9.00 | 1.50 |", text)

    def test_missing_markers_and_missing_binary_are_errors(self):
        bare = os.path.join(self.tmp, "bare.md")
        with open(bare, "w") as f:
            f.write("# no markers\n")
        proc = self.run_script("--from-json", self.json, "--out", bare)
        self.assertEqual(proc.returncode, 2)
        self.assertIn("marker", proc.stderr)
        proc = self.run_script("--binary", os.path.join(self.tmp, "nothing"), "--out", self.page)
        self.assertEqual(proc.returncode, 2)
        self.assertIn("nothing", proc.stderr)

    @unittest.skipUnless(os.environ.get("PBDBENCH_BENCH"), "PBDBENCH_BENCH (bench_solvers) not set")
    def test_one_real_run_of_a_tiny_filter(self):
        kept = os.path.join(self.tmp, "kept.json")
        proc = self.run_script("--binary", os.environ["PBDBENCH_BENCH"], "--filter",
                               "^(solver/chain/pbd/sequential/double/t1|plain/chain/pbd)/", "--reps", "1",
                               "--min-time", "0.01", "--out", self.page, "--keep-json", kept)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        with open(self.page) as f:
            text = f.read()
        self.assertIn("Repetitions: 1 a case, interleaved at random; 2 cases.", text)
        self.assertIn("--reps 1 --min-time 0.01", text)
        self.assertIn("| sequential ≥ 1.5× the plain loop | pbd, chain |", text)
        self.assertNotIn("| sequential ≥ 1.5× the plain loop | pbd, chain | – |", text)
        with open(kept) as f:
            self.assertIn("perf_report_machine", json.load(f)["context"])


if __name__ == "__main__":
    unittest.main()
