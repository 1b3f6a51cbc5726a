#!/usr/bin/python3
"""Tests of scripts/readme_tables.py: the README's generated block is what the script prints from
the reports' JSON (so the README's headline numbers cannot go stale), and the tables follow the
JSON on a small report written here."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(HERE, "..", "..", "scripts"))
ROOT = os.path.dirname(os.path.abspath(SCRIPTS))
sys.path.insert(0, SCRIPTS)
import readme_tables  # noqa: E402

SCRIPT = os.path.join(SCRIPTS, "readme_tables.py")


def part(pid, verdict, regime="article", ours="", says="says", published="", ours_value=None):
    return {"id": pid, "says": says, "verdict": verdict, "regime": regime, "published": published,
            "ours": ours, "ours_value": ours_value}


def report(command, claims):
    return {"tier": "full", "machine": "Test CPU, 3 cores",
            "build": "pbdbench 9.9 (Release build, GNU 1.0, commit 0123456789abcdef0123)",
            "command": command, "claims": claims}


CLAIMS = report("pbdbench claims --force", [
    {"id": "A1", "paper": "", "verdict": "supported", "measures": [],
     "parts": [part("A1.1", "supported"), part("A1.2", "contradicted", regime="beyond")]},
    {"id": "A2", "paper": "", "verdict": "mixed", "measures": [],
     "parts": [part("A2.1", "supported"), part("A2.2", "contradicted"), part("A2.3", "not testable")]},
])
PAPER = report("pbdbench paper --force", [
    {"id": "p1", "paper": "Doe, Roe 2001, A Title (Venue 2001)", "verdict": "mixed",
     "measures": [{"name": "cost", "value": 1.234, "units": "", "lo": 1.1, "hi": 1.5}],
     "parts": [part("p1.1", "reproduced"),
               part("p1.2", "not reproduced", ours="cost", says="costs | at most 3 %", published="1.03")]},
])


class ReadmeTables(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="readme_tables_")
        os.makedirs(os.path.join(self.tmp, "paper", "claims"))
        with open(os.path.join(self.tmp, "paper", "claims", "claims.json"), "w") as f:
            json.dump(CLAIMS, f)
        with open(os.path.join(self.tmp, "paper", "reproductions.json"), "w") as f:
            json.dump(PAPER, f)

    def tearDown(self):
        shutil.rmtree(self.tmp)

    def test_the_readme_block_is_what_the_script_prints(self):
        proc = subprocess.run([sys.executable, SCRIPT, "--check", os.path.join(ROOT, "README.md")],
                              capture_output=True, text=True)
        self.assertEqual(proc.returncode, 0, proc.stderr)

    def test_tables_follow_the_reports(self):
        text = readme_tables.block(self.tmp)
        self.assertIn("| supported | 1 | 2 | A1 |", text)        # A1.2 is beyond the regime
        self.assertIn("| contradicted | 0 | 1 |  |", text)
        self.assertIn("| mixed | 1 | – | A2 |", text)
        self.assertIn("| not testable | 0 | 1 |  |", text)
        self.assertIn("commit 0123456789)", text)
        self.assertIn("on Test CPU, 3 cores", text)
        self.assertIn("| Doe et al. 2001, *A Title* | 1 | 1 | 1 | 0 | 0 | 0 | 0 |", text)
        self.assertIn("| p1.2 | costs \\| at most 3 % | 1.03 | 1.23 [1.1, 1.5] |", text)

    def test_write_then_check_and_a_stale_block_fails(self):
        readme = os.path.join(self.tmp, "README.md")
        with open(readme, "w") as f:
            f.write("# x\n\n" + readme_tables.BEGIN + "\nold\n" + readme_tables.END + "\n\nafter\n")
        run = lambda *a: subprocess.run([sys.executable, SCRIPT, "--root", self.tmp, *a],
                                        capture_output=True, text=True)
        self.assertEqual(run("--check", readme).returncode, 1)
        self.assertEqual(run("--write", readme).returncode, 0)
        self.assertEqual(run("--check", readme).returncode, 0)
        with open(readme) as f:
            text = f.read()
        self.assertTrue(text.startswith("# x\n\n" + readme_tables.BEGIN))
        self.assertTrue(text.endswith(readme_tables.END + "\n\nafter\n"))
        self.assertNotIn("\nold\n", text)

    def test_missing_markers_are_an_error(self):
        readme = os.path.join(self.tmp, "README.md")
        with open(readme, "w") as f:
            f.write("# no markers\n")
        proc = subprocess.run([sys.executable, SCRIPT, "--root", self.tmp, "--check", readme],
                              capture_output=True, text=True)
        self.assertEqual(proc.returncode, 2)
        self.assertIn("markers", proc.stderr)


if __name__ == "__main__":
    unittest.main()
