#!/usr/bin/python3
"""Do two runs of the same experiments agree (a local run and a Slurm job array, say)?

  compare_results.py reports LOCAL.json OTHER.json EXPERIMENTS_DIR RUNS_DIR
      claims.json / reproductions.json of `pbdbench claims|paper`: every part's verdict and every
      measure (value and trials) must be identical, except those that read the wall clock
      (the measures of [[timing]] groups, those of series that the run files in RUNS_DIR mark
      deterministic = 0 or of the run scalar wall_time, and the measures computed from them); a
      timing part may differ, and is listed.
  compare_results.py runs LOCAL_DIR OTHER_DIR
      two folders of run files (a sweep): every deterministic series of each file, bit for bit.
  compare_results.py regress LOCAL.json OTHER.json REGISTRY.toml
      regress.json of `pbdbench regress`: the bitwise hash and every metric not marked timing.

Prints what it compared and every difference; exits 1 when something that must agree does not.
"""
import json
import math
import os
import re
import sys
import tomllib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402

NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*")


def same_number(a, b):
    if isinstance(a, str) or isinstance(b, str):  # "nan" as written by the JSON writers
        a, b = float(a), float(b)
    if a is None or b is None:
        return a is b
    return (math.isnan(a) and math.isnan(b)) or a == b


def wall_clock_series(run_dir):
    """Names of the series a run file marks non-deterministic (the wall clock), with components."""
    for root, _, files in os.walk(run_dir):
        for name in sorted(files):
            if name.endswith(".h5"):
                run = runfile.load(os.path.join(root, name), frames=False, model=False)
                out = {"wall_time"}
                for s, deterministic in run.deterministic.items():
                    if not deterministic:
                        out |= {s, s + ".x", s + ".y", s + ".z"}
                return out
    return {"wall_time", "wall_step"}


def timing_measures(experiment, wall):
    """Measures of a [[timing]] group, those reading a wall-clock series or scalar, and those
    computed from either."""
    timing = set()
    for m in experiment.get("measure", []):
        names = set(NAME.findall(m["value"]))
        if m.get("timing") or names & wall or names & timing:
            timing.add(m["name"])
    return timing


def compare_reports(local_path, other_path, experiments_dir, runs_dir):
    with open(local_path) as f:
        local = json.load(f)
    with open(other_path) as f:
        other = json.load(f)
    experiments = {}
    for name in os.listdir(experiments_dir):
        if name.endswith(".toml"):
            with open(os.path.join(experiments_dir, name), "rb") as f:
                e = tomllib.load(f)
            experiments[e["id"]] = e
    wall = wall_clock_series(runs_dir)
    verdicts, numbers, timing_differs = [], [], []
    parts = measures = timed = 0
    b_claims = {c["id"]: c for c in other["claims"]}
    if set(b_claims) != {c["id"] for c in local["claims"]}:
        verdicts.append("the two reports hold different experiments")
    for a in local["claims"]:
        b = b_claims.get(a["id"])
        if b is None:
            continue
        timing = timing_measures(experiments.get(a["id"], {}), wall)
        bm = {m["name"]: m for m in b["measures"]}
        for m in a["measures"]:
            if m["name"] in timing or m.get("timing"):
                timed += 1
                continue
            measures += 1
            n = bm.get(m["name"])
            if n is None or not same_number(m["value"], n["value"]) or len(m["trials"]) != len(n["trials"]) or \
                    not all(same_number(x, y) for x, y in zip(m["trials"], n["trials"])):
                numbers.append(f"{a['id']} measure {m['name']}: {m['value']} here, {n and n['value']} there")
        for pa, pb in zip(a["parts"], b["parts"]):
            parts += 1
            if pa["verdict"] != pb["verdict"]:
                line = f"{pa['id']} ({pa['says'][:60]}): {pa['verdict']} here, {pb['verdict']} there"
                (timing_differs if pa["timing"] else verdicts).append(line)
    timing_parts = sum(p["timing"] for c in local["claims"] for p in c["parts"])
    print(f"{len(local['claims'])} experiments, {parts} parts ({timing_parts} timing): the verdicts of the "
          f"{parts - timing_parts} others {'identical' if not verdicts else 'DIFFER'}; {measures} non-timing measures "
          f"{'identical' if not numbers else 'DIFFER'} (values and trials, bit for bit); {timed} timing measures "
          f"not compared; {len(timing_differs)} timing verdicts differ")
    for line in timing_differs:
        print(f"  timing part differs (wall clock, allowed): {line}")
    return verdicts + numbers


def compare_runs(local_dir, other_dir):
    problems = []
    files = sorted(f for f in os.listdir(local_dir) if f.endswith(".h5"))
    series = 0
    for name in files:
        path = os.path.join(other_dir, name)
        if not os.path.exists(path):
            problems.append(f"{name}: missing from {other_dir}")
            continue
        a = runfile.load(os.path.join(local_dir, name), frames=False, model=False)
        b = runfile.load(path, frames=False, model=False)
        for s, values in a.series.items():
            if not a.deterministic[s]:
                continue
            series += 1
            if s not in b.series or not np.array_equal(values, b.series[s], equal_nan=True):
                problems.append(f"{name}: series {s} differs")
        if a.attrs.get("status") != b.attrs.get("status"):
            problems.append(f"{name}: status differs")
    print(f"{len(files)} run files, {series} deterministic series: "
          f"{'identical, bit for bit' if not problems else 'DIFFER'}")
    return problems


def compare_regress(local_path, other_path, registry):
    with open(local_path) as f:
        local = json.load(f)
    with open(other_path) as f:
        other = json.load(f)
    with open(registry, "rb") as f:
        timing = {m["name"] for m in tomllib.load(f).get("metric", []) if m.get("timing", False)}
    problems = []
    values = 0
    cases = [c for c in local if c != "build"]
    for case in cases:
        for key, value in local[case].items():
            if key in timing:
                continue
            values += 1
            there = other.get(case, {}).get(key)
            same = value == there if isinstance(value, str) and value != "nan" else same_number(value, there)
            if not same:
                problems.append(f"{case} {key}: {value} here, {there} there")
    print(f"{len(cases)} cases: hashes and {values} non-timing values {'identical' if not problems else 'DIFFER'}")
    return problems


def main(argv):
    if len(argv) < 3 or argv[0] not in ("reports", "runs", "regress"):
        print(__doc__, file=sys.stderr)
        return 2
    missing = [p for p in argv[1:] if not os.path.exists(p)]
    if missing:  # the run that should have written it failed: say so, no traceback
        print(f"compare_results: nothing to compare: {', '.join(missing)} not found")
        return 1
    if argv[0] == "reports":
        problems = compare_reports(*argv[1:5])
    elif argv[0] == "runs":
        problems = compare_runs(*argv[1:3])
    else:
        problems = compare_regress(*argv[1:4])
    for p in problems:
        print(f"  DIFFERS: {p}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
