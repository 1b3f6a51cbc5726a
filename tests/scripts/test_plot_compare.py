#!/usr/bin/python3
"""Tests of scripts/plot_compare.py on compare files written here with h5py in the layout of
results/README.md ("Compare files"). The command line test (tests/harness/test_cli.py) draws one
from a compare file that `pbdbench compare` wrote.

Environment (set by tests/scripts/CMakeLists.txt):
    PBDBENCH_SCRIPTS   the scripts/ folder
    PBDBENCH_TEST_TMP  a folder for the files the tests write
"""
import os
import shutil
import subprocess
import sys
import unittest

import h5py
import numpy as np

SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS",
                         os.path.join(os.path.dirname(__file__), "..", "..", "scripts"))
TMP = os.path.join(os.environ.get("PBDBENCH_TEST_TMP", os.path.join(os.path.dirname(__file__), "tmp")),
                   "plot_compare")
PYTHON = "/usr/bin/python3"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

sys.path.insert(0, SCRIPTS)
import plot_compare  # noqa: E402


def write_compare(path, observables=True, zero_error=False):
    """A compare file: 11 frames over 1 s, 101 rows; with observables, a support force (run
    finite, reference NaN as from pbd), a tip displacement and a pendulum angle."""
    t = np.linspace(0.0, 1.0, 11)
    ts = np.linspace(0.0, 1.0, 101)
    with h5py.File(path, "w") as f:
        f.attrs["content"] = "pbdbench compare"
        f.attrs["run_solver"] = "xpbd"
        f.attrs["reference_solver"] = "pbd"
        f.attrs["run_scenario"] = "hanging_chain"
        g = f.create_group("compare")
        g["time"] = t
        err = np.zeros_like(t) if zero_error else 1e-4 * (1 + t)
        g["position_error_rms"] = err
        g["position_error_max"] = 2 * err
        g["series_time"] = ts
        d = g.create_group("diff")
        d["total_energy"] = 0.1 * ts
        o = g.create_group("observables")
        if observables:
            o["support_force_run"] = np.tile([0.0, 186.39, 0.0], (ts.size, 1))
            o["support_force_reference"] = np.full((ts.size, 3), np.nan)
            o["support_force_gap"] = np.full(ts.size, np.nan)
            o["tip_displacement_run"] = np.outer(ts, [0.0, -0.1, 0.0])
            o["tip_displacement_reference"] = np.outer(ts, [0.0, -0.11, 0.0])
            o["pendulum_angle_run"] = np.sin(2 * np.pi * ts / 0.4)
            o["pendulum_angle_reference"] = np.sin(2 * np.pi * ts / 0.41)
            o["pendulum_period_run"] = 0.4
            o["pendulum_period_reference"] = 0.41
    return path


def assert_png(test, path):
    test.assertTrue(os.path.isfile(path), f"{path} was not written")
    test.assertGreater(os.path.getsize(path), 1000, f"{path} is (almost) empty")
    with open(path, "rb") as f:
        test.assertEqual(f.read(8), PNG_MAGIC, f"{path} is not a PNG")


def run_script(*args):
    return subprocess.run([PYTHON, os.path.join(SCRIPTS, "plot_compare.py"), *map(str, args)],
                          capture_output=True, text=True)


def setUpModule():
    shutil.rmtree(TMP, ignore_errors=True)
    os.makedirs(TMP)


class PlotCompareTest(unittest.TestCase):
    def test_draws_a_png_with_every_observable(self):
        path = write_compare(os.path.join(TMP, "all.h5"))
        out = os.path.join(TMP, "all.png")
        r = run_script(path, "-o", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(r.stdout.strip(), f"wrote {out}")
        assert_png(self, out)
        titles = [p[0] for p in plot_compare.panels(plot_compare.load(path))]
        self.assertEqual(len(titles), 4, titles)
        self.assertIn("position error", titles[0])
        self.assertEqual(titles[1:3], ["|tip displacement|", "|support force|"])
        self.assertIn("pendulum angle", titles[3])
        self.assertIn("0.4 s", titles[3])

    def test_panels_show_both_runs_and_log_scale_for_the_error(self):
        data = plot_compare.load(write_compare(os.path.join(TMP, "both.h5")))
        chosen = plot_compare.panels(data)
        name, unit, log, curves = chosen[0]
        self.assertTrue(log)
        self.assertEqual(unit, "m")
        np.testing.assert_allclose(curves[0][2], 1e-4 * (1 + data["time"]))
        _, unit, log, curves = chosen[2]  # support force: the norm, the reference NaN throughout
        self.assertFalse(log)
        self.assertEqual(unit, "N")
        self.assertEqual(curves[0][0], "run (xpbd)")
        self.assertEqual(curves[1][0], "reference (pbd): NaN throughout")
        np.testing.assert_allclose(curves[0][2], 186.39)

    def test_without_observables_the_energy_difference(self):
        path = write_compare(os.path.join(TMP, "plain.h5"), observables=False)
        titles = [p[0] for p in plot_compare.panels(plot_compare.load(path))]
        self.assertEqual(len(titles), 2, titles)
        self.assertIn("total energy", titles[1])
        r = run_script(path)  # default output: the compare file with .png
        self.assertEqual(r.returncode, 0, r.stderr)
        assert_png(self, os.path.join(TMP, "plain.png"))

    def test_identical_runs_have_no_log_scale_trouble(self):
        path = write_compare(os.path.join(TMP, "same.h5"), observables=False, zero_error=True)
        r = run_script(path, "-o", os.path.join(TMP, "same.png"))
        self.assertEqual(r.returncode, 0, r.stderr)
        assert_png(self, os.path.join(TMP, "same.png"))

    def test_refuses_what_is_not_a_compare_file(self):
        r = run_script(os.path.join(TMP, "missing.h5"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("missing.h5", r.stderr)
        other = os.path.join(TMP, "other.h5")
        with h5py.File(other, "w") as f:
            f["series/time"] = np.zeros(3)
        r = run_script(other)
        self.assertEqual(r.returncode, 2)
        self.assertIn("not a compare file", r.stderr)


if __name__ == "__main__":
    unittest.main()
