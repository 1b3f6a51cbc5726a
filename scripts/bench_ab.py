#!/usr/bin/python3
"""Runs the benchmark programs of several builds side by side, alternating, for comparisons of
rates between builds and between thread counts on a shared machine.

For each round, each build in an order rotated every round, runs

    BINARY --benchmark_filter=FILTER --benchmark_repetitions=REPS
        --benchmark_enable_random_interleaving=true --benchmark_out=OUT/LABEL_rROUND.json
        --benchmark_out_format=json [--benchmark_min_time=T]

and prints, per case and build, the median [min, max] of a counter (default Mproj_per_s) over
every repetition of every round, the ratio to the first build (the median over rounds of the
ratio of the rounds' medians), and, for each case run at one thread (`/t1/`) and at N (`/tN/`),
the ratio tN / t1 of the medians within one process, per round: median [min, max] over the
rounds. Within one process the cases are interleaved at random, so the thread-count ratio is
measured side by side; alternating the builds spreads what the machine's load does over all of
them. The machine (the CPU model /proc/cpuinfo gives) and the load average before and after
each process are printed and kept in OUT/summary.json.

With --load N, N other processes (each a busy loop of this Python) run on the machine from
before the first round to after the last: what a shared machine's other tenants do, made
reproducible (for comparing thread counts on a loaded machine).

    /usr/bin/python3 scripts/bench_ab.py --rounds 6 --reps 3 \\
        --filter 'solver/cloth256_distance/(pbd|xpbd)/colored/double/t[12]' \\
        --build before=../before/build/benchmarks/bench_solvers \\
        --build after=build/benchmarks/bench_solvers --out bench_ab

A build is LABEL=BINARY (a benchmark program of this project). OUT must not exist. The
benchmarks find the scenarios through PBDBENCH_SCENARIOS, set to the source tree's scenarios/
unless already set. Standard library only.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys

from machine_info import cpu_model, load_average


def parse_build(text):
    label, sep, binary = text.partition("=")
    if not sep or not re.fullmatch(r"[A-Za-z0-9_.-]+", label) or not binary:
        raise argparse.ArgumentTypeError(f"--build {text!r}: expected LABEL=BINARY (LABEL of letters, digits, _ . -)")
    return {"label": label, "binary": binary}


def spread(xs):
    return {"median": statistics.median(xs), "min": min(xs), "max": max(xs), "n": len(xs)}


def fmt(s, digits=1):
    return f"{s['median']:.{digits}f} [{s['min']:.{digits}f}, {s['max']:.{digits}f}]"


def read_values(path, counter):
    """{case: [counter of each repetition]} of one benchmark JSON file."""
    try:
        with open(path) as f:
            data = json.load(f)
    except (OSError, ValueError):
        return {}  # nothing matched: Google Benchmark leaves the file empty
    values = {}
    for b in data.get("benchmarks", []):
        if b.get("run_type") != "iteration" or counter not in b:
            continue
        v = b[counter]
        if isinstance(v, (int, float)) and v == v:
            values.setdefault(b["run_name"], []).append(float(v))
    return values


THREADS = re.compile(r"/t(\d+)/")


def summarize(builds, rounds, counter):
    """rounds: [{label: {case: [values]}}] in round order. Returns the summary's tables."""
    labels = [b["label"] for b in builds]
    cases = sorted({c for r in rounds for per in r.values() for c in per})
    rates, ratios, scaling = [], [], []
    for case in cases:
        for label in labels:
            xs = [x for r in rounds for x in r.get(label, {}).get(case, [])]
            if xs:
                rates.append({"case": case, "build": label, **spread(xs)})
        base = labels[0]
        for label in labels[1:]:
            per_round = [statistics.median(r[label][case]) / statistics.median(r[base][case])
                         for r in rounds
                         if r.get(label, {}).get(case) and r.get(base, {}).get(case)]
            if per_round:
                ratios.append({"case": case, "build": label, "baseline": base, **spread(per_round)})
        m = THREADS.search(case)
        if m and m.group(1) != "1":
            one = case[:m.start()] + "/t1/" + case[m.end():]
            for label in labels:
                per_round = [statistics.median(r[label][case]) / statistics.median(r[label][one])
                             for r in rounds if r.get(label, {}).get(case) and r.get(label, {}).get(one)]
                if per_round:
                    scaling.append({"case": case, "threads": int(m.group(1)), "build": label,
                                    "per_round": per_round, **spread(per_round)})
    return {"rates": rates, "ratios": ratios, "scaling": scaling}


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", action="append", type=parse_build, required=True,
                        help="LABEL=BINARY; the first is the baseline of the ratios")
    parser.add_argument("--filter", required=True, help="--benchmark_filter of every run")
    parser.add_argument("--reps", type=int, default=3, help="--benchmark_repetitions (default 3)")
    parser.add_argument("--rounds", type=int, default=3, help="processes per build (default 3)")
    parser.add_argument("--min-time", type=float, help="--benchmark_min_time, seconds")
    parser.add_argument("--counter", default="Mproj_per_s", help="the counter compared (default Mproj_per_s)")
    parser.add_argument("--out", required=True, help="a folder for every run's JSON (must not exist)")
    parser.add_argument("--load", type=int, default=0,
                        help="busy processes kept running beside the benchmarks (default 0)")
    args = parser.parse_args(argv[1:])
    if args.reps < 1 or args.rounds < 1:
        parser.error("--reps and --rounds must be at least 1")
    if args.load < 0:
        parser.error("--load must be at least 0")
    labels = [b["label"] for b in args.build]
    if len(set(labels)) != len(labels):
        parser.error("two builds have one label")
    for b in args.build:
        if not os.access(b["binary"], os.X_OK):
            parser.error(f"--build {b['label']}: {b['binary']} is not an executable")
    if os.path.lexists(args.out):
        print(f"bench_ab.py: {args.out} exists; not overwriting it", file=sys.stderr)
        return 2
    os.makedirs(args.out)
    env = dict(os.environ)
    env.setdefault("PBDBENCH_SCENARIOS",
                   os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenarios"))
    runs, rounds = [], []
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.load)]
    try:
        status = measure(args, env, runs, rounds)
    finally:
        for p in busy:
            p.kill()
            p.wait()
    if status != 0:
        return status
    summary = summarize(args.build, rounds, args.counter)
    record = {"machine": cpu_model(), "builds": args.build, "filter": args.filter, "reps": args.reps,
              "rounds": args.rounds, "counter": args.counter, "load_processes": args.load,
              "load_pids": [p.pid for p in busy], "runs": runs, **summary}
    with open(os.path.join(args.out, "summary.json"), "w") as f:
        json.dump(record, f, indent=1)
    loads = [x for run in runs for x in (run["load_before"], run["load_after"])]
    print(f"machine: {record['machine']}; load average {min(loads):.2f} to {max(loads):.2f}; "
          f"{args.load} busy processes beside; "
          f"{args.rounds} rounds x {args.reps} repetitions a build; {args.counter}: median [min, max]")
    report(args, labels, summary)
    return 0


