#!/usr/bin/python3
"""Kill test of the run file: a writer killed with SIGKILL at a random moment must leave a file
that h5py opens in plain mode, whose status is "incomplete" and whose series and frames are
consistent (equal lengths, the values the writer wrote).

Each trial starts tests/runfile/runfile_stress_writer, kills it with SIGKILL at a random moment
and checks the file in a fresh /usr/bin/python3 process (so that a crash of the reader is a
failed trial, not a failed test run). Most kills come after the writer printed "ready"; a share
(--early) come at a random moment from its start, before the file may exist: for those, "no file
yet" is an accepted outcome, any other file must still pass.

    kill_test.py --writer BUILD/tests/runfile/runfile_stress_writer --design publish --trials 200

Exit status 0 when no trial failed. --design inplace, inplace-latest and swmr run the designs
that were measured and rejected (see results/README.md); they are expected to fail.
"""
import argparse
import json
import os
import random
import select
import signal
import subprocess
import sys
import time

PYTHON = "/usr/bin/python3"


def check_file(path):
    """Opens `path` as a reader after a crash would; returns a dict describing the outcome."""
    if not os.path.exists(path):
        return {"outcome": "absent"}
    import h5py
    import numpy as np

    try:
        f = h5py.File(path, "r")  # plain mode: no SWMR, no special flags
    except Exception as e:  # noqa: BLE001 - any failure to open is the finding
        out = {"outcome": "open-failed", "error": str(e).splitlines()[0][:200]}
        try:
            with h5py.File(path, "r", swmr=True):
                out["swmr_reader_opens"] = True
        except Exception:  # noqa: BLE001
            out["swmr_reader_opens"] = False
        return out
    try:
        with f:
            status = f.attrs.get("status")
            if isinstance(status, bytes):
                return {"outcome": "status-wrong", "error": "status is bytes, not str"}
            if status != "incomplete":
                return {"outcome": "status-wrong", "error": f"status = {status!r}"}
            lengths = {name: ds.shape[0] for name, ds in f["series"].items()}
            if len(set(lengths.values())) != 1:
                return {"outcome": "inconsistent", "error": f"series lengths differ: "
                        f"{sorted(set(lengths.values()))}"}
            rows = next(iter(lengths.values()))
            r = np.arange(rows, dtype=float)
            series = {name: ds[()] for name, ds in f["series"].items()}
            expected = {"step": r, "time": 0.01 * r, "kinetic_energy": 0.5 * r}
            for name, values in expected.items():
                if not np.array_equal(series[name], values):
                    return {"outcome": "inconsistent", "error": f"{name} has wrong values"}
            if not np.array_equal(series["linear_momentum"][:, 1], 2 * r):
                return {"outcome": "inconsistent", "error": "linear_momentum has wrong values"}
            ftime = f["frames/time"][()]
            pos = f["frames/positions"][()]
            nframes = ftime.shape[0]
            if pos.shape[0] != nframes:
                return {"outcome": "inconsistent",
                        "error": f"{nframes} frame times, {pos.shape[0]} frames"}
            rest = f["model/rest_positions"][()]
            for k in range(nframes):
                if ftime[k] != 0.2 * k or not np.array_equal(pos[k], rest + 1e-3 * k):
                    return {"outcome": "inconsistent", "error": f"frame {k} has wrong values"}
            # Rows are written with each frame: the series reach the last frame's row.
            if nframes and rows < 20 * (nframes - 1) + 1:
                return {"outcome": "inconsistent",
                        "error": f"{rows} rows but {nframes} frames"}
            return {"outcome": "ok", "rows": int(rows), "frames": int(nframes)}
    except Exception as e:  # noqa: BLE001
        return {"outcome": "read-failed", "error": str(e).splitlines()[0][:200]}


