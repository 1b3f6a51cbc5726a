"""What the figures of the project do with their axes and lines, so that none of them misleads.

- An exploded run must not flatten the others: an axis is set from the values of the runs that
  did not explode (axis_limits, keep_to), and the line of one that did runs off it, which its
  legend entry says (off_axis). On a linear axis, so is a run that blew up without crossing an
  explosion limit: one whose peak is more than OUTLIER times the median of the runs' peaks
  (outliers).
- No line hides under another without saying so: coincident() finds the lines that lie on an
  earlier one at the scale of the axis (within 1 % of its height at every point), for the legend
  to name; MARKERS and markevery() give each line its own marker at its own places, so that a
  line drawn over another still shows.
- shown_name() keeps absolute paths out of titles.
"""
import os

import numpy as np

MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*", "<", ">")
COINCIDE = 0.01  # of an axis's height: two lines closer than this at every point look like one
OUTLIER = 10.0   # a run whose peak |value| is this many times the median peak flattens the others


def finite(values, log=False):
    """The finite values of an array, flattened (the positive ones on a log axis)."""
    v = np.asarray(values, dtype=float).ravel()
    ok = np.isfinite(v)
    if log:
        ok &= v > 0
    return v[ok]


def axis_limits(arrays, log=False, margin=0.05):
    """(lo, hi) covering the finite values of `arrays` (positive ones on a log axis), widened by
    `margin` of the span on each side (of the span in decades on a log axis); None when there is
    no such value."""
    values = [finite(a, log) for a in arrays]
    v = np.concatenate(values) if values else np.array([])
    if not v.size:
        return None
    lo, hi = float(v.min()), float(v.max())
    if log:
        a, b = np.log10(lo), np.log10(hi)
        pad = margin * (b - a) if b > a else 0.5
        return 10.0 ** (a - pad), 10.0 ** (b + pad)
    pad = margin * (hi - lo) if hi > lo else (0.1 * abs(hi) if hi != 0 else 1.0)
    return lo - pad, hi + pad


def off_axis(values, lim, log=False):
    """Whether a finite value of `values` lies outside lim = (lo, hi)."""
    v = finite(values, log)
    return bool(v.size) and bool(v.min() < lim[0] or v.max() > lim[1])


def keep_to(ax, kept, others, log=False, axis="y"):
    """Sets ax's axis to the range of the arrays `kept` (the lines of the runs that did not
    explode) and returns the limits. When `kept` holds no value, the range of `others` (the
    other lines' arrays) is taken; None when neither holds one (the axis is left to matplotlib).
    See off_axis for which of the others run off the axis."""
    lim = axis_limits(kept, log) or axis_limits(others, log)
    if lim is None:
        return None
    (ax.set_ylim if axis == "y" else ax.set_xlim)(*lim)
    return lim


def outliers(peaks, factor=OUTLIER):
    """The indices of `peaks` (each run's largest |value| on an axis; NaN for none) more than
    `factor` times their median; none with fewer than three runs, or a median of 0."""
    p = np.asarray(peaks, dtype=float)
    ok = np.isfinite(p)
    if ok.sum() < 3:
        return set()
    median = float(np.median(p[ok]))
    if median <= 0:
        return set()
    return {int(k) for k in np.nonzero(ok & (p > factor * median))[0]}


def coincident(curves, lim, log=False, tolerance=COINCIDE):
    """Which lines lie on an earlier one. `curves`: one (x, y) per line (None where a line is
    not drawn); lim: the axis's (lo, hi). Returns {j: (i, identical)} for every line j that has
    the same x as an earlier line i, NaN at the same points, and y within `tolerance` of the
    axis's height at every point (in decades on a log axis); identical when the values are
    equal. i is the first line of its group."""
    if lim is None:
        return {}

    def scale(y):
        y = np.asarray(y, dtype=float)
        if log:
            return np.log10(np.where(y > 0, y, np.nan))
        return np.where(np.isfinite(y), y, np.nan)

    height = (np.log10(lim[1]) - np.log10(lim[0])) if log else (lim[1] - lim[0])
    out = {}
    for j, cj in enumerate(curves):
        if cj is None:
            continue
        for i in range(j):
            ci = curves[i]
            if ci is None or i in out:
                continue
            xi, xj = np.asarray(ci[0], dtype=float), np.asarray(cj[0], dtype=float)
            if xi.shape != xj.shape or not np.array_equal(xi, xj, equal_nan=True):
                continue
            a, b = scale(ci[1]), scale(cj[1])
            if a.shape != b.shape or not np.array_equal(np.isnan(a), np.isnan(b)):
                continue
            ok = ~np.isnan(a)
            if not ok.any():
                continue
            if np.max(np.abs(a[ok] - b[ok])) <= tolerance * height:
                out[j] = (i, bool(np.array_equal(a, b, equal_nan=True)))
                break
    return out


def markevery(k, count, points, marks=8):
    """Where line k of `count` puts its markers on `points` points: about `marks` of them,
    shifted from one line to the next, so that lines on top of each other still show theirs."""
    step = max(1, points // marks)
    return (min(points - 1, (k * step) // max(count, 1)) if points else 0, step)


def shown_name(path):
    """A file's name for a title: its stem, never the folder it is in ("hanging_chain")."""
    return os.path.splitext(os.path.basename(str(path)))[0]
