#!/usr/bin/python3
"""docs/sweeps.md, as a reader would use it: its sweep file is written as shown, its commands are
run as shown (build/pbdbench and scripts/ taken from this build and this source tree), and what
the page says of the keys, the files, the shards and the numbers is checked against what they did.

Run by CTest with PBDBENCH_BIN, PBDBENCH_SCENARIOS and PBDBENCH_SOURCE_DIR set.
"""
import json
import os
import re
import subprocess
import tempfile
import unittest

import h5py

BIN = os.environ["PBDBENCH_BIN"]
SOURCE = os.environ["PBDBENCH_SOURCE_DIR"]
DOC = os.path.join(SOURCE, "docs", "sweeps.md")


def blocks(text, language):
    """The fenced code blocks of `text` in `language`, in order."""
    return re.findall(r"^```" + language + r"\n(.*?)^```", text, flags=re.S | re.M)


def as_here(command):
    """A command of the page with this build's executable and this tree's scripts."""
    command = command.replace("build/pbdbench", BIN)
    return re.sub(r"(^|\s)scripts/", lambda m: m.group(1) + os.path.join(SOURCE, "scripts") + "/", command)


class SweepDocs(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        with open(DOC, encoding="utf-8") as f:
            cls.doc = f.read()
        cls.tmp = tempfile.TemporaryDirectory(prefix="pbdbench_sweep_docs_")
        cls.dir = cls.tmp.name
        # The sweep files of the page: each toml block that starts with "# NAME.toml".
        cls.files = []
        for block in blocks(cls.doc, "toml"):
            m = re.match(r"# (\S+\.toml)", block)
            if m:
                with open(os.path.join(cls.dir, m.group(1)), "w", encoding="utf-8") as f:
                    f.write(block)
                cls.files.append(m.group(1))
        # Its commands, each line of its sh blocks, in order.
        cls.results = []
        for block in blocks(cls.doc, "sh"):
            for line in block.splitlines():
                if line.strip() and not line.lstrip().startswith("#"):
                    r = subprocess.run(["bash", "-c", as_here(line)], cwd=cls.dir, capture_output=True, text=True,
                                       timeout=600)
                    cls.results.append((line, r))

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def index(self, folder, name="index.json"):
        with open(os.path.join(self.dir, "results", "sweeps", folder, name)) as f:
            return json.load(f)

    def test_every_command_runs(self):
        self.assertEqual(self.files, ["chain_sweep.toml"])
        self.assertEqual(len(self.results), 6)
        for line, r in self.results:
            self.assertEqual(r.returncode, 0, f"{line}\n{r.stdout}{r.stderr}")

    def test_what_the_page_says_they_did(self):
        first, again = self.results[0][1], self.results[1][1]
        self.assertIn("4 runs, 0 already complete, 4 to run, 2 at a time", first.stdout)
        self.assertIn("10 iterations x 1 substep against 1 iteration x 10 substeps", first.stdout)
        self.assertIn("4 already complete, 0 to run", again.stdout)
        index = self.index("chain_sweep")
        self.assertEqual(index["sweep"], "chain_sweep")
        self.assertEqual(index["parameters"], ["solver.name", "solver.iterations", "solver.substeps"])
        # The order of the runs: the grid outermost, each with every case; the stems as shown.
        self.assertEqual([r["file"] for r in index["runs"]],
                         ["solver.name-pbd__solver.iterations-10__solver.substeps-1.h5",
                          "solver.name-pbd__solver.iterations-1__solver.substeps-10.h5",
                          "solver.name-xpbd__solver.iterations-10__solver.substeps-1.h5",
                          "solver.name-xpbd__solver.iterations-1__solver.substeps-10.h5"])
        self.assertEqual({r["status"] for r in index["runs"]}, {"complete"})
        # index.jsonl: the sweep, then a line per run as it ended (the second command ran none and
        # left it).
        with open(os.path.join(self.dir, "results", "sweeps", "chain_sweep", "index.jsonl")) as f:
            lines = [json.loads(line) for line in f]
        self.assertEqual(lines[0]["sweep"], "chain_sweep")
        self.assertEqual(lines[0]["parameters"], index["parameters"])
        self.assertEqual(sorted(lines[1:], key=lambda r: r["file"]), sorted(index["runs"], key=lambda r: r["file"]))
        for r in index["runs"]:
            self.assertTrue(os.path.exists(os.path.join(self.dir, "results", "sweeps", "chain_sweep",
                                                        r["file"].replace(".h5", ".log"))))
        # "about 12 times smaller": the final constraint error, iterations against substeps.
        final = {}
        for r in index["runs"]:
            with h5py.File(os.path.join(self.dir, "results", "sweeps", "chain_sweep", r["file"]), "r") as f:
                final[(r["params"]["solver.name"], r["params"]["solver.substeps"])] = \
                    float(f["series/constraint_error_max"][-1])
        # xpbd about 12 times, pbd about 16 (its k derived from the compliance converges more
        # slowly over 10 iterations); with one iteration a substep the two are the same run.
        for solver, low, high in (("xpbd", 11, 13.5), ("pbd", 14.5, 17.5)):
            ratio = final[(solver, 1)] / final[(solver, 10)]
            self.assertGreater(ratio, low, solver)
            self.assertLess(ratio, high, solver)
        self.assertLess(abs(final[("pbd", 10)] - final[("xpbd", 10)]), 1e-9 * final[("xpbd", 10)])
        self.assertAlmostEqual(final[("xpbd", 1)], 0.044, delta=0.0005)
        self.assertAlmostEqual(final[("pbd", 1)], 0.057, delta=0.0005)
        self.assertAlmostEqual(final[("pbd", 10)], 0.0035, delta=0.00005)

    def test_shards_then_merge(self):
        shards = [self.index("sharded", f"index.shard-{i}-of-2.json") for i in range(2)]
        # Run k is in shard k % 2 (counted from 0).
        self.assertEqual([r["params"]["solver.substeps"] for r in shards[0]["runs"]], [1, 1])
        self.assertEqual([r["params"]["solver.substeps"] for r in shards[1]["runs"]], [10, 10])
        self.assertEqual(len(self.index("sharded")["runs"]), 4)
        self.assertTrue(os.path.getsize(os.path.join(self.dir, "results", "sweeps", "chain_sweep.png")) > 1000)

    def test_the_keys_table_is_every_key_the_loader_takes(self):
        bad = os.path.join(self.dir, "bad.toml")
        with open(bad, "w") as f:
            f.write('scenario = "hanging_chain"\nbogus = 1\n')
        r = subprocess.run([BIN, "sweep", bad], capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 2)
        allowed = re.search(r"\(expected ([a-z, ]+)\)", r.stderr).group(1).split(", ")
        table = self.doc[self.doc.index("## The keys"):self.doc.index("## What is written where")]
        documented = re.findall(r"^\| `\[*([a-z]+)\]*` \|", table, flags=re.M)
        self.assertEqual(sorted(documented), sorted(allowed))

    def test_the_exit_codes_of_the_page(self):
        table = self.doc[self.doc.index("## Exit codes"):]
        self.assertEqual(re.findall(r"^\| (\d) \|", table, flags=re.M), ["0", "1", "2", "4"])
        sweep = os.path.join(self.dir, "chain_sweep.toml")
        r = subprocess.run([BIN, "sweep", sweep, "--shard", "2/2"], capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 2)
        self.assertIn("shards are counted from 0: 0/2 to 1/2", r.stderr)
        r = subprocess.run([BIN, "sweep", sweep, "--out", os.path.join(self.dir, "unmade"), "--merge", "2"],
                           capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 1)
        self.assertIn("shard 1/2: 2 runs", r.stderr)


if __name__ == "__main__":
    unittest.main()
