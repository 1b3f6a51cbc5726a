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

    def test_shards_count_from_0_in_the_help_the_errors_and_the_progress(self):
        # Every command that takes --shard says so in its help.
        for command in ("sweep", "paper", "claims", "regress"):
            r = pbdbench(command, "--help")
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("Shards are counted from 0", " ".join(r.stdout.split()), command)
        sweep = self.write("s.toml", 'scenario = "hanging_chain"\n[set]\n"time.duration" = 0.05\n'
                                     '[grid]\n"solver.iterations" = [1, 2]\n')
        out = os.path.join(self.dir, "sharded")
        # The last shard of N is N-1/N; N/N (a count from 1) is refused with the range, before any run.
        for bad, says in (("2/2", "--shard 2/2: shards are counted from 0: 0/2 to 1/2"),
                          ("-1/2", "--shard -1/2: shards are counted from 0: 0/2 to 1/2"),
                          ("1/1", "--shard 1/1: shards are counted from 0: 0/1 alone"),
                          ("0/0", "--shard 0/0: N, the number of shards, must be at least 1"),
                          ("1of2", "--shard 1of2: expected I/N, two integers: shard I of N, counted from 0"),
                          ("a/2", "--shard a/2: expected I/N")):
            r = pbdbench("sweep", sweep, "--out", out, "--shard", bad)
            self.assertEqual(r.returncode, 2, bad + ": " + r.stdout + r.stderr)
            self.assertIn(says, r.stderr, bad)
            self.assertFalse(os.path.exists(out), bad)
        # The progress names the shard as --shard takes it, with the numbering.
        r = pbdbench("sweep", sweep, "--out", out, "--shard", "1/2")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("1 runs (shard 1/2, counted from 0: 0/2 to 1/2)", r.stdout)
        with open(os.path.join(out, "index.shard-1-of-2.json")) as f:
            self.assertEqual([run["params"]["solver.iterations"] for run in json.load(f)["runs"]], [2])

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

    def test_a_solver_that_cannot_run_the_scene_is_bad_input(self):
        # Found after parsing (the solver refuses the scene), still exit 2 and no file. ref-bdf
        # refuses colliders (only ref-be simulates contact).
        out = os.path.join(self.dir, "cube.h5")
        r = pbdbench("run", "soft_cube_drop", "--solver", "ref-bdf", "--set", "time.duration=0.05", "--out", out)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("does not simulate contacts", r.stderr)
        self.assertIn("soft_cube_drop.toml", r.stderr)
        self.assertFalse(os.path.exists(out))

    def test_series_has_a_header_and_says_where_the_datasets_live(self):
        r = pbdbench("series")
        self.assertEqual(r.returncode, 0)
        self.assertIn("/series/<name>", r.stdout)
        header = [l for l in r.stdout.splitlines() if l.startswith("name")]
        self.assertEqual(header[0].split(), ["name", "dim", "units", "doc"])

    def test_a_collapse_is_complete_with_warnings_in_the_run_line_and_the_summary(self):
        # A soft stable neo-Hookean bar (E = 2e5 Pa, nu = 0.45), xpbd, 10 iterations.
        out = os.path.join(self.dir, "bar.h5")
        r = pbdbench("run", "cantilever_fem", "--set", "scene.youngs_modulus=2e5", "--set", "scene.poisson_ratio=0.45",
                     "--set", "solver.substeps=1", "--set", "solver.iterations=10", "--set", "time.duration=0.5",
                     "--out", out, "--no-xdmf")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("complete with 3 warnings", r.stdout)
        self.assertIn("WARNING volume @1", r.stdout)
        self.assertIn("WARNING inverted @2", r.stdout)  # tets turned inside out (metrics/health.hpp)
        r = pbdbench("summary", out)
        self.assertIn("complete !3", r.stdout)
        self.assertIn("tet volume lost", r.stdout)
        self.assertIn("seen: tets turned inside out (inverted)", r.stdout)
        r = pbdbench("summary", "--csv", out)
        self.assertIn("energy_gain @", r.stdout)

    def test_untrusted_stops_are_warned_and_counted_in_the_summary(self):
        # One Newton iteration against a tolerance no step reaches: every step stops at the limit.
        out = os.path.join(self.dir, "limited.h5")
        r = pbdbench("run", "hanging_chain", "--solver", "global-cholmod", "--set", "solver.global.max_iterations=1",
                     "--set", "solver.global.tolerance=1e-15", "--set", "time.duration=0.1", "--out", out, "--no-xdmf")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("WARNING solver_stop @1", r.stdout)
        self.assertIn("iteration_limit", r.stdout)
        r = pbdbench("summary", out)
        self.assertIn("6 iteration_limit (not trusted) of 6 steps", r.stdout)
        r = pbdbench("summary", "--csv", out)
        self.assertIn("6 iteration_limit (not trusted) of 6 steps", r.stdout)
        # A converging run: its steps are counted, with no warning.
        out = os.path.join(self.dir, "pbd.h5")
        r = pbdbench("run", "hanging_chain", "--solver", "pbd", "--set", "time.duration=0.1", "--out", out, "--no-xdmf")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("6 fixed_work of 6 steps", pbdbench("summary", out).stdout)

    def test_options_of_another_family_are_warned_not_refused(self):
        out = os.path.join(self.dir, "xpbd.h5")
        r = pbdbench("run", "hanging_chain", "--solver", "xpbd", "--set", "solver.seed.damping=0.5",
                     "--set", "time.duration=0.05", "--out", out, "--quiet", "--no-xdmf")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("warning: solver.seed.damping (--set solver.seed.damping=0.5) is set but xpbd does not read it "
                      "(an option of pbd-seed)", r.stderr)
        r = pbdbench("describe", "hanging_chain", "--set", "solver.name=xpbd", "--set", "solver.seed.damping=0.5")
        self.assertIn("warning: solver.seed.damping", r.stdout)
        # A solver the catalogue lacks is refused with the line that names it.
        r = pbdbench("run", "hanging_chain", "--solver", "xbpd", "--out", out + ".no", "--quiet")
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("solver.name = 'xbpd' is not one of", r.stderr)

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
        # --solver as for run: the FEM groups say what pbd uses (nothing: it refuses) and what
        # xpbd uses (the compliances), not a "k = 1" pbd never applies.
        r = pbdbench("describe", "cantilever_fem", "--solver", "pbd")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("solver pbd", r.stdout)
        self.assertIn("fem_deviatoric): no k (pbd has no stiffness rule", r.stdout)
        self.assertNotIn("k = 1", r.stdout)
        self.assertIn("pbd refuses this scene", r.stdout)
        r = pbdbench("describe", "cantilever_fem", "--solver", "xpbd")
        self.assertIn("fem_deviatoric): alpha = ", r.stdout)
        out = os.path.join(self.dir, "a.h5")
        self.assertEqual(pbdbench("run", "spring", "--out", out, "--quiet").returncode, 0)
        r = pbdbench("summary", out)
        self.assertEqual(r.returncode, 0)
        self.assertIn("complete", r.stdout)
        # The README's `summary results/mine/*.h5`: the export's data file beside the run file
        # (a.viz.h5, written by run) is passed over, not refused, and without a line: a file
        # skipped by design is no failure to read about.
        viz = os.path.join(self.dir, "a.viz.h5")
        self.assertTrue(os.path.isfile(viz))
        r = pbdbench("summary", out, viz)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertNotIn("a.viz.h5", r.stderr + r.stdout)
        self.assertEqual(r.stderr, "")
        table = r.stdout.split("Why the steps stopped")[0]  # the rows, not the notes under them
        self.assertEqual([l.split()[0] for l in table.splitlines()[3:] if l.strip()], ["a"], r.stdout)
        self.assertIn("a: ", r.stdout.split("Why the steps stopped")[1])
        r = pbdbench("series", "--markdown")
        with open(os.path.join(SOURCE, "results", "README.md")) as f:
            self.assertIn(r.stdout.strip(), f.read())
        self.assertEqual(pbdbench("run").returncode, 2)
        self.assertEqual(pbdbench("frobnicate").returncode, 2)

    def chain(self, name, *sets, solver="xpbd"):
        out = os.path.join(self.dir, name)
        args = ["run", "hanging_chain", "--solver", solver, "--out", out, "--quiet"]
        for s in sets:
            args += ["--set", s]
        r = pbdbench(*args)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        return out

    def test_observable_series_in_run_files(self):
        xpbd, pbd = self.chain("xpbd.h5"), self.chain("pbd.h5", solver="pbd")
        with h5py.File(xpbd, "r") as f:
            force = f["series/support_force"][()]
            self.assertEqual(f["series/support_force"].attrs["units"], "N")
            self.assertEqual(f["series/tip_displacement"].shape, force.shape)
            self.assertEqual(f["series/pendulum_angle"].attrs["units"], "rad")
        self.assertTrue(np.all(np.isnan(force[0])))  # the initial row: no multipliers yet
        # 19 dynamic particles of 1 kg hang from the pin: 186.4 N upward. At 2 s the chain is
        # still settling, its support force swinging about the weight by about 1 % (183.9 N
        # measured); 3 % tells the weight from that of all 20 particles (196.2 N).
        weight = 19 * 9.81
        self.assertLess(abs(force[-1, 1] - weight), 0.03 * weight, force[-1])
        self.assertLess(np.abs(force[-1, [0, 2]]).max(), 1e-9 * weight, force[-1])
        with h5py.File(pbd, "r") as f:  # pbd keeps no multipliers: no support force
            self.assertTrue(np.all(np.isnan(f["series/support_force"][()])))

    def test_compare_two_runs_writes_hdf5_png_and_summary(self):
        # Frames every 10 steps (the default is a frame each 1/60 s, every step here).
        xpbd = self.chain("xpbd.h5", "output.frame_every=10")
        pbd = self.chain("pbd.h5", "output.frame_every=10", solver="pbd")
        out, png = os.path.join(self.dir, "cmp.h5"), os.path.join(self.dir, "cmp.png")
        r = pbdbench("compare", xpbd, pbd, "--out", out, "--plot", png)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        for text in ("run:       " + xpbd + " (xpbd, hanging_chain, complete)",
                     "reference: " + pbd + " (pbd, hanging_chain, complete)",
                     "13 common frames, t = 0 to 2 s", "13 at the same times, 0 interpolated",
                     "position error at t = 2 s", "largest max position error", "support force: run",
                     "NaN throughout in the reference", "total_energy", "-> " + out, "wrote " + png):
            self.assertIn(text, r.stdout)
        self.assertEqual(r.stderr, "")
        self.assertLess(r.stdout.index("-> " + out), r.stdout.index("wrote " + png))  # in order
        with open(png, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        with h5py.File(out, "r") as f, h5py.File(xpbd, "r") as a, h5py.File(pbd, "r") as b:
            self.assertEqual(attr(f, "run_solver"), "xpbd")
            self.assertEqual(attr(f, "reference_solver"), "pbd")
            self.assertEqual(attr(f, "run_file"), xpbd)
            self.assertEqual(attr(f, "reference_config"), attr(b, "config"))
            self.assertEqual(attr(f, "git_commit"), attr(a, "git_commit"))
            t = f["compare/time"][()]
            np.testing.assert_array_equal(t, a["frames/time"][()])
            rms = f["compare/position_error_rms"][()]
            self.assertEqual(rms.shape, t.shape)
            self.assertEqual(rms[0], 0.0)  # the same initial state
            x, y = a["frames/positions"][-1], b["frames/positions"][-1]
            e = np.linalg.norm(x - y, axis=1)
            self.assertAlmostEqual(rms[-1], np.sqrt(np.mean(e ** 2)), delta=1e-15)
            self.assertAlmostEqual(f["compare/position_error_max"][-1], e.max(), delta=1e-15)
            d = f["compare/diff/total_energy"][()]
            self.assertEqual(d.shape, f["compare/series_time"].shape)
            self.assertAlmostEqual(d[-1], a["series/total_energy"][-1] - b["series/total_energy"][-1], delta=1e-12)
            self.assertEqual(f["compare/diff/total_energy"].attrs["units"], "J")
            for name in ("wall_step", "time_project", "iterations", "step", "time"):
                self.assertNotIn(name, f["compare/diff"])
            self.assertIn("support_force_run", f["compare/observables"])
            self.assertTrue(np.all(np.isnan(f["compare/observables/support_force_reference"][()])))

    def test_compare_interpolates_a_sparser_reference_and_warns(self):
        fine = self.chain("fine.h5", "time.dt=0.008333333333333333", "time.duration=0.5", "output.frame_every=10")
        coarse = self.chain("coarse.h5", "time.duration=0.5", "output.frame_every=10")
        r = pbdbench("compare", fine, coarse, "--until", "0.4")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        # The fine run's frames every 10 steps of 1/120 s, the coarse one's every 1/6 s: up to 0.4 s,
        # 5 common frames, 3 of them (0, 1/6, 1/3 s) the reference's own.
        self.assertIn("5 common frames, t = 0 to 0.3333 s", r.stdout)
        self.assertIn("3 at the same times, 2 interpolated", r.stdout)
        self.assertIn("warning: the reference's frames are sparser", r.stderr)
        r = pbdbench("compare", coarse, fine)  # the other way round: nothing to interpolate
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("4 at the same times, 0 interpolated", r.stdout)
        self.assertEqual(r.stderr, "")

    def test_compare_refuses_different_scenes(self):
        chain = self.chain("chain.h5", "time.duration=0.1")
        longer = self.chain("longer.h5", "time.duration=0.1", "scene.link_length=0.11")
        fall = os.path.join(self.dir, "fall.h5")
        self.assertEqual(pbdbench("run", "free_fall", "--out", fall, "--quiet").returncode, 0)
        out = os.path.join(self.dir, "no.h5")
        r = pbdbench("compare", chain, fall, "--out", out)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("not runs of the same scene: 20 particles against 1", r.stderr)
        self.assertFalse(os.path.exists(out))
        r = pbdbench("compare", chain, longer)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("rest positions differ", r.stderr)
        self.assertEqual(pbdbench("compare", chain, chain, "--until", "-1").returncode, 2)
        self.assertEqual(pbdbench("compare", chain).returncode, 2)  # usage
        r = pbdbench("compare", chain, os.path.join(self.dir, "missing.h5"))
        self.assertEqual(r.returncode, 2)  # a file that is not a readable run file: bad input
        self.assertIn("missing.h5", r.stderr)

    def write_index(self, ids):
        """The claims index beside the experiments folder (claims need one: experiments/claim_index.hpp)."""
        text = ('[source]\ntitle = "t"\nkind = "k"\nlanguage = "l"\nauthor = "a"\norigin = "o"\n'
                'sha256 = "0"\n')
        for i in ids:
            text += (f'[[claim]]\nid = "{i}"\nsection = "{i[1:]}"\nclaim = "c"\noriginal = "o"\n'
                     'translation = "t"\n')
        self.write("index.toml", text)

    def test_claims_runs_one_experiment_writes_the_report_and_checks_verdicts(self):
        exp = os.path.join(self.dir, "experiments")
        os.makedirs(exp)
        self.write("experiments/S9.1.toml", """id = "S9.1"
section = "9.1"
claim = "a particle falls"
experiment = "a particle falls for 0.2 s"
scenario = "free_fall"
[[run]]
name = "xpbd"
set = { "time.duration" = 0.2, "scene.velocity" = [0.0, 0.0, 0.0] }
[[measure]]
name = "drop"
run = "xpbd"
units = "J"
value = "initial(potential_energy) - final(potential_energy)"
doc = "energy released"
[[part]]
says = "it falls"
quote = "落下"
translation = "falls"
judges = "method"
rule = "drop > 0"
[part.counterfactual]
why = "without gravity the particle released at rest does not fall"
runs = { xpbd = { "gravity" = [0.0, 0.0, 0.0] } }
[figure]
kind = "series"
series = "potential_energy"
runs = ["xpbd"]
""")
        self.write_index(["S9.1"])
        out = os.path.join(self.dir, "report")
        record = os.path.join(self.dir, "verdicts.toml")
        args = ["claims", "--experiments", exp, "--out", out, "--runs", os.path.join(self.dir, "runs")]
        r = pbdbench(*args, "--record", record)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("S9.1    supported", r.stdout)
        with open(os.path.join(out, "README.md")) as f:
            report = f.read()
        self.assertIn("| [S9.1](#s91) | c | 1 supported | **supported** | not registered; rules written before any result |", report)
        self.assertIn("On the variant the rule gives **contradicted**", report)  # its counterfactual flipped
        self.assertIn("1 part in the article's regime: 1 supported", report)
        self.assertTrue(os.path.exists(os.path.join(out, "figures", "S9.1.png")))
        with open(os.path.join(out, "claims.json")) as f:
            self.assertEqual(json.load(f)["claims"][0]["verdict"], "supported")
        # The same verdicts: exit 0; a changed record: exit 5 naming the part.
        self.assertEqual(pbdbench(*args, "--no-plots", "--expect", record).returncode, 0)
        with open(record) as f:
            text = f.read().replace('"S9.1.1" = "supported"', '"S9.1.1" = "contradicted"')
        self.write("changed.toml", text)
        r = pbdbench(*args, "--no-plots", "--expect", os.path.join(self.dir, "changed.toml"))
        self.assertEqual(r.returncode, 5, r.stdout + r.stderr)
        self.assertIn("S9.1.1: recorded contradicted, now supported", r.stderr)
        # An unknown id and a bad file are bad input (exit 2), naming the file and line.
        r = pbdbench(*args, "S9.9")
        self.assertEqual(r.returncode, 2)
        self.assertIn("no claim 'S9.9'", r.stderr)
        self.write("experiments/S9.2.toml", 'id = "S9.2"\nsection = "9.2"\nclaim = "x"\nexperiment = "y"\nbogus = 1\n')
        r = pbdbench(*args)
        self.assertEqual(r.returncode, 2)
        self.assertIn("S9.2.toml:5: bogus: unknown key", r.stderr)
        # An experiment the index does not know, and a claim of the index without an experiment.
        self.write("experiments/S9.2.toml", open(os.path.join(exp, "S9.1.toml")).read().replace('"S9.1"', '"S9.2"'))
        r = pbdbench(*args)
        self.assertEqual(r.returncode, 2)
        self.assertIn("'S9.2' is not a claim of the index", r.stderr)
        os.remove(os.path.join(exp, "S9.2.toml"))
        self.write_index(["S9.1", "S9.4"])
        r = pbdbench(*args)
        self.assertEqual(r.returncode, 2)
        self.assertIn("'S9.4' has neither an experiment", r.stderr)


    def test_experiment_shards_run_in_parallel_processes_and_merge(self):
        exp = os.path.join(self.dir, "experiments")
        os.makedirs(exp)
        self.write("experiments/S9.3.toml", """id = "S9.3"
section = "9.3"
claim = "shuffled orders still hold a chain"
experiment = "a short chain, 6 seeded trials"
scenario = "hanging_chain"
[[run]]
name = "shuffled"
set = { "time.duration" = 0.1, "solver.order" = "shuffled" }
trials = 6
trial_key = "solver.shuffle_seed"
[[measure]]
name = "err"
run = "shuffled"
value = "final(constraint_error_max)"
doc = "final error"
[[part]]
says = "held"
quote = "稳"
translation = "holds"
judges = "method"
rule = "err < 0.1"
[part.counterfactual]
why = "links a hundred million times softer stretch by half their length in 0.1 s"
runs = { shuffled = { "scene.compliance" = 1.0 } }
""")
        self.write_index(["S9.3"])
        runs = os.path.join(self.dir, "runs")
        args = ["claims", "--experiments", exp, "--runs", runs, "--no-plots"]
        shards = [subprocess.Popen([BIN, *args, "--shard", f"{i}/3"], stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True) for i in range(3)]
        for p in shards:
            out, err = p.communicate(timeout=300)
            self.assertEqual(p.returncode, 0, out + err)
            self.assertIn("4 runs made, 0 failed", out)  # 6 trials and their 6 counterfactual variants, over 3 shards
        for i in range(3):
            with open(os.path.join(runs, f"index.shard-{i}-of-3.json")) as f:
                index = json.load(f)
            self.assertEqual(len(index["runs"]), 12)
            mine = [r for k, r in enumerate(index["runs"]) if k % 3 == i]
            self.assertTrue(all(r["status"] == "complete" for r in mine), mine)
        # The merge: every run file is current, nothing runs again; the index lists all twelve.
        r = pbdbench(*args, "--out", os.path.join(self.dir, "report"), "--jobs", "2")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("12 runs, 0 to run", r.stderr)
        self.assertIn("S9.3    supported", r.stdout)
        with open(os.path.join(runs, "index.json")) as f:
            self.assertEqual([x["status"] for x in json.load(f)["runs"]], ["complete"] * 12)
        # The job array (--slurm) is test_slurm_cli.py's.

    def test_regress_update_compare_against_and_a_worse_metric(self):
        base = os.path.join(self.dir, "base.toml")
        a = os.path.join(self.dir, "a")
        args = ["regress", "spring_xpbd", "chain_pbd", "--baselines", base, "--no-plot"]
        r = pbdbench(*args, "--update", "--out", a)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("2 cases measured; baselines written", r.stdout)
        r = pbdbench(*args, "--out", a, "--repeat")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("0 worse", r.stdout)
        with open(os.path.join(a, "regress.md")) as f:
            self.assertIn("run twice, the same bits", f.read())
        # A baseline claiming a smaller final constraint error: now is worse, named, exit 6.
        with open(base) as f:
            text = f.read()
        lines = text.split("\n")
        start = lines.index("[chain_pbd]")
        for k in range(start, len(lines)):
            if lines[k].startswith("constraint_error_final = "):
                value = float(lines[k].split("=")[1])
                lines[k] = f"constraint_error_final = {value / 2!r}"
                break
        self.write("worse.toml", "\n".join(lines))
        r = pbdbench("regress", "spring_xpbd", "chain_pbd", "--baselines", os.path.join(self.dir, "worse.toml"),
                     "--out", os.path.join(self.dir, "b"))
        self.assertEqual(r.returncode, 6, r.stdout + r.stderr)
        self.assertRegex(r.stdout, r"chain_pbd +constraint_error_final .* worse")
        # The verdict table first; the timings after it, under their own heading, never a verdict.
        lines = r.stdout.splitlines()
        table = lines.index(next(l for l in lines if l.startswith("case ") and l.endswith("verdict")))
        heading = lines.index(next(l for l in lines if l.startswith("timings (")))
        worse = lines.index(next(l for l in lines if "constraint_error_final" in l))
        self.assertLess(table, worse)
        self.assertLess(worse, heading)
        timed = [k for k, l in enumerate(lines) if "wall_per_step" in l]
        self.assertTrue(timed)
        self.assertTrue(all(k > heading for k in timed), r.stdout)
        self.assertTrue(all(not lines[k].rstrip().endswith(("ratio", "same", "worse")) for k in timed), r.stdout)
        self.assertTrue(os.path.exists(os.path.join(self.dir, "b", "regress.png")))
        with h5py.File(os.path.join(self.dir, "b", "regress.h5")) as f:
            self.assertIn(b"worse", list(f["verdict"][()]))
        # Two result sets against each other: the same build, the same numbers.
        r = pbdbench("regress", "spring_xpbd", "chain_pbd", "--against", a, "--out", os.path.join(self.dir, "c"),
                     "--no-plot")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("0 better, 0 worse", r.stdout)
        r = pbdbench("regress", "no_such_case")
        self.assertEqual(r.returncode, 2)
        self.assertIn("no case named 'no_such_case'", r.stderr)

    def test_regress_shows_the_warnings_of_its_runs(self):
        # A registry of one's own (--registry) with a case whose run warns: the inverted tets of
        # failure 3.3 lose volume (metrics/health.hpp's volume_lost). The console and regress.md
        # list the warning after the verdicts; the verdicts stand (0 worse against its own baseline).
        registry = self.write("cases.toml", "\n".join([
            "[[metric]]", 'name = "volume_drift_final"', 'value = "abs(final(volume_drift))"',
            'doc = "|relative change of the tet volume| at the end"', 'worse = "higher"', "rel = 1e-3", "abs = 1e-12",
            "", "[[case]]", 'name = "inverted"', 'scenario = "failures/inverted_tets"',
            'set = { "solver.name" = "pbd" }', "quick = true", ""]))
        # Paths relative to the working folder, the baselines' without a folder of its own.
        out = os.path.join(self.dir, "w")
        args = ["regress", "--registry", "cases.toml", "--baselines", "base.toml", "--out", "w", "--no-plot"]
        r = pbdbench(*args, "--update", cwd=self.dir)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("1 cases measured; baselines written", r.stdout)
        self.assertTrue(os.path.exists(os.path.join(self.dir, "base.toml")))
        r = pbdbench(*args, cwd=self.dir)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("0 worse", r.stdout)
        lines = r.stdout.splitlines()
        heading = lines.index("warnings of the runs:")
        warned = [l for l in lines[heading + 1:] if l.startswith("  inverted: WARNING ")]
        self.assertTrue(warned, r.stdout)
        self.assertTrue(any("volume" in l for l in warned), r.stdout)
        with open(os.path.join(out, "regress.md")) as f:
            md = f.read()
        self.assertIn("## Warnings of the runs", md)
        self.assertIn("inverted: WARNING", md)
        # A registry that is not there is refused (exit 2).
        r = pbdbench("regress", "--registry", os.path.join(self.dir, "none.toml"), "--out", out)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("none.toml", r.stderr)


if __name__ == "__main__":
    unittest.main()
