#!/usr/bin/python3
"""Plots one metric of a sweep against a swept parameter, one line per value of --group-by.

    plot_sweep.py SWEEP_DIR|INDEX.json --x solver.iterations [--metric constraint_error_max]
                  [--at final|max|mean|rms] [--group-by solver.name]
                  [--log auto|x|y|both|none] [-o OUT.png]

The sweep index (<sweep_dir>/index.json, written by the harness):
    {"sweep": NAME, "scenario": NAME, "parameters": ["solver.name", ...],
     "runs": [{"file": "relative/path.h5", "params": {"solver.name": "pbd", ...},
               "status": "complete"}, ...]}

Each run's series --metric (the norm, for a 3-vector series) is reduced to one number by --at:
final (the last row), max, mean or rms over the rows, NaNs ignored; the axis label says which.
Without --group-by, the runs are grouped by the other parameters that vary in the sweep. Runs
that exploded are drawn with an x, and the y axis is set from the runs that did not: an exploded
run beyond it is drawn at its edge (an x with an arrow) and counted in the legend, so that it
cannot flatten the others. A line that lies on another (within 1 % of the axis's height at every
point) says so in the legend ("= GROUP"), and each line has its own marker. Runs whose file is
missing or unreadable are skipped with a warning. --log both (x, y) puts an axis on a log scale,
as a rate of convergence wants; by default (--log auto) an axis is logarithmic when the values
are positive and span more than two decades (y) or one decade (x). The x axis is categorical
when the parameter is not numeric. The title names the sweep and its scenario (never a path).
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
import plot_axes  # noqa: E402
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


def parser():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep", metavar="SWEEP_DIR|INDEX.json")
    ap.add_argument("--x", required=True, help="the swept parameter on the x axis")
    ap.add_argument("--metric", default="constraint_error_max", help="a series name")
    ap.add_argument("--at", choices=sorted(REDUCTIONS), default="final",
                    help="how a run's series becomes one number (default final)")
    ap.add_argument("--group-by", help="one line per value of this parameter")
    ap.add_argument("--log", choices=["auto", "x", "y", "both", "none"], default="auto",
                    help="which axes are logarithmic (default auto: by the span of the values)")
    ap.add_argument("-o", "--output", default="sweep.png", help="output image (default sweep.png)")
    return ap


def figure(args):
    """The figure of parsed arguments `args`; raises SweepError saying why there is none.
    Returns (figure, runs skipped)."""
    index_path, index = load_index(args.sweep)
    base = os.path.dirname(os.path.abspath(index_path))
    entries = index["runs"]
    params = list(index.get("parameters") or [])
    for e in entries:
        for k in e.get("params", {}):
            if k not in params:
                params.append(k)
    for name in [args.x] + ([args.group_by] if args.group_by else []):
        if not any(name in e.get("params", {}) for e in entries):
            raise SweepError(f"{index_path}: no run has the parameter {name!r} "
                             f"(parameters: {', '.join(params) or 'none'})")

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
            raise SweepError(f"{path} has no series {args.metric!r} "
                             f"(it has: {', '.join(sorted(run.series))})")
        units = units or run.units.get(args.metric, "")
        group = ", ".join(f"{k.split('.')[-1]}={runfile.format_value(p.get(k, '?'))}"
                          for k in group_keys) or args.metric
        points.setdefault(group, []).append((p[args.x], y, run.exploded))
    if not points:
        raise SweepError(f"{index_path}: no readable run to plot")

    xs_all = [x for pts in points.values() for x, _, _ in pts]
    numeric = all(is_number(x) for x in xs_all)
    categories = []
    if not numeric:  # categorical axis, in order of first appearance
        for x in xs_all:
            if x not in categories:
                categories.append(x)
    kept = [y for pts in points.values() for _, y, exploded in pts if not exploded]
    every = [y for pts in points.values() for _, y, _ in pts]
    positive = [y for y in (kept or every) if np.isfinite(y)]
    log_x = numeric and min(xs_all) > 0 and (
        args.log in ("x", "both") or (args.log == "auto" and max(xs_all) / min(xs_all) > 10))
    log_y = bool(positive) and min(positive) > 0 and (
        args.log in ("y", "both") or (args.log == "auto" and max(positive) / min(positive) > 100))

    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    lines = []  # (group, xs, ys, exploded flags)
    for i, (group, pts) in enumerate(points.items()):
        pts = sorted(pts, key=lambda q: q[0] if numeric else categories.index(q[0]))
        xs = [q[0] if numeric else categories.index(q[0]) for q in pts]
        lines.append((group, xs, [q[1] for q in pts], [q[2] for q in pts]))
    if log_x:
        ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    lim = plot_axes.keep_to(ax, [np.array(kept)], [np.array(every)], log_y)
    same = plot_axes.coincident([(xs, ys) for _, xs, ys, _ in lines], lim, log_y)
    off_count = 0
    for i, (group, xs, ys, boom_flags) in enumerate(lines):
        color = plt.cm.tab10(i % 10)
        label = group
        if i in same:
            j, identical = same[i]
            label += f" ({'identical to' if identical else '='} {lines[j][0]}: drawn over it)"
        ax.plot(xs, ys, marker=plot_axes.MARKERS[i % len(plot_axes.MARKERS)], color=color, label=label,
                markersize=7 if i in same else 5, fillstyle="none" if i in same else "full")
        for x, y, exploded in zip(xs, ys, boom_flags):
            if not exploded:
                continue
            if lim is not None and np.isfinite(y) and lim[0] <= y <= lim[1]:
                ax.plot([x], [y], linestyle="none", marker="x", color=color, markersize=10, mew=2)
            else:  # beyond the axis (or NaN): at its top edge
                off_count += 1
                top = lim[1] if lim is not None else (ax.get_ylim()[1])
                ax.plot([x], [top], linestyle="none", marker="x", color=color, markersize=10, mew=2,
                        clip_on=False)
                ax.annotate("", xy=(x, top), xytext=(0, -14), textcoords="offset points",
                            arrowprops=dict(arrowstyle="->", color=color), annotation_clip=False)
    if not numeric:
        ax.set_xticks(range(len(categories)))
        ax.set_xticklabels([runfile.format_value(c) for c in categories])
    elif log_x:
        ticks = sorted(set(xs_all))
        if len(ticks) <= 12:  # label the swept values themselves, not powers of ten
            ax.set_xticks(ticks)
            ax.set_xticklabels([runfile.format_value(t) for t in ticks])
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel(args.x)
    ax.set_ylabel(f"{args.metric}, {REDUCTIONS[args.at][0]} [{units or '?'}]")
    title = f"sweep {index.get('sweep', '?')}"
    if index.get("scenario"):
        title += f", scenario {plot_axes.shown_name(index['scenario'])}"
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if any(q[2] for pts in points.values() for q in pts):
        handles.append(plt.Line2D([], [], color="0.3", marker="x", linestyle="none", mew=2))
        labels.append("exploded" + (f" ({off_count} beyond the axis: at its top edge)" if off_count else ""))
    ax.legend(handles, labels, fontsize=8)
    fig.tight_layout()
    return fig, skipped


def main(argv=None):
    args = parser().parse_args(argv)
    try:
        fig, skipped = figure(args)
    except SweepError as e:
        print(f"plot_sweep.py: {e}", file=sys.stderr)
        return 1
    try:
        fig.savefig(args.output, dpi=120)
    except (OSError, ValueError) as e:
        print(f"plot_sweep.py: cannot write {args.output}: {e}", file=sys.stderr)
        return 1
    finally:
        plt.close(fig)
    print(f"wrote {args.output}" + (f" ({skipped} runs skipped)" if skipped else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
