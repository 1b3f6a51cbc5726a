#!/usr/bin/python3
"""Nothing lost, nothing hidden: what --out may replace, one writer per file, interrupts inside
long steps, sweeps that stop and whose children die with them, and the messages of bad input.

Run by CTest with PBDBENCH_BIN (the executable), PBDBENCH_SCENARIOS and PBDBENCH_SOURCE_DIR set.
"""
import json
import os
import signal
import socket
import subprocess
import tempfile
import time
import unittest

import h5py

BIN = os.environ["PBDBENCH_BIN"]
SOURCE = os.environ["PBDBENCH_SOURCE_DIR"]
# A step of minutes: 64 x 64 cloth, 100,000 projection sweeps per step.
LONG_STEP = ["hanging_cloth", "--set", "solver.iterations=100000", "--set", "time.duration=1"]
# Many short steps: a chain for 2000 s (120,000 steps, a few seconds to a minute).
LONG_RUN = ["hanging_chain", "--set", "time.duration=2000"]


def pbdbench(*args, cwd=None, timeout=300):
    return subprocess.run([BIN, *args], capture_output=True, text=True, cwd=cwd, timeout=timeout)


def wait_for(predicate, timeout=60.0, what="a condition"):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


def attr(f, name):
    value = f.attrs[name]
    return value.decode() if isinstance(value, bytes) else value


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie (exited, not yet reaped) counts as dead.
    with open(f"/proc/{pid}/stat") as f:
        return f.read().split(")")[-1].split()[0] != "Z"


def children_of(pid):
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().split(")")[-1].split()
                if int(fields[1]) == pid:
                    out.append(int(entry))
            except OSError:
                pass
    return out


