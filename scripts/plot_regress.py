#!/usr/bin/python3
"""Draws what `pbdbench regress` found: the change of every metric against its baseline, in units of
its tolerance, one bar per case and metric (worse in red, better in green, same in grey; timings
and new metrics left out).

    plot_regress.py REGRESS.h5 OUT.png
"""
import math
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def strings(ds):
    return [v.decode() if isinstance(v, bytes) else str(v) for v in ds[()]]


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    with h5py.File(argv[1], "r") as f:
        cases, metrics, verdicts = strings(f["case"]), strings(f["metric"]), strings(f["verdict"])
        change, allowed = list(f["change"][()]), list(f["allowed"][()])
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
