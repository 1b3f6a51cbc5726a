#!/usr/bin/python3
"""Times whole `pbdbench run`s of several builds side by side, for comparisons end to end.

For each repetition, each scene and each build in an order rotated every repetition, runs

    BINARY run SCENE --solver SOLVER --set time.duration=D [build's --set ...] --out TMP.h5
        --no-xdmf --quiet --force

and takes the child's CPU time (user + system, from wait4) and its wall time. Prints, per scene
and build, the median [min, max] of each and of first build / build per repetition, with the CPU
model and the load average, and writes every run to --out (JSON).

With --series NAME (repeatable), also the sum over the run of that series of the run file (a
step's `time_*` series: the wall time of one part of the step, results/README.md), in ms, the
same way: a part of the step timed apart from the rest of the run and from the load between runs.

    /usr/bin/python3 scripts/time_runs.py --reps 5 --solver global-cholmod \\
        --scene hanging_cloth:0.1 --scene cantilever_beam:0.5 \\
        --build old=../e2ebcc1/build/pbdbench \\
        --build "off=build/pbdbench --set solver.global.factor_reuse=false" \\
        --build on=build/pbdbench --out timings.json
    /usr/bin/python3 scripts/time_runs.py --reps 4 --solver xpbd --scene hanging_cloth:2 \
        --series time_residual --series time_project \
        --build before=../before/build/pbdbench --build after=build/pbdbench --out residuals.json

A build is LABEL=BINARY followed by extra arguments of `run`. The first build is the baseline of
the ratios. PBDBENCH_SCENARIOS is set to the source tree's scenarios/ unless already set.
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

from machine_info import cpu_model, load_average


def parse_build(text):
    label, sep, rest = text.partition("=")
    words = shlex.split(rest)
    if not sep or not label or not words:
        raise argparse.ArgumentTypeError(f"--build {text!r}: expected LABEL=BINARY [ARGS...]")
    return {"label": label, "binary": words[0], "args": words[1:]}


def parse_scene(text):
    name, sep, duration = text.partition(":")
    try:
        d = float(duration)
    except ValueError:
        d = None
    if not sep or not name or d is None or not d > 0:
        raise argparse.ArgumentTypeError(f"--scene {text!r}: expected NAME:DURATION (seconds, > 0)")
    return {"name": name, "duration": d}


def time_one(cmd, env):
    """(cpu seconds, wall seconds, exit status) of one child."""
    t0 = time.monotonic()
    child = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.monotonic() - t0
    child.returncode = os.waitstatus_to_exitcode(status)
    err = child.stderr.read().decode(errors="replace")
    child.stderr.close()
    return usage.ru_utime + usage.ru_stime, wall, child.returncode, err


def summary(values):
    return f"{statistics.median(values):.2f} [{min(values):.2f}, {max(values):.2f}]"


def series_sums(path, names):
    """{name: the sum over the run file's rows of series `name`, in ms (NaN rows left out)}."""
    import h5py  # Debian's python3-h5py; only --series needs it
    import math
    out = {}
    with h5py.File(path, "r") as f:
        for name in names:
            key = f"series/{name}"
            if key not in f:
                raise KeyError(f"{path}: no series {name!r}")
            out[name] = 1e3 * math.fsum(float(v) for v in f[key][()] if not math.isnan(v))
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--reps", type=int, default=5)
    p.add_argument("--solver", required=True)
    p.add_argument("--scene", type=parse_scene, action="append", required=True)
    p.add_argument("--build", type=parse_build, action="append", required=True)
    p.add_argument("--series", action="append", default=[],
                   help="also tabulate the run's sum of this series of the run file, ms (repeatable)")
    p.add_argument("--out", required=True, help="JSON file of every run (refused if it exists)")
    a = p.parse_args(argv)
    if a.reps < 1:
        p.error("--reps must be at least 1")
    if os.path.exists(a.out):
        p.error(f"--out {a.out}: exists; this script does not overwrite")
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env.setdefault("PBDBENCH_SCENARIOS", os.path.join(root, "scenarios"))
    runs = []
    with tempfile.TemporaryDirectory(prefix="pbdbench_time_runs_") as tmp:
        for rep in range(a.reps):
            for scene in a.scene:
                n = len(a.build)
                for k in range(n):
                    b = a.build[(k + rep) % n]
                    out = os.path.join(tmp, "run.h5")
                    cmd = [b["binary"], "run", scene["name"], "--solver", a.solver, "--set",
                           f"time.duration={scene['duration']!r}", *b["args"], "--out", out,
                           "--no-xdmf", "--quiet", "--force"]
                    load = load_average()
                    cpu, wall, rc, err = time_one(cmd, env)
                    if rc != 0:
                        sys.stderr.write(err)
                        sys.exit(f"time_runs: {' '.join(cmd)} exited with {rc}")
                    try:
                        sums = series_sums(out, a.series) if a.series else {}
                    except KeyError as e:
                        sys.exit(f"time_runs: {e.args[0]}")
                    os.remove(out)
                    runs.append({"rep": rep, "scene": scene["name"], "build": b["label"],
                                 "cpu_s": cpu, "wall_s": wall, "load": load, "series_ms": sums})
    record = {"cpu": cpu_model(), "solver": a.solver, "builds": a.build, "scenes": a.scene,
              "series": a.series, "runs": runs}
    with open(a.out, "x") as f:
        json.dump(record, f, indent=1)
    print(f"CPU: {record['cpu']}; solver {a.solver}; {a.reps} repetitions; "
          f"load average {min(r['load'] for r in runs):.2f}-{max(r['load'] for r in runs):.2f}")
    base = a.build[0]["label"]
    print(f"| scene | build | CPU time, s | wall time, s | {base} / build, CPU | {base} / build, wall |")
    print("|---|---|---|---|---|---|")
    for scene in a.scene:
        at = {(r["build"], r["rep"]): r for r in runs if r["scene"] == scene["name"]}
        for b in a.build:
            mine = [at[(b["label"], k)] for k in range(a.reps)]
            ratio_cpu = [at[(base, k)]["cpu_s"] / at[(b["label"], k)]["cpu_s"] for k in range(a.reps)]
            ratio_wall = [at[(base, k)]["wall_s"] / at[(b["label"], k)]["wall_s"] for k in range(a.reps)]
            print(f"| {scene['name']} | {b['label']} | {summary([r['cpu_s'] for r in mine])} | "
                  f"{summary([r['wall_s'] for r in mine])} | {summary(ratio_cpu)} | {summary(ratio_wall)} |")
    if a.series:
        print()
        print(f"| scene | build | series | sum over the run, ms | {base} / build |")
        print("|---|---|---|---|---|")
        for scene in a.scene:
            at = {(r["build"], r["rep"]): r for r in runs if r["scene"] == scene["name"]}
            for name in a.series:
                for b in a.build:
                    mine = [at[(b["label"], k)]["series_ms"][name] for k in range(a.reps)]
                    ratio = [at[(base, k)]["series_ms"][name] / at[(b["label"], k)]["series_ms"][name]
                             if at[(b["label"], k)]["series_ms"][name] > 0 else float("nan")
                             for k in range(a.reps)]
                    print(f"| {scene['name']} | {b['label']} | {name} | {summary(mine)} | {summary(ratio)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
