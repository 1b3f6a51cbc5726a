"""The ParaView output (runfile/xdmf.hpp) read by ParaView's own XDMF readers (pvbatch, Debian's
python3-paraview; the legacy "XDMF Reader" and "Xdmf3ReaderS") without a warning, and by meshio
(Debian's python3-meshio, XDMF 3): every frame's time, the positions and velocities of the run
file, the topology, the colliders moving with their motion, and the per-cell fields defined on
every cell, compared with the run file read by h5py; and scripts/paraview_screenshot.py
rendering a screenshot with no display (xvfb-run, Debian's xvfb). scripts/install_deps.sh
installs all three packages.

Environment: PBDBENCH_BIN (the pbdbench executable), PBDBENCH_SCENARIOS, PBDBENCH_SCRIPTS.
"""
import json
import os
import shutil
import subprocess
import tempfile
import unittest

import h5py
import numpy as np

BIN = os.environ.get("PBDBENCH_BIN", "pbdbench")
SCENARIOS = os.environ.get("PBDBENCH_SCENARIOS", os.path.join(os.path.dirname(__file__), "..", "..", "scenarios"))
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(os.path.dirname(__file__), "..", "..", "scripts"))
DUMP = os.path.join(os.path.dirname(os.path.abspath(__file__)), "xdmf_dump.py")
PVBATCH = shutil.which("pvbatch")
# What ParaView's readers printed on the export of old ("Cannot find DataItem element in geometry
# xml", three times a file), and any other warning or error line of VTK's.
READER_COMPLAINTS = ("Cannot find DataItem", "Warning", "WARN", "ERR|", "ERROR")
try:
    import meshio
except ImportError:
    meshio = None


def run(*args):
    return subprocess.run([BIN, *args], capture_output=True, text=True, check=False)


def paraview_read(xdmf, index, reader="legacy"):
    """The export at frame `index` as ParaView's reader `reader` sees it; fails on any warning."""
    p = subprocess.run([PVBATCH, DUMP, xdmf, str(index), reader], capture_output=True, text=True, timeout=120)
    lines = [l for l in p.stdout.splitlines() if l.startswith("JSON")]
    if p.returncode != 0 or not lines:
        raise AssertionError(f"pvbatch failed ({p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    said = [l for l in (p.stdout + p.stderr).splitlines() if not l.startswith("JSON")
            and any(c in l for c in READER_COMPLAINTS)]
    if said:
        raise AssertionError(f"ParaView's {reader} reader complained about {xdmf}:\n" + "\n".join(said[:10]))
    return json.loads(lines[-1][4:])


