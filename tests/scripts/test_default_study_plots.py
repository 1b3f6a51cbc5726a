#!/usr/bin/python3
"""The default study's figures (scripts/plot_default_study.py, what scripts/study.sh draws), read
from the matplotlib figure objects: rates on log axes, no path in a title, no empty panel, an
exploded run that does not flatten the others, and lines on top of each other named in the
legend. The study is the real one (studies/default/), shortened to 0.25 s; the explosion and the
identical lines are made by editing copies of its run files.

Environment (set by tests/scripts/CMakeLists.txt):
    PBDBENCH_BIN       the pbdbench executable
    PBDBENCH_SCRIPTS   the scripts/ folder
    PBDBENCH_TEST_TMP  a folder for the files the tests write
"""
import glob
import json
import os
import shutil
import subprocess
import sys
import unittest

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.join(HERE, "..", "..")
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(SOURCE, "scripts"))
BIN = os.environ.get("PBDBENCH_BIN", os.path.join(SOURCE, "build", "pbdbench"))
TMP = os.path.join(os.environ.get("PBDBENCH_TEST_TMP", os.path.join(HERE, "tmp")), "default_study_plots")
CLOTH, CHAIN = "cloth_pbd_vs_xpbd", "chain_iterations_vs_substeps"
RATES = ["cloth_stretch_peak_vs_iterations.png", "cloth_stretch_rms_mean_vs_iterations.png",
         "chain_iterations_vs_substeps.png"]

sys.path.insert(0, SCRIPTS)
import plot_axes  # noqa: E402
import plot_default_study  # noqa: E402


def copy_study(name):
    """A copy of the study, to edit."""
    target = os.path.join(TMP, name)
    shutil.rmtree(target, ignore_errors=True)
    shutil.copytree(os.path.join(TMP, "study"), target)
    return target


def run_file(study, sweep, **params):
    with open(os.path.join(study, sweep, "index.json")) as f:
        for r in json.load(f)["runs"]:
            if all(r["params"].get(k) == v for k, v in params.items()):
                return os.path.join(study, sweep, r["file"])
    raise AssertionError(f"no run {params} in {sweep}")


def explode(path, factor=1e6):
    """Marks a run file exploded and multiplies its error and energy series by `factor`, as a
    run that blew up before its limits stopped it."""
    with h5py.File(path, "r+") as f:
        for name in f["series"]:
            if name.startswith("constraint_error") or name.endswith("energy"):
                f["series"][name][...] = f["series"][name][...] * factor
        f.attrs["status"] = "exploded"


def legend_texts(fig):
    """The legends' labels, each on one line (plot_axes.figure_legend wraps them to their column)."""
    texts = []
    for legend in fig.legends + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]:
        texts += [" ".join(t.get_text().split()) for t in legend.get_texts()]
    return texts


def titles(fig):
    out = [ax.get_title() for ax in fig.axes]
    if fig._suptitle is not None:
        out.append(fig._suptitle.get_text())
    return out


def finite_points_inside(ax, line):
    x, y = (np.asarray(v, dtype=float) for v in line.get_data())
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    return int(np.sum(np.isfinite(x) & np.isfinite(y) & (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)))


