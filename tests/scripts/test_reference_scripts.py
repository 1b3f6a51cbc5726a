"""Tests of scripts/fit_growth.py and scripts/summarize_compare.py on inputs written here."""
import contextlib
import io
import json
import os
import sys
import tempfile
import unittest

import h5py
import numpy as np

sys.path.insert(0, os.environ.get("PBDBENCH_SCRIPTS", os.path.join(os.path.dirname(__file__), "../../scripts")))
import fit_growth  # noqa: E402
import summarize_compare  # noqa: E402


def run(main, argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    return code, out.getvalue()


class FitGrowth(unittest.TestCase):
    def test_exponent_of_a_power_law_per_family(self):
        # time = 1e-6 size^1.5 s, two repetitions each; the counter grows as size^1.
        benchmarks = []
        for size in (1000, 4000, 16000):
            for rep in range(2):
                benchmarks.append({
                    "name": f"ref-be/beam/{size}tets/iterations:1/repeats:2",
                    "run_name": f"ref-be/beam/{size}tets/iterations:1",
                    "run_type": "iteration", "real_time": 1e-3 * size ** 1.5, "time_unit": "ms",
                    "tets": size, "linear_seconds": 2e-6 * size, "newton_iterations": 4,
                })
        benchmarks.append(dict(benchmarks[0], run_type="aggregate", real_time=1e9))  # ignored
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "cost.json")
            with open(path, "w") as f:
                json.dump({"context": {"cpu_model": "test"}, "benchmarks": benchmarks}, f)
            code, out = run(fit_growth.main, [path])
        self.assertEqual(code, 0)
        self.assertIn("ref-be/beam\n", out)
        exponent = out.strip().splitlines()[-1].split()
        self.assertEqual(exponent[0], "exponent")
        self.assertAlmostEqual(float(exponent[1]), 1.5, places=6)   # time
        self.assertAlmostEqual(float(exponent[2]), 0.0, places=6)   # newton_iterations
        self.assertAlmostEqual(float(exponent[3]), 1.0, places=6)   # linear_seconds

    def test_unreadable_file_is_an_error(self):
        with contextlib.redirect_stderr(io.StringIO()):
            code, _ = run(fit_growth.main, ["/nonexistent/cost.json"])
        self.assertEqual(code, 1)


class SummarizeCompare(unittest.TestCase):
    def write(self, path, rms, mx, tip_gap):
        with h5py.File(path, "w") as f:
            f.attrs["run_scenario"] = "cantilever_beam"
            f.attrs["run_solver"] = "xpbd"
            f.attrs["reference_solver"] = "ref-bdf"
            f.attrs["run_status"] = "complete"
            f.attrs["run_config"] = "[solver]\nname = \"xpbd\"\niterations = 2\nsubsteps = 5\n[solver.pbd]\n"
            c = f.create_group("compare")
            c["time"] = np.array([0.0, 1.0, 2.0])
            c["position_error_rms"] = np.array(rms)
            c["position_error_max"] = np.array(mx)
            o = c.create_group("observables")
            o["tip_displacement_relative_gap"] = np.array(tip_gap)

    def test_one_line_per_compare_file(self):
        with tempfile.TemporaryDirectory() as d:
            self.write(os.path.join(d, "compare-a.h5"), [0, 0.5, 0.25], [0, 0.9, 0.4], [np.nan, 0.1, 0.2])
            code, out = run(summarize_compare.main, [d])
        self.assertEqual(code, 0)
        lines = out.strip().splitlines()
        self.assertEqual(len(lines), 2)
        row = lines[1]
        self.assertIn("xpbd 2it x 5sub", row)
        self.assertIn("ref-bdf", row)
        fields = row.split()
        # t, RMS and max at the last time, the largest max, then the observable's last value.
        self.assertIn("0.25", fields)
        self.assertIn("0.4", fields)
        self.assertIn("0.9", fields)
        self.assertIn("tip gap 0.2 rel", row)


if __name__ == "__main__":
    unittest.main()