def run_trial(args, path, rng):
    for p in (path, path + ".tmp"):
        if os.path.exists(p):
            os.remove(p)
    cmd = [args.writer, args.design, path, str(args.flush), str(args.step_us), str(args.particles)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    early = rng.random() < args.early
    ready = False
    if early:
        time.sleep(rng.uniform(0.0, args.early_window))
    else:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            r, _, _ = select.select([proc.stdout], [], [], deadline - time.monotonic())
            if not r:
                break
            line = proc.stdout.readline()
            if not line or line.strip() == b"ready":
                ready = bool(line)
                break
        if not ready:
            proc.kill()
            proc.wait()
            return {"outcome": "writer-failed",
                    "error": proc.stderr.read().decode(errors="replace")[:300]}
        time.sleep(rng.uniform(0.0, args.max_delay))
    if proc.poll() is not None:  # it ended by itself: that is a failure of the writer
        return {"outcome": "writer-failed",
                "error": proc.stderr.read().decode(errors="replace")[:300]}
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    if early and not ready:
        out = proc.stdout.read()
        ready = b"ready" in out
    checker = subprocess.run([PYTHON, os.path.abspath(__file__), "--check", path],
                             capture_output=True, text=True)
    if checker.returncode != 0:
        result = {"outcome": "reader-crashed",
                  "error": (checker.stderr.strip().splitlines() or ["?"])[-1][:200]}
    else:
        result = json.loads(checker.stdout)
    result["early"] = early
    result["ready"] = ready
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", metavar="PATH", help="check one file and print the outcome (JSON)")
    ap.add_argument("--writer", help="the runfile_stress_writer executable")
    ap.add_argument("--design", default="publish",
                    choices=["publish", "inplace", "inplace-latest", "swmr"])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--dir", default="kill_test", help="where the trial files go")
    ap.add_argument("--flush", type=float, default=0.02,
                    help="the writer's flush interval, s (small: many flushes to land in)")
    ap.add_argument("--step-us", type=int, default=200, help="simulated step time, microseconds")
    ap.add_argument("--particles", type=int, default=200)
    ap.add_argument("--max-delay", type=float, default=1.0,
                    help="kill at a uniform random time up to this many s after 'ready'")
    ap.add_argument("--early", type=float, default=0.1,
                    help="share of trials killed at a random moment from the writer's start")
    ap.add_argument("--early-window", type=float, default=0.05,
                    help="those kills fall uniformly in this many s after the start")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--json", metavar="FILE", help="write every trial's outcome here")
    args = ap.parse_args()

    if args.check:
        print(json.dumps(check_file(args.check)))
        return 0
    if not args.writer:
        ap.error("--writer is required")
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2**32)
    rng = random.Random(seed)
    os.makedirs(args.dir, exist_ok=True)
    path = os.path.join(args.dir, f"kill_{args.design}.h5")

    results = []
    counts = {}
    failures = 0
    for i in range(args.trials):
        r = run_trial(args, path, rng)
        results.append(r)
        outcome = r["outcome"]
        accepted = outcome == "ok" or (outcome == "absent" and not r["ready"])
        counts[outcome] = counts.get(outcome, 0) + 1
        if not accepted:
            failures += 1
            print(f"trial {i}: {outcome}: {r.get('error', '')}"
                  f"{' (killed early)' if r['early'] else ''}", flush=True)
    ok_rows = [r["rows"] for r in results if r["outcome"] == "ok"]
    print(f"design {args.design}: {args.trials} kills (seed {seed}, flush {args.flush} s, "
          f"{sum(r['early'] for r in results)} early), {failures} failed "
          f"({100.0 * failures / max(args.trials, 1):.1f} %)")
    print("outcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    swmr = [r.get("swmr_reader_opens") for r in results if "swmr_reader_opens" in r]
    if swmr:
        print(f"of the files h5py could not open, a SWMR reader opened {sum(swmr)} of {len(swmr)}")
    if ok_rows:
        print(f"rows in the files that passed: min {min(ok_rows)}, max {max(ok_rows)}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"design": args.design, "seed": seed, "trials": results}, out, indent=1)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
