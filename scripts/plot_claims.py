#!/usr/bin/python3
"""Draws the figure of every claim of a claims report (written by `pbdbench claims`).

    plot_claims.py REPORT_DIR          reads REPORT_DIR/claims.json (pbdbench claims) or
                                       REPORT_DIR/reproductions.json (pbdbench paper), writes
                                       REPORT_DIR/figures/<id>.png

Each claim's [figure] (experiments/experiment.hpp) is one of:
    series   one series of the listed runs (their first trial) against time, one line per run;
             a run that exploded ends with an x at the step where it did
    bars     the listed measures, one bar each, labelled with their values; a NaN measure is
             drawn as an empty bar labelled "NaN"; a timing measure (or one computed from one)
             carries its 95 % interval as an error bar
The verdict is written in the title (a reproduction's: reproduced / not reproduced). Run files are found relative to REPORT_DIR (claims.json
stores them so); a missing run file leaves the figure out with a warning, it does not fail. A
figure newer than claims.json and than the run files it reads is up to date and not redrawn.
"""
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402


def value_label(v):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "NaN"
    if v != 0 and (abs(v) < 1e-2 or abs(v) >= 1e4):
        return f"{v:.2e}"
    return f"{v:.3g}"


def series_values(run, name):
    """A width-1 series, or a component of a width-3 one (name.x, name.y, name.z)."""
    if name in run.series:
        return np.asarray(run.series[name], dtype=float)
    base, _, comp = name.rpartition(".")
    if base in run.series and comp in ("x", "y", "z"):
        return np.asarray(run.series[base], dtype=float)[:, "xyz".index(comp)]
    return None


def plot_series(ax, claim, report_dir):
    fig = claim["figure"]
    runs = {r["name"]: r for r in claim["runs"]}
    drawn = 0
    for name in fig["runs"]:
        files = runs.get(name, {}).get("files", [])
        if not files:
            continue
        path = os.path.join(report_dir, files[0])
        try:
            run = runfile.load(path, frames=False)
        except runfile.RunFileError as e:
            print(f"plot_claims.py: {claim['id']}: {e}", file=sys.stderr)
            continue
        y = series_values(run, fig["series"])
        if y is None:
            continue
        t = np.asarray(run.series["time"], dtype=float)
        n = min(len(t), len(y))
        if fig["log"]:
            y = np.abs(y)
        line, = ax.plot(t[:n], y[:n], label=name)
        if run.status == "exploded" and n > 0:
            ax.plot([t[n - 1]], [y[n - 1]], "x", color=line.get_color(), markersize=9)
        drawn += 1
    if fig["log"]:
        ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(fig["ylabel"] or fig["series"])
    if drawn:
        ax.legend(fontsize=8)
    return drawn


def plot_bars(ax, claim):
    fig = claim["figure"]
    measures = {m["name"]: m for m in claim["measures"]}
    names = [n for n in fig["measures"] if n in measures]
    values = [measures[n]["value"] for n in names]
    heights = [0.0 if v is None else v for v in values]
    if fig["log"]:
        heights = [abs(h) if h else np.nan for h in heights]
    lo = [measures[n].get("lo") for n in names]
    hi = [measures[n].get("hi") for n in names]
    err = None
    if any(x is not None for x in lo):
        err = np.array([[h - (l if l is not None else h) for h, l in zip(heights, lo)],
                        [(u if u is not None else h) - h for h, u in zip(heights, hi)]])
        err = np.clip(np.nan_to_num(err), 0.0, None)
    bars = ax.bar(range(len(names)), heights, color="tab:blue", yerr=err, capsize=4 if err is not None else 0)
    for b, v in zip(bars, values):
        h = b.get_height()
        y = h if np.isfinite(h) else 0.0
        ax.annotate(value_label(v), (b.get_x() + b.get_width() / 2, y), ha="center",
                    va="bottom", fontsize=8)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
    if fig["log"]:
        ax.set_yscale("log")
    ax.set_ylabel(fig["ylabel"])
    return len(names)


def up_to_date(target, json_time, claim, report_dir):
    """True when the figure exists and is newer than claims.json and the run files it reads."""
    if not os.path.exists(target):
        return False
    t = os.path.getmtime(target)
    if t < json_time:
        return False
    if claim["figure"]["kind"] == "series":
        runs = {r["name"]: r for r in claim["runs"]}
        for name in claim["figure"]["runs"]:
            files = runs.get(name, {}).get("files", [])
            if files:
                path = os.path.join(report_dir, files[0])
                if not os.path.exists(path) or os.path.getmtime(path) > t:
                    return False
    return True


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    report_dir = argv[1]
    json_path = os.path.join(report_dir, "claims.json")
    if not os.path.exists(json_path):
        json_path = os.path.join(report_dir, "reproductions.json")
    with open(json_path, encoding="utf-8") as f:
        report = json.load(f)
    out_dir = os.path.join(report_dir, "figures")
    os.makedirs(out_dir, exist_ok=True)
    written = current = 0
    json_time = os.path.getmtime(json_path)
    for claim in report["claims"]:
        kind = claim["figure"]["kind"]
        if kind == "none":
            continue
        target = os.path.join(out_dir, claim["id"] + ".png")
        if up_to_date(target, json_time, claim, report_dir):
            current += 1
            continue
        fig, ax = plt.subplots(figsize=(6.4, 3.8))
        drawn = plot_series(ax, claim, report_dir) if kind == "series" else plot_bars(ax, claim)
        title = claim["figure"]["title"] or claim["id"]
        ax.set_title(f"{claim['id']}: {title}\nverdict: {claim['verdict']}", fontsize=9)
        ax.grid(True, alpha=0.3)
        fig.tight_layout()
        if drawn:
            fig.savefig(target, dpi=110)
            written += 1
        else:
            print(f"plot_claims.py: {claim['id']}: nothing to draw", file=sys.stderr)
        plt.close(fig)
    print(f"plot_claims.py: {written} figures drawn, {current} up to date -> {out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
