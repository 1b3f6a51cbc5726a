#!/usr/bin/python3
"""Plots run files over time, runs overlaid: the standard panel or chosen series.

    plot_runs.py RUN.h5 [RUN.h5 ...] [-o OUT.png] [--series a,b,...]

The standard panel: constraint error (max solid, RMS dashed; log scale), volume drift (tets
solid, closed surface dashed), energies (kinetic, potential, elastic, total; the total alone
for more than three runs) and the drift of the total energy relative to its start. Each run gets one colour, labelled by the configuration
keys whose values differ between the runs (solver name, iterations, substeps, ...), and its own
marker. An exploded run is marked with an x at its explosion time and "(exploded)" in its label;
each panel's axis is set from the runs that did not explode, and the label of an exploded run
whose line leaves it says where ("off the axis in: energy"). A run whose line lies on another's
(within 1 % of the axis's height everywhere) says so in its label ("= LABEL in: energy", or
"identical to LABEL"). An incomplete or failed run says so in its label. Series that are NaN
throughout, in every run, are left out, and so is a panel with nothing to draw.

--series plots the named series instead, one panel each (the norm of a 3-vector series).
The output format follows the extension of OUT (PNG by default).
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

MANY_RUNS = 3  # beyond this many runs, the energy panel draws the total energy alone
ENERGY_STYLES = [("kinetic_energy", ":", "kinetic"), ("potential_energy", "-.", "potential"),
                 ("elastic_energy", (0, (1, 3)), "elastic"), ("total_energy", "-", "total")]


def values(run, name):
    """A series as a 1-D array (the norm for a (rows, 3) series), or None."""
    v = run.series.get(name)
    if v is None:
        return None
    if v.ndim == 2:
        v = np.linalg.norm(v, axis=1)
    return v


def all_nan(runs, name):
    for run in runs:
        v = values(run, name)
        if v is not None and v.size and not np.all(np.isnan(v)):
            return False
    return True


def run_labels(runs):
    """Each run's legend label: the configuration keys whose values differ between the runs, less
    the solver options its solver does not read (ref-be's iterations: runfile.keys_read)."""
    keys = runfile.differing_keys(runs) if len(runs) > 1 else []
    reads = runfile.solver_reads() if keys else None
    labels = []
    for run in runs:
        mine = runfile.keys_read(run, keys, reads) if keys else []
        text = runfile.label(run, mine) if mine else (
            run.name if len(runs) > 1 else str(run.attrs.get("solver", run.name)))
        if run.status != "complete":
            text += f" ({run.status})"
        labels.append(text)
    if len(set(labels)) < len(labels):  # identical configurations: tell them apart by file
        labels = [f"{lab} [{run.name}]" for lab, run in zip(labels, runs)]
    return labels


def explosion_point(run, y):
    """(t, y) where to mark an exploded run: the explosion time and the last finite value of y
    at or before it."""
    t = run.series.get("time")
    if not run.exploded or t is None or y is None or not len(t):
        return None
    te = run.attrs.get("exploded_time", -1.0)
    if not isinstance(te, (int, float)) or te < 0:
        te = t[-1]
    ok = np.isfinite(y) & (t <= te + 1e-12)
    if not ok.any():
        return None
    i = np.nonzero(ok)[0][-1]
    return te, y[i]


SERIES_NAMES = {name: short for name, _, short in ENERGY_STYLES} | {
    "constraint_error_max": "max", "constraint_error_rms": "RMS", "volume_drift": "tets",
    "surface_volume_drift": "surface"}


def plot_series(ax, runs, colors, name, style="-", transform=None, log=False):
    """Plots one series of every run on ax; returns the curves drawn, [(run index, t, y)]."""
    curves = []
    for k, (run, color) in enumerate(zip(runs, colors)):
        t = run.series.get("time")
        y = values(run, name)
        if t is None or y is None or not len(y) or np.all(np.isnan(y)):
            continue
        n = min(len(t), len(y))
        t, y = t[:n], y[:n]
        if transform is not None:
            y = transform(y)
        if log:
            y = np.where(y > 0, y, np.nan)  # zeros and negatives have no place on a log axis
        ax.plot(t, y, linestyle=style, color=color, linewidth=1.2,
                marker=plot_axes.MARKERS[k % len(plot_axes.MARKERS)], markersize=4,
                markevery=plot_axes.markevery(k, len(runs), n))
        mark = explosion_point(run, y)
        if mark is not None:
            ax.plot([mark[0]], [mark[1]], marker="x", color=color, markersize=9, mew=2)
        curves.append((k, name, t, y))
    if log and curves:
        ax.set_yscale("log")
    return curves


def units_of(runs, name):
    for run in runs:
        if name in run.units:
            return run.units[name]
    return ""


def first_finite(y):
    if y is None:
        return None
    finite = y[np.isfinite(y)]
    return float(finite[0]) if finite.size else None


def relative_drift(y):
    y0 = first_finite(y)
    if y0 is None:
        return y
    return (y - y0) / abs(y0) if y0 != 0 else y - y0


def standard_panels(runs):
    """[(title, ylabel, draw(ax, colors) -> bool, style legend entries)]"""
    panels = []
    if not (all_nan(runs, "constraint_error_max") and all_nan(runs, "constraint_error_rms")):
        panels.append(("constraint error", "normalised error [1]", lambda ax, c: (
            plot_series(ax, runs, c, "constraint_error_max", "-", log=True)
            + plot_series(ax, runs, c, "constraint_error_rms", "--", log=True)),
            [("-", "max"), ("--", "RMS")]))
    vol = [(n, s, lab) for n, s, lab in [("volume_drift", "-", "tets"),
                                          ("surface_volume_drift", "--", "surface")]
           if not all_nan(runs, n)]
    if vol:
        panels.append(("volume drift", "(V - V0) / V0 [1]", lambda ax, c: sum(
            (plot_series(ax, runs, c, n, s) for n, s, _ in vol), []),
            [(s, lab) for _, s, lab in vol]))
    energies = [(n, s, lab) for n, s, lab in ENERGY_STYLES if not all_nan(runs, n)]
    if len(runs) > MANY_RUNS:  # four lines a run would bury each other: the total alone
        energies = [e for e in energies if e[0] == "total_energy"]
    if energies:
        panels.append(("energy", "energy [J]", lambda ax, c: sum(
            (plot_series(ax, runs, c, n, s) for n, s, _ in energies), []),
            [(s, lab) for _, s, lab in energies]))
    if not all_nan(runs, "total_energy"):
        # Relative to |E0|; a run that starts at E0 = 0 has no relative drift: E - E0 in J.
        starts = [first_finite(values(r, "total_energy")) for r in runs]
        if all(e0 != 0 for e0 in starts if e0 is not None):
            ylabel = "(E - E0) / |E0| [1]"
        elif all(e0 == 0 for e0 in starts if e0 is not None):
            ylabel = "E - E0 [J]"
        else:
            ylabel = "(E - E0) / |E0| [1], or E - E0 [J] where E0 = 0"
        panels.append(("total energy drift", ylabel,
                       lambda ax, c: plot_series(ax, runs, c, "total_energy", "-",
                                                 transform=relative_drift), []))
    return panels


def chosen_panels(runs, names):
    panels = []
    for name in names:
        known = any(name in r.series for r in runs)
        if not known:
            raise SystemExit(f"plot_runs.py: no series named {name!r} in these files "
                             f"(they have: {', '.join(sorted(runs[0].series))})")
        if all_nan(runs, name):
            print(f"plot_runs.py: {name} is NaN throughout in every run: left out",
                  file=sys.stderr)
            continue
        width3 = any(name in r.series and r.series[name].ndim == 2 for r in runs)
        log = name.startswith("constraint_error") or name.startswith("residual")
        ylabel = f"{'|' + name + '|' if width3 else name} [{units_of(runs, name)}]"
        panels.append((name, ylabel,
                       lambda ax, c, name=name, log=log: plot_series(ax, runs, c, name, log=log),
                       []))
    return panels


def keep_exploded_apart(ax, runs, curves):
    """Sets the panel's y axis from the runs that did not explode (nor, on a linear axis, blew up
    far beyond the others: plot_axes.outliers); returns the indices of the runs whose line
    leaves it, and the limits."""
    log = ax.get_yscale() == "log"
    apart = {k for k, _, _, _ in curves if runs[k].exploded}
    if not log:
        peaks = [max((float(np.max(np.abs(v))) for v in (plot_axes.finite(y) for kk, _, _, y in curves if kk == k)
                      if v.size), default=np.nan) for k in range(len(runs))]
        apart |= plot_axes.outliers(peaks)
    kept = [y for k, _, _, y in curves if k not in apart]
    others = [(k, y) for k, _, _, y in curves if k in apart]
    lim = plot_axes.keep_to(ax, kept, [y for _, y in others], log)
    if lim is None:
        return set(), None
    # A spike of a few points (one row of 25,000 J) flattens the rest as much as a run does.
    bulk = plot_axes.bulk_limits(kept, log)
    if bulk is not None:
        lim = bulk
        ax.set_ylim(*lim)
    return {k for k, _, _, y in curves if plot_axes.off_axis(y, lim, log)}, lim


def figure(runs, series=None, title=None):
    """The figure of `runs` (loaded run files): the standard panel, or one panel per name of
    `series`. Raises SystemExit with a message when there is nothing to draw."""
    panels = chosen_panels(runs, series) if series else standard_panels(runs)
    colors = [plt.cm.tab10(i % 10) for i in range(len(runs))]
    labels = run_labels(runs)
    # Draw first, keep the panels that drew something.
    scratch = plt.figure()
    drawn = []
    for title_, ylabel, draw, styles in panels:
        ax = scratch.add_subplot()
        curves = draw(ax, colors)
        scratch.delaxes(ax)
        # A panel whose lines are NaN or 0 throughout says nothing: left out.
        if curves and plot_axes.informative([y for _, _, _, y in curves]):
            drawn.append((title_, ylabel, draw, styles))
    plt.close(scratch)
    if not drawn:
        raise SystemExit("plot_runs.py: nothing to plot: every series is NaN, 0 or empty")

    ncols = 2 if len(drawn) > 1 else 1
    nrows = (len(drawn) + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(6.4 * ncols, 3.6 * nrows + 0.8), squeeze=False)
    off = {}    # run -> panels its line leaves
    same = {}   # run -> {(other run, identical): [panels]}
    lines = {}  # run -> how many lines it has
    for ax, (title_, ylabel, draw, styles) in zip(axes.flat, drawn):
        curves = draw(ax, colors)
        for k, _, _, _ in curves:
            lines[k] = lines.get(k, 0) + 1
        gone, lim = keep_exploded_apart(ax, runs, curves)
        notes = []
        for k in sorted(gone):
            off.setdefault(k, []).append(title_)
            peak = max(float(np.max(np.abs(v))) for v in (plot_axes.finite(y) for kk, _, _, y in curves if kk == k)
                       if v.size)
            unit = ylabel.rsplit("[", 1)[-1].rstrip("]") if "[" in ylabel else ""
            notes.append(f"{labels[k]}: {'exploded, ' if runs[k].exploded else ''}up to "
                         f"{plot_axes.value_text(peak)}{' ' + unit if unit and unit != '1' else ''}, off the axis")
        plot_axes.name_outliers(ax, notes)  # named where it is missing, not only in the legend
        log = ax.get_yscale() == "log"
        for name in dict.fromkeys(c[1] for c in curves):
            of_name = [c for c in curves if c[1] == name]
            pairs = plot_axes.coincident([(t, y) for _, _, t, y in of_name], lim, log)
            several = len({c[1] for c in curves}) > 1  # name the series when the panel has several
            where = f"{title_} ({SERIES_NAMES.get(name, name)})" if several else title_
            for j, (i, identical) in pairs.items():
                panels_ = same.setdefault(of_name[j][0], {}).setdefault((of_name[i][0], identical), [])
                if where not in panels_:
                    panels_.append(where)
        ax.set_title(title_)
        ax.set_xlabel(f"time [{units_of(runs, 'time') or 's'}]")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        if styles:
            handles = [plt.Line2D([], [], color="0.3", linestyle=s) for s, _ in styles]
            # The upper left holds the note on lines off the axis (plot_axes.name_outliers).
            ax.legend(handles, [lab for _, lab in styles], fontsize=8, loc="upper right" if notes else "best")
    free = list(axes.flat)[len(drawn):]
    for ax in free[1:]:
        fig.delaxes(ax)

    shown = list(labels)
    for k in range(len(runs)):
        notes = []
        for (i, identical), where in same.get(k, {}).items():
            if identical and len(where) == lines.get(k, 0):  # every line of the run
                notes.append(f"identical to {labels[i]}")
            else:
                notes.append(f"{'identical to' if identical else '='} {labels[i]} in: {', '.join(where)}")
        if k in off:
            notes.append(f"off the axis in: {', '.join(off[k])}")
        if notes:
            shown[k] += " (" + "; ".join(notes) + ")"
    handles = [plt.Line2D([], [], color=c, linewidth=2, marker=plot_axes.MARKERS[k % len(plot_axes.MARKERS)],
                          markersize=5) for k, c in enumerate(colors)]
    if any(r.exploded for r in runs):
        handles.append(plt.Line2D([], [], color="0.3", marker="x", linestyle="none", mew=2))
        shown.append("explosion")
    scenario = plot_axes.shown_name(runs[0].attrs.get("scenario", ""))
    fig.suptitle(title or (f"scenario {scenario}" if scenario else ""))
    # In the grid's free cell when there is one and it fits, else below the panels (the figure
    # grows by its height); inside the figure, labels wrapped to fit.
    plot_axes.figure_legend(fig, handles, shown, fontsize=8, top=0.95, slot=free[0] if free else None)
    return fig


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", metavar="RUN.h5")
    ap.add_argument("-o", "--output", default="runs.png", help="output image (default runs.png)")
    ap.add_argument("--series", help="comma-separated series to plot instead of the standard panel")
    ap.add_argument("--title", help="figure title (default: the scenario)")
    args = ap.parse_args(argv)

    runs = []
    for path in runfile.without_viz(args.runs, "plot_runs.py"):
        try:
            runs.append(runfile.load(path, frames=False, model=False))
        except runfile.RunFileError as e:
            print(f"plot_runs.py: cannot read run file {e}", file=sys.stderr)
            return 1
    for run in runs:
        if "time" not in run.series:
            print(f"plot_runs.py: {run.path} has no /series/time", file=sys.stderr)
            return 1

    series = [s.strip() for s in args.series.split(",") if s.strip()] if args.series else None
    try:
        fig = figure(runs, series, args.title)
    except SystemExit as e:
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)
            return 1
        raise
    try:
        fig.savefig(args.output, dpi=120)
    except (OSError, ValueError) as e:
        print(f"plot_runs.py: cannot write {args.output}: {e}", file=sys.stderr)
        return 1
    finally:
        plt.close(fig)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
