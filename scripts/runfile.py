#!/usr/bin/python3
"""Loads pbdbench's HDF5 files: run files, compare, convergence and regression files (the
layouts are in results/README.md and in runfile/*.hpp, which write them). Scripts read these
files through this module, never with h5py directly.

    import runfile
    run = runfile.load("results/pendulum/xpbd.h5")
    run.status                      # "complete", "exploded", "failed" or "incomplete"
    run.series["constraint_error_max"], run.units["constraint_error_max"]
    run.config["solver"]["iterations"]
    runfile.label(run, ["solver.name", "solver.iterations"])   # "name=xpbd, iterations=10"

    cmp = runfile.load_compare("out/compare.h5")     # pbdbench compare
    cmp.data["position_error_max"], cmp.diff["total_energy"], cmp.observables
    conv = runfile.load_converge("out/converge.h5")  # pbdbench converge
    for key, method in conv.methods: method["residual"], method["attrs"]["converged"]
    reg = runfile.load_regress("out/regress.h5")     # pbdbench regress
    reg.rows[0]["case"], reg.columns["change"]
    runfile.load_any(path)                           # whichever of the four it is

Every dataset under /series is read, whatever its name, so a series added to the writer needs
no change here (likewise the datasets of the other kinds). An incomplete file (a run still
going, or killed) loads like any other: its series end at the writer's last flush.

Depends on numpy and h5py only; runs under /usr/bin/python3 (Python 3.11: tomllib).
"""
import json
import os
import shutil
import subprocess
import sys
import tomllib

import h5py
import numpy as np

__all__ = ["Run", "Compare", "Converge", "Regress", "RunFileError", "load", "load_viz", "is_viz",
           "without_viz",
           "load_compare", "load_converge", "load_regress", "load_any", "kind", "status_of",
           "label", "differing_keys", "config_value", "format_value", "solver_reads", "keys_read",
           "find_pbdbench"]


class RunFileError(Exception):
    """A file of the project that is missing, cannot be read or is not of the kind asked for;
    the message names the path."""


class Run:
    """One run file, loaded.

    path        the file
    attrs       every root attribute (str, int or float)
    status      attrs["status"]
    config      the resolved configuration (the `config` attribute parsed as TOML; {} if absent
                or unparsable, with config_error saying why)
    series      name -> numpy array, (rows,) or (rows, 3), float64
    units, docs name -> the dataset's `units` / `doc` attribute
    deterministic  name -> bool (False for wall-clock timings)
    rows        the number of rows (the shortest series)
    frame_time  (F,) s, or None
    frames      (F, n, 3) m positions, or None (load(..., frames=False) skips them)
    velocities  (F, n, 3) m/s velocities of the same frames, or None (older files, frames=False)
    warnings    the run's warnings (metrics/health.hpp), one string each; [] when none
    model       name -> numpy array of /model, plus "group_names" (list of str) and
                "constraint_kind_names"
    """

    def __init__(self, path):
        self.path = str(path)
        self.attrs = {}
        self.config = {}
        self.config_error = None
        self.series = {}
        self.units = {}
        self.docs = {}
        self.deterministic = {}
        self.frame_time = None
        self.frames = None
        self.velocities = None
        self.model = {}

    @property
    def status(self):
        return self.attrs.get("status", "incomplete")

    @property
    def warnings(self):
        text = self.attrs.get("warnings", "")
        return [line for line in text.split("\n") if line] if isinstance(text, str) else []

    @property
    def rows(self):
        return min((len(v) for v in self.series.values()), default=0)

    @property
    def exploded(self):
        return self.status == "exploded"

    @property
    def name(self):
        return os.path.splitext(os.path.basename(self.path))[0]

    def __repr__(self):
        return f"Run({self.path!r}, status={self.status!r}, rows={self.rows})"


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return value


