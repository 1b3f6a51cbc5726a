#!/usr/bin/python3
"""Animates run files side by side: the motion, the colliders, elements coloured by a field.

    animate.py RUN.h5 [RUN2.h5 ...] -o OUT.mp4|OUT.gif [--field constraint_error] [--view xy]
               [--fps N] [--pbdbench PATH]

Each run gets a panel, labelled with the configuration keys whose values differ between the runs
(solver name, iterations, ...), its status and its warnings; the simulated time is in the title.
The panels share their axes: the bounds of the runs that did not explode (an exploded run's
particles fly off the panel rather than shrink the others).

Elements are coloured by a per-element field of the run's ParaView export (RUN.viz.h5,
runfile/xdmf.hpp): "constraint_error" (the default), "change" (edge strain, triangle area
change, tet volume change), or "none". A run without its export gets one from
`pbdbench export` (--pbdbench, $PBDBENCH_BIN, or pbdbench on the PATH). Tets are drawn by their
faces, triangles as faces, edges (chains, springs, distance constraints) as lines; planes,
spheres and bowls in grey, moving with their motion.

--view: the plane to project on, "xy", "xz" or "zy" (default: the one holding gravity and the
model's widest horizontal axis), or "3d": a perspective view (the body's outer faces shaded by
the field, its edges, the colliders), --elev and --azim degrees. Each panel is shaped like what
it shows (the runs' bounds), so the body fills the frame rather than a strip of it. Frames
follow the first run's frame times; the others show their frame at or before that time. --fps defaults to real time (the frame spacing), at most 60;
when the frames are sparser than 1/30 s the script says how to ask for more
(--set output.frame_every=1).

MP4 needs ffmpeg (Debian's, installed by scripts/install_deps.sh); GIF uses Pillow.
"""
import argparse
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import animation  # noqa: E402
from matplotlib.collections import LineCollection, PolyCollection  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import runfile  # noqa: E402

AXES = {"x": 0, "y": 1, "z": 2}
FIELDS = {
    "constraint_error": ("edge_constraint_error", "triangle_constraint_error", "tet_constraint_error"),
    "change": ("edge_strain", "triangle_area_change", "tet_volume_change"),
}


find_pbdbench = runfile.find_pbdbench


def viz_of(path, pbdbench):
    """The run's export (RUN.viz.h5), made with `pbdbench export` when missing or older."""
    viz = os.path.splitext(path)[0] + ".viz.h5"
    if not os.path.isfile(viz) or os.path.getmtime(viz) < os.path.getmtime(path):
        exe = find_pbdbench(pbdbench)
        if exe is None:
            raise SystemExit(f"animate.py: {viz} is missing and no pbdbench was found to export it "
                             "(--pbdbench PATH or $PBDBENCH_BIN)")
        p = subprocess.run([exe, "export", path], capture_output=True, text=True)
        if p.returncode != 0:
            raise SystemExit(f"animate.py: pbdbench export {path} failed:\n{p.stderr}")
    return runfile.load_viz(viz)


def default_view(run):
    g = np.asarray(run.model.get("gravity", [0.0, -9.81, 0.0]), dtype=float)
    up = int(np.argmax(np.abs(g))) if np.any(g) else 1
    rest = np.asarray(run.model["rest_positions"], dtype=float)
    spans = rest.max(axis=0) - rest.min(axis=0) if len(rest) else np.ones(3)
    horizontal = max((k for k in range(3) if k != up), key=lambda k: spans[k])
    return horizontal, up


def frame_at(times, t):
    """The index of the last frame at or before t."""
    k = int(np.searchsorted(times, t + 1e-12, side="right")) - 1
    return max(0, min(k, len(times) - 1))


def tet_faces(tets):
    return np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]], tets[:, [1, 2, 3]]])


