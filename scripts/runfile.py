#!/usr/bin/python3
"""Loads pbdbench run files (HDF5; the layout is in results/README.md).

    import runfile
    run = runfile.load("results/pendulum/xpbd.h5")
    run.status                      # "complete", "exploded", "failed" or "incomplete"
    run.series["constraint_error_max"], run.units["constraint_error_max"]
    run.config["solver"]["iterations"]
    runfile.label(run, ["solver.name", "solver.iterations"])   # "name=xpbd, iterations=10"

Every dataset under /series is read, whatever its name, so a series added to the writer needs
no change here. An incomplete file (a run still going, or killed) loads like any other: its
series end at the writer's last flush.

Depends on numpy and h5py only; runs under /usr/bin/python3 (Python 3.11: tomllib).
"""
import os
import tomllib

import h5py
import numpy as np

__all__ = ["Run", "RunFileError", "load", "load_viz", "label", "differing_keys", "config_value",
           "format_value"]


class RunFileError(Exception):
    """A run file that is missing or cannot be read; the message names the path."""


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


def load_viz(path):
    """The fields of a run's ParaView export (RUN.viz.h5, written by `pbdbench run` or
    `pbdbench export RUN.h5`; runfile/xdmf.hpp): name -> numpy array (edges, triangles, tets,
    collider_points (F or 1, P, 3), collider_triangles, displacement, inv_mass, pinned, and per
    frame and cell edge_strain, edge_constraint_error, triangle_area_change,
    triangle_constraint_error, tet_volume_change, tet_constraint_error). Raises RunFileError."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise RunFileError(f"{path}: no such file")
    try:
        with h5py.File(path, "r") as f:
            return {name: ds[()] for name, ds in f.items() if isinstance(ds, h5py.Dataset)}
    except OSError as e:
        raise RunFileError(f"{path}: cannot read: {e}") from e
