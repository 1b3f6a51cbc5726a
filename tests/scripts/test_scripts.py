#!/usr/bin/python3
"""Tests of scripts/runfile.py, scripts/plot_runs.py and scripts/plot_sweep.py on run files
written by the C++ writer (the runfile_fixture helper).

Environment (set by tests/scripts/CMakeLists.txt):
    PBDBENCH_FIXTURE   the runfile_fixture executable
    PBDBENCH_SCRIPTS   the scripts/ folder
    PBDBENCH_TEST_TMP  a folder for the files the tests write
"""
import json
import os
import shutil
import subprocess
import sys
import unittest

import numpy as np

FIXTURE = os.environ.get("PBDBENCH_FIXTURE", "")
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS",
                         os.path.join(os.path.dirname(__file__), "..", "..", "scripts"))
TMP = os.environ.get("PBDBENCH_TEST_TMP", os.path.join(os.path.dirname(__file__), "tmp"))
PYTHON = "/usr/bin/python3"

sys.path.insert(0, SCRIPTS)
import runfile  # noqa: E402

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def fixture(path, *args):
    """Writes a run file with the C++ fixture writer; returns its path."""
    os.makedirs(os.path.dirname(path), exist_ok=True)
    subprocess.run([FIXTURE, path, *map(str, args)], check=True)
    return path


def script(name, *args):
    return subprocess.run([PYTHON, os.path.join(SCRIPTS, name), *map(str, args)],
                          capture_output=True, text=True)


def assert_png(test, path):
    test.assertTrue(os.path.isfile(path), f"{path} was not written")
    test.assertGreater(os.path.getsize(path), 1000, f"{path} is (almost) empty")
    with open(path, "rb") as f:
        test.assertEqual(f.read(8), PNG_MAGIC, f"{path} is not a PNG")


def setUpModule():
    if not FIXTURE or not os.access(FIXTURE, os.X_OK):
        raise RuntimeError("PBDBENCH_FIXTURE must name the runfile_fixture executable")
    shutil.rmtree(TMP, ignore_errors=True)
    os.makedirs(TMP)


