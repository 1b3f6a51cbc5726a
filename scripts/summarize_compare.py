#!/usr/bin/python3
"""Prints one line per compare file (`pbdbench compare --out`) found in the given directories:
the run, its reference, the position error (RMS and max over particles) at the last common
time and its largest max over time, and the gap in the scene's observable where it has one.

    summarize_compare.py DIR [DIR ...]

Depends on numpy and h5py only (through runfile.py); runs under /usr/bin/python3.
"""
import glob
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402

OBSERVABLES = [  # (name in /compare/observables, label, units)
    ("support_force_relative_gap", "support force gap", "rel"),
    ("tip_displacement_relative_gap", "tip gap", "rel"),
    ("pendulum_period_relative_difference", "period", "rel"),
]


def label(config_text, solver):
    """The solver and the iteration/substep counts that matter for it."""
    if solver.startswith("ref-"):
        return solver
    it = sub = None
    section = None
    for line in config_text.splitlines():
        s = line.strip()
        if s.startswith("["):
            section = s
        elif section == "[solver]" and s.startswith("iterations ="):
            it = s.split("=")[1].strip()
        elif section == "[solver]" and s.startswith("substeps ="):
            sub = s.split("=")[1].strip()
    return f"{solver} {it}it x {sub}sub"


def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def summarize(path):
    c = runfile.load_compare(path)
    a = c.attrs
    rms = np.asarray(c.data["position_error_rms"])
    mx = np.asarray(c.data["position_error_max"])
    t = np.asarray(c.data["time"])
    obs = []
    for name, lab, units in OBSERVABLES:
        if name in c.observables:
            v = np.atleast_1d(np.asarray(c.observables[name], dtype=float))
            v = v[np.isfinite(v)]
            if v.size:
                obs.append(f"{lab} {v[-1]:.3g} {units}")
    status = text(a["run_status"])
    return {
        "scene": text(a["run_scenario"]),
        "run": label(text(a["run_config"]), text(a["run_solver"])),
        "reference": text(a["reference_solver"]),
        "status": status,
        "t": t[-1] if t.size else math.nan,
        "rms": rms[-1] if rms.size else math.nan,
        "max": mx[-1] if mx.size else math.nan,
        "peak": np.nanmax(mx) if mx.size else math.nan,
        "obs": "; ".join(obs),
    }


def main(argv):
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    rows = []
    for d in argv:
        files = sorted(glob.glob(os.path.join(d, "compare-*.h5")))
        if not files:
            print(f"summarize_compare.py: no compare files in {d}", file=sys.stderr)
        for p in files:
            try:
                rows.append(summarize(p))
            except (OSError, KeyError, runfile.RunFileError) as e:
                print(f"summarize_compare.py: cannot read {p}: {e}", file=sys.stderr)
                return 1
    head = ("scene", "run", "vs", "status", "t (s)", "RMS err (m)", "max err (m)", "peak max (m)", "observable")
    print(f"{head[0]:16} {head[1]:22} {head[2]:8} {head[3]:9} {head[4]:>6} {head[5]:>11} {head[6]:>11} {head[7]:>12}  {head[8]}")
    for r in rows:
        print(f"{r['scene']:16} {r['run']:22} {r['reference']:8} {r['status']:9} {r['t']:6.3g} "
              f"{r['rms']:11.3g} {r['max']:11.3g} {r['peak']:12.3g}  {r['obs']}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
