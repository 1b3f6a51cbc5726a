"""scripts/animate.py and scripts/watch.sh: a collapsing FEM bar beside the same bar under a
reference, as GIF (Pillow: frames counted) and MP4 (ffmpeg: frames counted with ffprobe); the
frame colours follow the chosen field; a run without its export gets one; bad output names are
refused.

Environment: PBDBENCH_BIN, PBDBENCH_SCENARIOS, PBDBENCH_SCRIPTS.
"""
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np
from PIL import Image

BIN = os.environ["PBDBENCH_BIN"]
SCENARIOS = os.environ["PBDBENCH_SCENARIOS"]
SCRIPTS = os.environ["PBDBENCH_SCRIPTS"]
ANIMATE = os.path.join(SCRIPTS, "animate.py")
BAR = ["--set", "scene.youngs_modulus=2e5", "--set", "scene.poisson_ratio=0.45", "--set", "time.duration=0.25"]


def run(*args, env=None):
    return subprocess.run(list(args), capture_output=True, text=True, env=env)


class Animate(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="pbdbench_animate_")
        cls.xpbd = os.path.join(cls.dir, "xpbd.h5")
        cls.ref = os.path.join(cls.dir, "ref.h5")
        fem = os.path.join(SCENARIOS, "cantilever_fem.toml")
        r = run(BIN, "run", fem, *BAR, "--set", "solver.substeps=1", "--set", "solver.iterations=10",
                "--out", cls.xpbd, "--quiet")
        assert r.returncode == 0, r.stdout + r.stderr
        r = run(BIN, "run", fem, *BAR, "--out", cls.ref, "--quiet", "--no-xdmf")  # xpbd, 40 substeps
        assert r.returncode == 0, r.stdout + r.stderr

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.dir, ignore_errors=True)

    def test_gif_side_by_side_with_the_export_made_on_the_way(self):
        out = os.path.join(self.dir, "bar.gif")
        self.assertFalse(os.path.exists(os.path.join(self.dir, "ref.viz.h5")))
        env = dict(os.environ, PBDBENCH_BIN=BIN)
        r = run(sys.executable, ANIMATE, self.xpbd, self.ref, "-o", out, "--max-frames", "6", env=env)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertTrue(os.path.exists(os.path.join(self.dir, "ref.viz.h5")), "animate.py exported the run")
        with Image.open(out) as im:
            self.assertEqual(im.n_frames, 6)
            im.seek(5)
            last = np.asarray(im.convert("RGB"), dtype=int)
            im.seek(0)
            first = np.asarray(im.convert("RGB"), dtype=int)
        self.assertGreater(int(np.abs(last - first).sum()), 0, "the frames differ: the bar moves")
        self.assertIn("2 run(s)", r.stdout)

    def test_mp4_has_one_video_frame_per_run_frame(self):
        out = os.path.join(self.dir, "bar.mp4")
        r = run(sys.executable, ANIMATE, self.xpbd, "-o", out, "--field", "change", "--pbdbench", BIN)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        p = run("ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                "stream=nb_read_frames", "-of", "csv=p=0", out)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(int(p.stdout.strip()), 16, "0.25 s at a frame per 1/60 s, and the initial frame")

    def test_the_field_colours_the_cells_that_carry_it(self):
        # A cloth's triangles carry no constraint of their own: their constraint_error is that of
        # their edges' distance constraints (runfile/xdmf.hpp), so its faces carry the colour, as
        # the FEM bar's tets do; a chain has edges only, and they carry it.
        sys.path.insert(0, SCRIPTS)
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import animate
        import runfile
        cloth = os.path.join(self.dir, "cloth.h5")
        r = run(BIN, "run", os.path.join(SCENARIOS, "hanging_cloth.toml"), "--set", "scene.resolution=[6, 6]",
                "--set", "time.duration=0.1", "--out", cloth, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        norm = matplotlib.colors.Normalize(0.0, 1.0)
        chain = os.path.join(self.dir, "chain_colour.h5")
        r = run(BIN, "run", os.path.join(SCENARIOS, "hanging_chain.toml"), "--set", "time.duration=0.1",
                "--out", chain, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        for path, faces in ((cloth, True), (self.xpbd, True), (chain, False)):
            run_ = runfile.load(path)
            viz = animate.viz_of(path, BIN)
            fig, ax = plt.subplots()
            panel = animate.Panel(ax, run_, viz, (0, 1), "constraint_error", norm, "viridis", "label")
            panel.draw(run_.frame_time[-1])
            self.assertEqual(panel.face_coloured, faces, path)
            if faces:
                self.assertTrue(np.isfinite(np.ma.filled(panel.faces.get_array(), np.nan)).any(), path)
            else:
                self.assertTrue(panel.lines_drawn, path)
                self.assertEqual(len(panel.lines.get_segments()), len(viz["edges"]))
                self.assertTrue(np.isfinite(np.ma.filled(panel.lines.get_array(), np.nan)).any(), path)
            plt.close(fig)

    def test_the_panels_fill_the_frame_flat_and_in_3d(self):
        # Each panel is shaped like the runs' bounds: the long bar fills its panel instead of a
        # strip of a square one. In 3D the body is drawn by its outer faces.
        sys.path.insert(0, SCRIPTS)
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import animate
        import runfile
        runs = [runfile.load(p) for p in (self.xpbd, self.ref)]
        vizes = [animate.viz_of(p, BIN) for p in (self.xpbd, self.ref)]
        norm = matplotlib.colors.Normalize(0.0, 1.0)
        view = animate.default_view(runs[0])
        fig, panels = animate.layout(runs, vizes, view, False, "constraint_error", norm, "viridis", ["solver.iterations"])
        for p in panels:
            p.draw(runs[0].frame_time[-1])
        self.assertGreater(animate.drawn_fraction(fig), 0.5, "the panels cover most of the frame")
        plt.close(fig)
        # A chain hanging straight is a line: its box is widened to a third of its length, and the
        # panel is shaped like that box, not a strip of a square.
        lo, hi = animate.widened(np.array([0.0, 0.0]), np.array([0.01, 2.0]))
        np.testing.assert_allclose(hi - lo, [2.0 / 3.0, 2.0])
        w, h = animate.panel_shape(lo, hi)
        self.assertAlmostEqual(w / h, 1.0 / 3.0)
        fig, panels = animate.layout(runs, vizes, view, True, "constraint_error", norm, "viridis", ["solver.iterations"])
        for p in panels:
            p.draw(runs[0].frame_time[-1])
        self.assertEqual([ax.name for ax in fig.axes if ax.get_label() != "<colorbar>"], ["3d", "3d"])
        tets = len(vizes[0]["tets"])
        self.assertLess(len(panels[0].faces), 4 * tets, "only the outer faces are drawn")
        self.assertTrue(np.isfinite(np.ma.filled(panels[0].poly.get_array(), np.nan)).any())
        self.assertGreater(animate.drawn_fraction(fig), 0.5)
        plt.close(fig)
        out = os.path.join(self.dir, "bar3d.gif")
        r = run(sys.executable, ANIMATE, self.xpbd, "-o", out, "--view", "3d", "--max-frames", "3", "--pbdbench", BIN)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("view: 3d", r.stdout)
        with Image.open(out) as im:
            self.assertEqual(im.n_frames, 3)

    def test_sparse_frames_say_how_to_ask_for_more_and_bad_names_are_refused(self):
        sparse = os.path.join(self.dir, "sparse.h5")
        r = run(BIN, "run", os.path.join(SCENARIOS, "hanging_chain.toml"), "--set", "time.duration=0.5",
                "--set", "output.frame_every=10", "--out", sparse, "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        r = run(sys.executable, ANIMATE, sparse, "-o", os.path.join(self.dir, "chain.gif"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("output.frame_every=1", r.stderr)
        r = run(sys.executable, ANIMATE, sparse, "-o", os.path.join(self.dir, "chain.avi"))
        self.assertEqual(r.returncode, 2)
        self.assertIn(".mp4 or .gif", r.stderr)


if __name__ == "__main__":
    unittest.main()
