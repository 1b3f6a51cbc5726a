#!/usr/bin/python3
"""Shares of a run's time by the part of the harness it was spent in, from a perf profile.

    perf record -F 2000 --call-graph dwarf,32768 -o perf.data \\
        build/benchmarks/bench_solvers --benchmark_repetitions=4 --benchmark_filter='^harness/cloth64/inline'
    perf script -i perf.data -F tid,ip,sym > perf.txt
    /usr/bin/python3 scripts/perf_shares.py perf.txt

Each sample of `perf script`'s text
(a line with the thread id, then its frames innermost first, then a blank line) is put in the
first part of PARTS whose name pattern one of its frames contains; a sample in none is "other".
The run's thread is the thread with the most samples; shares are of its samples, and the other
threads' samples are counted apart, by the outermost frame of ours (pbdbench::) they fall under.
Standard library only.
"""
import argparse
import collections
import sys

# (part, substrings of a frame's symbol), tried in this order: a sample goes to the first match.
PARTS = [
    ("solver step", ["Solver::step"]),
    ("setup", ["build_scene", "make_solver", "measure_baseline", "plan_run"]),
    ("measure", ["pbdbench::measure"]),  # after setup: measure_baseline is the setup's
    ("velocity_hf", ["velocity_hf_rms"]),
    ("health", ["HealthMonitor"]),
    ("finish", ["RunFileWriter::finish"]),
    ("frames", ["RunFileWriter::append_frame"]),
    ("publish", ["RunFileWriter::Impl::publish"]),
    ("rows", ["RunFileWriter::append"]),  # after frames: append_frame is the frames'
    ("file creation", ["RunFileWriter::RunFileWriter"]),
    ("step logger", ["StepLogger"]),
    ("run_config", ["run_config"]),
]


def samples(lines):
    """(thread id, [symbols, innermost first]) of each sample of `perf script -F tid,ip,sym`."""
    block = []
    for line in list(lines) + [""]:
        line = line.rstrip("\n")
        if line.strip():
            block.append(line)
            continue
        if block:
            frames = []
            for f in block[1:]:
                parts = f.strip().split(None, 1)
                frames.append(parts[1] if len(parts) > 1 else "?")
            yield block[0].strip(), frames
        block = []


def part_of(frames):
    for name, keys in PARTS:
        if any(k in f for f in frames for k in keys):
            return name
    return "other"


def outermost_ours(frames):
    ours = [f for f in frames if "pbdbench::" in f]
    return ours[-1] if ours else (frames[-1] if frames else "?")


def shares(lines):
    """{'run_thread', 'samples', 'parts': {part: count}, 'others': {frame: count}}."""
    all_samples = list(samples(lines))
    if not all_samples:
        raise ValueError("no samples: expected the text of `perf script -F tid,ip,sym`")
    counts = collections.Counter(tid for tid, _ in all_samples)
    run_thread = counts.most_common(1)[0][0]
    parts, others = collections.Counter(), collections.Counter()
    for tid, frames in all_samples:
        if tid == run_thread:
            parts[part_of(frames)] += 1
        else:
            others[outermost_ours(frames)] += 1
    return {"run_thread": run_thread, "samples": counts[run_thread], "parts": parts, "others": others}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("perf_text", help="the output of `perf script -F tid,ip,sym`")
    args = ap.parse_args()
    with open(args.perf_text, errors="replace") as f:
        try:
            s = shares(f)
        except ValueError as e:
            print(f"{args.perf_text}: {e}", file=sys.stderr)
            return 2
    n = s["samples"]
    print(f"run thread {s['run_thread']}: {n} samples; shares of them")
    for name, c in s["parts"].most_common():
        print(f"  {name:14} {c:7d} {100.0 * c / n:6.2f} %")
    if s["others"]:
        print("other threads (as a share of the run thread's samples), by the outermost frame of ours:")
        for frame, c in s["others"].most_common(10):
            print(f"  {c:7d} {100.0 * c / n:6.2f} %  {frame[:100]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
