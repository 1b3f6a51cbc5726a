#!/usr/bin/python3
"""Plots one metric of a sweep against a swept parameter, one line per value of --group-by.

    plot_sweep.py SWEEP_DIR|INDEX.json --x solver.iterations [--metric constraint_error_max]
                  [--at final|max|mean|rms] [--group-by solver.name] [-o OUT.png]

The sweep index (<sweep_dir>/index.json, written by the harness):
    {"sweep": NAME, "scenario": NAME, "parameters": ["solver.name", ...],
     "runs": [{"file": "relative/path.h5", "params": {"solver.name": "pbd", ...},
               "status": "complete"}, ...]}

Each run's series --metric (the norm, for a 3-vector series) is reduced to one number by --at:
final (the last row), max, mean or rms over the rows, NaNs ignored; the axis label says which.
Without --group-by, the runs are grouped by the other parameters that vary in the sweep. Runs
that exploded are drawn with an x; runs whose file is missing or unreadable are skipped with a
warning. Axes switch to a log scale when the values are positive and span more than two decades
(y) or one decade (x); the x axis is categorical when the parameter is not numeric.
"""
import argparse
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402

REDUCTIONS = {
    "final": ("value at the end of the run", lambda v: v[-1] if len(v) else np.nan),
    "max": ("maximum over the run", lambda v: np.nanmax(v) if np.isfinite(v).any() else np.nan),
    "mean": ("mean over the run", lambda v: np.nanmean(v) if np.isfinite(v).any() else np.nan),
    "rms": ("RMS over the run",
            lambda v: np.sqrt(np.nanmean(v * v)) if np.isfinite(v).any() else np.nan),
}


class SweepError(Exception):
    pass


def load_index(where):
    path = os.path.join(where, "index.json") if os.path.isdir(where) else where
    if not os.path.isfile(path):
        raise SweepError(f"{path}: no such file")
    try:
        with open(path, encoding="utf-8") as f:
            index = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        raise SweepError(f"{path}: cannot read the sweep index: {e}") from e
    if not isinstance(index, dict) or not isinstance(index.get("runs"), list):
        raise SweepError(f"{path}: not a sweep index (no \"runs\" list)")
    return path, index


def reduce_metric(run, metric, at):
    v = run.series.get(metric)
    if v is None:
        return None
    if v.ndim == 2:
        v = np.linalg.norm(v, axis=1)
    return float(REDUCTIONS[at][1](np.asarray(v, dtype=float)))


def is_number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep", metavar="SWEEP_DIR|INDEX.json")
    ap.add_argument("--x", required=True, help="the swept parameter on the x axis")
    ap.add_argument("--metric", default="constraint_error_max", help="a series name")
    ap.add_argument("--at", choices=sorted(REDUCTIONS), default="final",
                    help="how a run's series becomes one number (default final)")
    ap.add_argument("--group-by", help="one line per value of this parameter")
    ap.add_argument("-o", "--output", default="sweep.png", help="output image (default sweep.png)")
    args = ap.parse_args(argv)

    try:
        index_path, index = load_index(args.sweep)
    except SweepError as e:
        print(f"plot_sweep.py: {e}", file=sys.stderr)
        return 1
    base = os.path.dirname(os.path.abspath(index_path))
    entries = index["runs"]
    params = list(index.get("parameters") or [])
    for e in entries:
        for k in e.get("params", {}):
            if k not in params:
                params.append(k)
    for name in [args.x] + ([args.group_by] if args.group_by else []):
        if not any(name in e.get("params", {}) for e in entries):
            print(f"plot_sweep.py: {index_path}: no run has the parameter {name!r} "
                  f"(parameters: {', '.join(params) or 'none'})", file=sys.stderr)
            return 1

    if args.group_by:
        group_keys = [args.group_by]
    else:  # the other parameters that vary
        group_keys = [p for p in params if p != args.x and
                      len({repr(e.get("params", {}).get(p)) for e in entries}) > 1]

    points = {}  # group label -> list of (x, y, exploded)
    units = ""
    skipped = 0
    for e in entries:
        p = e.get("params", {})
        if args.x not in p:
            continue
        path = os.path.join(base, e.get("file", ""))
        try:
            run = runfile.load(path, frames=False, model=False)
        except runfile.RunFileError as err:
            print(f"plot_sweep.py: warning: skipped: {err}", file=sys.stderr)
            skipped += 1
            continue
        y = reduce_metric(run, args.metric, args.at)
        if y is None:
            print(f"plot_sweep.py: {path} has no series {args.metric!r} "
                  f"(it has: {', '.join(sorted(run.series))})", file=sys.stderr)
            return 1
        units = units or run.units.get(args.metric, "")
        group = ", ".join(f"{k.split('.')[-1]}={runfile.format_value(p.get(k, '?'))}"
                          for k in group_keys) or args.metric
        points.setdefault(group, []).append((p[args.x], y, run.exploded))
    if not points:
        print(f"plot_sweep.py: {index_path}: no readable run to plot", file=sys.stderr)
        return 1

    xs_all = [x for pts in points.values() for x, _, _ in pts]
    numeric = all(is_number(x) for x in xs_all)
    if not numeric:  # categorical axis, in order of first appearance
        categories = []
        for x in xs_all:
            if x not in categories:
                categories.append(x)

    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    ys_all = []
    for i, (group, pts) in enumerate(points.items()):
        color = plt.cm.tab10(i % 10)
        pts = sorted(pts, key=lambda q: q[0] if numeric else categories.index(q[0]))
        xs = [q[0] if numeric else categories.index(q[0]) for q in pts]
        ys = [q[1] for q in pts]
        ys_all += [y for y in ys if np.isfinite(y)]
        ax.plot(xs, ys, marker="o", color=color, label=group)
        boom = [(x, y) for x, y, (_, _, exploded) in zip(xs, ys, pts) if exploded]
        if boom:
            ax.plot([b[0] for b in boom], [b[1] for b in boom], linestyle="none", marker="x",
                    color=color, markersize=10, mew=2)
    if not numeric:
        ax.set_xticks(range(len(categories)))
        ax.set_xticklabels([runfile.format_value(c) for c in categories])
    elif min(xs_all) > 0 and max(xs_all) / min(xs_all) > 10:
        ax.set_xscale("log")
        ticks = sorted(set(xs_all))
        if len(ticks) <= 12:  # label the swept values themselves, not powers of ten
            ax.set_xticks(ticks)
            ax.set_xticklabels([runfile.format_value(t) for t in ticks])
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    if ys_all and min(ys_all) > 0 and max(ys_all) / min(ys_all) > 100:
        ax.set_yscale("log")
    ax.set_xlabel(args.x)
    ax.set_ylabel(f"{args.metric}, {REDUCTIONS[args.at][0]} [{units or '?'}]")
    title = f"sweep {index.get('sweep', '?')}"
    if index.get("scenario"):
        title += f", scenario {index['scenario']}"
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if any(q[2] for pts in points.values() for q in pts):
        handles.append(plt.Line2D([], [], color="0.3", marker="x", linestyle="none", mew=2))
        labels.append("exploded")
    ax.legend(handles, labels, fontsize=8)
    fig.tight_layout()
    try:
        fig.savefig(args.output, dpi=120)
    except (OSError, ValueError) as e:
        print(f"plot_sweep.py: cannot write {args.output}: {e}", file=sys.stderr)
        return 1
    plt.close(fig)
    print(f"wrote {args.output}" + (f" ({skipped} runs skipped)" if skipped else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
