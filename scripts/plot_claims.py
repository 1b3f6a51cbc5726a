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
A run of one or two rows (a static equilibrium) is drawn as a dashed level across the axis.
The verdict is written in the title (a reproduction's: reproduced / not reproduced). The title
says what ran: a placeholder {tets}, {triangles}, {edges} or {particles} is filled from the
claim's run files (12,800 with a thousands separator), and a count of tets, triangles or particles
that the runs contradict (a full-tier title on a quick-tier run) is replaced by theirs, with a
warning. A series figure goes on a log axis when its values span more than three decades (symlog
when they change sign); a bars figure whose measures are all 0 or NaN is drawn as the list of its
values instead of bars of no height (docs/figures.md). Run files are found relative to REPORT_DIR (claims.json
stores them so); a missing run file leaves the figure out with a warning, it does not fail. A
figure newer than claims.json and than the run files it reads is up to date and not redrawn.
"""
import json
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plot_axes  # noqa: E402
import runfile  # noqa: E402

COUNTED = {"tets": "tets", "tetrahedra": "tets", "triangles": "triangles", "particles": "particles",
           "edges": "edges"}


def value_label(v):
    return plot_axes.value_text(None if v is None else float(v))


def run_counts(claim, report_dir):
    """What the claim's runs hold: {"tets": n, "triangles": n, "edges": n, "particles": n}, each
    only when every run file that can be read has the same count."""
    seen = {}
    for r in claim.get("runs", []):
        for rel in r.get("files", [])[:1]:
            path = os.path.join(report_dir, rel)
            if not os.path.exists(path):
                continue
            try:
                run = runfile.load(path, frames=False)
            except runfile.RunFileError:
                continue
            m = run.model
            counts = {"tets": len(m.get("tets", ())), "triangles": len(m.get("triangles", ())),
                      "edges": len(m.get("edges", ())), "particles": len(m.get("rest_positions", ()))}
            for k, v in counts.items():
                seen.setdefault(k, set()).add(int(v))
    return {k: next(iter(v)) for k, v in seen.items() if len(v) == 1}


def title_of(text, counts, claim_id=""):
    """The figure's title with its placeholders ({tets}, ...) filled from `counts`, and a count
    the runs contradict ("12,800 StVK tets" on a run of 200) replaced by theirs (with a warning
    on stderr)."""
    for k, v in counts.items():
        text = text.replace("{" + k + "}", f"{v:,}")

    def fix(m):
        kind = COUNTED[m.group(3).lower()]
        stated = int(m.group(1).replace(",", ""))
        actual = counts.get(kind)
        if actual is None or actual == stated:
            return m.group(0)
        print(f"plot_claims.py: {claim_id}: the title says {m.group(1)} {m.group(3)}, the runs have "
              f"{actual:,}: the title shows theirs", file=sys.stderr)
        return f"{actual:,}{m.group(2)}{m.group(3)}"
    return re.sub(r"\b(\d[\d,]*)(\s+(?:[A-Za-z][\w-]*\s+){0,2})(tets|tetrahedra|triangles|particles|edges)\b",
                  fix, text)


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
    values = []
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
        if 0 < n <= 2 and run.status != "exploded" and np.isfinite(y[n - 1]):
            # A run of a step or two (a static equilibrium, ref-static) is a level, not a stub at
            # the start of the axis: drawn across it.
            line = ax.axhline(y[n - 1], linestyle="--", color=f"C{drawn % 10}", label=f"{name} (final state)")
        else:
            line, = ax.plot(t[:n], y[:n], label=name, color=f"C{drawn % 10}")
        values.append(y[:n])
        if run.status == "exploded" and n > 0:
            ax.plot([t[n - 1]], [y[n - 1]], "x", color=line.get_color(), markersize=9)
        drawn += 1
    if fig["log"]:
        ax.set_yscale("log")
    else:  # values over decades (an exploding run beside a calm one) would flatten the calm one
        plot_axes.set_scale(ax, values)
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
    if not plot_axes.informative([[np.nan if v is None else v for v in values]]):
        # Bars of no height show nothing: the values as a list, the axes hidden.
        ax.axis("off")
        ax.text(0.5, 0.5, "\n".join(f"{n} = {value_label(v)}" for n, v in zip(names, values))
                + f"\n\n(every measure is {'0' if any(v == 0 for v in values) else 'NaN'}: no bars to draw)",
                transform=ax.transAxes, ha="center", va="center", fontsize=10)
        return len(names)
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
    else:
        plot_axes.set_scale(ax, [heights])
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


def claim_figure(claim, report_dir):
    """(the figure of one claim, how many runs or measures it drew)."""
    kind = claim["figure"]["kind"]
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    drawn = plot_series(ax, claim, report_dir) if kind == "series" else plot_bars(ax, claim)
    title = title_of(claim["figure"]["title"] or claim["id"], run_counts(claim, report_dir), claim["id"])
    ax.set_title(plot_axes.wrap(f"{claim['id']}: {title}", 90) + f"\nverdict: {claim['verdict']}", fontsize=9)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig, drawn


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
        fig, drawn = claim_figure(claim, report_dir)
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