class Panel:
    def __init__(self, ax, run, viz, view, field, norm, cmap, label):
        self.ax, self.run, self.viz, self.view = ax, run, viz, view
        self.field, self.norm, self.cmap = field, norm, cmap
        self.times = run.frame_time
        ax.set_title(label, fontsize=8)
        ax.set_aspect("equal")
        i, j = view
        self.colliders = None
        tris = viz.get("collider_triangles")
        if tris is not None and len(tris):
            self.colliders = PolyCollection([], facecolor="0.75", edgecolor="0.6", linewidth=0.2, alpha=0.5, zorder=1)
            ax.add_collection(self.colliders)
        self.tets = np.asarray(viz.get("tets", np.zeros((0, 4), int)))
        self.tris = np.asarray(viz.get("triangles", np.zeros((0, 3), int)))
        self.edges = np.asarray(viz.get("edges", np.zeros((0, 2), int)))
        # Faces (tets, else triangles) carry the colour when the field has values on them; where
        # it has none (a cloth's triangles carry no constraint: their constraint_error is NaN),
        # the faces are drawn plain and the edges carry the colour instead.
        face_kind = "tet" if len(self.tets) else ("triangle" if len(self.tris) else None)
        self.face_coloured = face_kind is not None and self.has_values(face_kind)
        self.lines_drawn = bool(len(self.edges)) and (
            face_kind is None or (not self.face_coloured and self.has_values("edge")))
        if face_kind is None or self.face_coloured:
            self.faces = PolyCollection([], cmap=cmap, norm=norm, edgecolor="k", linewidth=0.1, zorder=2)
        else:
            self.faces = PolyCollection([], facecolor="0.92", edgecolor="0.7", linewidth=0.1, zorder=2)
        ax.add_collection(self.faces)
        self.lines = LineCollection([], cmap=cmap, norm=norm, linewidth=1.5, zorder=3)
        ax.add_collection(self.lines)
        self.points = ax.plot([], [], ".", color="k", markersize=2, zorder=4)[0]
        self.pinned = ax.plot([], [], "s", color="tab:red", markersize=3, zorder=5)[0]
        self.pinned_mask = np.asarray(viz.get("pinned", []), dtype=float) > 0
        del i, j

    def has_values(self, kind):
        """Whether the field has a value (not NaN) on some cell of this kind in some frame."""
        if self.field is None:
            return True
        v = self.viz.get(dict(zip(("edge", "triangle", "tet"), FIELDS[self.field]))[kind])
        return v is not None and bool(np.isfinite(np.asarray(v, dtype=float)).any())

    def cell_values(self, kind, f, n):
        if self.field is None:
            return np.zeros(n)
        name = dict(zip(("edge", "triangle", "tet"), FIELDS[self.field]))[kind]
        v = self.viz.get(name)
        return np.asarray(v[f], dtype=float) if v is not None and len(v) > f else np.full(n, np.nan)

    def draw(self, t):
        f = frame_at(self.times, t)
        x = self.run.frames[f]
        i, j = self.view
        p = x[:, [i, j]]
        polys, values = [], []
        if len(self.tets):
            faces = tet_faces(self.tets)
            polys.append(p[faces])
            values.append(np.tile(self.cell_values("tet", f, len(self.tets)), 4))
        elif len(self.tris):
            polys.append(p[self.tris])
            values.append(self.cell_values("triangle", f, len(self.tris)))
        if polys:
            self.faces.set_verts(list(np.concatenate(polys)))
            if self.face_coloured:
                self.faces.set_array(np.ma.masked_invalid(np.concatenate(values)))
        if self.lines_drawn:
            self.lines.set_segments(list(p[self.edges]))
            self.lines.set_array(np.ma.masked_invalid(self.cell_values("edge", f, len(self.edges))))
        self.points.set_data(p[:, 0], p[:, 1])
        if self.pinned_mask.size == len(p):
            self.pinned.set_data(p[self.pinned_mask, 0], p[self.pinned_mask, 1])
        if self.colliders is not None:
            cp = self.viz["collider_points"]
            c = cp[min(f, len(cp) - 1)] if len(cp) > 1 else cp[0]
            self.colliders.set_verts(list(c[:, [i, j]][self.viz["collider_triangles"]]))


