#!/usr/bin/python3
"""Tests of scripts/perf_shares.py on a small `perf script -F tid,ip,sym` text written here."""
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(HERE, "..", "..", "scripts"))
sys.path.insert(0, SCRIPTS)
import perf_shares  # noqa: E402


def sample(tid, *frames):
    return [f" {tid} "] + [f"\t    {i:x} {f}" for i, f in enumerate(frames)] + [""]


# Run thread 10: 4 solver samples, 2 in measure (one under the step logger), 1 in the file's
# creation, 1 in measure_baseline (setup, not measure), 1 in append_frame's pwrite, 1 of nothing
# of ours. Thread 11 (the frame worker): 2 samples.
TEXT = "\n".join(
    sample(10, "pbdbench::xpbd_distance", "pbdbench::XpbdSolver::step", "pbdbench::run_config") * 4
    + sample(10, "pbdbench::constraint_values", "pbdbench::measure", "pbdbench::StepLogger::log")
    + sample(10, "pbdbench::measure", "pbdbench::run_config")
    + sample(10, "H5Dcreate2", "pbdbench::RunFileWriter::RunFileWriter", "pbdbench::run_config")
    + sample(10, "pbdbench::measure_baseline", "pbdbench::run_config")
    + sample(10, "__pwrite64", "pbdbench::RunFileWriter::append_frame", "pbdbench::StepLogger::log")
    + sample(10, "[unknown]")
    + sample(11, "[unknown]", "pbdbench::FrameCompressor::work") * 2)


class PerfShares(unittest.TestCase):
    def test_parts_of_the_run_thread(self):
        s = perf_shares.shares(TEXT.splitlines(keepends=True))
        self.assertEqual(s["run_thread"], "10")
        self.assertEqual(s["samples"], 10)
        self.assertEqual(dict(s["parts"]), {"solver step": 4, "measure": 2, "file creation": 1, "setup": 1,
                                            "frames": 1, "other": 1})
        self.assertEqual(dict(s["others"]), {"pbdbench::FrameCompressor::work": 2})

    def test_command_line(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "perf.txt")
            with open(path, "w") as f:
                f.write(TEXT)
            r = subprocess.run(["/usr/bin/python3", os.path.join(SCRIPTS, "perf_shares.py"), path],
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("run thread 10: 10 samples", r.stdout)
            self.assertIn("measure", r.stdout)
            self.assertIn("20.00 %", r.stdout)  # measure: 2 of 10
            empty = os.path.join(tmp, "empty.txt")
            open(empty, "w").close()
            r = subprocess.run(["/usr/bin/python3", os.path.join(SCRIPTS, "perf_shares.py"), empty],
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2)
            self.assertIn("empty.txt", r.stderr)


if __name__ == "__main__":
    unittest.main()
