#!/usr/bin/python3
"""Writes the seed corpus of the rule language's cases into a folder, for scripts/fuzz.sh:

    make_seeds.py rules DIR         fuzz_loader's inputs: the byte 4 (a rule), then the rule
    make_seeds.py experiments DIR   fuzz_experiment's inputs: whole experiment files

The cases are those that crashed the parser or decided a part wrongly: 10,000 nested
parentheses, a long sum, a long `and`, a long run of unary operators (each beyond the limits of
experiments/expression.hpp), a division by zero and other non-finite values, hexadecimal and
out-of-range numbers; for experiment files, the same rules in a part and a measure, and trial and
repeat counts without end. The long cases are cut to 64 KiB, fuzz.sh's -max_len (the longer ones
of the issue, 100,000 terms and a million operators, are tests/experiments/test_expression.cpp's).
"""
import os
import sys

MAX = 65536 - 1  # fuzz.sh's -max_len, less fuzz_loader's mode byte

RULES = {
    "parens_10000": "(" * 10000 + "a" + ")" * 10000 + " > 0",
    "sum_16000": "1" + " + 1" * 16000,
    "and_6000": "a > 0" + " and a > 0" * 6000,
    "unary_60000": "-" * 60000 + "1",
    "not_16000": "not " * 16000 + "a",
    "power_30000": "2" + "^2" * 30000,
    "calls_10000": "abs(" * 10000 + "1" + ")" * 10000,
    "divide_by_zero": "a / zero > 5",
    "zero_by_zero": "(a > 100) / 0 * 0 == 0",
    "log_zero": "log10(zero) < 1",
    "sqrt_negative": "sqrt(b) >= 0",
    "overflow": "10^400 > 1",
    "infinite_name": "big > 2 and a > 0",
    "infinite_series": "final(s) > 1 or max(s) > 1",
    "hexadecimal": "0x10 > a",
    "hex_float": "0x1p4 > a",
    "out_of_range": "1e999 > a",
    "number_into_name": "2a + 1",
    "reductions": "mean_from(s, 0.1) + at(s, 0.25) - period(s) + max_last(s, 0.2) > min(a, b, zero)",
}

EXPERIMENT = """id = "S9.9"
section = "9.9"
claim = "a particle falls"
experiment = "a particle falls for 0.1 s"
scenario = "free_fall"
[set]
"time.duration" = 0.1
[quick]
trials = 2
[[run]]
name = "pbd"
set = {{ "solver.name" = "pbd" }}
trials = {trials}
trial_key = "solver.shuffle_seed"
[[timing]]
name = "t"
runs = ["pbd"]
repeats = {repeats}
[[measure]]
name = "drop"
run = "pbd"
value = "{value}"
doc = "energy lost"
[[part]]
says = "it falls"
quote = "它会落下"
translation = "it falls"
judges = "method"
rule = "{rule}"
"""

EXPERIMENTS = {
    "good": dict(trials=3, repeats=9, value="initial(potential_energy) - final(potential_energy)", rule="drop > 0"),
    "rule_parens": dict(trials=3, repeats=9, value="final(potential_energy)", rule="(" * 10000 + "drop" + ")" * 10000),
    "rule_and": dict(trials=3, repeats=9, value="final(potential_energy)", rule="drop > 0" + " and drop > 0" * 4000),
    "rule_unary": dict(trials=3, repeats=9, value="final(potential_energy)", rule="-" * 40000 + "drop > 0"),
    "rule_divides_by_zero": dict(trials=3, repeats=9, value="final(potential_energy)", rule="drop / 0 > 5"),
    "measure_divides_by_zero": dict(trials=3, repeats=9, value="final(potential_energy) / 0", rule="drop > 5"),
    "measure_hexadecimal": dict(trials=3, repeats=9, value="final(potential_energy) * 0x10", rule="drop > 0"),
    "trials_endless": dict(trials=1000000000, repeats=9, value="final(potential_energy)", rule="drop > 0"),
    "trials_float": dict(trials="1e9", repeats=9, value="final(potential_energy)", rule="drop > 0"),
    "repeats_endless": dict(trials=3, repeats=1000000000, value="final(potential_energy)", rule="drop > 0"),
}


def main():
    kind, folder = sys.argv[1], sys.argv[2]
    os.makedirs(folder, exist_ok=True)
    if kind == "rules":
        for name, rule in RULES.items():
            with open(os.path.join(folder, "rule-" + name), "wb") as f:
                f.write(b"\x04" + rule.encode()[:MAX])
    elif kind == "experiments":
        for name, fields in EXPERIMENTS.items():
            with open(os.path.join(folder, "experiment-" + name), "wb") as f:
                f.write(EXPERIMENT.format(**fields).encode()[:MAX + 1])
    else:
        sys.exit(f"make_seeds.py: '{kind}' is not rules or experiments")


if __name__ == "__main__":
    main()
