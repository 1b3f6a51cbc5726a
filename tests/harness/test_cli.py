#!/usr/bin/python3
"""The pbdbench command line end to end, as a user types it: exit codes, messages, files.

Run by CTest with PBDBENCH_BIN (the executable), PBDBENCH_SCENARIOS and PBDBENCH_SOURCE_DIR set.
"""
import json
import os
import signal
import subprocess
import tempfile
import time
import unittest

import h5py
import numpy as np

BIN = os.environ["PBDBENCH_BIN"]
SOURCE = os.environ["PBDBENCH_SOURCE_DIR"]


def pbdbench(*args, cwd=None, timeout=300):
    return subprocess.run([BIN, *args], capture_output=True, text=True, cwd=cwd, timeout=timeout)


def wait_for_rows(path, rows, timeout=60.0):
    """Waits until the run file at `path` holds at least `rows` rows of series (the writer
    publishes complete files by rename, so they can be read while the run goes on)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with h5py.File(path, "r") as f:
                if f["series/time"].shape[0] >= rows:
                    return
        except (OSError, KeyError):
            pass
        time.sleep(0.05)
    raise AssertionError(f"{path} did not reach {rows} rows in {timeout} s")


def attr(f, name):
    value = f.attrs[name]
    return value.decode() if isinstance(value, bytes) else value


class CliTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_cli_")
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def write(self, name, text):
        path = os.path.join(self.dir, name)
        with open(path, "w") as f:
            f.write(text)
        return path

    def test_run_writes_a_complete_file_that_h5py_reads(self):
        out = os.path.join(self.dir, "ff.h5")
        r = pbdbench("run", "free_fall", "--out", out, "--set", "time.duration=0.5")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("complete", r.stdout)
        with h5py.File(out, "r") as f:
            self.assertEqual(attr(f, "status"), "complete")
            self.assertEqual(attr(f, "solver"), "xpbd")
            self.assertIn("duration = 0.5", attr(f, "config"))
            for key in ("git_commit", "compiler", "cxx_flags", "build_type", "pbdbench_version"):
                self.assertTrue(attr(f, key), key)
            t = f["series/time"][()]
            self.assertAlmostEqual(t[-1], 0.5, places=12)
            for name in ("constraint_error_max", "constraint_error_rms", "volume_drift", "kinetic_energy",
                         "potential_energy", "elastic_energy", "total_energy"):
                self.assertEqual(f["series/" + name].shape[0], t.shape[0], name)
                self.assertIn("units", f["series/" + name].attrs)
            self.assertEqual(f["frames/positions"].shape[1:], (1, 3))
            self.assertEqual(f["frames/positions"].shape[0], f["frames/time"].shape[0])
            self.assertEqual(f["model/rest_positions"].shape, (1, 3))

    def test_solver_flag_and_overrides(self):
        out = os.path.join(self.dir, "chain.h5")
        r = pbdbench("run", "hanging_chain", "--solver", "pbd", "--set", "solver.iterations=3",
                     "--set", "time.duration=0.2", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stderr)
        with h5py.File(out, "r") as f:
            self.assertEqual(attr(f, "solver"), "pbd")
            self.assertIn("iterations = 3", attr(f, "config"))
            self.assertTrue(np.all(f["series/iterations"][1:] == 3))

    def test_unknown_override_is_refused_naming_it(self):
        r = pbdbench("run", "free_fall", "--set", "solver.iteratons=3", "--out", os.path.join(self.dir, "x.h5"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("solver.iteratons", r.stderr)
        self.assertIn("solver.iterations", r.stderr)  # the suggestion
        self.assertFalse(os.path.exists(os.path.join(self.dir, "x.h5")))

    def test_bad_scenario_file_names_file_key_and_line(self):
        path = self.write("mine.toml", '[time]\ndt = 0.01\nduration = 1.0\n[scene]\nkind = "particle"\nmass = -2.0\n')
        r = pbdbench("run", path, "--out", os.path.join(self.dir, "x.h5"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("mine.toml:6", r.stderr)
        self.assertIn("scene.mass", r.stderr)

    def test_nan_is_refused(self):
        path = self.write("nan.toml", '[time]\ndt = nan\nduration = 1.0\n[scene]\nkind = "particle"\n')
        r = pbdbench("run", path, "--out", os.path.join(self.dir, "x.h5"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("nan.toml:2", r.stderr)
        self.assertIn("time.dt", r.stderr)

    def test_explosion_exit_code_and_record(self):
        out = os.path.join(self.dir, "boom.h5")
        r = pbdbench("run", "free_fall", "--set", "limits.max_speed=6", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 3, r.stdout + r.stderr)
        with h5py.File(out, "r") as f:
            self.assertEqual(attr(f, "status"), "exploded")
            step = int(f.attrs["exploded_step"])
            self.assertEqual(f["series/time"].shape[0], step + 1)

    def test_sweep_runs_in_parallel_then_skips_what_is_complete(self):
        sweep = self.write("s.toml", 'scenario = "hanging_chain"\n[set]\n"time.duration" = 0.2\n'
                                     '[grid]\n"solver.name" = ["pbd", "xpbd"]\n"solver.iterations" = [1, 3]\n')
        out = os.path.join(self.dir, "sweep")
        r = pbdbench("sweep", sweep, "--out", out, "--jobs", "2")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("0 already complete, 4 to run", r.stdout)
        with open(os.path.join(out, "index.json")) as f:
            index = json.load(f)
        self.assertEqual(index["parameters"], ["solver.name", "solver.iterations"])
        self.assertEqual(len(index["runs"]), 4)
        self.assertEqual({run["status"] for run in index["runs"]}, {"complete"})
        self.assertEqual(index["runs"][0]["params"], {"solver.name": "pbd", "solver.iterations": 1})
        for run in index["runs"]:
            self.assertTrue(os.path.exists(os.path.join(out, run["file"])))
        mtimes = [os.path.getmtime(os.path.join(out, run["file"])) for run in index["runs"]]
        r = pbdbench("sweep", sweep, "--out", out, "--jobs", "2")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("4 already complete, 0 to run", r.stdout)
        self.assertEqual(mtimes, [os.path.getmtime(os.path.join(out, run["file"])) for run in index["runs"]])
        r = pbdbench("sweep", sweep, "--out", out, "--jobs", "2", "--force", "--quiet")
        self.assertEqual(r.returncode, 0)
        self.assertIn("0 already complete, 4 to run", r.stdout)

    def test_sweep_shards_cover_the_grid(self):
        sweep = self.write("s.toml", 'scenario = "hanging_chain"\n[set]\n"time.duration" = 0.1\n'
                                     '[grid]\n"solver.iterations" = [1, 2, 3]\n')
        out = os.path.join(self.dir, "sharded")
        files = []
        for i in range(2):
            r = pbdbench("sweep", sweep, "--out", out, "--shard", f"{i}/2", "--quiet")
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            with open(os.path.join(out, f"index.shard-{i}-of-2.json")) as f:
                files += [run["file"] for run in json.load(f)["runs"]]
        self.assertEqual(len(files), 3)
        self.assertEqual(len(set(files)), 3)
        r = pbdbench("sweep", sweep, "--out", out, "--shard", "2/2")
        self.assertEqual(r.returncode, 2)

    def test_sweep_with_a_refused_run_starts_nothing(self):
        sweep = self.write("bad.toml", 'scenario = "hanging_chain"\n[grid]\n"solver.iterations" = [1, 0]\n')
        out = os.path.join(self.dir, "bad")
        r = pbdbench("sweep", sweep, "--out", out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("solver.iterations", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(out, "index.json")))

    def test_sigkill_leaves_a_readable_incomplete_file(self):
        out = os.path.join(self.dir, "killed.h5")
        p = subprocess.Popen([BIN, "run", "hanging_cloth", "--set", "time.duration=600", "--out", out, "--quiet"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wait_for_rows(out, 3)
        p.send_signal(signal.SIGKILL)
        p.wait()
        with h5py.File(out, "r") as f:
            self.assertEqual(attr(f, "status"), "incomplete")
            self.assertGreater(f["series/time"].shape[0], 1)
            self.assertEqual(f["model/rest_positions"].shape, (4096, 3))

    def test_sigint_marks_the_file_incomplete_and_exits_4(self):
        out = os.path.join(self.dir, "interrupted.h5")
        p = subprocess.Popen([BIN, "run", "hanging_cloth", "--set", "time.duration=600", "--out", out, "--quiet"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        wait_for_rows(out, 2)  # the file exists once the run has started, signal handlers in place
        p.send_signal(signal.SIGINT)
        stdout, _ = p.communicate(timeout=60)
        self.assertEqual(p.returncode, 4, stdout)
        with h5py.File(out, "r") as f:
            self.assertEqual(attr(f, "status"), "incomplete")
            self.assertIn("interrupted", attr(f, "status_reason"))

    def test_list_describe_summary_series(self):
        r = pbdbench("list")
        self.assertEqual(r.returncode, 0)
        for name in ("free_fall", "spring", "pendulum", "hanging_chain", "hanging_cloth", "cantilever_beam",
                     "soft_cube_drop", "balls_in_bowl", "pbd-seed", "xpbd"):
            self.assertIn(name, r.stdout)
        r = pbdbench("describe", "hanging_cloth")
        self.assertEqual(r.returncode, 0)
        for key in ("time.dt", "solver.iterations", "scene.resolution", "scene.stretch_compliance"):
            self.assertIn(key, r.stdout)
        r = pbdbench("describe", "cloth")
        self.assertEqual(r.returncode, 0)
        self.assertIn("scene.bending_model", r.stdout)
        # "spring" is both a scenario and a scene kind: the scenario wins, --kind asks for the kind.
        r = pbdbench("describe", "spring")
        self.assertIn("spring.toml:", r.stdout)
        r = pbdbench("describe", "spring", "--kind")
        self.assertIn("Scene kind 'spring'", r.stdout)
        self.assertEqual(pbdbench("describe", "no_such_thing").returncode, 2)
        out = os.path.join(self.dir, "a.h5")
        self.assertEqual(pbdbench("run", "spring", "--out", out, "--quiet").returncode, 0)
        r = pbdbench("summary", out)
        self.assertEqual(r.returncode, 0)
        self.assertIn("complete", r.stdout)
        r = pbdbench("series", "--markdown")
        with open(os.path.join(SOURCE, "results", "README.md")) as f:
            self.assertIn(r.stdout.strip(), f.read())
        self.assertEqual(pbdbench("run").returncode, 2)
        self.assertEqual(pbdbench("frobnicate").returncode, 2)


if __name__ == "__main__":
    unittest.main()