def cells_of(block, vtk_type):
    """The indices of a block's cells of one VTK type (10 tetra, 5 triangle, 4 poly-line)."""
    return [k for k, t in enumerate(block["cell_types"]) if t == vtk_type]


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
        with open(xdmf) as f:
            self.assertIn('<Xdmf Version="3.0">', f.read())
        with h5py.File(out, "r") as f:
            times = f["frames/time"][:]
            x = f["frames/positions"][:]
            v = f["frames/velocities"][:]
            tets = f["model/tets"][:]
            rest = f["model/rest_positions"][:]
        self.assertEqual(len(times), 31, "one frame per 1/60 s by default, the initial one included")
        k = 10

        def vol(p):
            return np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6
        expected = vol(x[k][tets]) / vol(rest[tets]) - 1
        for reader in ("legacy", "xdmf3"):
            got = paraview_read(xdmf, k, reader)
            np.testing.assert_allclose(got["times"], times, rtol=0, atol=1e-12)
            tb = got["blocks"]["body"]
            tet_cells = cells_of(tb, 10)  # VTK_TETRA
            self.assertEqual(tet_cells, list(range(len(tets))), reader)
            np.testing.assert_allclose(np.array(tb["points"]), x[k], rtol=0, atol=1e-12)
            np.testing.assert_allclose(np.array(tb["point_arrays"]["velocity"]), v[k], rtol=0, atol=1e-12)
            np.testing.assert_allclose(np.array(tb["point_arrays"]["displacement"]), x[k] - rest, rtol=0, atol=1e-12)
            # Volume change of each tet, from the positions, against the reader's cell array.
            change = np.array(tb["cell_arrays"]["change"], dtype=float)
            np.testing.assert_allclose(change[: len(tets)], expected, rtol=1e-9, atol=1e-12)
            # The collapse shows in the fields: the tets lost volume and carry a constraint error,
            # which every cell has (none left to the missing-value colour).
            self.assertLess(float(np.mean(expected)), -0.1)
            error = np.array(tb["cell_arrays"]["constraint_error"], dtype=float)
            self.assertEqual(len(error), tb["cells"])
            self.assertTrue(np.isfinite(error).all(), f"{reader}: constraint_error has a value on every cell")
            self.assertGreater(float(error[: len(tets)].max()), 0.1)
            pinned = np.array(tb["point_arrays"]["pinned"])
            self.assertEqual(int(pinned.sum()), 9, "the clamped face: 3 x 3 particles")

    @unittest.skipIf(meshio is None, "meshio not installed: scripts/install_deps.sh installs python3-meshio")
    def test_meshio_reads_the_time_series(self):
        out = os.path.join(self.dir, "bar_meshio.h5")
        r = run("run", os.path.join(SCENARIOS, "cantilever_fem.toml"), "--set", "scene.youngs_modulus=2e5",
                "--set", "scene.poisson_ratio=0.45", "--set", "solver.substeps=1", "--set", "solver.iterations=10",
                "--set", "time.duration=0.1", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        with h5py.File(out, "r") as f:
            times = f["frames/time"][:]
            x = f["frames/positions"][:]
            v = f["frames/velocities"][:]
            tets = f["model/tets"][:]
            rest = f["model/rest_positions"][:]
        with meshio.xdmf.TimeSeriesReader(os.path.join(self.dir, "bar_meshio.xdmf")) as reader:
            points, cells = reader.read_points_cells()
            np.testing.assert_allclose(points, x[0], rtol=0, atol=0)
            blocks = {c.type: c.data for c in cells}
            np.testing.assert_array_equal(blocks["tetra"], tets)
            self.assertEqual(reader.num_steps, len(times))
            k = len(times) - 1
            t, point_data, cell_data = reader.read_data(k)
        self.assertEqual(t, times[k])
        np.testing.assert_allclose(point_data["displacement"], x[k] - rest, rtol=0, atol=1e-15)
        np.testing.assert_allclose(point_data["velocity"], v[k], rtol=0, atol=0)
        names = [c.type for c in cells]
        change = dict(zip(names, cell_data["change"]))["tetra"]

        def vol(p):
            return np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6
        np.testing.assert_allclose(change, vol(x[k][tets]) / vol(rest[tets]) - 1, rtol=1e-9, atol=1e-12)
        for name, values in zip(names, cell_data["constraint_error"]):
            self.assertTrue(np.isfinite(values).all(), f"constraint_error on every {name} cell")

    def test_cloth_triangles_carry_the_constraint_error_of_their_edges(self):
        # A cloth's triangles hold no constraint of their own: their error is the largest of their
        # edges' distance constraints, so colouring by it paints no cell in the missing-value colour.
        out = os.path.join(self.dir, "cloth_grid.h5")
        r = run("run", os.path.join(SCENARIOS, "hanging_cloth.toml"), "--set", "scene.resolution=[6, 6]",
                "--set", "time.duration=0.1", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        got = paraview_read(os.path.join(self.dir, "cloth_grid.xdmf"), 6)
        body = got["blocks"]["body"]
        error = np.array(body["cell_arrays"]["constraint_error"], dtype=float)
        tris, edges = cells_of(body, 5), cells_of(body, 4)
        self.assertTrue(tris and edges)
        self.assertTrue(np.isfinite(error).all())
        with h5py.File(os.path.join(self.dir, "cloth_grid.viz.h5"), "r") as f:
            tri_nodes = f["triangles"][:]
            edge_nodes = f["edges"][:]
        edge_error = {tuple(sorted(e)): error[c] for e, c in zip(edge_nodes.tolist(), edges)}
        for tri, c in zip(tri_nodes.tolist(), tris):
            own = [edge_error[tuple(sorted(p))] for p in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[0], tri[2]))
                   if tuple(sorted(p)) in edge_error]
            self.assertTrue(own)
            self.assertEqual(error[c], max(own))
        self.assertGreater(float(error[tris].max()), 0.0)

    def test_screenshot_without_a_display(self):
        out = os.path.join(self.dir, "cloth_shot.h5")
        r = run("run", os.path.join(SCENARIOS, "hanging_cloth.toml"), "--set", "scene.resolution=[8, 8]",
                "--set", "time.duration=0.2", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        png = os.path.join(self.dir, "cloth_shot.png")
        env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
        p = subprocess.run(["/usr/bin/python3", os.path.join(SCRIPTS, "paraview_screenshot.py"),
                            os.path.join(self.dir, "cloth_shot.xdmf"), "-o", png, "--size", "480x320"],
                           capture_output=True, text=True, timeout=180, env=env)
        self.assertEqual(p.returncode, 0, p.stdout[-2000:] + p.stderr[-3000:])
        self.assertFalse([l for l in (p.stdout + p.stderr).splitlines() if "Cannot find DataItem" in l])
        from PIL import Image
        with Image.open(png) as im:
            self.assertEqual(im.size, (480, 320))
            rgb = np.asarray(im.convert("RGB"), dtype=int)
        background = np.all(rgb >= 250, axis=2)
        self.assertGreater(float(1 - background.mean()), 0.05, "the cloth covers part of the image")
        # ParaView's missing-value colour is yellow (1, 1, 0); the cool-to-warm map has none.
        yellow = (rgb[..., 0] > 150) & (rgb[..., 1] > 150) & (rgb[..., 2] < 80)
        self.assertEqual(int(yellow.sum()), 0, "no cell drawn in the missing-value colour")

    def test_chain_shows_as_edges_and_moving_sphere_moves(self):
        out = os.path.join(self.dir, "chain.h5")
        r = run("run", os.path.join(SCENARIOS, "hanging_chain.toml"), "--set", "time.duration=0.1", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        got = paraview_read(os.path.join(self.dir, "chain.xdmf"), 3)
        with h5py.File(out, "r") as f:
            kinds = f["model/constraint_kind"][:]
            x = f["frames/positions"][3]
        eb = got["blocks"]["body"]
        self.assertEqual(eb["cells"], int(np.sum(kinds == 0)), "one edge per distance constraint")
        self.assertEqual(sorted(set(eb["cell_types"])), [4])  # VTK_POLY_LINE of 2 points
        np.testing.assert_allclose(np.array(eb["points"]), x, rtol=0, atol=1e-12)
        self.assertIn("change", eb["cell_arrays"])

        out = os.path.join(self.dir, "cloth.h5")
        r = run("run", os.path.join(SCENARIOS, "cloth_on_character.toml"), "--set", "time.duration=0.5",
                "--set", "scene.resolution=[8, 8]", "--out", out, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        xdmf = os.path.join(self.dir, "cloth.xdmf")
        for reader in ("legacy", "xdmf3"):
            first, last = paraview_read(xdmf, 0, reader), paraview_read(xdmf, 30, reader)
            c0 = np.array(first["blocks"]["colliders"]["points"]).mean(axis=0)
            c1 = np.array(last["blocks"]["colliders"]["points"]).mean(axis=0)
            # The sphere starts at (0, 1.15, 0.28) and circles the y axis with radius 1 m from t = 0.25 s.
            np.testing.assert_allclose(c0, [0.0, 1.15, 0.28], atol=1e-9)
            self.assertGreater(float(np.linalg.norm(c1 - c0)), 0.1, "the sphere moved with its motion")
            self.assertAlmostEqual(float(c1[1]), 1.15, places=9)
            self.assertNotIn("constraint_error", first["blocks"]["colliders"]["cell_arrays"])

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
        self.assertIn("exists and is not a pbdbench ParaView export", r.stderr)
        with open(xdmf) as f:
            self.assertEqual(f.read(), "my notes\n")
        os.remove(xdmf)
        r = run("export", out)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        r = run("export", out)  # an earlier export is replaced
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertEqual(paraview_read(xdmf, 0)["blocks"]["body"]["cells"], 1)


if __name__ == "__main__":
    unittest.main()