def outer_faces(tets):
    """The faces of `tets` that belong to one tet only (the body's surface)."""
    faces = tet_faces(tets)
    key = np.sort(faces, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    keep = np.zeros(len(faces), dtype=bool)
    keep[first[count == 1]] = True
    return faces[keep], np.tile(np.arange(len(tets)), 4)[keep]


class Panel3D:
    """A run in perspective: the outer faces of its tets (else its triangles) coloured by the
    field (plain where it has no value), its edges when it has no faces, the colliders clipped
    to the panel's box."""

    def __init__(self, ax, run, viz, box, field, norm, cmap, label, elev, azim, axes=(0, 2, 1)):
        self.ax, self.run, self.viz, self.field, self.norm, self.cmap = ax, run, viz, field, norm, cmap
        self.box = box
        self.axes = list(axes)  # the model's axes drawn as the plot's x, y and z (z: up)
        self.times = run.frame_time
        ax.set_title(label, fontsize=8)
        ax.view_init(elev=elev, azim=azim)
        tets = np.asarray(viz.get("tets", np.zeros((0, 4), int)))
        tris = np.asarray(viz.get("triangles", np.zeros((0, 3), int)))
        self.edges = np.asarray(viz.get("edges", np.zeros((0, 2), int)))
        if len(tets):
            self.faces, self.owner = outer_faces(tets)
            self.kind = "tet"
        elif len(tris):
            self.faces, self.owner, self.kind = tris, np.arange(len(tris)), "triangle"
        else:
            self.faces, self.owner, self.kind = np.zeros((0, 3), int), np.zeros(0, int), None
        self.poly = Poly3DCollection([], cmap=cmap, norm=norm, edgecolor=(0, 0, 0, 0.25), linewidth=0.2)
        ax.add_collection3d(self.poly)
        self.lines = Line3DCollection([], cmap=cmap, norm=norm, linewidth=1.5)
        ax.add_collection3d(self.lines)
        self.colliders = None
        if viz.get("collider_triangles") is not None and len(viz["collider_triangles"]):
            self.colliders = Poly3DCollection([], facecolor=(0.6, 0.6, 0.6, 0.25), edgecolor=(0.5, 0.5, 0.5, 0.2),
                                              linewidth=0.2)
            ax.add_collection3d(self.colliders)

    def values(self, name, f, n):
        if self.field is None:
            return np.full(n, np.nan)
        v = self.viz.get(dict(zip(("edge", "triangle", "tet"), FIELDS[self.field]))[name])
        return np.asarray(v[f], dtype=float) if v is not None and len(v) > f else np.full(n, np.nan)

    def draw(self, t):
        f = frame_at(self.times, t)
        x = self.run.frames[f][:, self.axes]
        if len(self.faces):
            self.poly.set_verts(list(x[self.faces]))
            v = self.values(self.kind, f, int(self.owner.max()) + 1 if len(self.owner) else 0)[self.owner]
            if np.isfinite(v).any():
                self.poly.set_array(np.ma.masked_invalid(v))
            else:
                self.poly.set_facecolor((0.75, 0.8, 0.9, 1.0))
        elif len(self.edges):
            self.lines.set_segments(list(x[self.edges]))
            self.lines.set_array(np.ma.masked_invalid(self.values("edge", f, len(self.edges))))
        if self.colliders is not None:
            cp = self.viz["collider_points"]
            c = (cp[min(f, len(cp) - 1)] if len(cp) > 1 else cp[0])[:, self.axes]
            c = np.clip(c, self.box[0], self.box[1])
            self.colliders.set_verts(list(c[self.viz["collider_triangles"]]))


def bounds(runs, view, pad=0.04):
    """The axes' bounds: every frame of the runs that did not explode (all runs if each did),
    widened by `pad` of the largest span."""
    calm = [r for r in runs if not r.exploded] or runs
    pts = np.concatenate([r.frames[:, :, list(view)].reshape(-1, len(view)) for r in calm])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = pad * max(float(np.max(hi - lo)), 1e-3)
    return lo - margin, hi + margin


def widened(lo, hi, least=1.0 / 3.0):
    """The box lo..hi with each side at least `least` of the longest, about its centre: a chain
    hanging straight is a line, and its equal-aspect panel would be a strip of the frame."""
    lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
    need = least * float(np.max(hi - lo))
    for k in range(len(lo)):
        if hi[k] - lo[k] < need:
            mid = 0.5 * (lo[k] + hi[k])
            lo[k], hi[k] = mid - 0.5 * need, mid + 0.5 * need
    return lo, hi


def panel_shape(lo, hi, view3d=False):
    """(width, height) in inches of a panel that an equal-aspect drawing of the box lo..hi fills:
    its aspect ratio kept within [1/3, 3] (a very long body gets a strip, not a line)."""
    if view3d:
        return 5.0, 4.2
    w, h = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    ratio = min(3.0, max(1.0 / 3.0, w / h if h > 0 else 3.0))
    area = 18.0  # square inches a panel gets
    height = (area / ratio) ** 0.5
    return ratio * height, height


def drawn_fraction(fig):
    """The share of the figure's area covered by its panels as drawn (equal-aspect axes shrink
    to their data's shape: what an animation shows of the body)."""
    fig.canvas.draw()
    total = 0.0
    for ax in fig.axes:
        if ax.get_label() == "<colorbar>":
            continue
        bb = ax.get_position(original=False)
        total += bb.width * bb.height
    return total


def layout(runs, vizes, view, view3d, field, norm, cmap, keys, elev=20.0, azim=-60.0):
    """The figure and its panels, one per run, each shaped like the runs' bounds so that the
    body fills it; a colour bar at the right when a field colours the cells."""
    if view3d:
        # Up (against gravity) is the plot's z; the widest horizontal axis its x.
        horizontal, up = default_view(runs[0])
        axes3 = (horizontal, 3 - horizontal - up, up)
        lo, hi = bounds(runs, axes3)
    else:
        lo, hi = widened(*bounds(runs, view))
    w, h = panel_shape(lo, hi, view3d)
    bar = 0.9 if field else 0.0
    fig = plt.figure(figsize=(w * len(runs) + bar + 0.3, h + 0.9), layout="constrained")
    panels = []
    for k, (run, viz) in enumerate(zip(runs, vizes)):
        text = runfile.label(run, keys) if keys else f"{run.attrs.get('scenario', run.name)} [{run.attrs.get('solver', '?')}]"
        status = run.status if not run.warnings else f"{run.status}, {len(run.warnings)} warning(s)"
        codes = sorted({w_.split(" ")[0] for w_ in run.warnings})
        label = f"{text}\n{status}" + (f": {', '.join(codes)}" if codes else "")
        if view3d:
            ax = fig.add_subplot(1, len(runs), k + 1, projection="3d")
            panels.append(Panel3D(ax, run, viz, (lo, hi), field, norm, cmap, label, elev, azim, axes3))
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[1], hi[1])
            ax.set_zlim(lo[2], hi[2])
            ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * float(np.max(hi - lo))))
            ax.set_xlabel("xyz"[axes3[0]] + " (m)", fontsize=8)
            ax.set_ylabel("xyz"[axes3[1]] + " (m)", fontsize=8)
            ax.set_zlabel("xyz"[axes3[2]] + " (m)", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.locator_params(nbins=4)
        else:
            ax = fig.add_subplot(1, len(runs), k + 1)
            panels.append(Panel(ax, run, viz, view, field, norm, cmap, label))
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[1], hi[1])
            ax.set_xlabel("xyz"[view[0]] + " (m)")
            ax.set_ylabel("xyz"[view[1]] + " (m)")
    if field:
        sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(sm, ax=fig.axes, shrink=0.8, pad=0.02, fraction=min(0.15, 0.35 / fig.get_figwidth()),
                     label=field.replace("_", " ") + (" (strain / area / volume change)" if field == "change" else ""))
    return fig, panels


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+", help="run files (HDF5)")
    ap.add_argument("-o", "--out", required=True, help="OUT.mp4 (ffmpeg) or OUT.gif (Pillow)")
    ap.add_argument("--field", default="constraint_error", choices=["constraint_error", "change", "none"])
    ap.add_argument("--view", choices=["xy", "xz", "zy", "3d"], help="the plane to project on, or 3d")
    ap.add_argument("--elev", type=float, default=20.0, help="--view 3d: the camera's elevation (degrees)")
    ap.add_argument("--azim", type=float, default=-60.0, help="--view 3d: the camera's azimuth (degrees)")
    ap.add_argument("--fps", type=float, help="frames a second (default: real time, at most 60)")
    ap.add_argument("--pbdbench", help="the pbdbench executable, to export runs that have no RUN.viz.h5")
    ap.add_argument("--max-frames", type=int, default=0, help="draw at most this many frames (evenly spaced)")
    args = ap.parse_args(argv)

    ext = os.path.splitext(args.out)[1].lower()
    if ext not in (".mp4", ".gif"):
        ap.error(f"--out {args.out}: the name must end in .mp4 or .gif")
    if ext == ".mp4" and not animation.FFMpegWriter.isAvailable():
        raise SystemExit("animate.py: MP4 needs ffmpeg (scripts/install_deps.sh installs it); or write a .gif")
    try:
        runs = [runfile.load(p) for p in args.runs]
    except runfile.RunFileError as e:
        raise SystemExit(f"animate.py: {e}")
    for r in runs:
        if r.frames is None or r.frame_time is None or len(r.frame_time) == 0:
            raise SystemExit(f"animate.py: {r.path} has no frames")
    vizes = [viz_of(p, args.pbdbench) for p in args.runs]
    view3d = args.view == "3d"
    view = tuple(AXES[c] for c in args.view) if args.view and not view3d else default_view(runs[0])

    times = runs[0].frame_time
    if args.max_frames and len(times) > args.max_frames:
        times = times[np.linspace(0, len(times) - 1, args.max_frames).round().astype(int)]
    spacing = float(np.median(np.diff(runs[0].frame_time))) if len(runs[0].frame_time) > 1 else 1 / 30
    fps = args.fps or min(60.0, max(1.0, 1.0 / spacing if spacing > 0 else 30.0))
    if spacing > 1 / 30 + 1e-9:
        print(f"animate.py: frames are {spacing:.3g} s apart; for a smoother animation rerun with "
              "--set output.frame_every=1 (a frame every step)", file=sys.stderr)

    keys = [k for k in runfile.differing_keys(runs) if not k.startswith("output.")]
    field = None if args.field == "none" else args.field
    values = []
    for v in vizes:
        for name in FIELDS.get(field, ()):
            a = v.get(name)
            if a is not None and a.size:
                values.append(np.asarray(a, dtype=float).ravel())
    values = np.concatenate(values) if values else np.zeros(1)
    values = values[np.isfinite(values)]
    vmax = float(np.percentile(np.abs(values), 99)) if values.size else 1.0
    vmax = vmax if vmax > 0 else 1.0
    if field == "change":
        norm, cmap = matplotlib.colors.Normalize(-vmax, vmax), "coolwarm"
    else:
        norm, cmap = matplotlib.colors.Normalize(0.0, vmax), "viridis"

    fig, panels = layout(runs, vizes, view, view3d, field, norm, cmap, keys, args.elev, args.azim)
    scenario = runs[0].attrs.get("scenario", "")
    title = fig.suptitle("")

    def update(k):
        t = float(times[k])
        for p in panels:
            p.draw(t)
        title.set_text(f"{scenario}   t = {t:.3f} s")
        return []

    anim = animation.FuncAnimation(fig, update, frames=len(times), blit=False)
    writer = animation.FFMpegWriter(fps=fps) if ext == ".mp4" else animation.PillowWriter(fps=fps)
    anim.save(args.out, writer=writer, dpi=90)
    print(f"animate.py: {args.out} ({len(times)} frames at {fps:g} fps, {len(runs)} run(s), colour: {args.field}, "
          f"view: {args.view or 'xyz'[view[0]] + 'xyz'[view[1]]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
