#!/usr/bin/python3
"""A stand-in for Slurm's sbatch, for the tests of `pbdbench ... --slurm N` (test_cli.py).

It records each submission (its options and script) in $FAKE_SBATCH_DIR/submissions.jsonl and
runs the job at once, to completion, as Slurm would on one node: each array task with
SLURM_ARRAY_TASK_ID and friends set, in the script's --chdir, its output to the script's
--output (%A, %a, %j expanded). Since every job has ended when sbatch returns, a dependency
(--dependency=afterany:ID) is always satisfied. Tasks listed in $FAKE_SBATCH_SKIP (e.g. "1,3")
never run, as when they are cancelled before they start. Prints the job id (--parsable).
"""
import json
import os
import re
import subprocess
import sys


def expand(listing):
    out = []
    for part in listing.split("%")[0].split(","):
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def sbatch_argument(line):
    """The arguments of one #SBATCH line's text, split as sbatch splits them (src/sbatch/opt.c,
    _get_argument): at blanks outside quotes ('...' or "..."), a backslash escaping the next
    character anywhere, an unquoted '#' ending the line."""
    args, i, n = [], 0, len(line)
    while True:
        while i < n and line[i].isspace():
            i += 1
        if i >= n:
            return args
        arg, quote, escape, started = "", None, False, False
        while i < n and (quote or not line[i].isspace()):
            c = line[i]
            if escape:
                escape = False
            elif c == "\\":
                escape, i = True, i + 1
                continue
            elif quote:
                if c == quote:
                    quote, i = None, i + 1
                    continue
            elif c in "\"'":
                quote, i, started = c, i + 1, True
                continue
            elif c == "#":
                i = n
                break
            arg += c
            started = True
            i += 1
        if quote:
            raise SystemExit(f"sbatch: unmatched {quote} in [{line}]")
        if started:
            args.append(arg)


def script_arguments(text):
    """The sbatch arguments of a script's #SBATCH lines, read until its first command."""
    args = []
    for line in text.split("\n"):
        if line.startswith("#SBATCH"):
            args.extend(sbatch_argument(line[len("#SBATCH"):]))
        elif line.strip() and not line.strip().startswith("#"):
            break
    return args


def expand_pattern(pattern, job, task):
    """A file name pattern of --output: %A, %a, %j, and %% for a '%'."""
    out, k = "", 0
    while k < len(pattern):
        if pattern[k] == "%" and k + 1 < len(pattern):
            c = pattern[k + 1]
            out += {"A": str(job), "a": str(task), "j": str(job), "%": "%"}.get(c, "%" + c)
            k += 2
        else:
            out += pattern[k]
            k += 1
    return out


def main():
    state = os.environ["FAKE_SBATCH_DIR"]
    args = sys.argv[1:]
    script = args[-1]
    options = {}
    for a in args[:-1]:
        if a.startswith("--") and "=" in a:
            k, v = a[2:].split("=", 1)
            options[k] = v
    directives = {}
    with open(script) as f:
        text = f.read()
    for a in script_arguments(text):
        m = re.match(r"--([a-z-]+)=(.*)", a, re.S)
        if m:
            directives[m.group(1)] = m.group(2)
    counter = os.path.join(state, "next_id")
    job = int(open(counter).read()) if os.path.exists(counter) else 100
    with open(counter, "w") as f:
        f.write(str(job + 1))
    array = options.get("array", directives.get("array"))
    skip = {int(x) for x in os.environ.get("FAKE_SBATCH_SKIP", "").split(",") if x}
    record = {"job": job, "options": options, "script": script, "array": array, "tasks": {}}
    cwd = directives.get("chdir", os.getcwd())
    env = dict(os.environ, SLURM_JOB_ID=str(job), SLURM_CPUS_PER_TASK="1")
    env.pop("FAKE_SBATCH_SKIP", None)
    for task in expand(array) if array else [None]:
        if task is not None and task in skip:
            record["tasks"][str(task)] = "skipped"
            continue
        out = directives.get("output", os.path.join(cwd, f"slurm-{job}.out"))
        out = expand_pattern(out, job, task)
        task_env = dict(env)
        if task is not None:
            task_env.update(SLURM_ARRAY_JOB_ID=str(job), SLURM_ARRAY_TASK_ID=str(task))
        with open(out, "w") as log:
            rc = subprocess.run(["bash", script], cwd=cwd, env=task_env, stdout=log, stderr=subprocess.STDOUT).returncode
        record["tasks"][str(task)] = rc
    with open(os.path.join(state, "submissions.jsonl"), "a") as f:
        f.write(json.dumps(record) + "\n")
    print(job)


if __name__ == "__main__":
    main()