class LoaderTest(unittest.TestCase):
    def test_reads_every_series_with_units(self):
        path = fixture(os.path.join(TMP, "loader", "run.h5"), "--rows", 40)
        listed = subprocess.run([FIXTURE, "--list-series"], capture_output=True, text=True,
                                check=True).stdout.splitlines()
        expected = dict(line.split("\t") for line in listed)
        run = runfile.load(path)
        self.assertEqual(set(run.series), set(expected))
        for name, units in expected.items():
            self.assertEqual(run.units[name], units, name)
            self.assertTrue(run.docs[name], f"{name} has no doc")
            self.assertEqual(run.series[name].shape[0], 40, name)
            self.assertEqual(run.series[name].dtype, np.float64, name)
        self.assertEqual(run.series["linear_momentum"].shape, (40, 3))
        self.assertEqual(run.series["time"].shape, (40,))
        np.testing.assert_array_equal(run.series["step"], np.arange(40.0))
        self.assertFalse(run.deterministic["wall_step"])
        self.assertTrue(run.deterministic["kinetic_energy"])
        self.assertEqual(run.rows, 40)

    def test_attributes_config_frames_model(self):
        path = fixture(os.path.join(TMP, "loader", "attrs.h5"), "--solver", "pbd",
                       "--iterations", 7, "--rows", 31)
        run = runfile.load(path)
        self.assertEqual(run.status, "complete")
        self.assertIsInstance(run.attrs["status"], str)
        self.assertEqual(run.attrs["solver"], "pbd")
        self.assertEqual(run.attrs["format_version"], 1)
        self.assertEqual(run.attrs["steps_completed"], 30)
        self.assertEqual(run.config["solver"]["iterations"], 7)
        self.assertEqual(runfile.config_value(run, "solver.name"), "pbd")
        self.assertEqual(runfile.config_value(run, "scenario_file"), "scenarios/fixture.toml")
        # Frames every 10 rows: rows 0, 10, 20, 30.
        np.testing.assert_allclose(run.frame_time, [0.0, 0.1, 0.2, 0.3])
        self.assertEqual(run.frames.shape, (4, 4, 3))
        self.assertEqual(run.model["group_names"], ["stretch", "volume", "bending"])
        self.assertEqual(run.model["constraint_kind_names"],
                         ["distance", "volume", "bending", "fem_deviatoric", "fem_hydrostatic",
                          "fem_strain_triangle", "fem_strain_tet"])
        self.assertEqual(run.model["rest_positions"].shape, (4, 3))
        self.assertEqual(list(run.model["constraint_kind"]), [0] * 6 + [1, 2])
        light = runfile.load(path, frames=False, model=False)
        self.assertIsNone(light.frames)
        self.assertEqual(light.model, {})

    def test_incomplete_and_crashed_files_load(self):
        for status in ("incomplete", "crashed"):
            path = fixture(os.path.join(TMP, "loader", f"{status}.h5"), "--status", status,
                           "--rows", 20)
            run = runfile.load(path)
            self.assertEqual(run.status, "incomplete", status)
            self.assertEqual(run.rows, 20, status)
            self.assertFalse(os.path.exists(path + ".tmp"), status)

    def test_exploded_file(self):
        path = fixture(os.path.join(TMP, "loader", "exploded.h5"), "--status", "exploded",
                       "--rows", 40)
        run = runfile.load(path)
        self.assertTrue(run.exploded)
        self.assertEqual(run.attrs["exploded_step"], 30)
        self.assertAlmostEqual(run.attrs["exploded_time"], 0.3)
        self.assertIn("non-finite", run.attrs["status_reason"])
        self.assertEqual(run.rows, 31)
        self.assertTrue(np.isnan(run.series["max_speed"][-1]))

    def test_labels_from_differing_config(self):
        a = fixture(os.path.join(TMP, "loader", "a.h5"), "--solver", "pbd", "--iterations", 5)
        b = fixture(os.path.join(TMP, "loader", "b.h5"), "--solver", "xpbd", "--iterations", 5)
        c = fixture(os.path.join(TMP, "loader", "c.h5"), "--solver", "xpbd", "--iterations", 20)
        runs = [runfile.load(p) for p in (a, b, c)]
        keys = runfile.differing_keys(runs)
        self.assertEqual(keys, ["solver.name", "solver.iterations"])
        self.assertEqual(runfile.label(runs[0], keys), "name=pbd, iterations=5")
        self.assertEqual(runfile.differing_keys(runs[1:2]), [])
        self.assertEqual(runfile.label(runs[2], keys), "name=xpbd, iterations=20")
        self.assertEqual(runfile.label(runs[1], []), "b")
        # Two keys with the same last component are shown in full.
        self.assertEqual(runfile.label(runs[0], ["solver.name", "scenario.name"]),
                         "solver.name=pbd, scenario.name=fixture")

    def test_missing_and_unreadable_files_raise_naming_the_path(self):
        missing = os.path.join(TMP, "loader", "missing.h5")
        with self.assertRaisesRegex(runfile.RunFileError, "missing.h5"):
            runfile.load(missing)
        junk = os.path.join(TMP, "loader", "junk.h5")
        os.makedirs(os.path.dirname(junk), exist_ok=True)
        with open(junk, "w") as f:
            f.write("not HDF5\n")
        with self.assertRaisesRegex(runfile.RunFileError, "junk.h5"):
            runfile.load(junk)


