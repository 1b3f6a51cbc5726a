#!/usr/bin/python3
"""Draws what `pbdbench regress` found: the change of every metric against its baseline, in units of
its tolerance, one bar per case and metric (worse in red, better in green, same in grey; timings
and new metrics left out).

    plot_regress.py REGRESS.h5 OUT.png
"""
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        columns = runfile.load_regress(argv[1]).columns
    except runfile.RunFileError as e:
        print(f"plot_regress.py: {e}", file=sys.stderr)
        return 2
    cases, metrics, verdicts = columns["case"], columns["metric"], columns["verdict"]
    change, allowed = list(columns["change"]), list(columns["allowed"])
    labels, values, colors = [], [], []
    for c, m, v, d, a in zip(cases, metrics, verdicts, change, allowed):
        if v in ("ratio", "new"):
            continue
        if math.isnan(d):
            x = 0.0
        elif a > 0:
            x = d / a
        else:
            x = 0.0 if d == 0 else math.copysign(10.0, d)
        labels.append(f"{c} {m}")
        values.append(max(-10.0, min(10.0, x)))
        colors.append({"worse": "tab:red", "better": "tab:green"}.get(v, "0.6"))
    fig, ax = plt.subplots(figsize=(7, max(2.5, 0.16 * len(labels))))
    ax.barh(range(len(labels)), values, color=colors)
    ax.set_yticks(range(len(labels)))
    ax.set_yticklabels(labels, fontsize=5)
    ax.axvline(-1, color="k", lw=0.5, ls="--")
    ax.axvline(1, color="k", lw=0.5, ls="--")
    ax.set_xlabel("change / allowed (clipped to +-10; dashed: the tolerance)")
    ax.set_title(f"regression: {verdicts.count('worse')} worse, {verdicts.count('better')} better, "
                 f"{verdicts.count('same')} same", fontsize=9)
    fig.tight_layout()
    fig.savefig(argv[2], dpi=110)
    print(f"plot_regress.py: -> {argv[2]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