class OutputPaths(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_safety_")
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def path(self, name):
        return os.path.join(self.dir, name)

    def refused(self, out, *why):
        r = pbdbench("run", "spring", "--set", "time.duration=0.1", "--out", out, "--quiet", "--no-xdmf")
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("--out " + out, r.stderr)
        for w in why:
            self.assertIn(w, r.stderr)
        self.assertFalse(os.path.exists(out + ".lock"))
        self.assertFalse(os.path.exists(out + ".shadow"))
        return r

    def test_a_file_that_is_not_a_run_file_is_never_replaced(self):
        for name, content in [("notes.txt", b"my notes\n"), ("other.h5", b"\x89HDF\r\n\x1a\nnot really"),
                              ("empty.h5", b"")]:
            out = self.path(name)
            with open(out, "wb") as f:
                f.write(content)
            self.refused(out, "not a pbdbench run file")
            with open(out, "rb") as f:
                self.assertEqual(f.read(), content, name)

    def test_an_hdf5_file_of_another_kind_is_not_replaced(self):
        out = self.path("data.h5")
        with h5py.File(out, "w") as f:
            f["x"] = [1, 2, 3]
            f.attrs["status"] = "complete"  # not enough to be a run file
        self.refused(out, "not a pbdbench run file")
        with h5py.File(out, "r") as f:
            self.assertEqual(list(f["x"][()]), [1, 2, 3])

    def test_directories_devices_pipes_links_and_the_scenario_are_refused(self):
        os.mkdir(self.path("folder"))
        self.refused(self.path("folder"), "is a directory")
        self.refused("/dev/null", "character device")
        os.mkfifo(self.path("pipe"))
        self.refused(self.path("pipe"), "named pipe")
        good = self.path("good.h5")
        self.assertEqual(pbdbench("run", "spring", "--set", "time.duration=0.1", "--out", good, "--quiet").returncode, 0)
        os.symlink(good, self.path("link.h5"))
        self.refused(self.path("link.h5"), "symbolic link")
        scenario = self.path("s.toml")
        with open(scenario, "w") as f:
            f.write('[scene]\nkind = "spring"\n[time]\nduration = 0.1\n')
        r = pbdbench("run", scenario, "--out", scenario, "--quiet")
        self.assertEqual(r.returncode, 2)
        self.assertIn("scenario file itself", r.stderr)
        with open(scenario) as f:
            self.assertIn("spring", f.read())

    def test_a_run_file_is_replaced(self):
        out = self.path("run.h5")
        for solver in ("xpbd", "pbd"):
            r = pbdbench("run", "spring", "--solver", solver, "--set", "time.duration=0.1", "--out", out, "--quiet", "--no-xdmf")
            self.assertEqual(r.returncode, 0, r.stderr)
            with h5py.File(out, "r") as f:
                self.assertEqual(attr(f, "solver"), solver)
        self.assertEqual(sorted(os.listdir(self.dir)), ["run.h5"])  # no lock, no working copy left

    def test_a_missing_folder_is_created_and_a_read_only_one_is_named(self):
        out = self.path("new/sub/run.h5")
        self.assertEqual(pbdbench("run", "spring", "--set", "time.duration=0.1", "--out", out, "--quiet", "--no-xdmf").returncode, 0)
        if os.geteuid() == 0:
            self.skipTest("root writes into read-only folders")
        ro = self.path("ro")
        os.mkdir(ro)
        os.chmod(ro, 0o555)
        r = self.refused(os.path.join(ro, "run.h5"), "not writable")
        self.assertNotIn("cannot remove", r.stderr)


class OneWriter(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_writer_")
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def test_a_second_writer_is_refused_naming_the_first(self):
        out = os.path.join(self.dir, "run.h5")
        first = subprocess.Popen([BIN, "run", *LONG_RUN, "--out", out, "--quiet", "--no-xdmf"],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            wait_for(lambda: os.path.exists(out), what="the first run's file")
            r = pbdbench("run", "spring", "--out", out, "--quiet", "--no-xdmf")
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn(f"pid {first.pid}", r.stderr)
            self.assertIn(f"host {socket.gethostname()}", r.stderr)
            self.assertIn("one writer per file", r.stderr)
        finally:
            first.send_signal(signal.SIGINT)
            first.communicate(timeout=60)
        self.assertEqual(first.returncode, 4)
        with h5py.File(out, "r") as f:
            self.assertEqual(attr(f, "scenario"), "hanging_chain")  # the second writer changed nothing
        self.assertEqual(sorted(os.listdir(self.dir)), ["run.h5"])

    def test_the_lock_of_a_killed_writer_is_taken_over(self):
        out = os.path.join(self.dir, "run.h5")
        p = subprocess.Popen([BIN, "run", *LONG_RUN, "--out", out, "--quiet", "--no-xdmf"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wait_for(lambda: os.path.exists(out), what="the file")
        p.send_signal(signal.SIGKILL)
        p.wait()
        self.assertTrue(os.path.exists(out + ".lock"))  # left behind, but no longer held
        with h5py.File(out, "r") as f:
            self.assertEqual(attr(f, "status"), "incomplete")
        r = pbdbench("run", "spring", "--set", "time.duration=0.1", "--out", out, "--quiet", "--no-xdmf")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(os.listdir(self.dir)), ["run.h5"])


class Interrupts(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_interrupt_")
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def test_sigint_and_sigterm_stop_a_long_step_within_a_second(self):
        for sig in (signal.SIGINT, signal.SIGTERM):
            out = os.path.join(self.dir, f"long-{sig}.h5")
            p = subprocess.Popen([BIN, "run", *LONG_STEP, "--out", out, "--quiet", "--no-xdmf"],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            wait_for(lambda: os.path.exists(out), what="the file")
            time.sleep(1.0)  # well inside the first step (minutes)
            t0 = time.monotonic()
            p.send_signal(sig)
            stdout, stderr = p.communicate(timeout=60)
            latency = time.monotonic() - t0
            print(f"signal {sig}: the run ended {latency:.3f} s after it")
            self.assertEqual(p.returncode, 4, stdout + stderr)
            # Within a second; the margin is for a loaded machine.
            self.assertLess(latency, 5.0)
            with h5py.File(out, "r") as f:
                self.assertEqual(attr(f, "status"), "incomplete")
                self.assertIn("interrupted during step 1", attr(f, "status_reason"))
                self.assertEqual(f["series/time"].shape[0], 1)  # the initial row: step 1 never ended


class Sweeps(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_sweep_")
        self.dir = self.tmp.name
        self.sweep = os.path.join(self.dir, "long.toml")
        with open(self.sweep, "w") as f:
            f.write('scenario = "hanging_chain"\n[set]\n"time.duration" = 2000.0\n'
                    '[grid]\n"solver.iterations" = [1, 2, 3, 4, 5, 6]\n')
        self.out = os.path.join(self.dir, "out")

    def tearDown(self):
        self.tmp.cleanup()

    def start(self):
        p = subprocess.Popen([BIN, "sweep", self.sweep, "--out", self.out, "--jobs", "2"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        wait_for(lambda: len(children_of(p.pid)) == 2 and all(
            os.path.exists(os.path.join(self.out, f"solver.iterations-{k}.h5")) for k in (1, 2)),
            what="two running children")
        return p, children_of(p.pid)

    def test_an_interrupted_sweep_stops_its_children_launches_nothing_and_exits_4(self):
        p, kids = self.start()
        p.send_signal(signal.SIGINT)  # the parent only: it must stop the children itself
        stdout, stderr = p.communicate(timeout=60)
        self.assertEqual(p.returncode, 4, stdout + stderr)
        self.assertIn("interrupted", stdout)
        for kid in kids:
            self.assertFalse(alive(kid))
        for k in (1, 2):
            with h5py.File(os.path.join(self.out, f"solver.iterations-{k}.h5"), "r") as f:
                self.assertEqual(attr(f, "status"), "incomplete")
        for k in (3, 4, 5, 6):  # never started
            self.assertFalse(os.path.exists(os.path.join(self.out, f"solver.iterations-{k}.h5")))
        with open(os.path.join(self.out, "index.json")) as f:
            statuses = [r["status"] for r in json.load(f)["runs"]]
        self.assertEqual(statuses, ["incomplete", "incomplete", "pending", "pending", "pending", "pending"])

    def test_children_die_with_a_killed_parent_and_a_rerun_resumes(self):
        p, kids = self.start()
        p.send_signal(signal.SIGKILL)
        p.communicate()
        wait_for(lambda: not any(alive(k) for k in kids), timeout=30, what="the children to end")
        for k in (1, 2):
            path = os.path.join(self.out, f"solver.iterations-{k}.h5")
            with h5py.File(path, "r") as f:
                self.assertEqual(attr(f, "status"), "incomplete")
            self.assertFalse(os.path.exists(path + ".lock"))  # each ended cleanly (SIGTERM)

    def test_a_rerun_does_not_start_a_run_whose_writer_is_alive(self):
        os.makedirs(self.out)
        busy = os.path.join(self.out, "solver.iterations-1.h5")
        other = subprocess.Popen([BIN, "run", *LONG_RUN, "--out", busy, "--quiet"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            wait_for(lambda: os.path.exists(busy), what="the other writer's file")
            small = os.path.join(self.dir, "small.toml")
            with open(small, "w") as f:
                f.write('scenario = "hanging_chain"\n[set]\n"time.duration" = 0.2\n'
                        '[grid]\n"solver.iterations" = [1, 2]\n')
            r = pbdbench("sweep", small, "--out", self.out, "--jobs", "2")
            self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
            self.assertIn(f"being written by pid {other.pid}", r.stdout)
            self.assertTrue(alive(other.pid))
            with h5py.File(os.path.join(self.out, "solver.iterations-2.h5"), "r") as f:
                self.assertEqual(attr(f, "status"), "complete")
        finally:
            other.send_signal(signal.SIGINT)
            other.wait(timeout=60)


class Messages(unittest.TestCase):
    def test_a_mistyped_command_is_named(self):
        r = pbdbench("rnu", "spring")
        self.assertEqual(r.returncode, 2)
        self.assertIn("unknown command 'rnu' (did you mean 'run'?)", r.stderr)

    def test_negative_jobs_are_refused(self):
        r = pbdbench("sweep", os.path.join(SOURCE, "studies", "default", "chain_iterations_vs_substeps.toml"),
                     "--jobs", "-3")
        self.assertEqual(r.returncode, 2)
        self.assertIn("--jobs", r.stderr)

    def test_summary_of_a_file_that_is_not_a_run_file(self):
        r = pbdbench("summary", os.path.join(SOURCE, "scenarios", "spring.toml"))
        self.assertEqual(r.returncode, 2)
        self.assertIn("not a pbdbench run file", r.stderr)

    def test_a_huge_unknown_key_is_refused_at_once_and_shown_cut(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "big.toml")
            with open(path, "w") as f:
                f.write('[scene]\nkind = "spring"\n' + "k" * (1 << 20) + " = 1\n")
            t0 = time.monotonic()
            r = pbdbench("run", path, "--out", os.path.join(d, "x.h5"))
            print(f"a 1 MiB unknown key: refused in {time.monotonic() - t0:.2f} s")
            self.assertEqual(r.returncode, 2)
            self.assertIn(f"{path}:3: unknown key", r.stderr)
            self.assertIn("(1048582 characters)", r.stderr)  # "scene." and the 1 MiB key
            self.assertLess(len(r.stderr), 1000)

    def test_a_planned_run_beyond_the_machine_is_refused_unless_forced(self):
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "x.h5")
            # 10^10 projections a step for 1200 steps: about 43 hours, beyond the one-day limit.
            args = ["hanging_chain", "--set", "scene.links=100000", "--set", "solver.iterations=100000",
                    "--set", "time.duration=20", "--out", out, "--quiet"]
            r = pbdbench("run", *args)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn("does not fit this machine", r.stderr)
            self.assertIn("--force", r.stderr)
            self.assertFalse(os.path.exists(out))


if __name__ == "__main__":
    unittest.main()