def _attr_value(value):
    """An HDF5 attribute as a plain Python value."""
    value = _text(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "OSU":
            return [_text(v) for v in value.tolist()]
        return value
    if isinstance(value, np.generic):
        return value.item()
    return value


def load(path, frames=True, model=True):
    """Reads a run file. Raises RunFileError naming the path when it is missing or unreadable."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise RunFileError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise RunFileError(f"{path}: cannot open as HDF5: {e}") from e
    run = Run(path)
    try:
        with f:
            run.attrs = {k: _attr_value(v) for k, v in f.attrs.items()}
            text = run.attrs.get("config")
            if isinstance(text, str) and text:
                try:
                    run.config = tomllib.loads(text)
                except tomllib.TOMLDecodeError as e:
                    run.config_error = str(e)
            if "series" in f:
                for name, ds in f["series"].items():
                    if not isinstance(ds, h5py.Dataset):
                        continue
                    run.series[name] = np.asarray(ds[()], dtype=float)
                    run.units[name] = _text(ds.attrs.get("units", ""))
                    run.docs[name] = _text(ds.attrs.get("doc", ""))
                    run.deterministic[name] = bool(ds.attrs.get("deterministic", 1))
            if "frames" in f:
                if "time" in f["frames"]:
                    run.frame_time = np.asarray(f["frames/time"][()], dtype=float)
                if frames and "positions" in f["frames"]:
                    run.frames = np.asarray(f["frames/positions"][()], dtype=float)
                if frames and "velocities" in f["frames"]:
                    run.velocities = np.asarray(f["frames/velocities"][()], dtype=float)
            if model and "model" in f:
                g = f["model"]
                for name, ds in g.items():
                    if isinstance(ds, h5py.Dataset):
                        run.model[name] = ds[()]
                run.model["group_names"] = [_text(v) for v in g.attrs.get("group_names", [])]
                if "constraint_kind" in g:
                    run.model["constraint_kind_names"] = [
                        _text(v) for v in g["constraint_kind"].attrs.get("kind_names", [])]
    except (OSError, KeyError, ValueError) as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e
    return run


def config_value(run, key, default=None):
    """A configuration value by dotted key ("solver.iterations"); falls back to a root
    attribute of the same name ("solver", "scenario", "dt")."""
    node = run.config
    for part in key.split("."):
        if isinstance(node, dict) and part in node:
            node = node[part]
        else:
            node = None
            break
    if node is not None:
        return node
    return run.attrs.get(key, default)


def _flatten(table, prefix=""):
    out = {}
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def differing_keys(runs):
    """The dotted configuration keys whose values are not the same in every run, in the order
    they first appear."""
    flat = [_flatten(r.config) for r in runs]
    keys = []
    for f in flat:
        for k in f:
            if k not in keys:
                keys.append(k)
    missing = object()
    return [k for k in keys if len({repr(f.get(k, missing)) for f in flat}) > 1]


def find_pbdbench(given=None):
    """The pbdbench executable: `given`, $PBDBENCH_BIN, pbdbench on the PATH, or the build
    folder's (build/pbdbench beside scripts/); None when there is none."""
    here = os.path.dirname(os.path.abspath(__file__))
    for candidate in (given, os.environ.get("PBDBENCH_BIN"), shutil.which("pbdbench"),
                      os.path.join(here, "..", "build", "pbdbench")):
        if candidate and os.path.isfile(candidate) and os.access(candidate, os.X_OK):
            return candidate
    return None


_SOLVER_READS = {}


def solver_reads(pbdbench=None):
    """Which solver options each solver reads, from the solver catalogue (`pbdbench list
    --solver-keys`): (every solver option key, {solver name: set of the keys it reads}); None
    when no pbdbench is found or it cannot say (an older build)."""
    exe = find_pbdbench(pbdbench)
    if exe is None:
        return None
    if exe not in _SOLVER_READS:
        try:
            p = subprocess.run([exe, "list", "--solver-keys"], capture_output=True, text=True, timeout=60)
            table = json.loads(p.stdout) if p.returncode == 0 else None
            _SOLVER_READS[exe] = (set(table["keys"]), {k: set(v) for k, v in table["reads"].items()})
        except (OSError, ValueError, KeyError, TypeError, subprocess.TimeoutExpired):
            _SOLVER_READS[exe] = None
    return _SOLVER_READS[exe]


def keys_read(run, keys, reads=None):
    """The keys of `keys` that the run's solver reads: a solver option (solver.iterations, ...)
    that its solver does not read (ref-be's iterations) is left out; every other key is kept.
    `reads`: solver_reads()'s answer (looked up when None); without it every key is kept."""
    reads = solver_reads() if reads is None else reads
    if not reads:
        return list(keys)
    options, by_solver = reads
    solver = config_value(run, "solver.name") or run.attrs.get("solver")
    mine = by_solver.get(solver)
    if mine is None:
        return list(keys)
    return [k for k in keys if k not in options or k in mine]


def format_value(value):
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    return str(value)


def label(run, keys):
    """A legend label from the values of `keys` in this run ("name=xpbd, iterations=10"):
    each key is shown by its last component, or in full when two keys share it. With no keys,
    the file name."""
    keys = list(keys)
    if not keys:
        return run.name
    last = [k.split(".")[-1] for k in keys]
    parts = []
    for k, short in zip(keys, last):
        shown = short if last.count(short) == 1 else k
        parts.append(f"{shown}={format_value(config_value(run, k, '?'))}")
    return ", ".join(parts)


def is_viz(path):
    """Whether the file is a run's ParaView data file (RUN.viz.h5: its root attribute
    `pbdbench_viz`), which `pbdbench run` writes beside the run file."""
    try:
        with h5py.File(os.fspath(path), "r") as f:
            return "pbdbench_viz" in f.attrs
    except OSError:
        return False


def without_viz(paths, program):
    """`paths` without the ParaView data files among them (a folder's *.h5 holds each run's
    RUN.viz.h5 beside RUN.h5), passed over silently: skipping them is by design, and a line per
    run would read like a failure. `program` is kept for the callers' signature."""
    del program
    return [p for p in paths if not is_viz(p)]


def load_viz(path):
    """The fields of a run's ParaView export (RUN.viz.h5, written by `pbdbench run` or
    `pbdbench export RUN.h5`; runfile/xdmf.hpp): name -> numpy array. Its datasets (edges,
    triangles, tets, mixed, inv_mass, pinned, collider_triangles), and the per-frame data gathered
    over the frames: collider_points (F, or 1 when the colliders do not move; P, 3), and the cell
    fields split by cell type (the export stores them per frame for all cells, tets, then
    triangles, then edges): edge_strain, edge_constraint_error, triangle_area_change,
    triangle_constraint_error, tet_volume_change, tet_constraint_error, each (F, cells).
    Raises RunFileError."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise RunFileError(f"{path}: no such file")
    try:
        with h5py.File(path, "r") as f:
            out = {name: ds[()] for name, ds in f.items() if isinstance(ds, h5py.Dataset)}
            frames = f.get("frames")
            if not isinstance(frames, h5py.Group):
                return out
            names = sorted(frames)
            counts = [len(out.get(k, ())) for k in ("tets", "triangles", "edges")]
            bounds = np.cumsum([0] + counts)
            for field, per_kind in (("change", ("tet_volume_change", "triangle_area_change", "edge_strain")),
                                    ("constraint_error", ("tet_constraint_error", "triangle_constraint_error",
                                                          "edge_constraint_error"))):
                rows = np.array([frames[n][field][()] for n in names if field in frames[n]], dtype=float)
                if len(rows) != len(names):
                    continue
                rows = rows.reshape(len(names), -1)
                for k, name in enumerate(per_kind):
                    out[name] = rows[:, bounds[k]:bounds[k + 1]]
            colliders = [frames[n]["collider_points"][()] for n in names if "collider_points" in frames[n]]
            if colliders:
                out["collider_points"] = np.array(colliders, dtype=float)
            return out
    except (OSError, KeyError) as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e


# ---------------------------------------------------------------------------------------------
# The other kinds of file: compare (runfile/compare_file.hpp), convergence
# (runfile/converge_file.hpp) and regression (runfile/regress_file.hpp).

def _open(path):
    """The file opened with h5py (to be used in a with statement). Raises RunFileError."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise RunFileError(f"{path}: no such file")
    try:
        return h5py.File(path, "r")
    except OSError as e:
        raise RunFileError(f"{path}: cannot open as HDF5: {e}") from e


def _attrs(obj):
    return {k: _attr_value(v) for k, v in obj.attrs.items()}


def _dataset(ds):
    """A dataset as a numpy array, a scalar dataset as a float, strings as a list of str."""
    value = ds[()]
    if ds.shape == ():
        return _attr_value(value)
    if ds.dtype.kind in "OSU":
        return [_text(v) for v in value.tolist()]
    return np.asarray(value)


class Compare:
    """A compare file (pbdbench compare), loaded.

    path         the file
    attrs        every root attribute
    run, reference  the two runs' root attributes run_<key> / reference_<key>, by key (file,
                 solver, scenario, status, config, git_commit)
    warnings     attrs["warnings"], one string each
    data         name -> array, every dataset directly under /compare (time,
                 position_error_rms, position_error_max, series_time, run_frame,
                 reference_frame, ... when present)
    diff         series name -> (rows,) run - reference (|run - reference| for 3-vectors)
    diff_units   series name -> its units
    observables  name -> array, or float for the scalars (pendulum periods)
    """

    def __init__(self, path):
        self.path = str(path)
        self.attrs = {}
        self.data = {}
        self.diff = {}
        self.diff_units = {}
        self.observables = {}

    def _prefixed(self, prefix):
        return {k[len(prefix):]: v for k, v in self.attrs.items() if k.startswith(prefix)}

    @property
    def run(self):
        return self._prefixed("run_")

    @property
    def reference(self):
        return self._prefixed("reference_")

    @property
    def warnings(self):
        text = self.attrs.get("warnings", "")
        return [line for line in text.split("\n") if line] if isinstance(text, str) else []

    def __repr__(self):
        return f"Compare({self.path!r}, frames={len(self.data.get('time', []))})"


def load_compare(path):
    """Reads a compare file. Raises RunFileError naming the path when it is missing, unreadable
    or not a compare file (no /compare)."""
    path = os.fspath(path)
    out = Compare(path)
    try:
        with _open(path) as f:
            if "compare" not in f:
                raise RunFileError(f"{path}: not a compare file (no /compare)")
            out.attrs = _attrs(f)
            g = f["compare"]
            for name, obj in g.items():
                if isinstance(obj, h5py.Dataset):
                    out.data[name] = _dataset(obj)
            if "diff" in g:
                for name, ds in g["diff"].items():
                    out.diff[name] = _dataset(ds)
                    out.diff_units[name] = _text(ds.attrs.get("units", ""))
            if "observables" in g:
                for name, ds in g["observables"].items():
                    out.observables[name] = _dataset(ds)
    except (OSError, KeyError, ValueError) as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e
    return out


class Converge:
    """A convergence file (pbdbench converge), loaded.

    path     the file
    attrs    every root attribute (scene, dt, tolerance, methods, machine, ...)
    methods  [(key, method)] in the file's order (attrs["methods"]); method: name -> float
             array (iteration, residual, time, and error or inner_iterations), plus "attrs" (the
             group's attributes: method, iteration_kind, xpbd, converged, final_error)
    """

    def __init__(self, path):
        self.path = str(path)
        self.attrs = {}
        self.methods = []

    def method(self, key):
        """The method of this key, or None."""
        return next((m for k, m in self.methods if k == key), None)

    def __repr__(self):
        return f"Converge({self.path!r}, methods={[k for k, _ in self.methods]})"


def load_converge(path):
    """Reads a convergence file. Raises RunFileError naming the path when it is missing,
    unreadable or not a convergence file."""
    path = os.fspath(path)
    out = Converge(path)
    try:
        with _open(path) as f:
            out.attrs = _attrs(f)
            if out.attrs.get("content") != "pbdbench converge":
                raise RunFileError(f"{path}: not a convergence file")
            for key in [k for k in str(out.attrs.get("methods", "")).split(",") if k]:
                g = f[key]
                m = {name: np.asarray(ds[()], dtype=float) for name, ds in g.items()}
                m["attrs"] = _attrs(g)
                out.methods.append((key, m))
    except (OSError, KeyError, ValueError) as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e
    return out


# The regression file's columns, in its order: strings, then numbers.
REGRESS_TEXT_COLUMNS = ("case", "metric", "units", "verdict")
REGRESS_NUMBER_COLUMNS = ("baseline", "now", "change", "allowed")


class Regress:
    """A regression file (regress.h5 of pbdbench regress), loaded.

    path     the file
    columns  name -> list of str (case, metric, units, verdict) or float array (baseline, now,
             change, allowed), one entry per row
    rows     one dict per (case, metric): the same names -> one value
    """

    def __init__(self, path):
        self.path = str(path)
        self.columns = {}

    @property
    def rows(self):
        n = len(self.columns.get("case", []))
        return [{k: v[i] if isinstance(v, list) else float(v[i]) for k, v in self.columns.items()}
                for i in range(n)]

    def __repr__(self):
        return f"Regress({self.path!r}, rows={len(self.columns.get('case', []))})"


def load_regress(path):
    """Reads a regression file. Raises RunFileError naming the path when it is missing,
    unreadable, or a column is missing or of another length."""
    path = os.fspath(path)
    out = Regress(path)
    try:
        with _open(path) as f:
            for name in REGRESS_TEXT_COLUMNS + REGRESS_NUMBER_COLUMNS:
                if name not in f:
                    raise RunFileError(f"{path}: not a regression file (no column {name})")
                ds = f[name]
                out.columns[name] = ([_text(v) for v in ds[()].tolist()]
                                     if name in REGRESS_TEXT_COLUMNS
                                     else np.asarray(ds[()], dtype=float))
            lengths = {len(v) for v in out.columns.values()}
            if len(lengths) > 1:
                raise RunFileError(f"{path}: the columns differ in length ({sorted(lengths)})")
    except (OSError, KeyError, ValueError) as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e
    return out


def kind(path):
    """"run", "compare", "converge" or "regress": which of the project's files this is. Raises
    RunFileError when it is none of them."""
    path = os.fspath(path)
    try:
        with _open(path) as f:
            content = _text(f.attrs.get("content", ""))
            if content == "pbdbench converge":
                return "converge"
            if content == "pbdbench compare" or "compare" in f:
                return "compare"
            if "series" in f or "status" in f.attrs:
                return "run"
            if all(name in f for name in REGRESS_TEXT_COLUMNS + REGRESS_NUMBER_COLUMNS):
                return "regress"
    except OSError as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e
    raise RunFileError(f"{path}: not a pbdbench file (run, compare, converge or regress)")


def load_any(path, **options):
    """Loads whichever kind of file this is (kind()); options go to load() for a run file."""
    return {"run": lambda: load(path, **options), "compare": lambda: load_compare(path),
            "converge": lambda: load_converge(path), "regress": lambda: load_regress(path)}[
        kind(path)]()


def status_of(path):
    """A run file's status attribute alone (cheap: no series read); "" when it has none.
    Raises RunFileError."""
    path = os.fspath(path)
    try:
        with _open(path) as f:
            return str(_attr_value(f.attrs.get("status", "")))
    except OSError as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e
