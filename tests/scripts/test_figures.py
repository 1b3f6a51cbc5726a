#!/usr/bin/python3
"""The figures of the project read from their matplotlib figure objects (docs/figures.md): the
legend inside the figure, only the keys a solver reads in a run's label, no panel of zeros or
NaNs, a log axis where the values span decades, a title that says what ran, an outlier named
rather than flattening the others, regress's figure bounded at any number of cases; and the
helpers of scripts/plot_axes.py they are made with.

Environment (set by tests/scripts/CMakeLists.txt):
    PBDBENCH_BIN       the pbdbench executable (which keys each solver reads: list --solver-keys)
    PBDBENCH_FIXTURE   tests/scripts/runfile_fixture (small run files)
    PBDBENCH_SCRIPTS   the scripts/ folder
    PBDBENCH_TEST_TMP  a folder for the files the tests write
"""
import json
import os
import shutil
import subprocess
import sys
import unittest
import unittest.mock

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = os.environ.get("PBDBENCH_SCRIPTS", os.path.join(HERE, "..", "..", "scripts"))
FIXTURE = os.environ.get("PBDBENCH_FIXTURE")
TMP = os.path.join(os.environ.get("PBDBENCH_TEST_TMP", os.path.join(HERE, "tmp")), "figures")

sys.path.insert(0, SCRIPTS)
sys.path.insert(0, HERE)
import plot_axes  # noqa: E402
import plot_claims  # noqa: E402
import plot_compare  # noqa: E402
import plot_regress  # noqa: E402
import plot_runs  # noqa: E402
import runfile  # noqa: E402
from test_plot_compare import write_compare  # noqa: E402


def setUpModule():
    shutil.rmtree(TMP, ignore_errors=True)
    os.makedirs(TMP)


def fixture(path, *args):
    subprocess.run([FIXTURE, path, *map(str, args)], check=True)
    return path


def zero_panels(fig):
    """The titles of the visible axes that draw data and all of whose data are 0 or NaN."""
    out = []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison:
            continue
        data = plot_axes.axes_data(ax)
        if data and not plot_axes.informative(data):
            out.append(ax.get_title())
    return out


def fig_texts(fig):
    texts = [t.get_text() for t in fig.texts]
    for ax in fig.axes:
        texts += [ax.get_title()] + [t.get_text() for t in ax.texts]
        if ax.get_legend() is not None:
            texts += [t.get_text() for t in ax.get_legend().get_texts()]
    for legend in fig.legends:
        texts += [t.get_text() for t in legend.get_texts()]
    return texts


class PlotAxesTest(unittest.TestCase):
    def test_informative_and_scales(self):
        self.assertFalse(plot_axes.informative([np.zeros(5), np.full(3, np.nan)]))
        self.assertTrue(plot_axes.informative([np.zeros(5), [0.0, 1e-12]]))
        self.assertEqual(plot_axes.scale_for([[1.0, 2.0, 5e3]]), "log")      # 3.7 decades
        self.assertEqual(plot_axes.scale_for([[1.0, 2.0, 5e2]]), "linear")   # 2.7 decades
        self.assertEqual(plot_axes.scale_for([[-1.0, 0.0, 1e13]]), "symlog")
        self.assertEqual(plot_axes.scale_for([[np.nan, 1.0]]), "linear")
        self.assertAlmostEqual(plot_axes.span_decades([[1e-3, 0.0, -10.0]]), 4.0)

    def test_figure_legend_is_inside_the_figure_and_below_the_panels(self):
        fig, axes = plt.subplots(2, 2, figsize=(12.8, 8))
        handles = [plt.Line2D([], [], color=f"C{k}") for k in range(7)]
        labels = [f"name=xpbd, iterations={k}, " + "a long note on where this line leaves the axis " * 3
                  for k in range(7)]
        legend = plot_axes.figure_legend(fig, handles, labels)
        self.assertTrue(plot_axes.inside_figure(fig, legend))
        renderer = fig.canvas.get_renderer()
        top = legend.get_window_extent(renderer).y1
        for ax in axes.flat:
            self.assertGreaterEqual(ax.get_tightbbox(renderer).y0, top - 1, "the legend covers no panel")
        plt.close(fig)

    def test_outliers_are_named_in_the_panel(self):
        fig, ax = plt.subplots()
        text = plot_axes.name_outliers(ax, ["boom: up to 2.5e4 J, off the axis"])
        self.assertEqual(text.get_text(), "boom: up to 2.5e4 J, off the axis")
        self.assertIsNone(plot_axes.name_outliers(ax, []))
        plt.close(fig)