def measure(args, env, runs, rounds):
    """The rounds: every build's process in rotated order; its values into rounds, its record
    into runs. 0, or 1 when a process failed or matched nothing."""
    n = len(args.build)
    for r in range(args.rounds):
        per = {}
        for i in range(n):
            b = args.build[(r + i) % n]
            path = os.path.join(args.out, f"{b['label']}_r{r + 1}.json")
            cmd = [b["binary"], f"--benchmark_filter={args.filter}",
                   f"--benchmark_repetitions={args.reps}", "--benchmark_enable_random_interleaving=true",
                   f"--benchmark_out={path}", "--benchmark_out_format=json"]
            if args.min_time is not None:
                cmd.append(f"--benchmark_min_time={args.min_time}")
            before = load_average()
            proc = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            after = load_average()
            if proc.returncode != 0:
                print(f"bench_ab.py: {b['label']} (round {r + 1}) failed, exit {proc.returncode}:\n{proc.stderr}",
                      file=sys.stderr)
                return 1
            per[b["label"]] = read_values(path, args.counter)
            if not per[b["label"]]:
                print(f"bench_ab.py: {b['label']}: no case matches {args.filter!r} with a counter "
                      f"{args.counter}", file=sys.stderr)
                return 1
            runs.append({"round": r + 1, "build": b["label"], "file": os.path.basename(path),
                         "load_before": before, "load_after": after})
        rounds.append(per)
    return 0


def report(args, labels, summary):
    for b in args.build:
        print(f"  {b['label']}: {b['binary']}")
    print()
    print(f"| case | build | {args.counter} | / {labels[0]} (per round) |")
    print("|---|---|---|---|")
    ratio_of = {(x["case"], x["build"]): x for x in summary["ratios"]}
    for x in summary["rates"]:
        ratio = ratio_of.get((x["case"], x["build"]))
        print(f"| {x['case']} | {x['build']} | {fmt(x)} | {fmt(ratio, 3) if ratio else '1'} |")
    if summary["scaling"]:
        print()
        print("| case | build | tN / t1 in one process (per round) | rounds |")
        print("|---|---|---|---|")
        for x in summary["scaling"]:
            print(f"| {x['case']} | {x['build']} | {fmt(x, 3)} | "
                  + " ".join(f"{v:.2f}" for v in x["per_round"]) + " |")


if __name__ == "__main__":
    sys.exit(main(sys.argv))
