#!/usr/bin/python3
"""Draws the default study's figures from its run files (scripts/study.sh runs it).

    plot_default_study.py STUDY_DIR

STUDY_DIR holds one sweep directory per file of studies/default/ (each with its index.json).
Figures are written beside them and redrawn only when a sweep's index is newer than the figure.
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plot_runs  # noqa: E402
import plot_sweep  # noqa: E402
import runfile  # noqa: E402


def stale(figure, index):
    return not os.path.exists(figure) or os.path.getmtime(figure) < os.path.getmtime(index)


def load_index(sweep_dir):
    path = os.path.join(sweep_dir, "index.json")
    with open(path, encoding="utf-8") as f:
        return path, json.load(f)


def cloth_figures(sweep_dir, out_dir):
    index_path, index = load_index(sweep_dir)
    written = []
    panel = os.path.join(out_dir, "cloth_runs.png")
    if stale(panel, index_path):
        files = [os.path.join(sweep_dir, r["file"]) for r in index["runs"]]
        if plot_runs.main(files + ["-o", panel, "--title", "hanging_cloth: PBD and XPBD"]) != 0:
            raise SystemExit(1)
    written.append(panel)
    # A swinging cloth's error at one instant says little: take the peak and the mean over the run.
    for metric, at, name in (("constraint_error_max_stretch", "max", "cloth_stretch_peak_vs_iterations.png"),
                             ("constraint_error_rms_stretch", "mean", "cloth_stretch_rms_mean_vs_iterations.png")):
        figure = os.path.join(out_dir, name)
        if stale(figure, index_path):
            if plot_sweep.main([sweep_dir, "--x", "solver.iterations", "--metric", metric, "--at", at,
                                "--group-by", "solver.name", "-o", figure]) != 0:
                raise SystemExit(1)
        written.append(figure)
    return written


def chain_figure(sweep_dir, out_dir):
    """Constraint error against projection sweeps per step (iterations x substeps), one line for
    iterations alone and one for substeps alone, per solver."""
    index_path, index = load_index(sweep_dir)
    figure = os.path.join(out_dir, "chain_iterations_vs_substeps.png")
    if not stale(figure, index_path):
        return [figure]
    lines = {}
    for r in index["runs"]:
        p = r["params"]
        it, sub = p["solver.iterations"], p["solver.substeps"]
        mode = "substeps (1 iteration each)" if it == 1 and sub > 1 else "iterations (1 substep)"
        run = runfile.load(os.path.join(sweep_dir, r["file"]), frames=False, model=False)
        err = run.series["constraint_error_max"]
        value = np.nanmean(err[1:]) if len(err) > 1 else np.nan
        lines.setdefault((p["solver.name"], mode), []).append((it * sub, value))
        if it == 1 and sub == 1:  # n = 1 belongs to both lines
            lines.setdefault((p["solver.name"], "substeps (1 iteration each)"), []).append((1, value))
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for (solver, mode), pts in sorted(lines.items()):
        pts.sort()
        x, y = zip(*pts)
        ax.plot(x, y, marker="o", linestyle="-" if mode.startswith("sub") else "--", label=f"{solver}: {mode}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("projection sweeps per step (iterations x substeps)")
    ax.set_ylabel("max relative link stretch, mean over the run")
    ax.set_title("hanging_chain: iterations against substeps at equal cost")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(figure, dpi=120)
    plt.close(fig)
    print(f"wrote {figure}")
    return [figure]


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    study = argv[1]
    figures = []
    try:
        figures += cloth_figures(os.path.join(study, "cloth_pbd_vs_xpbd"), study)
        figures += chain_figure(os.path.join(study, "chain_iterations_vs_substeps"), study)
    except (OSError, KeyError, ValueError, runfile.RunFileError) as e:
        print(f"plot_default_study.py: {e}", file=sys.stderr)
        return 1
    print("figures:")
    for f in figures:
        print(f"  {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