def regress_columns(cases, metrics, changes):
    rows = [(c, m) for c in cases for m in metrics]
    verdicts = ["worse" if d > 1 else "better" if d < -1 else "same" for d in changes]
    return {"case": [c for c, _ in rows], "metric": [m for _, m in rows], "units": ["1"] * len(rows),
            "verdict": verdicts, "baseline": [1.0] * len(rows), "now": [1.0 + d for d in changes],
            "change": list(changes), "allowed": [1.0] * len(rows)}


class PlotRegressTest(unittest.TestCase):
    METRICS = ["energy_drift", "constraint_error_max", "volume_drift", "penetration", "momentum", "stretch"]

    def test_nothing_moved_is_said_in_words_not_as_empty_bars(self):
        cases = [f"case_{k:02d}" for k in range(22)]
        fig = plot_regress.figure(regress_columns(cases, self.METRICS, [0.0] * 132))
        self.assertEqual(zero_panels(fig), [])
        self.assertLess(fig.get_figheight(), 4.0)
        self.assertTrue(any("132 metrics of 22 cases" in t for t in fig_texts(fig)), fig_texts(fig))
        plt.close(fig)

    def test_changes_far_inside_the_tolerance_still_show(self):
        # The quick tier's regress.png: 6 metrics moved by 1e-13 to 6e-12 of their tolerance
        # (rounding), 94 not at all, 32 not measured by their case (NaN).
        cases = [f"case_{k:02d}" for k in range(22)]
        changes = [0.0] * 132
        changes[:3] = [5.9e-12, 3.3e-13, -1.1e-13]
        changes[100:] = [float("nan")] * 32
        fig = plot_regress.figure(regress_columns(cases, self.METRICS, changes))
        ax = fig.axes[0]
        self.assertEqual(len(ax.patches), 3)
        self.assertGreater(max(abs(p.get_width()) for p in ax.patches) / ax.get_xlim()[1], 0.5,
                           "the largest bar spans most of its half of the axis")
        self.assertIn("32 not measured", ax.get_title())
        plt.close(fig)

    def test_many_cases_stay_readable(self):
        rng = np.random.default_rng(1)
        for n in (3, 40, 500):
            cases = [f"case_{k:03d}" for k in range(n)]
            changes = rng.normal(0.0, 2.0, n * len(self.METRICS))
            fig = plot_regress.figure(regress_columns(cases, self.METRICS, changes))
            ax = fig.axes[0]
            self.assertLessEqual(len(ax.patches), plot_regress.MAX_BARS, n)
            self.assertLessEqual(fig.get_figheight() * 110, 1100, f"{n} cases: the figure's height is bounded")
            self.assertGreaterEqual(min(t.get_fontsize() for t in ax.get_yticklabels()), 8)
            self.assertEqual(zero_panels(fig), [])
            # The largest change is among the bars, and what is left out is counted.
            biggest = max(abs(changes))
            self.assertAlmostEqual(max(abs(p.get_width()) for p in ax.patches), min(biggest, plot_regress.CLIP))
            if n * len(self.METRICS) > plot_regress.MAX_BARS:
                self.assertIn("more moved", ax.get_title())
            plt.close(fig)


class PlotCompareTest(unittest.TestCase):
    def test_a_support_force_of_zeros_takes_no_panel(self):
        path = write_compare(os.path.join(TMP, "nothing_pinned.h5"))
        with h5py.File(path, "r+") as f:
            f["compare/observables/support_force_run"][...] = 0.0
            f["compare/observables/support_force_reference"][...] = 0.0
        fig = plot_compare.figure(plot_compare.load(path))
        titles = [ax.get_title() for ax in fig.axes]
        self.assertNotIn("|support force|", titles)
        self.assertEqual(len(titles), 3, titles)
        self.assertEqual(zero_panels(fig), [])
        plt.close(fig)

    def test_identical_positions_are_said_in_the_title(self):
        path = write_compare(os.path.join(TMP, "same.h5"), observables=False, zero_error=True)
        fig = plot_compare.figure(plot_compare.load(path))
        self.assertIn("identical", fig._suptitle.get_text())
        self.assertEqual([ax.get_title() for ax in fig.axes], ["total energy, run - reference"])
        plt.close(fig)


