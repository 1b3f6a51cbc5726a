#!/usr/bin/python3
"""Fits how the cost of a benchmark grows with problem size, from Google Benchmark JSON output.

    fit_growth.py COST.json [--size tets] [--counters newton_iterations,linear_seconds]

For every benchmark family (the name without its size part, e.g. "1536tets", and Google
Benchmark's iterations/repeats suffixes), takes the median over repetitions of
the real time and of each counter, and fits log(value) = a + p log(size) by least squares: p is
the growth exponent (time ~ size^p). Prints a table per family, the fit and the context the
benchmark recorded (machine, build).
"""
import argparse
import json
import math
import re
import sys
from collections import defaultdict


def median(values):
    v = sorted(values)
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def fit(xs, ys):
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x > 0 and y > 0]
    if len(pts) < 2:
        return float("nan")
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    sxy = sum((p[0] - mx) * (p[1] - my) for p in pts)
    return sxy / sxx if sxx > 0 else float("nan")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("json")
    ap.add_argument("--size", default="tets", help="the counter that measures problem size")
    ap.add_argument("--counters", default="newton_iterations,linear_setups,linear_seconds")
    args = ap.parse_args(argv)
    try:
        with open(args.json) as f:
            data = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        print(f"fit_growth.py: cannot read {args.json}: {e}", file=sys.stderr)
        return 1
    counters = [c for c in args.counters.split(",") if c]
    families = defaultdict(lambda: defaultdict(lambda: defaultdict(list)))
    for b in data.get("benchmarks", []):
        if b.get("run_type") == "aggregate":
            continue
        name = b.get("run_name", b["name"])
        # The family: the name without its size and Google Benchmark's own suffixes
        # ("ref-be/beam/1536tets/iterations:1" -> "ref-be/beam").
        family = "/".join(p for p in name.split("/")
                          if not re.fullmatch(r"\d+[a-z]*|(iterations|repeats|threads):\d+", p))
        if args.size not in b:
            continue
        size = b[args.size]
        families[family][size]["time"].append(b["real_time"] * {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]])
        for c in counters:
            if c in b:
                families[family][size][c].append(b[c])
    ctx = data.get("context", {})
    print("machine: {} ({} CPUs); build: {} {} {} commit {}".format(
        ctx.get("cpu_model", ctx.get("host_name", "?")), ctx.get("num_cpus", "?"), ctx.get("compiler", "?"),
        ctx.get("build_type", "?"), ctx.get("cxx_flags", ""), ctx.get("git_commit", "?")))
    for family, by_size in families.items():
        sizes = sorted(by_size)
        cols = ["time"] + [c for c in counters if any(by_size[s][c] for s in sizes)]
        print(f"\n{family}")
        print("  " + f"{args.size:>10}" + "".join(f"{c:>20}" for c in cols))
        med = {c: [median(by_size[s][c]) if by_size[s][c] else float('nan') for s in sizes] for c in cols}
        for i, s in enumerate(sizes):
            print("  " + f"{s:>10.0f}" + "".join(f"{med[c][i]:>20.4g}" for c in cols))
        print("  " + f"{'exponent':>10}" + "".join(f"{fit(sizes, med[c]):>20.2f}" for c in cols))
    return 0


if __name__ == "__main__":
    sys.exit(main())
