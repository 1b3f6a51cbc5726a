#!/usr/bin/python3
"""Plots a compare file written by `pbdbench compare` (layout in results/README.md).

    plot_compare.py COMPARE.h5 [-o OUT.png]

Panels, over time: the position error between the run and the reference (RMS and max over the
particles, log scale); then, for each observable of the scene that the file holds, both runs
(tip displacement and support force as the norm of the vector, the pendulum angle as is). When
the scene has no observable, the difference of the total energy (run - reference) takes their
place. A panel whose values are 0 or NaN throughout is left out (the support force of a scene
with nothing pinned, the position error of a run identical to its reference: the title says so).
The output format follows the extension of OUT (PNG by default: COMPARE.png).
Exit codes: 0 written, 1 the image could not be written, 2 not a compare file.
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plot_axes  # noqa: E402
import runfile  # noqa: E402


# A compare file that is missing or not one; the message names the path.
CompareFileError = runfile.RunFileError


def load(path):
    """The compare file as a dict: attrs (root attributes), time, position_error_rms/max,
    series_time, diff (name -> array), observables (name -> array or float)."""
    c = runfile.load_compare(path)
    try:
        return {
            "attrs": c.attrs,
            "time": c.data["time"],
            "position_error_rms": c.data["position_error_rms"],
            "position_error_max": c.data["position_error_max"],
            "series_time": c.data["series_time"],
            "diff": c.diff,
            "observables": c.observables,
        }
    except KeyError as e:
        raise CompareFileError(f"{path}: cannot read: no /compare/{e.args[0]}") from e


def _norm(v):
    v = np.asarray(v, dtype=float)
    return np.linalg.norm(v, axis=1) if v.ndim == 2 else v


def _finite(*arrays):
    return any(np.isfinite(np.asarray(a, dtype=float)).any() for a in arrays)


def _nan_label(label, values):
    return label if _finite(values) else label + ": NaN throughout"


def panels(data):
    """The panels to draw: (title, ylabel, log, [(label, x, y, style)])."""
    attrs = data["attrs"]
    run = f"run ({attrs.get('run_solver', '?')})"
    ref = f"reference ({attrs.get('reference_solver', '?')})"
    out = []
    t = data["time"]
    curves = []
    for key, label, style in (("position_error_rms", "RMS over particles", "-"),
                              ("position_error_max", "max over particles", "--")):
        y = np.asarray(data[key], dtype=float)
        y = np.where(y > 0, y, np.nan)  # a log scale cannot show 0 (identical positions)
        curves.append((label, t, y, style))
    if plot_axes.informative([c[2] for c in curves]):
        out.append(("position error |x_run - x_reference|", "m", True, curves))

    obs = data["observables"]
    ts = data["series_time"]
    for name, title, unit in (("tip_displacement", "|tip displacement|", "m"),
                              ("support_force", "|support force|", "N")):
        a, b = obs.get(name + "_run"), obs.get(name + "_reference")
        if a is not None and b is not None and plot_axes.informative([_norm(a), _norm(b)]):
            out.append((title, unit, False, [(_nan_label(run, a), ts, _norm(a), "-"),
                                             (_nan_label(ref, b), ts, _norm(b), "--")]))
    a, b = obs.get("pendulum_angle_run"), obs.get("pendulum_angle_reference")
    if a is not None and b is not None and plot_axes.informative([a, b]):
        title = "pendulum angle"
        pr, pf = obs.get("pendulum_period_run"), obs.get("pendulum_period_reference")
        if pr is not None and pf is not None:
            title += f" (periods: run {pr:.4g} s, reference {pf:.4g} s)"
        out.append((title, "rad", False, [(_nan_label(run, a), ts, a, "-"),
                                          (_nan_label(ref, b), ts, b, "--")]))
    observed = any(o[0] != "position error |x_run - x_reference|" for o in out)
    if not observed and "total_energy" in data["diff"] and plot_axes.informative([data["diff"]["total_energy"]]):
        out.append(("total energy, run - reference", "J", False,
                    [("difference", ts, data["diff"]["total_energy"], "-")]))
    return out


def identical(data):
    """Whether the run's positions equal the reference's at every compared frame."""
    return not plot_axes.informative([data["position_error_max"]]) and _finite(data["position_error_max"])


def figure(data, title=None):
    """The figure of a compare file (load()'s dict)."""
    chosen = panels(data)
    attrs = data["attrs"]
    title = title or "{} vs {}: {}".format(attrs.get("run_solver", "?"), attrs.get("reference_solver", "?"),
                                           attrs.get("run_scenario", ""))
    if identical(data):
        title += "\n(positions identical to the reference at every frame)"
    if not chosen:
        fig, ax = plt.subplots(figsize=(8, 2.4))
        ax.axis("off")
        ax.text(0.5, 0.5, "nothing to draw: every compared value is 0 or NaN", transform=ax.transAxes,
                ha="center", va="center")
        fig.suptitle(title, fontsize=11)
        fig.tight_layout()
        return fig
    fig, axes = plt.subplots(len(chosen), 1, figsize=(8, 2.8 * len(chosen) + 0.6), sharex=True,
                             squeeze=False)
    for ax, (name, unit, log, curves) in zip(axes[:, 0], chosen):
        for label, x, y, style in curves:
            ax.plot(x, y, style, label=label)
        if log and _finite(*[c[2] for c in curves]):
            ax.set_yscale("log")
        ax.set_title(name, fontsize=10)
        ax.set_ylabel(f"[{unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def plot(data, out_path, title=None):
    fig = figure(data, title)
    try:
        fig.savefig(out_path, dpi=110)
    finally:
        plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("compare", help="compare file written by pbdbench compare --out")
    parser.add_argument("-o", "--out", help="output image (default: COMPARE with .png)")
    parser.add_argument("--title", help="figure title")
    args = parser.parse_args(argv)
    try:
        data = load(args.compare)
    except CompareFileError as e:
        print(f"plot_compare.py: {e}", file=sys.stderr)
        return 2
    out = args.out or os.path.splitext(args.compare)[0] + ".png"
    try:
        plot(data, out, args.title)
    except (OSError, ValueError) as e:
        print(f"plot_compare.py: cannot write {out}: {e}", file=sys.stderr)
        return 1
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