@unittest.skipUnless(os.path.isfile(BIN), f"no pbdbench executable at {BIN}")
class DefaultStudyPlots(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        shutil.rmtree(TMP, ignore_errors=True)
        os.makedirs(TMP)
        cls.study = os.path.join(TMP, "study")
        for sweep in (CLOTH, CHAIN):
            r = subprocess.run([BIN, "sweep", os.path.join(SOURCE, "studies", "default", sweep + ".toml"),
                                "--out", os.path.join(cls.study, sweep), "--set", "time.duration=0.25",
                                "--jobs", "2", "--quiet"], capture_output=True, text=True, timeout=600)
            assert r.returncode == 0, r.stdout + r.stderr
        cls.figures = plot_default_study.figures(cls.study)

    @classmethod
    def tearDownClass(cls):
        plt.close("all")

    def test_the_study_draws_its_four_figures(self):
        self.assertEqual(sorted(self.figures), sorted(RATES + ["cloth_runs.png"]))
        r = subprocess.run(["/usr/bin/python3", os.path.join(SCRIPTS, "plot_default_study.py"), self.study],
                           capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        for name in self.figures:
            self.assertTrue(os.path.getsize(os.path.join(self.study, name)) > 1000, name)

    def test_rates_are_on_log_axes(self):
        for name in RATES:
            ax = self.figures[name].axes[0]
            self.assertEqual((ax.get_xscale(), ax.get_yscale()), ("log", "log"), name)
        panels = {ax.get_title(): ax for ax in self.figures["cloth_runs.png"].axes}
        self.assertEqual(panels["constraint error"].get_yscale(), "log")

    def test_no_path_in_a_title(self):
        for name, fig in self.figures.items():
            for title in titles(fig):
                self.assertNotIn("/", title, name)
                self.assertNotIn(".toml", title, name)
        self.assertIn("scenario hanging_cloth", self.figures["cloth_stretch_peak_vs_iterations.png"].axes[0].get_title())

    def test_no_empty_panel(self):
        for name, fig in self.figures.items():
            for ax in fig.axes:
                if not ax.get_visible() or not ax.axison:  # the grid's free cell holds the legend
                    self.assertTrue(ax.get_visible() is False or ax.get_legend() is not None,
                                    f"{name}: an empty cell")
                    continue
                drawn = [line for line in ax.get_lines() if finite_points_inside(ax, line) > 0]
                self.assertTrue(drawn, f"{name}: panel {ax.get_title()!r} shows nothing")

    def test_an_exploded_run_does_not_flatten_the_others(self):
        study = copy_study("exploded")
        boom_cloth = run_file(study, CLOTH, **{"solver.name": "pbd", "solver.iterations": 5})
        boom_chain = run_file(study, CHAIN, **{"solver.name": "xpbd", "solver.iterations": 1,
                                                "solver.substeps": 1})
        explode(boom_cloth)
        explode(boom_chain)
        figures = plot_default_study.figures(study)

        # Over time: each panel's axis is the other runs'; the exploded run's label says where it left.
        fig = figures["cloth_runs.png"]
        label = next(t for t in legend_texts(fig) if t.startswith("name=pbd, iterations=5"))
        self.assertIn("exploded", label)
        self.assertIn("off the axis in: ", label)
        panels = {ax.get_title(): ax for ax in fig.axes}
        with h5py.File(boom_cloth, "r") as f:
            peaks = {"constraint error": np.nanmax(f["series/constraint_error_max"][...]),
                     "energy": np.nanmax(np.abs(f["series/total_energy"][...]))}
        for title, peak in peaks.items():
            self.assertLess(panels[title].get_ylim()[1], 1e-3 * peak, title)
            self.assertIn(title, label)

        # Against a parameter: the exploded point is at the axis's top edge, counted in the legend.
        for name in ("cloth_stretch_peak_vs_iterations.png", "chain_iterations_vs_substeps.png"):
            ax = figures[name].axes[0]
            texts = legend_texts(figures[name])
            self.assertTrue(any(t.startswith("exploded") for t in texts), (name, texts))
            lo, hi = ax.get_ylim()
            # The span of the axis is the other runs': a few decades, not the explosion's 1e6.
            self.assertLess(np.log10(hi / lo), 4.5, name)

    def test_lines_on_top_of_each_other_are_named(self):
        study = copy_study("identical")
        # Every xpbd run of the cloth replaced by the pbd run of the same iterations.
        for it in (5, 10, 20, 40):
            shutil.copyfile(run_file(study, CLOTH, **{"solver.name": "pbd", "solver.iterations": it}),
                            run_file(study, CLOTH, **{"solver.name": "xpbd", "solver.iterations": it}))
        figures = plot_default_study.figures(study)
        texts = legend_texts(figures["cloth_stretch_peak_vs_iterations.png"])
        self.assertIn("name=xpbd (identical to name=pbd: drawn over it)", texts)
        texts = legend_texts(figures["cloth_runs.png"])
        # Each xpbd copy is named as drawn over another line: "identical to" its pbd run, or,
        # where pbd's own runs at several iterations coincide in a panel (pbd's k derived from
        # the cloth's compliance converges with the iterations), "=" the earliest of them.
        copies = [t for t in texts if "solver.name-xpbd" in t and ("identical to" in t or "(= " in t)]
        self.assertEqual(len(copies), 4, texts)
        self.assertGreaterEqual(len([t for t in copies if "identical to" in t]), 3, texts)
        # Each line has its own marker, so that the one drawn over still shows.
        ax = figures["cloth_stretch_peak_vs_iterations.png"].axes[0]
        markers = [line.get_marker() for line in ax.get_lines() if len(line.get_xdata()) > 1]
        self.assertEqual(len(set(markers)), len(markers))

    def test_helpers(self):
        # Coincident lines: within 1 % of the axis's height everywhere, NaN at the same points.
        x = [1, 2, 3]
        lines = [(x, [1.0, 2.0, 3.0]), (x, [1.0, 2.0, 3.0]), (x, [1.0, 2.01, 3.0]), (x, [1.0, 2.5, 3.0]), None,
                 (x, [1.0, np.nan, 3.0])]
        self.assertEqual(plot_axes.coincident(lines, (0.0, 4.0)), {1: (0, True), 2: (0, False)})
        self.assertEqual(plot_axes.coincident(lines, (0.0, 0.4)), {1: (0, True)})  # a taller axis tells them apart
        # On a log axis, in decades.
        self.assertEqual(plot_axes.coincident([(x, [1e-3, 1e-2, 1e-1]), (x, [1.01e-3, 1e-2, 1e-1])],
                                              (1e-4, 1.0), log=True), {1: (0, False)})
        # A peak ten times the median is kept apart; fewer than three runs, nothing.
        self.assertEqual(plot_axes.outliers([1.0, 2.0, 1.5, 40.0, np.nan]), {3})
        self.assertEqual(plot_axes.outliers([1.0, 40.0]), set())
        # Limits: the finite values with a margin; the positive ones on a log axis.
        self.assertEqual(plot_axes.axis_limits([np.array([0.0, 10.0, np.inf])]), (-0.5, 10.5))
        lo, hi = plot_axes.axis_limits([np.array([-1.0, 1e-2, 1.0, np.nan])], log=True)
        self.assertAlmostEqual(np.log10(lo), -2.1)
        self.assertAlmostEqual(np.log10(hi), 0.1)
        self.assertIsNone(plot_axes.axis_limits([np.array([np.nan])]))
        self.assertEqual(plot_axes.shown_name("/home/me/scenarios/hanging_chain.toml"), "hanging_chain")


if __name__ == "__main__":
    unittest.main()
