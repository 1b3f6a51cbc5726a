#!/usr/bin/python3
"""Prints the cost against accuracy of PBD and the global solvers: one Markdown table per scene,
from the run files of scripts/global_study.sh (or any run files).

    summarize_global.py DIR_OR_FILE [...]

Files are grouped by scene (the run's `scenario` attribute), in the order given. A row per run:
  xpbd (run with --set shadow.solver=...): sweeps per step, the mean shadow_gap_rms and the
    largest shadow_gap_max (how far its steps land from the converged step x*), its final
    constraint_error_max, ms per step, the shadow's cost in run steps (shadow_cost_ratio) and
    the largest shadow_residual_position (above the tolerance: a shadow step not converged);
  global-*: its Newton (or Levenberg-Marquardt) iterations per step, its final
    constraint_error_max, ms per step and the largest residual_position of its steps.
Means are over the steps that have a value (a shadow may solve only every k-th step).

Depends on numpy and h5py only (through runfile.py); runs under /usr/bin/python3.
"""
import glob
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402

GLOBAL_ORDER = ["global-cholmod", "global-cg", "global-ceres"]
COLUMNS = ["run", "iterations", "mean shadow_gap_rms (m)", "max shadow_gap_max (m)",
           "final constraint_error_max", "ms/step", "shadow cost ratio",
           "max residual (m)"]


def _steps(run, name):
    """A series over the steps (row 0, the initial state, dropped), NaN where absent."""
    v = run.series.get(name)
    if v is None:
        return np.full(max(run.rows - 1, 0), math.nan)
    return np.asarray(v, dtype=float)[1:]


def _finite(v):
    v = np.asarray(v, dtype=float)
    return v[np.isfinite(v)]


def _mean(v):
    v = _finite(v)
    return float(v.mean()) if v.size else math.nan


def _max(v):
    v = _finite(v)
    return float(v.max()) if v.size else math.nan


def _g(v, digits=3):
    return "–" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def row(run):
    """The table row of one run: (sort key, cells)."""
    solver = str(runfile.config_value(run, "solver.name", run.attrs.get("solver", "?")))
    it = runfile.config_value(run, "solver.iterations", None)
    sub = runfile.config_value(run, "solver.substeps", 1)
    status = "" if run.status == "complete" else f" ({run.status})"
    wall = 1e3 * _mean(_steps(run, "wall_step"))
    err = _finite(_steps(run, "constraint_error_max"))
    final_err = float(err[-1]) if err.size else math.nan
    if solver.startswith("global-"):
        newton = _mean(_steps(run, "newton_iterations"))
        inner = _mean(_steps(run, "linear_iterations"))
        if solver == "global-ceres":
            its = f"{_g(inner)} LM"
        elif solver == "global-cg":
            its = f"{_g(newton)} Newton ({_g(inner)} CG)"
        else:
            its = f"{_g(newton)} Newton"
        cells = [solver + status, its, "–", "–", _g(final_err), _g(wall), "–",
                 _g(_max(_steps(run, "residual_position")))]
        order = (1, GLOBAL_ORDER.index(solver) if solver in GLOBAL_ORDER else 99, 0)
        return order, cells
    label = f"{solver} {it} it" + (f" x {sub} sub" if sub not in (None, 1) else "")
    shadow = str(runfile.config_value(run, "shadow.solver", "") or "")
    if shadow:
        label += f" (shadow {shadow})"
    cells = [label + status, f"{it} sweep{'' if it == 1 else 's'}" if it is not None else "?",
             _g(_mean(_steps(run, "shadow_gap_rms"))), _g(_max(_steps(run, "shadow_gap_max"))),
             _g(final_err), _g(wall), _g(_mean(_steps(run, "shadow_cost_ratio"))),
             _g(_max(_steps(run, "shadow_residual_position")))]
    return (0, 0, it if isinstance(it, (int, float)) else 0), cells


def table(runs):
    rows = sorted((row(r) for r in runs), key=lambda kc: kc[0])
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "|".join("---" for _ in COLUMNS) + "|"]
    lines += ["| " + " | ".join(cells) + " |" for _, cells in rows]
    return "\n".join(lines)


def heading(scene, runs):
    r = runs[0]
    dt = runfile.config_value(r, "time.dt", r.attrs.get("dt", math.nan))
    dur = runfile.config_value(r, "time.duration", math.nan)
    every = {runfile.config_value(x, "shadow.every", 1) for x in runs
             if runfile.config_value(x, "shadow.solver", "")}
    text = f"### {scene}: dt = {_g(float(dt), 4)} s, {_g(float(dur), 4)} s simulated"
    if every:
        text += f", shadow every {', '.join(str(e) for e in sorted(every))} step(s)"
    return text


def collect(paths):
    files = []
    for p in paths:
        if os.path.isdir(p):
            files += sorted(glob.glob(os.path.join(p, "*.h5")))
        else:
            files.append(p)
    return files


def main(argv):
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    scenes = {}
    for path in collect(argv):
        try:
            run = runfile.load(path, frames=False, model=False)
        except runfile.RunFileError as e:
            print(f"summarize_global.py: {e}", file=sys.stderr)
            return 1
        if "series" not in run.attrs and not run.series:
            continue
        scene = str(run.attrs.get("scenario", "?"))
        scenes.setdefault(scene, []).append(run)
    if not scenes:
        print("summarize_global.py: no run files", file=sys.stderr)
        return 1
    first = True
    for scene, runs in scenes.items():
        if not first:
            print()
        first = False
        print(heading(scene, runs))
        print()
        print(table(runs))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
