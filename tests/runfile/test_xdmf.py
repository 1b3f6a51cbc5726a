"""The ParaView output (runfile/xdmf.hpp) read by ParaView's own XDMF reader (pvbatch, Debian's
python3-paraview, installed by scripts/install_deps.sh): every frame's time, the positions and
velocities of the run file, the topology, the colliders moving with their motion, and the
per-cell fields, compared with the run file read by h5py.

Environment: PBDBENCH_BIN (the pbdbench executable), PBDBENCH_SCENARIOS.
"""
import json
import math
import os
import shutil
import subprocess
import tempfile
import unittest

import h5py
import numpy as np

BIN = os.environ.get("PBDBENCH_BIN", "pbdbench")
SCENARIOS = os.environ.get("PBDBENCH_SCENARIOS", os.path.join(os.path.dirname(__file__), "..", "..", "scenarios"))
DUMP = os.path.join(os.path.dirname(os.path.abspath(__file__)), "xdmf_dump.py")
PVBATCH = shutil.which("pvbatch")


def run(*args):
    return subprocess.run([BIN, *args], capture_output=True, text=True, check=False)


def paraview_read(xdmf, index):
    p = subprocess.run([PVBATCH, DUMP, xdmf, str(index)], capture_output=True, text=True, timeout=120)
    lines = [l for l in p.stdout.splitlines() if l.startswith("JSON")]
    if p.returncode != 0 or not lines:
        raise AssertionError(f"pvbatch failed ({p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    return json.loads(lines[-1][4:])


@unittest.skipIf(PVBATCH is None, "pvbatch not installed: scripts/install_deps.sh installs python3-paraview "
                 "(the README's test command runs it)")
class XdmfReadByParaView(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="pbdbench_xdmf_")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.dir, ignore_errors=True)

    def test_collapsing_fem_bar_tets_fields_and_positions(self):
        out = os.path.join(self.dir, "bar.h5")
        r = run("run", os.path.join(SCENARIOS, "cantilever_fem.toml"), "--set", "scene.youngs_modulus=2e5",
                "--set", "scene.poisson_ratio=0.45", "--set", "solver.substeps=1", "--set", "solver.iterations=10",
                "--set", "time.duration=0.5", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("ParaView: ", r.stdout)
        xdmf = os.path.join(self.dir, "bar.xdmf")
        with h5py.File(out, "r") as f:
            times = f["frames/time"][:]
            x = f["frames/positions"][:]
            v = f["frames/velocities"][:]
            tets = f["model/tets"][:]
            rest = f["model/rest_positions"][:]
        self.assertEqual(len(times), 31, "one frame per 1/60 s by default, the initial one included")
        k = 10
        got = paraview_read(xdmf, k)
        np.testing.assert_allclose(got["times"], times, rtol=0, atol=1e-12)
        tb = got["blocks"]["tets"]
        self.assertEqual(tb["cells"], len(tets))
        self.assertEqual(tb["cell_types"], [10])  # VTK_TETRA
        np.testing.assert_allclose(np.array(tb["points"]), x[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.array(tb["point_arrays"]["velocity"]), v[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.array(tb["point_arrays"]["displacement"]), x[k] - rest, rtol=0, atol=1e-12)
        # Volume change of each tet, from the positions, against the reader's cell array.
        def vol(p):
            return np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6
        expected = vol(x[k][tets]) / vol(rest[tets]) - 1
        np.testing.assert_allclose(np.array(tb["cell_arrays"]["volume_change"]), expected, rtol=1e-9, atol=1e-12)
        # The collapse shows in the fields: the tets lost volume and carry a constraint error.
        self.assertLess(float(np.mean(expected)), -0.1)
        self.assertGreater(max(tb["cell_arrays"]["constraint_error"]), 0.1)
        pinned = np.array(tb["point_arrays"]["pinned"])
        self.assertEqual(int(pinned.sum()), 9, "the clamped face: 3 x 3 particles")

    def test_chain_shows_as_edges_and_moving_sphere_moves(self):
        out = os.path.join(self.dir, "chain.h5")
        r = run("run", os.path.join(SCENARIOS, "hanging_chain.toml"), "--set", "time.duration=0.1", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        got = paraview_read(os.path.join(self.dir, "chain.xdmf"), 3)
        with h5py.File(out, "r") as f:
            kinds = f["model/constraint_kind"][:]
            x = f["frames/positions"][3]
        eb = got["blocks"]["edges"]
        self.assertEqual(eb["cells"], int(np.sum(kinds == 0)), "one edge per distance constraint")
        self.assertEqual(eb["cell_types"], [4])  # VTK_POLY_LINE of 2 points
        np.testing.assert_allclose(np.array(eb["points"]), x, rtol=0, atol=1e-12)
        self.assertIn("strain", eb["cell_arrays"])

        out = os.path.join(self.dir, "cloth.h5")
        r = run("run", os.path.join(SCENARIOS, "cloth_on_character.toml"), "--set", "time.duration=0.5",
                "--set", "scene.resolution=[8, 8]", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        xdmf = os.path.join(self.dir, "cloth.xdmf")
        first, last = paraview_read(xdmf, 0), paraview_read(xdmf, 30)
        c0 = np.array(first["blocks"]["colliders"]["points"]).mean(axis=0)
        c1 = np.array(last["blocks"]["colliders"]["points"]).mean(axis=0)
        # The sphere starts at (0, 1.15, 0.28) and circles the y axis with radius 1 m from t = 0.25 s.
        np.testing.assert_allclose(c0, [0.0, 1.15, 0.28], atol=1e-9)
        self.assertGreater(float(np.linalg.norm(c1 - c0)), 0.1, "the sphere moved with its motion")
        self.assertAlmostEqual(float(c1[1]), 1.15, places=9)

    def test_export_refuses_to_replace_a_file_that_is_not_ours(self):
        out = os.path.join(self.dir, "spring.h5")
        r = run("run", os.path.join(SCENARIOS, "spring.toml"), "--set", "time.duration=0.1", "--out", out,
                "--quiet", "--no-xdmf")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        xdmf = os.path.join(self.dir, "spring.xdmf")
        self.assertFalse(os.path.exists(xdmf))
        with open(xdmf, "w") as f:
            f.write("my notes\n")
        r = run("export", out)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("not an earlier pbdbench export", r.stderr)
        with open(xdmf) as f:
            self.assertEqual(f.read(), "my notes\n")
        os.remove(xdmf)
        r = run("export", out)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        r = run("export", out)  # an earlier export is replaced
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertEqual(paraview_read(xdmf, 0)["blocks"]["edges"]["cells"], 1)


if __name__ == "__main__":
    unittest.main()
