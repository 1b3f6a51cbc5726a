#!/usr/bin/python3
"""A long run stays within a memory bound: `pbdbench run hanging_chain` for 10^5 and for 10^6
steps (dt = 1 ms), each in its own process, measuring its peak resident memory (ru_maxrss).
The longer run must not use more than the shorter one plus a margin (memory does not grow
with the run's length) nor more than the bound stated in results/README.md; its file must be
complete with every row, and nothing may be left beside it (lock, working copy).

    long_run_test.py BUILD/pbdbench [--steps 1000000] [--dir DIR]
"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile

BOUND_MB = 64.0       # results/README.md, "Memory and disk"
MARGIN_MB = 8.0       # what the longer run may use beyond the shorter one (allocator noise)


def measure(exe, steps, out):
    """Runs the chain for `steps` steps in a child of a fresh interpreter; returns its peak RSS
    in MB (ru_maxrss of the children of that interpreter: only this run)."""
    code = (
        "import resource, subprocess, sys\n"
        "r = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
        "sys.stderr.write(r.stdout + r.stderr)\n"
        "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n")
    cmd = [sys.executable, "-c", code, exe, "run", "hanging_chain", "--set", "time.dt=0.001",
           "--set", f"time.duration={steps / 1000.0}", "--set", "output.frame_every=1000",
           "--out", out, "--quiet", "--no-xdmf"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    rc, kb = r.stdout.split()
    if int(rc) != 0:
        raise SystemExit(f"the run of {steps} steps failed (exit {rc}):\n{r.stderr}")
    return int(kb) / 1024.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("exe")
    ap.add_argument("--steps", type=int, default=1000000)
    ap.add_argument("--dir", default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="pbdbench_long_run_", dir=args.dir) as tmp:
        short_out = os.path.join(tmp, "short.h5")
        long_out = os.path.join(tmp, "long.h5")
        short_mb = measure(args.exe, args.steps // 10, short_out)
        long_mb = measure(args.exe, args.steps, long_out)
        import h5py
        with h5py.File(long_out, "r") as f:
            status = f.attrs["status"]
            rows = f["series/time"].shape[0]
        size_mb = os.path.getsize(long_out) / 1e6
        left = sorted(set(os.listdir(tmp)) - {"short.h5", "long.h5"})
    print(f"peak RSS: {short_mb:.1f} MB for {args.steps // 10} steps, {long_mb:.1f} MB for {args.steps} "
          f"steps (file {size_mb:.0f} MB, {rows} rows, {status})")
    problems = []
    if status != "complete" or rows != args.steps + 1:
        problems.append(f"the file is {status} with {rows} rows, expected complete with {args.steps + 1}")
    if long_mb > short_mb + MARGIN_MB:
        problems.append(f"memory grew with the run: {long_mb:.1f} MB > {short_mb:.1f} + {MARGIN_MB} MB")
    if long_mb > BOUND_MB:
        problems.append(f"{long_mb:.1f} MB is above the stated bound of {BOUND_MB} MB")
    if left:
        problems.append(f"left beside the files: {left}")
    for p in problems:
        print("FAIL " + p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
