#!/usr/bin/python3
"""Tests of `pbdbench converge`, scripts/plot_convergence.py and scripts/summarize_global.py on
tiny scenes: a 6 x 6 cloth and a 3 x 1 x 1 block for the convergence files, a 5-particle chain
for the run files.

Environment (set by tests/scripts/CMakeLists.txt):
    PBDBENCH_BIN       the pbdbench executable
    PBDBENCH_SCRIPTS   the scripts/ folder
    PBDBENCH_TEST_TMP  a folder for the files the tests write
"""
import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import unittest

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(HERE, "..", "..", "scripts"))
BIN = os.environ.get("PBDBENCH_BIN", os.path.join(HERE, "..", "..", "build", "pbdbench"))
TMP = os.path.join(os.environ.get("PBDBENCH_TEST_TMP", os.path.join(HERE, "tmp")), "global_scripts")
PYTHON = "/usr/bin/python3"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
METHODS = ["xpbd-sequential", "xpbd-colored", "xpbd-jacobi", "global-cholmod", "global-cg",
           "global-cg-matrix-free", "global-ceres"]

sys.path.insert(0, SCRIPTS)
import summarize_global  # noqa: E402


def pbdbench(*args):
    return subprocess.run([BIN, *args], capture_output=True, text=True, timeout=120)


def text(v):
    return v.decode() if isinstance(v, bytes) else v


