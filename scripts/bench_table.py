#!/usr/bin/python3
"""A table of every case of a bench_solvers JSON file (Google Benchmark's
--benchmark_out, with its repetitions kept: --benchmark_repetitions=N, no
--benchmark_report_aggregates_only).

    /usr/bin/python3 scripts/bench_table.py bench.json

For each benchmark: the median of each counter over the repetitions and its spread (the lowest
and highest repetition), with the machine and the build from the file's context. Standard library
only."""
import json
import statistics
import sys
from collections import OrderedDict


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    with open(argv[1]) as f:
        data = json.load(f)
    ctx = data.get("context", {})
    print("machine: %s, %s cores available (%s CPUs reported), load average %s" % (
        ctx.get("cpu_model", "?"), ctx.get("available_cores", "?"), ctx.get("num_cpus", "?"),
        ctx.get("load_avg", "?")))
    print("build: %s %s, %s, %s, commit %s, %s" % (
        ctx.get("build_type", "?"), ctx.get("compiler", "?"), ctx.get("cxx_flags", "?"),
        ctx.get("library_build_type", "?"), ctx.get("git_commit", "?"), ctx.get("date", "?")))
    runs = OrderedDict()
    for b in data.get("benchmarks", []):
        if b.get("run_type") != "iteration":
            continue
        runs.setdefault(b["run_name"], []).append(b)
    print()
    print("| benchmark | reps | M projections/s (wall): median [min, max] | M projections/s (CPU, 1 thread): median [min, max] | step ms: median | other |")
    print("|---|---|---|---|---|---|")
    for name, reps in runs.items():
        def stat(key):
            xs = [r[key] for r in reps if key in r]
            if not xs:
                return None
            return statistics.median(xs), min(xs), max(xs)
        mp = stat("Mproj_per_s")
        mc = stat("Mproj_per_cpu_s")
        step = stat("step_ms")
        other = []
        for key in ("logging_pct", "logging_cpu_pct", "overhead_pct", "run_s"):
            s = stat(key)
            if s:
                other.append("%s %.3g [%.3g, %.3g]" % (key, *s))
        print("| %s | %d | %s | %s | %s | %s |" % (
            name.replace("/real_time", "").replace("/iterations:1", ""), len(reps),
            "%.1f [%.1f, %.1f]" % mp if mp else "",
            "%.1f [%.1f, %.1f]" % mc if mc else "",
            "%.3f" % step[0] if step else "",
            "; ".join(other)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
