#!/usr/bin/python3
"""Draws the default study's figures from its run files (scripts/study.sh runs it).

    plot_default_study.py STUDY_DIR

STUDY_DIR holds one sweep directory per file of studies/default/ (each with its index.json).
Figures are written beside them and redrawn only when a sweep's index is newer than the figure:
the cloth runs over time, the cloth's peak and mean stretch against the iterations (log-log) and
the chain's stretch against the projection sweeps per step, iterations against substeps
(log-log). Axes are set from the runs that did not explode, and lines that lie on top of each
other say so in the legend (plot_axes.py).
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plot_axes  # noqa: E402
import plot_runs  # noqa: E402
import plot_sweep  # noqa: E402
import runfile  # noqa: E402


def stale(figure, index):
    return not os.path.exists(figure) or os.path.getmtime(figure) < os.path.getmtime(index)


def load_index(sweep_dir):
    path = os.path.join(sweep_dir, "index.json")
    with open(path, encoding="utf-8") as f:
        return path, json.load(f)


def load_runs(sweep_dir, index):
    return [runfile.load(os.path.join(sweep_dir, r["file"]), frames=False, model=False) for r in index["runs"]]


def cloth_runs_figure(sweep_dir):
    """Every cloth run over time (plot_runs.py's standard panel)."""
    _, index = load_index(sweep_dir)
    return plot_runs.figure(load_runs(sweep_dir, index), title="hanging_cloth: PBD and XPBD")


def cloth_sweep_figure(sweep_dir, metric, at):
    """A cloth metric against the iterations, per solver, on log-log axes: the point is how fast
    it falls with the iterations (halving as they double is a slope of -1)."""
    args = plot_sweep.parser().parse_args([sweep_dir, "--x", "solver.iterations", "--metric", metric, "--at", at,
                                           "--group-by", "solver.name", "--log", "both"])
    return plot_sweep.figure(args)[0]


def chain_figure(sweep_dir):
    """Constraint error against projection sweeps per step (iterations x substeps), one line for
    iterations alone and one for substeps alone, per solver, on log-log axes (the slopes are the
    rates). An exploded run is an x, and the axis is set from the others; a line on top of
    another says so in the legend."""
    _, index = load_index(sweep_dir)
    lines = {}
    for r in index["runs"]:
        p = r["params"]
        it, sub = p["solver.iterations"], p["solver.substeps"]
        mode = "substeps (1 iteration each)" if it == 1 and sub > 1 else "iterations (1 substep)"
        run = runfile.load(os.path.join(sweep_dir, r["file"]), frames=False, model=False)
        err = run.series["constraint_error_max"]
        value = np.nanmean(err[1:]) if len(err) > 1 and np.isfinite(err[1:]).any() else np.nan
        point = (it * sub, value, run.exploded)
        lines.setdefault((p["solver.name"], mode), []).append(point)
        if it == 1 and sub == 1:  # n = 1 belongs to both lines
            lines.setdefault((p["solver.name"], "substeps (1 iteration each)"), []).append(point)
    keys = sorted(lines)
    for key in keys:
        lines[key].sort()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    ax.set_xscale("log")
    ax.set_yscale("log")
    kept = [np.array([v for _, v, boom in lines[k] if not boom]) for k in keys]
    everything = [np.array([v for _, v, _ in lines[k]]) for k in keys]
    lim = plot_axes.keep_to(ax, kept, everything, log=True)
    curves = [([n for n, _, _ in lines[k]], [v for _, v, _ in lines[k]]) for k in keys]
    same = plot_axes.coincident(curves, lim, log=True)
    solvers = sorted({solver for solver, _ in keys})
    exploded = 0
    for i, key in enumerate(keys):
        solver, mode = key
        x, y = curves[i]
        label = f"{solver}: {mode}"
        if i in same:
            j, identical = same[i]
            label += (f" ({'identical to' if identical else 'on top of'} {keys[j][0]}: {keys[j][1].split(' ')[0]};"
                      " drawn over it, hollow)")
        color = plt.cm.tab10(solvers.index(solver) % 10)
        ax.plot(x, y, color=color, linestyle="-" if mode.startswith("sub") else "--",
                marker=plot_axes.MARKERS[i % len(plot_axes.MARKERS)], markersize=8 if i in same else 5,
                fillstyle="none" if i in same else "full", label=label)
        for n, v, boom in lines[key]:
            if not boom:
                continue
            exploded += 1
            top = lim[1] if lim is not None else ax.get_ylim()[1]
            inside = lim is not None and np.isfinite(v) and lim[0] <= v <= lim[1]
            ax.plot([n], [v if inside else top], marker="x", color=color, markersize=10, mew=2, linestyle="none",
                    clip_on=False)
    handles, labels = ax.get_legend_handles_labels()
    if exploded:
        handles.append(plt.Line2D([], [], color="0.3", marker="x", linestyle="none", mew=2))
        labels.append(f"exploded ({exploded} runs; the axis is the others', beyond it at the top edge)")
    ax.set_xlabel("projection sweeps per step (iterations x substeps)")
    ax.set_ylabel("max relative link stretch, mean over the run")
    ax.set_title("hanging_chain: iterations against substeps at equal cost")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(handles, labels, fontsize=7)
    fig.tight_layout()
    return fig


def plans(study):
    """[(figure file, its sweep's index, how to draw it)] for the study in folder `study`."""
    cloth = os.path.join(study, "cloth_pbd_vs_xpbd")
    chain = os.path.join(study, "chain_iterations_vs_substeps")
    # A swinging cloth's error at one instant says little: take the peak and the mean over the run.
    return [
        ("cloth_runs.png", cloth, lambda: cloth_runs_figure(cloth)),
        ("cloth_stretch_peak_vs_iterations.png", cloth,
         lambda: cloth_sweep_figure(cloth, "constraint_error_max_stretch", "max")),
        ("cloth_stretch_rms_mean_vs_iterations.png", cloth,
         lambda: cloth_sweep_figure(cloth, "constraint_error_rms_stretch", "mean")),
        ("chain_iterations_vs_substeps.png", chain, lambda: chain_figure(chain)),
    ]


def figures(study):
    """Every figure of the study, drawn: {file name: matplotlib Figure} (the tests read them)."""
    return {name: draw() for name, _, draw in plans(study)}


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    study = argv[1]
    written = []
    try:
        for name, sweep_dir, draw in plans(study):
            path = os.path.join(study, name)
            index_path, _ = load_index(sweep_dir)
            if stale(path, index_path):
                fig = draw()
                try:
                    fig.savefig(path, dpi=120)
                finally:
                    plt.close(fig)
                print(f"wrote {path}")
            written.append(path)
    except (OSError, KeyError, ValueError, runfile.RunFileError, plot_sweep.SweepError) as e:
        print(f"plot_default_study.py: {e}", file=sys.stderr)
        return 1
    except SystemExit as e:  # plot_runs: nothing to draw
        print(e.code, file=sys.stderr)
        return 1
    print("figures:")
    for f in written:
        print(f"  {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
