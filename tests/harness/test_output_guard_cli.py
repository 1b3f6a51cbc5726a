#!/usr/bin/python3
"""One output guard for every command that writes (runfile/output_guard.hpp), end to end: each of
`compare`, `converge`, `export`, `sweep`, `regress`, `paper` (the claims' code) and `register`
refuses, with exit 2 naming the argument and the file, its own inputs, files that are not its
earlier output, devices, folders, symbolic links and a link planted at its temporary, and leaves
them as they were; it replaces its own earlier output. (`run --out`: test_cli_safety.py.)

Run by CTest with PBDBENCH_BIN (the executable) and PBDBENCH_SCENARIOS set.
"""
import os
import subprocess
import tempfile
import unittest

BIN = os.environ["PBDBENCH_BIN"]

EXPERIMENT = """kind = "reproduction"
id = "chain_err"
section = "1"
paper = "nobody 2026"
claim = "a chain holds"
experiment = "a short chain"
scenario = "hanging_chain"
[set]
"time.duration" = 0.05
[[setup]]
what = "chain"
value = "the catalog's"
from = "assumed"
why = "a test"
[[run]]
name = "one"
[[measure]]
name = "err"
run = "one"
value = "final(constraint_error_max)"
doc = "final error"
[[part]]
says = "held"
rule = "err < 0.1"
published = "held"
source = "nowhere"
"""

NOTES = b"my notes, not pbdbench's\n"


def pbdbench(*args, cwd=None, timeout=300):
    return subprocess.run([BIN, *args], capture_output=True, text=True, cwd=cwd, timeout=timeout)


class OutputGuardCliTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_output_guard_")
        cls.dir = cls.tmp.name
        cls.run_a = os.path.join(cls.dir, "a.h5")
        cls.run_b = os.path.join(cls.dir, "b.h5")
        for out, solver in ((cls.run_a, "xpbd"), (cls.run_b, "pbd")):
            r = pbdbench("run", "spring", "--solver", solver, "--set", "time.duration=0.05", "--out", out, "--quiet",
                         "--no-xdmf")
            assert r.returncode == 0, r.stdout + r.stderr

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def setUp(self):
        self.case = tempfile.mkdtemp(dir=self.dir)

    def path(self, name):
        return os.path.join(self.case, name)

    def notes(self, name):
        p = self.path(name)
        with open(p, "wb") as f:
            f.write(NOTES)
        return p

    def unchanged(self, p, content=NOTES):
        with open(p, "rb") as f:
            self.assertEqual(f.read(), content, p)

    def refused(self, args, argument, target, *why, cwd=None):
        r = pbdbench(*args, cwd=cwd)
        self.assertEqual(r.returncode, 2, f"{args}: {r.stdout}{r.stderr}")
        self.assertIn(f"{argument} {target}", r.stderr)
        for w in why:
            self.assertIn(w, r.stderr)
        return r

    def common_refusals(self, command, kind, extra=()):
        """A text file, a folder, a device, a link and a link planted at the temporary."""
        text = self.notes("notes.h5")
        self.refused([*command, "--out", text, *extra], "--out", text, f"is not a pbdbench {kind}")
        self.unchanged(text)
        folder = self.path("folder")
        os.mkdir(folder)
        self.refused([*command, "--out", folder, *extra], "--out", folder, "is a directory")
        self.refused([*command, "--out", "/dev/null", *extra], "--out", "/dev/null", "character device")
        victim = self.notes("victim.txt")
        link = self.path("link.h5")
        os.symlink(victim, link)
        self.refused([*command, "--out", link, *extra], "--out", link, "symbolic link")
        out = self.path("out.h5")
        os.symlink(victim, out + ".tmp")
        self.refused([*command, "--out", out, *extra], "--out", out, f"its temporary {out}.tmp", "symbolic link")
        self.unchanged(victim)
        self.assertFalse(os.path.exists(out))
        os.remove(out + ".tmp")
        # Its own earlier output is replaced.
        for _ in range(2):
            r = pbdbench(*command, "--out", out, *extra)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertFalse(os.path.exists(out + ".tmp"))
        return out

    def test_compare(self):
        with open(self.run_a, "rb") as f:
            before = f.read()
        self.refused(["compare", self.run_a, self.run_b, "--out", self.run_a], "--out", self.run_a,
                     "is the run file compared itself")
        self.refused(["compare", self.run_a, self.run_b, "--out", self.run_b], "--out", self.run_b,
                     "is the reference run file itself")
        with open(self.run_a, "rb") as f:
            self.assertEqual(f.read(), before)
        out = self.common_refusals(["compare", self.run_a, self.run_b], "compare file")
        # Another pbdbench HDF5 file (a run file) is not a compare file.
        copy = self.path("copy.h5")
        with open(self.run_a, "rb") as f, open(copy, "wb") as g:
            g.write(f.read())
        self.refused(["compare", self.run_a, self.run_b, "--out", copy], "--out", copy, "is not a pbdbench compare file")
        self.assertTrue(os.path.getsize(out) > 0)
        # --plot: only an earlier figure of matplotlib's is replaced (its PNG names it).
        plot = self.notes("plot.png")
        self.refused(["compare", self.run_a, self.run_b, "--plot", plot], "--plot", plot,
                     "is not a pbdbench plot (a matplotlib figure)")
        self.unchanged(plot)
        self.refused(["compare", self.run_a, self.run_b, "--plot", self.run_b], "--plot", self.run_b,
                     "is the reference run file itself")
        self.refused(["compare", self.run_a, self.run_b, "--out", out, "--plot", out], "--plot", out,
                     "is the compare file (--out) itself")
        os.remove(plot)
        for _ in range(2):
            r = pbdbench("compare", self.run_a, self.run_b, "--plot", plot)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_converge(self):
        scenario = self.path("s.toml")
        with open(scenario, "w") as f:
            f.write('[scene]\nkind = "spring"\n[time]\nduration = 0.1\n')
        self.refused(["converge", scenario, "--out", scenario, "--quiet"], "--out", scenario,
                     "is the scenario file itself")
        with open(scenario) as f:
            self.assertIn("spring", f.read())
        self.common_refusals(["converge", scenario], "convergence file", extra=("--quiet",))

    def test_export(self):
        self.refused(["export", self.run_a, "--out", self.run_a], "--out", self.run_a, "is the run file exported itself")
        self.assertEqual(pbdbench("compare", self.run_a, self.run_a).returncode, 0, "the run file is whole")
        text = self.notes("notes.xdmf")
        self.refused(["export", self.run_a, "--out", text], "--out", text, "is not a pbdbench ParaView export")
        self.unchanged(text)
        # A link planted at either temporary: the XDMF's and its data file's.
        victim = self.notes("victim.txt")
        for planted in ("x.xdmf.tmp", "x.viz.h5.tmp"):
            os.symlink(victim, self.path(planted))
            self.refused(["export", self.run_a, "--out", self.path("x.xdmf")], "--out", "", "its temporary",
                         "symbolic link")
            self.unchanged(victim)
            os.remove(self.path(planted))
        for _ in range(2):
            r = pbdbench("export", self.run_a, "--out", self.path("x.xdmf"))
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        # The data file beside it is guarded too.
        data = self.notes("y.viz.h5")
        self.refused(["export", self.run_a, "--out", self.path("y.xdmf")], "--out", data,
                     "is not a pbdbench ParaView data file")
        self.unchanged(data)

    def test_sweep(self):
        sweep = self.path("s.toml")
        with open(sweep, "w") as f:
            f.write('scenario = "spring"\n[set]\n"time.duration" = 0.05\n[grid]\n"solver.iterations" = [1, 2]\n')
        text = self.notes("notes.txt")
        r = pbdbench("sweep", sweep, "--out", text, "--quiet")
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn(text, r.stderr)
        self.unchanged(text)
        r = pbdbench("sweep", sweep, "--out", sweep, "--quiet")
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        with open(sweep) as f:
            self.assertIn("grid", f.read())

    def test_regress(self):
        base = self.path("base.toml")
        args = ["regress", "spring_xpbd", "--baselines", base, "--no-plot"]
        text = self.notes("notes.txt")
        self.refused([*args, "--update", "--out", text], "--out", text, "not a folder")
        self.unchanged(text)
        # A folder of someone else's: its regress.md is not replaced, and no run is made.
        mine = self.path("mine")
        os.mkdir(mine)
        report = os.path.join(mine, "regress.md")
        with open(report, "wb") as f:
            f.write(NOTES)
        self.refused([*args, "--update", "--out", mine], "--out", report, "is not a pbdbench regression report")
        self.unchanged(report)
        self.assertFalse(os.path.exists(os.path.join(mine, "runs")))
        # --update: the baselines must be pbdbench's.
        self.notes("base.toml")
        self.refused([*args, "--update", "--out", self.path("r")], "--baselines", base,
                     "is not a pbdbench baselines file")
        self.unchanged(base)
        os.remove(base)
        for extra in (["--update"], [], []):
            r = pbdbench(*args, *extra, "--out", self.path("r"))
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_paper_report_and_record(self):
        exp = self.path("exp")
        os.mkdir(exp)
        with open(os.path.join(exp, "chain_err.toml"), "w") as f:
            f.write(EXPERIMENT)
        args = ["paper", "--experiments", exp, "--runs", self.path("runs"), "--no-plots"]
        report = self.path("report")
        os.mkdir(report)
        readme = os.path.join(report, "README.md")
        with open(readme, "wb") as f:
            f.write(NOTES)
        self.refused([*args, "--out", report], "--out", readme, "is not a pbdbench report")
        self.unchanged(readme)
        self.assertFalse(os.path.exists(self.path("runs")), "refused before any run")
        os.remove(readme)
        record = self.notes("verdicts.toml")
        self.refused([*args, "--out", report, "--record", record], "--record", record,
                     "is not a pbdbench verdict record")
        self.unchanged(record)
        os.remove(record)
        for _ in range(2):
            r = pbdbench(*args, "--out", report, "--record", record)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

        # register: appends to pbdbench's registry only (a TOML file of someone else's here).
        registry = self.path("registry.toml")
        with open(registry, "wb") as f:
            f.write(b"# my own registry\n")
        self.refused(["register", "paper", "--experiments", exp, "--results", self.path("none.json")],
                     "the registry", registry, "is not a pbdbench registry")
        self.unchanged(registry, b"# my own registry\n")
        os.remove(registry)
        r = pbdbench("register", "paper", "--experiments", exp, "--results", self.path("none.json"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        with open(registry) as f:
            self.assertIn("chain_err", f.read())


if __name__ == "__main__":
    unittest.main()
