#!/usr/bin/python3
"""Draws what `pbdbench regress` found: the change of each metric against its baseline, in units of
its tolerance (change / allowed), for the metrics that moved the most, one bar each (worse in red,
better in green, within the tolerance in grey; timings and new metrics left out).

    plot_regress.py REGRESS.h5 OUT.png

The figure stays readable at any number of cases: it shows at most MAX_BARS bars, the largest
|change / allowed| first, and says in its title how many metrics of how many cases it left out
and the largest |change / allowed| among them; the figure's height is bounded. When no metric
moved at all (every change 0), there are no bars to draw: the figure says so in words.
"""
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plot_axes  # noqa: E402
import runfile  # noqa: E402

MAX_BARS = 30  # the most bars a figure shows: beyond, labels would no longer be readable
CLIP = 10.0    # |change / allowed| beyond this is drawn at the edge, its value written beside


def rows_of(columns):
    """[(case, metric, verdict, change / allowed)] for the rows that compare a value with its
    baseline (not "ratio" nor "new"); a NaN change is left out, a change with no tolerance
    (allowed 0) is +-inf."""
    out = []
    for c, m, v, d, a in zip(columns["case"], columns["metric"], columns["verdict"], columns["change"],
                             columns["allowed"]):
        if v in ("ratio", "new") or math.isnan(d):
            continue
        x = d / a if a > 0 else (0.0 if d == 0 else math.copysign(math.inf, d))
        out.append((c, m, v, x))
    return out


def figure(columns):
    """The figure of a regression file's columns (runfile.load_regress(path).columns)."""
    verdicts = list(columns["verdict"])
    rows = rows_of(columns)
    cases = sorted({r[0] for r in rows})
    unmeasured = sum(1 for v, d in zip(verdicts, columns["change"]) if v not in ("ratio", "new") and math.isnan(d))
    moved = sorted((r for r in rows if r[3] != 0), key=lambda r: -abs(r[3]))
    shown, rest = moved[:MAX_BARS], moved[MAX_BARS:]
    title = (f"regression: {verdicts.count('worse')} worse, {verdicts.count('better')} better, "
             f"{verdicts.count('same')} same ({len(rows)} metrics of {len(cases)} cases compared"
             + (f"; {unmeasured} not measured by their case" if unmeasured else "") + ")")
    if not shown:
        fig, ax = plt.subplots(figsize=(7, 2.4))
        ax.axis("off")
        ax.text(0.5, 0.5, f"no metric moved: every change of the {len(rows)} metrics of {len(cases)} "
                "cases is 0", transform=ax.transAxes, ha="center", va="center", fontsize=10)
        ax.set_title(plot_axes.wrap(title, 70), fontsize=9)
        fig.tight_layout()
        return fig
    unmoved = len(rows) - len(moved)
    notes = []
    if rest:
        notes.append(f"{len(rest)} more moved, |change| <= {plot_axes.value_text(abs(rest[0][3]))} x allowed")
    if unmoved:
        notes.append(f"{unmoved} unchanged")
    shown = shown[::-1]  # the largest at the top
    labels = [f"{c}: {m}" for c, m, _, _ in shown]
    values = [max(-CLIP, min(CLIP, x)) for _, _, _, x in shown]
    colors = [{"worse": "tab:red", "better": "tab:green"}.get(v, "0.6") for _, _, v, _ in shown]
    fig, ax = plt.subplots(figsize=(8, 1.3 + 0.24 * len(shown)))
    ax.barh(range(len(shown)), values, color=colors)
    top = max(abs(v) for v in values)
    # The scale of the largest bar: changes far inside the tolerance (rounding, 1e-13 of it) show
    # as bars rather than as nothing on an axis to +-1.
    edge = max(1.2, 1.1 * top) if top >= 0.05 else 1.35 * top
    for k, (v, (_, _, _, x)) in enumerate(zip(values, shown)):
        ax.text(v, k, f" {plot_axes.value_text(x)} " if abs(x) <= CLIP else f" {plot_axes.value_text(x)} (clipped) ",
                va="center", ha="left" if v > 0 else "right", fontsize=7)
    ax.set_yticks(range(len(shown)))
    ax.set_yticklabels(labels, fontsize=8)
    ax.axvline(0, color="k", lw=0.5)
    if edge >= 1:
        ax.axvline(-1, color="k", lw=0.5, ls="--")
        ax.axvline(1, color="k", lw=0.5, ls="--")
        ax.set_xlabel(f"change / allowed (dashed: the tolerance; clipped to +-{CLIP:g})")
    else:
        ax.set_xlabel("change / allowed (every change far inside its tolerance, which is at +-1)")
    ax.set_xlim(-edge * 1.25, edge * 1.25)
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(5, symmetric=True))
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: "0" if v == 0 else plot_axes.value_text(v)))
    ax.set_title(plot_axes.wrap(title, 70) + ("\n" + "; ".join(notes) if notes else ""), fontsize=9)
    ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        columns = runfile.load_regress(argv[1]).columns
    except runfile.RunFileError as e:
        print(f"plot_regress.py: {e}", file=sys.stderr)
        return 2
    fig = figure(columns)
    try:
        fig.savefig(argv[2], dpi=110)
    except (OSError, ValueError) as e:
        print(f"plot_regress.py: cannot write {argv[2]}: {e}", file=sys.stderr)
        return 1
    finally:
        plt.close(fig)
    print(f"plot_regress.py: -> {argv[2]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