class OtherKindsTest(unittest.TestCase):
    """runfile.py loads every kind of file the project writes: compare, convergence and
    regression files written by runfile/'s C++ writers (runfile_fixture --compare etc.)."""

    @classmethod
    def setUpClass(cls):
        d = os.path.join(TMP, "kinds")
        os.makedirs(d, exist_ok=True)
        cls.files = {}
        for kind in ("compare", "converge", "regress"):
            path = os.path.join(d, f"{kind}.h5")
            subprocess.run([FIXTURE, f"--{kind}", path], check=True)
            cls.files[kind] = path
        cls.files["run"] = fixture(os.path.join(d, "run.h5"), "--rows", 20)

    def test_compare(self):
        c = runfile.load_compare(self.files["compare"])
        self.assertEqual(c.attrs["content"], "pbdbench compare")
        self.assertEqual(c.run["solver"], "xpbd")
        self.assertEqual(c.reference["solver"], "ref-bdf")
        self.assertEqual(c.warnings, ["first warning", "second warning"])
        np.testing.assert_array_equal(c.data["time"], [0.0, 0.5])
        np.testing.assert_array_equal(c.data["position_error_max"], [0.0, 2e-3])
        np.testing.assert_array_equal(c.data["reference_frame"], [[0, 0], [0, 1]])
        np.testing.assert_array_equal(c.data["series_time"], [0.0, 0.25, 0.5])
        np.testing.assert_array_equal(c.diff["total_energy"], [0.0, 0.1, 0.2])
        self.assertEqual(c.diff_units["linear_momentum"], "kg m/s")
        self.assertEqual(c.observables["tip_displacement_run"].shape, (3, 3))
        self.assertEqual(c.observables["pendulum_period_run"], 1.5)
        self.assertEqual(c.observables["pendulum_periods_run"], 2.0)
        self.assertNotIn("support_force_run", c.observables)

    def test_converge(self):
        c = runfile.load_converge(self.files["converge"])
        self.assertEqual([k for k, _ in c.methods], ["xpbd-sequential", "global-cholmod"])
        self.assertEqual(c.attrs["machine"], "fixture CPU")
        x = c.method("xpbd-sequential")
        np.testing.assert_array_equal(x["iteration"], [1, 2, 3])
        np.testing.assert_array_equal(x["error"], [0.4, 0.2, 0.1])
        self.assertEqual(x["attrs"]["xpbd"], 1)
        g = c.method("global-cholmod")
        self.assertEqual(g["attrs"]["converged"], 1)
        self.assertIn("inner_iterations", g)
        self.assertNotIn("error", g)
        self.assertIsNone(c.method("global-ceres"))

    def test_regress(self):
        r = runfile.load_regress(self.files["regress"])
        self.assertEqual(r.columns["case"], ["chain", "cloth"])
        self.assertEqual(r.columns["verdict"], ["same", "ratio"])
        np.testing.assert_array_equal(r.columns["change"], [0.0, 1.5])
        self.assertEqual(r.rows[1], {"case": "cloth", "metric": "wall_time", "units": "s",
                                     "verdict": "ratio", "baseline": 2.0, "now": 3.0,
                                     "change": 1.5, "allowed": 0.0})

    def test_kind_and_load_any(self):
        expected = {"run": runfile.Run, "compare": runfile.Compare, "converge": runfile.Converge,
                    "regress": runfile.Regress}
        for kind, path in self.files.items():
            self.assertEqual(runfile.kind(path), kind)
            self.assertIsInstance(runfile.load_any(path), expected[kind])
        self.assertEqual(runfile.status_of(self.files["run"]), "complete")

    def test_wrong_kind_and_missing_files_raise_naming_the_path(self):
        run = self.files["run"]
        with self.assertRaisesRegex(runfile.RunFileError, "run.h5.*not a compare file"):
            runfile.load_compare(run)
        with self.assertRaisesRegex(runfile.RunFileError, "run.h5.*not a convergence file"):
            runfile.load_converge(run)
        with self.assertRaisesRegex(runfile.RunFileError, "run.h5.*not a regression file"):
            runfile.load_regress(run)
        missing = os.path.join(TMP, "kinds", "missing.h5")
        for load in (runfile.load_compare, runfile.load_converge, runfile.load_regress,
                     runfile.kind, runfile.status_of):
            with self.assertRaisesRegex(runfile.RunFileError, "missing.h5"):
                load(missing)


class PlotRunsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        d = os.path.join(TMP, "plot_runs")
        cls.pbd = fixture(os.path.join(d, "pbd.h5"), "--solver", "pbd", "--iterations", 5)
        cls.xpbd = fixture(os.path.join(d, "xpbd.h5"), "--solver", "xpbd", "--iterations", 5)
        cls.boom = fixture(os.path.join(d, "boom.h5"), "--solver", "xpbd", "--iterations", 1,
                           "--status", "exploded")
        cls.crashed = fixture(os.path.join(d, "crashed.h5"), "--status", "crashed")
        cls.dir = d

    def test_standard_panel(self):
        out = os.path.join(self.dir, "standard.png")
        r = script("plot_runs.py", self.pbd, self.xpbd, self.boom, self.crashed, "-o", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn(out, r.stdout)
        assert_png(self, out)

    def test_export_data_files_are_passed_over(self):
        # `plot_runs.py results/mine/*.h5` after `pbdbench run`: RUN.viz.h5 lies beside RUN.h5.
        import h5py
        viz = os.path.join(self.dir, "pbd.viz.h5")
        with h5py.File(viz, "w") as f:
            f.attrs["pbdbench_viz"] = "pbd.h5"
            f["pinned"] = np.zeros(3)
        self.assertTrue(runfile.is_viz(viz))
        self.assertFalse(runfile.is_viz(self.pbd))
        out = os.path.join(self.dir, "with_viz.png")
        r = script("plot_runs.py", self.pbd, viz, "-o", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertNotIn(viz, r.stderr)  # skipped by design, so silently
        assert_png(self, out)

    def test_chosen_series(self):
        out = os.path.join(self.dir, "chosen.png")
        r = script("plot_runs.py", self.pbd, "--series",
                   "kinetic_energy,linear_momentum,constraint_error_max_stretch", "-o", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        assert_png(self, out)

    def test_all_nan_series_are_left_out(self):
        # Without tets and without a closed surface both volume drifts are NaN throughout.
        flat = fixture(os.path.join(self.dir, "flat.h5"), "--no-volume", 1)
        import plot_runs
        run = runfile.load(flat, frames=False, model=False)
        self.assertTrue(np.all(np.isnan(run.series["volume_drift"])))
        titles = [p[0] for p in plot_runs.standard_panels([run])]
        self.assertNotIn("volume drift", titles)
        self.assertEqual(titles, ["constraint error", "energy", "total energy drift"])
        titles = [p[0] for p in plot_runs.standard_panels([run, runfile.load(self.pbd)])]
        self.assertIn("volume drift", titles)
        out = os.path.join(self.dir, "flat.png")
        r = script("plot_runs.py", flat, "-o", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        assert_png(self, out)

    def test_labels_name_what_differs_and_mark_explosions(self):
        import plot_runs
        runs = [runfile.load(p, frames=False, model=False) for p in (self.pbd, self.xpbd,
                                                                      self.boom)]
        labels = plot_runs.run_labels(runs)
        self.assertEqual(labels[0], "name=pbd, iterations=5")
        self.assertEqual(labels[1], "name=xpbd, iterations=5")
        self.assertEqual(labels[2], "name=xpbd, iterations=1 (exploded)")
        t, _ = plot_runs.explosion_point(runs[2], runs[2].series["kinetic_energy"])
        self.assertAlmostEqual(t, runs[2].attrs["exploded_time"])

    def test_bad_paths(self):
        r = script("plot_runs.py", os.path.join(self.dir, "nope.h5"), "-o",
                   os.path.join(self.dir, "x.png"))
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("nope.h5", r.stderr)
        r = script("plot_runs.py", self.pbd, "-o", os.path.join(self.dir, "no", "dir", "x.png"))
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("cannot write", r.stderr)
        r = script("plot_runs.py", self.pbd, "--series", "no_such_series", "-o",
                   os.path.join(self.dir, "y.png"))
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("no_such_series", r.stderr)


class PlotSweepTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = os.path.join(TMP, "sweep")
        runs = []
        for solver in ("pbd", "xpbd"):
            for it in (1, 2, 5, 10, 20):
                rel = os.path.join("runs", f"{solver}_{it}.h5")
                status = "exploded" if (solver, it) == ("pbd", 1) else "complete"
                fixture(os.path.join(cls.dir, rel), "--solver", solver, "--iterations", it,
                        "--status", status)
                runs.append({"file": rel, "params": {"solver.name": solver,
                                                     "solver.iterations": it},
                             "status": status})
        runs.append({"file": "runs/lost.h5", "params": {"solver.name": "xpbd",
                                                         "solver.iterations": 50},
                     "status": "complete"})  # its file is missing: skipped with a warning
        cls.index = os.path.join(cls.dir, "index.json")
        with open(cls.index, "w") as f:
            json.dump({"sweep": "iterations", "scenario": "fixture",
                       "parameters": ["solver.name", "solver.iterations"], "runs": runs}, f)

    def test_metric_against_parameter(self):
        for at in ("final", "max", "mean", "rms"):
            out = os.path.join(self.dir, f"sweep_{at}.png")
            r = script("plot_sweep.py", self.dir, "--x", "solver.iterations", "--metric",
                       "constraint_error_max", "--at", at, "--group-by", "solver.name",
                       "-o", out)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn(out, r.stdout)
            self.assertIn("lost.h5", r.stderr)
            assert_png(self, out)

    def test_index_file_and_default_grouping(self):
        out = os.path.join(self.dir, "sweep_index.png")
        r = script("plot_sweep.py", self.index, "--x", "solver.iterations", "--metric",
                   "linear_momentum", "-o", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        assert_png(self, out)

    def test_categorical_x(self):
        out = os.path.join(self.dir, "sweep_solver.png")
        r = script("plot_sweep.py", self.index, "--x", "solver.name", "--at", "max", "-o", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        assert_png(self, out)

    def test_reduction_is_named_on_the_axis(self):
        import plot_sweep
        run = runfile.load(os.path.join(self.dir, "runs", "xpbd_5.h5"), frames=False)
        v = run.series["kinetic_energy"]
        self.assertEqual(plot_sweep.reduce_metric(run, "kinetic_energy", "final"), v[-1])
        self.assertEqual(plot_sweep.reduce_metric(run, "kinetic_energy", "max"), v.max())
        self.assertAlmostEqual(plot_sweep.reduce_metric(run, "kinetic_energy", "mean"), v.mean())
        self.assertAlmostEqual(plot_sweep.reduce_metric(run, "kinetic_energy", "rms"),
                               float(np.sqrt(np.mean(v * v))))
        for at, (words, _) in plot_sweep.REDUCTIONS.items():
            self.assertTrue(words, at)

    def test_bad_paths_and_arguments(self):
        r = script("plot_sweep.py", os.path.join(self.dir, "nope"), "--x", "solver.iterations")
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("nope", r.stderr)
        r = script("plot_sweep.py", self.index, "--x", "solver.substeps")
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("solver.substeps", r.stderr)
        r = script("plot_sweep.py", self.index, "--x", "solver.iterations", "--metric", "bogus")
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("bogus", r.stderr)
        bad = os.path.join(self.dir, "bad.json")
        with open(bad, "w") as f:
            f.write("{not json")
        r = script("plot_sweep.py", bad, "--x", "solver.iterations")
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("bad.json", r.stderr)


if __name__ == "__main__":
    unittest.main()
