#!/usr/bin/python3
"""Plots convergence files written by `pbdbench converge` (one step of a scene solved by xpbd in
three orders and by the global solvers).

    plot_convergence.py FILE.h5 [FILE2.h5 ...] -o OUT.png

One row per file (scene), two panels: the residual (max_i |g_i| / m_i, m) against iterations
and against wall time, log-log, one line per method. Iterations are projection sweeps for
xpbd, Newton iterations for global-cholmod and global-cg, Levenberg-Marquardt iterations for
global-ceres (the legend says which). The residual at x~ (where every global solve starts) and
the global tolerance are drawn as horizontal lines.
Exit codes: 0 written, 1 the image could not be written, 2 not a convergence file.
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402

# Line style and legend label of each method of the file; unknown keys are drawn with defaults.
STYLE = {
    "xpbd-sequential": dict(color="C0", ls="--", marker="o", ms=4, label="xpbd Gauss-Seidel (sweeps)"),
    "xpbd-colored": dict(color="C1", ls="--", marker="s", ms=4,
                         label="xpbd coloured Gauss-Seidel (sweeps)"),
    "xpbd-jacobi": dict(color="C2", ls="--", marker="^", ms=4, label="xpbd Jacobi (sweeps)"),
    # The three Newton solvers take the same iterates: open markers of decreasing size and
    # lines of decreasing width keep each visible where they coincide.
    "global-cholmod": dict(color="C3", ls="-", lw=3.0, marker="D", ms=7, mfc="none",
                           label="global-cholmod (Newton its)"),
    "global-cg": dict(color="C4", ls="-", lw=2.0, marker="v", ms=5, mfc="none",
                      label="global-cg, incomplete Cholesky (Newton its)"),
    "global-cg-matrix-free": dict(color="C5", ls="-", lw=1.0, marker="<", ms=4,
                                  label="global-cg matrix-free (Newton its)"),
    "global-ceres": dict(color="C6", ls="-", lw=1.0, marker="x", ms=4, label="global-ceres (LM its)"),
}


# A convergence file that is missing or not one; the message names the path.
ConvergeFileError = runfile.RunFileError


def load(path):
    """The file as a dict: attrs (root attributes) and methods, a list of (key, dict with
    iteration, residual, time, optionally error and inner_iterations, and attrs) in file order."""
    c = runfile.load_converge(path)
    return {"attrs": c.attrs, "methods": c.methods}


def _positive(x, y):
    """The points with x > 0 and y > 0 (log axes): drops the start (iteration 0) and exact zeros."""
    keep = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    return x[keep], y[keep]


def draw(data, ax_it, ax_time):
    a = data["attrs"]
    for key, m in data["methods"]:
        style = dict(lw=1.2, ms=4)
        style.update(STYLE.get(key, dict(ls="-", marker=".", label=key)))
        for ax, xname in ((ax_it, "iteration"), (ax_time, "time")):
            x, y = _positive(m[xname], m["residual"])
            ax.plot(x, y, **style)
    for ax in (ax_it, ax_time):
        start = float(a.get("start_residual", np.nan))
        if np.isfinite(start) and start > 0:
            ax.axhline(start, color="0.5", ls=":", lw=1, label="residual at x~ (start)")
        tol = float(a.get("tolerance", np.nan))
        if np.isfinite(tol) and tol > 0:
            ax.axhline(tol, color="k", ls="-.", lw=0.8, label="global tolerance")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.grid(True, which="major", alpha=0.3)
        ax.set_ylabel("residual max |g_i|/m_i (m)")
    title = (f"{a.get('scene', '?')}: one step of {float(a.get('dt', np.nan)):.4g} s after "
             f"{a.get('warmup_steps', '?')} warm-up steps")
    ax_it.set_title(title + ", against iterations", fontsize=9)
    ax_time.set_title(title + ", against wall time", fontsize=9)
    ax_it.set_xlabel("iterations (xpbd: sweeps; Newton; LM)")
    ax_time.set_xlabel("wall time (s)")


def main(argv=None):
    p = argparse.ArgumentParser(description="Plot `pbdbench converge` files.")
    p.add_argument("files", nargs="+", help="convergence files (HDF5)")
    p.add_argument("-o", "--out", help="image to write (default: the first file with .png)")
    args = p.parse_args(argv)
    try:
        data = [load(f) for f in args.files]
    except ConvergeFileError as e:
        print(f"plot_convergence.py: {e}", file=sys.stderr)
        return 2
    out = args.out or os.path.splitext(args.files[0])[0] + ".png"
    fig, axes = plt.subplots(len(data), 2, figsize=(12, 4.4 * len(data) + 1.2), squeeze=False)
    for d, (ax_it, ax_time) in zip(data, axes):
        draw(d, ax_it, ax_time)
    # One legend for every panel, below them: each label once, in the order first drawn.
    handles = {}
    for ax in axes.flat:
        for h, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, h)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center", ncol=3, fontsize=8)
    machine = data[0]["attrs"].get("machine", "")
    if machine:
        fig.suptitle(f"{machine} ({data[0]['attrs'].get('build_type', '?')} build)", fontsize=8)
    fig.tight_layout(rect=(0, 1.0 / (4.4 * len(data) + 1.2), 1, 1))
    try:
        if os.path.dirname(out):
            os.makedirs(os.path.dirname(out), exist_ok=True)
        fig.savefig(out, dpi=120)
    except OSError as e:
        print(f"plot_convergence.py: cannot write {out}: {e}", file=sys.stderr)
        return 1
    print(f"plot_convergence.py: wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