@unittest.skipUnless(os.path.isfile(BIN), f"no pbdbench executable at {BIN}")
class Converge(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        shutil.rmtree(TMP, ignore_errors=True)
        os.makedirs(TMP)
        cls.cloth = os.path.join(TMP, "converge-cloth.h5")
        cls.cloth_run = pbdbench("converge", "hanging_cloth", "--set", "scene.resolution=[6, 6]",
                                 "--max-sweeps", "50", "--warmup-steps", "2", "--out", cls.cloth)
        cls.block = os.path.join(TMP, "converge-block.h5")
        cls.block_run = pbdbench("converge", "cantilever_beam", "--set", "scene.cells=[3, 1, 1]",
                                 "--set", "scene.size=[0.3, 0.1, 0.1]", "--max-sweeps", "20",
                                 "--warmup-steps", "3", "--quiet", "--out", cls.block)

    def test_file_has_every_method_with_its_datasets(self):
        self.assertEqual(self.cloth_run.returncode, 0, self.cloth_run.stderr)
        with h5py.File(self.cloth, "r") as f:
            self.assertEqual(text(f.attrs["content"]), "pbdbench converge")
            self.assertEqual(text(f.attrs["scene"]), "hanging_cloth")
            self.assertEqual(int(f.attrs["warmup_steps"]), 2)
            self.assertAlmostEqual(float(f.attrs["dt"]), 1.0 / 60.0)
            for key in ("machine", "build_type", "residual_note"):
                self.assertTrue(text(f.attrs[key]), key)
            self.assertEqual(text(f.attrs["methods"]).split(","), METHODS)
            for m in METHODS:
                g = f[m]
                self.assertTrue(text(g.attrs["method"]))
                for name in ("iteration", "residual", "time"):
                    self.assertGreater(g[name].shape[0], 0, f"{m}/{name}")
                    self.assertEqual(g[name].shape, g["iteration"].shape)
                self.assertEqual(text(g["residual"].attrs["units"]), "m")
                self.assertEqual(text(g["time"].attrs["units"]), "s")
                self.assertEqual("error" in g, m.startswith("xpbd"))
            sweeps = f["xpbd-sequential/iteration"][()]
            self.assertEqual(list(sweeps), [1, 2, 3, 5, 7, 10, 15, 20, 30, 50])

    def test_global_methods_reach_the_tolerance(self):
        for path in (self.cloth, self.block):
            with h5py.File(path, "r") as f:
                tol = float(f.attrs["tolerance"])
                for m in METHODS[3:]:
                    residual = f[m]["residual"][()]
                    self.assertLessEqual(residual[-1], tol, f"{path}: {m}")
                    self.assertEqual(int(f[m].attrs["converged"]), 1, f"{path}: {m}")
                    # Each starts from x~: the same first residual as the file's start.
                    self.assertAlmostEqual(residual[0], float(f.attrs["start_residual"]),
                                           delta=1e-12 * residual[0])

    def test_gauss_seidel_converges_towards_x_star(self):
        with h5py.File(self.cloth, "r") as f:
            g = f["xpbd-sequential"]
            residual, error = g["residual"][()], g["error"][()]
            self.assertLess(residual[-1], residual[0])
            self.assertLess(error[-1], error[0])
            self.assertTrue(np.all(g["time"][()] > 0))
            self.assertEqual(float(f["global-cholmod"].attrs["final_error"]), 0.0)

    def test_table_on_stdout(self):
        out = self.cloth_run.stdout
        self.assertIn("to 1e-06 m", out)
        for m in METHODS:
            self.assertIn(m, out)
        self.assertIn("-> " + self.cloth, out)
        self.assertEqual(self.block_run.returncode, 0, self.block_run.stderr)
        self.assertEqual(self.block_run.stderr, "")  # --quiet: no progress lines

    def test_methods_subset_and_bad_input(self):
        path = os.path.join(TMP, "subset.h5")
        r = pbdbench("converge", "hanging_cloth", "--set", "scene.resolution=[4, 4]",
                     "--methods", "xpbd-jacobi,global-cg", "--max-sweeps", "3", "--quiet",
                     "--out", path)
        self.assertEqual(r.returncode, 0, r.stderr)
        with h5py.File(path, "r") as f:
            self.assertEqual(text(f.attrs["methods"]), "xpbd-jacobi,global-cg")
            self.assertEqual(list(f["xpbd-jacobi/iteration"][()]), [1, 2, 3])
        r = pbdbench("converge", "hanging_cloth", "--methods", "newton", "--out", path)
        self.assertEqual(r.returncode, 2)
        self.assertIn("unknown method 'newton'", r.stderr)
        r = pbdbench("converge", "hanging_cloth", "--max-sweeps", "0", "--out", path)
        self.assertEqual(r.returncode, 2)

    def test_plot_writes_a_png(self):
        png = os.path.join(TMP, "convergence.png")
        r = subprocess.run([PYTHON, os.path.join(SCRIPTS, "plot_convergence.py"), self.cloth,
                            self.block, "-o", png], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(png, "rb") as f:
            self.assertEqual(f.read(8), PNG_MAGIC)

    def test_plot_refuses_a_file_that_is_not_one(self):
        path = os.path.join(TMP, "other.h5")
        with h5py.File(path, "w") as f:
            f.attrs["content"] = "pbdbench compare"
        r = subprocess.run([PYTHON, os.path.join(SCRIPTS, "plot_convergence.py"), path, "-o",
                            os.path.join(TMP, "other.png")], capture_output=True, text=True,
                           timeout=120)
        self.assertEqual(r.returncode, 2)
        self.assertIn("not a convergence file", r.stderr)


@unittest.skipUnless(os.path.isfile(BIN), f"no pbdbench executable at {BIN}")
class SummarizeGlobal(unittest.TestCase):
    def test_one_table_with_a_row_per_run(self):
        d = os.path.join(TMP, "runs", "hanging_chain")
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        common = ["--set", "scene.links=4", "--set", "time.duration=0.05", "--set",
                  "solver.substeps=1", "--quiet"]
        r = pbdbench("run", "hanging_chain", "--solver", "xpbd", "--set", "solver.iterations=5",
                     "--set", "shadow.solver=global-cholmod", *common, "--out",
                     os.path.join(d, "xpbd-it5.h5"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        r = pbdbench("run", "hanging_chain", "--solver", "global-cholmod", *common, "--out",
                     os.path.join(d, "global-cholmod.h5"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = summarize_global.main([d])
        self.assertEqual(code, 0)
        lines = out.getvalue().strip().splitlines()
        self.assertTrue(lines[0].startswith("### hanging_chain"), lines[0])
        table = [line for line in lines if line.startswith("|")]
        self.assertEqual(len(table), 4)  # header, rule, two runs
        self.assertIn("mean shadow_gap_rms (m)", table[0])
        xpbd, newton = (line.split("|")[1:-1] for line in table[2:])
        self.assertIn("xpbd 5 it (shadow global-cholmod)", xpbd[0])
        self.assertEqual(xpbd[1].strip(), "5 sweeps")
        for cell in (xpbd[2], xpbd[3], xpbd[5], xpbd[6]):
            self.assertGreater(float(cell), 0.0)
        self.assertIn("global-cholmod", newton[0])
        self.assertIn("Newton", newton[1])
        self.assertLessEqual(float(newton[7]), 1e-9)

    def test_no_run_files_is_an_error(self):
        empty = os.path.join(TMP, "empty")
        os.makedirs(empty, exist_ok=True)
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            self.assertEqual(summarize_global.main([empty]), 1)


class TimeRuns(unittest.TestCase):
    """scripts/time_runs.py: whole runs of two builds side by side (here one binary, with and
    without an option), every run recorded, the table's ratios against the first build."""

    def test_two_builds_rotated_and_tabled(self):
        os.makedirs(TMP, exist_ok=True)
        out = os.path.join(TMP, "timings.json")
        if os.path.exists(out):
            os.remove(out)
        args = ["--reps", "2", "--solver", "global-cholmod", "--scene", "hanging_chain:0.05",
                "--build", f"reuse={BIN}",
                "--build", f"direct={BIN} --set solver.global.factor_reuse=false", "--out", out]
        r = subprocess.run([PYTHON, os.path.join(SCRIPTS, "time_runs.py"), *args],
                           capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out) as f:
            record = json.load(f)
        self.assertEqual(len(record["runs"]), 4)
        # The order rotates: the first repetition starts with the first build, the second with
        # the second.
        self.assertEqual([x["build"] for x in record["runs"]], ["reuse", "direct", "direct", "reuse"])
        for x in record["runs"]:
            self.assertGreater(x["cpu_s"], 0.0)
            self.assertGreater(x["wall_s"], 0.0)
        self.assertIn("| hanging_chain | reuse |", r.stdout)
        self.assertIn("| hanging_chain | direct |", r.stdout)
        # The baseline against itself is 1 in every repetition.
        row = [line for line in r.stdout.splitlines() if line.startswith("| hanging_chain | reuse |")][0]
        self.assertTrue(row.endswith("| 1.00 [1.00, 1.00] | 1.00 [1.00, 1.00] |"), row)
        # An existing --out is not overwritten; a malformed --build is refused.
        again = subprocess.run([PYTHON, os.path.join(SCRIPTS, "time_runs.py"), *args],
                               capture_output=True, text=True, timeout=60)
        self.assertEqual(again.returncode, 2)
        self.assertIn("exists", again.stderr)
        bad = subprocess.run([PYTHON, os.path.join(SCRIPTS, "time_runs.py"), "--solver", "x",
                              "--scene", "a:1", "--build", "nolabel", "--out", out + ".2"],
                             capture_output=True, text=True, timeout=60)
        self.assertEqual(bad.returncode, 2)
        self.assertIn("LABEL=BINARY", bad.stderr)

    def test_series_summed_per_run(self):
        """--series: the run file's time_* series summed over each run, tabled like the times;
        a series the run file lacks stops the script with its name."""
        os.makedirs(TMP, exist_ok=True)
        out = os.path.join(TMP, "timings_series.json")
        for path in (out, out + ".2"):
            if os.path.exists(path):
                os.remove(path)
        args = ["--reps", "1", "--solver", "xpbd", "--scene", "hanging_chain:0.05",
                "--series", "time_residual", "--series", "time_project",
                "--build", f"on={BIN}", "--build", f"off={BIN} --set solver.xpbd.residuals=false"]
        r = subprocess.run([PYTHON, os.path.join(SCRIPTS, "time_runs.py"), *args, "--out", out],
                           capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out) as f:
            record = json.load(f)
        runs = {x["build"]: x for x in record["runs"]}
        self.assertGreater(runs["on"]["series_ms"]["time_residual"], 0.0)
        self.assertEqual(runs["off"]["series_ms"]["time_residual"], 0.0)  # not computed: 0 a step
        self.assertGreater(runs["off"]["series_ms"]["time_project"], 0.0)
        self.assertIn("| hanging_chain | on | time_residual |", r.stdout)
        self.assertIn("| hanging_chain | off | time_project |", r.stdout)
        missing = subprocess.run([PYTHON, os.path.join(SCRIPTS, "time_runs.py"), "--reps", "1", "--solver",
                                  "xpbd", "--scene", "hanging_chain:0.05", "--series", "no_such_series",
                                  "--build", f"on={BIN}", "--out", out + ".2"],
                                 capture_output=True, text=True, timeout=300)
        self.assertNotEqual(missing.returncode, 0)
        self.assertIn("no_such_series", missing.stderr)
        self.assertFalse(os.path.exists(out + ".2"))


if __name__ == "__main__":
    unittest.main()