@unittest.skipIf(FIXTURE is None, "PBDBENCH_FIXTURE not set")
class PlotRunsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        d = os.path.join(TMP, "runs")
        os.makedirs(d, exist_ok=True)
        cls.xpbd10 = fixture(os.path.join(d, "xpbd10.h5"), "--solver", "xpbd", "--iterations", 10)
        cls.xpbd20 = fixture(os.path.join(d, "xpbd20.h5"), "--solver", "xpbd", "--iterations", 20)
        cls.refbe = fixture(os.path.join(d, "refbe.h5"), "--solver", "ref-be", "--iterations", 10)
        cls.spike = fixture(os.path.join(d, "spike.h5"), "--solver", "xpbd", "--iterations", 40)
        # One run's total energy jumps to 25,000 J for a row, as a cloth run did in the default study.
        with h5py.File(cls.spike, "r+") as f:
            e = f["series/total_energy"]
            e[len(e) // 2] = 2.5e4

    def test_labels_name_only_the_keys_a_solver_reads(self):
        reads = runfile.solver_reads()
        if reads is None:
            self.skipTest("no pbdbench with list --solver-keys")
        self.assertIn("solver.iterations", reads[1]["xpbd"])
        self.assertNotIn("solver.iterations", reads[1]["ref-be"])
        runs = [runfile.load(p, frames=False, model=False) for p in (self.xpbd10, self.xpbd20, self.refbe)]
        labels = plot_runs.run_labels(runs)
        self.assertEqual(labels[:2], ["name=xpbd, iterations=10", "name=xpbd, iterations=20"])
        self.assertEqual(labels[2], "name=ref-be")

    def test_the_legend_is_inside_the_figure(self):
        runs = [runfile.load(p, frames=False, model=False)
                for p in (self.xpbd10, self.xpbd20, self.refbe, self.spike)]
        for chosen in (None, ["total_energy"], ["total_energy", "kinetic_energy", "constraint_error_max"]):
            # Four panels: below them; one: below it; three: in the grid's free cell.
            fig = plot_runs.figure(runs, series=chosen, title="hanging_cloth: PBD and XPBD")
            legends = fig.legends + [ax.get_legend() for ax in fig.axes if not ax.axison]
            self.assertEqual(len(legends), 1, chosen)
            legend = legends[0]
            self.assertTrue(plot_axes.inside_figure(fig, legend), chosen)
            renderer = fig.canvas.get_renderer()
            box = legend.get_window_extent(renderer)
            for ax in fig.axes:
                if ax.axison:  # no panel under the legend
                    self.assertFalse(ax.get_window_extent(renderer).overlaps(box), (chosen, ax.get_title()))
            self.assertEqual(zero_panels(fig), [])
            self.assertEqual([ax for ax in fig.axes if not ax.axison and ax.get_legend() is None], [],
                             "no empty cell")
            plt.close(fig)
        # Labels of 63 characters on one panel: three columns of them were 1.44 times the figure's
        # width, and the legend was cut off on both sides.
        long_labels = [f"name=xpbd, iterations={k}, substeps={k}, order=gauss-seidel, seed=1" for k in range(4)]
        with unittest.mock.patch.object(plot_runs, "run_labels", lambda runs_: long_labels[:len(runs_)]):
            fig = plot_runs.figure(runs, series=["total_energy"])
        self.assertTrue(plot_axes.inside_figure(fig, fig.legends[0]))
        plt.close(fig)

    def test_a_spike_is_named_not_left_to_flatten_the_others(self):
        runs = [runfile.load(p, frames=False, model=False)
                for p in (self.xpbd10, self.xpbd20, self.refbe, self.spike)]
        fig = plot_runs.figure(runs)
        energy = next(ax for ax in fig.axes if ax.get_title() == "energy")
        self.assertLess(energy.get_ylim()[1], 5e3, "the spike does not set the axis (the others reach 3.2e3 J)")
        notes = [t.get_text() for t in energy.texts]
        self.assertTrue(any("iterations=40" in n and "2.50e+04" in n for n in notes), notes)
        plt.close(fig)


@unittest.skipIf(FIXTURE is None, "PBDBENCH_FIXTURE not set")
class PlotClaimsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = os.path.join(TMP, "claims")
        os.makedirs(os.path.join(cls.dir, "runs"), exist_ok=True)
        fixture(os.path.join(cls.dir, "runs", "calm.h5"), "--solver", "xpbd")
        boom = fixture(os.path.join(cls.dir, "runs", "boom.h5"), "--solver", "pbd-seed")
        fixture(os.path.join(cls.dir, "runs", "static.h5"), "--solver", "ref-static", "--rows", 2)
        with h5py.File(boom, "r+") as f:  # a volume that grows to 1e13, as S3.3's listing run did
            v = f["series/kinetic_energy"]
            v[...] = np.geomspace(1.0, 1e13, len(v))

        def claim(cid, kind, **figure):
            base = {"kind": kind, "series": "", "runs": [], "measures": [], "log": False, "ylabel": "",
                    "title": ""}
            base.update(figure)
            return {"id": cid, "verdict": "mixed", "figure": base,
                    "runs": [{"name": "calm", "files": ["runs/calm.h5"]}, {"name": "boom", "files": ["runs/boom.h5"]},
                             {"name": "static", "files": ["runs/static.h5"]}],
                    "measures": [{"name": "e_0", "value": 0}, {"name": "e_01", "value": 0},
                                 {"name": "e_03", "value": 0}, {"name": "small", "value": 1e-3},
                                 {"name": "large", "value": 12.0}]}
        cls.claims = {
            "zeros": claim("S3.4", "bars", measures=["e_0", "e_01", "e_03"], ylabel="effective restitution",
                           title="restitution 0, 0.1 and 0.3"),
            "decades": claim("B", "bars", measures=["small", "large", "e_0"], title="bars over decades"),
            "series": claim("S3.3", "series", series="kinetic_energy", runs=["calm", "boom"],
                            title="A tet block of {tets} tets, 12,800 StVK tets in the paper's words"),
            "level": claim("L", "series", series="kinetic_energy", runs=["calm", "static"], title="with a static run"),
        }
        with open(os.path.join(cls.dir, "claims.json"), "w") as f:
            json.dump({"claims": list(cls.claims.values())}, f)

    def test_bars_of_zeros_are_written_as_values(self):
        fig, drawn = plot_claims.claim_figure(self.claims["zeros"], self.dir)
        self.assertEqual(drawn, 3)
        self.assertEqual(zero_panels(fig), [])
        self.assertTrue(any("e_01 = 0" in t for t in fig_texts(fig)))
        plt.close(fig)

    def test_values_over_decades_get_a_log_axis(self):
        fig, _ = plot_claims.claim_figure(self.claims["series"], self.dir)
        self.assertEqual(fig.axes[0].get_yscale(), "log")
        plt.close(fig)
        fig, _ = plot_claims.claim_figure(self.claims["decades"], self.dir)
        self.assertEqual(fig.axes[0].get_yscale(), "symlog", "1e-3 to 12 beside a 0: four decades")
        plt.close(fig)

    def test_a_run_of_two_rows_is_a_level_across_the_axis(self):
        fig, drawn = plot_claims.claim_figure(self.claims["level"], self.dir)
        self.assertEqual(drawn, 2)
        ax = fig.axes[0]
        level = [line for line in ax.get_lines() if line.get_label() == "static (final state)"]
        self.assertEqual(len(level), 1)
        self.assertEqual(list(level[0].get_xdata()), [0, 1], "it spans the axis")
        plt.close(fig)

    def test_the_title_says_what_ran(self):
        fig, _ = plot_claims.claim_figure(self.claims["series"], self.dir)
        title = fig.axes[0].get_title()
        self.assertIn("A tet block of 1 tets", title)
        self.assertNotIn("12,800", title)
        self.assertIn("1 StVK tets", title)
        plt.close(fig)

    def test_the_script_draws_them(self):
        r = subprocess.run(["/usr/bin/python3", os.path.join(SCRIPTS, "plot_claims.py"), self.dir],
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("the title says 12,800 tets, the runs have 1", r.stderr)
        for cid in ("S3.4", "B", "S3.3", "L"):
            self.assertTrue(os.path.getsize(os.path.join(self.dir, "figures", cid + ".png")) > 1000)


if __name__ == "__main__":
    unittest.main()
