#!/usr/bin/python3
"""Runs every file of the bad-input corpus (tests/bad_input/*.toml) through pbdbench and checks
that each is refused: exit code 2, a message on stderr that names the key or argument at fault
(the file's `# expect:` line) and, when the file gives `# line: N`, the file and line
("FILE:N:"); and that no run file was written.

Header lines of a corpus file (comments, so that the rest is the input itself):
  # expect: TEXT     the message must contain TEXT (required)
  # line: N          the message must contain "<file>:N:"
  # command: NAME    the subcommand (default run); the file is its first argument
  # args: ...        more arguments (split on spaces)
  # out: PATH        --out PATH (relative to this folder; default a fresh path in a temporary folder)

    run_corpus.py BUILD/pbdbench
"""
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))


def header(path):
    fields = {}
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if not line.startswith("# "):
                break
            key, _, value = line[2:].partition(":")
            fields[key.strip()] = value.strip()
    return fields


def main():
    exe = os.path.abspath(sys.argv[1])
    failures = []
    files = sorted(f for f in os.listdir(HERE) if f.endswith(".toml"))
    with tempfile.TemporaryDirectory(prefix="pbdbench_bad_input_") as tmp:
        for name in files:
            path = os.path.join(HERE, name)
            h = header(path)
            if "expect" not in h:
                failures.append(f"{name}: no '# expect:' line")
                continue
            command = h.get("command", "run")
            args = [exe, command, path] + (h["args"].split() if "args" in h else [])
            fresh = os.path.join(tmp, name + ".h5")
            out = os.path.join(HERE, h["out"]) if "out" in h and not h["out"].startswith("/") else h.get("out", fresh)
            before = None
            if os.path.isfile(out):
                with open(out, "rb") as f:
                    before = f.read()
            if command == "run":
                args += ["--out", out, "--quiet"]
            r = subprocess.run(args, capture_output=True, text=True, cwd=tmp, timeout=120)
            problems = []
            if r.returncode != 2:
                problems.append(f"exit {r.returncode}, expected 2")
            if h["expect"] not in r.stderr:
                problems.append(f"the message does not name '{h['expect']}'")
            if "line" in h and f"{path}:{h['line']}:" not in r.stderr:
                problems.append(f"the message does not give {name}:{h['line']}")
            if os.path.exists(fresh):
                problems.append(f"a file was written at {fresh}")
            if before is not None:
                with open(out, "rb") as f:
                    if f.read() != before:
                        problems.append(f"{out} was changed")
            for leftover in (out + ".lock", out + ".shadow"):
                if os.path.exists(leftover) and not leftover.startswith("/dev/"):
                    problems.append(f"{leftover} was left behind")
            if problems:
                failures.append(f"{name}: " + "; ".join(problems) + f"\n    stderr: {r.stderr.strip()[:400]}")
            else:
                print(f"ok   {name}: {r.stderr.strip().splitlines()[-1][:160] if r.stderr.strip() else ''}")
    for f in failures:
        print("FAIL " + f)
    print(f"{len(files) - len(failures)} passed, {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
