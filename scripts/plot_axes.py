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


# ---------------------------------------------------------------------------------------------
# What every figure checks before it is written: the legend inside the figure, no panel without
# information, log axes where the values span decades, outliers named rather than flattening the
# rest (docs/figures.md). The tests read the same functions from the figure objects.

DECADES = 3.0  # values spanning more than this many decades go on a log axis


def informative(arrays):
    """Whether `arrays` hold a finite value other than 0: a panel of NaNs and zeros says nothing
    that its title could not, and is left out (or replaced by a sentence)."""
    for a in arrays:
        v = finite(a)
        if v.size and np.any(v != 0):
            return True
    return False


def span_decades(arrays):
    """How many decades the finite non-zero |values| of `arrays` span (0 with fewer than two)."""
    v = np.concatenate([np.abs(finite(a)) for a in arrays] or [np.array([])])
    v = v[v > 0]
    if v.size < 2:
        return 0.0
    return float(np.log10(v.max() / v.min()))


def scale_for(arrays, decades=DECADES):
    """The y scale for `arrays`: "log" when their values are all positive and span more than
    `decades` decades, "symlog" when they change sign and span as much, else "linear"."""
    v = np.concatenate([finite(a) for a in arrays] or [np.array([])])
    if v.size < 2 or span_decades([v]) <= decades:
        return "linear"
    return "log" if np.all(v > 0) else "symlog"


def set_scale(ax, arrays, decades=DECADES):
    """Sets ax's y scale by scale_for (symlog's linear part: the smallest non-zero |value|)."""
    scale = scale_for(arrays, decades)
    if scale == "symlog":
        v = np.abs(np.concatenate([finite(a) for a in arrays]))
        ax.set_yscale("symlog", linthresh=float(v[v > 0].min()))
    elif scale == "log":
        ax.set_yscale("log")
    return scale


BULK = 0.01   # the share of the points at each end that bulk_limits sets aside to find the bulk
SQUEEZE = 4.0  # the extremes flatten the bulk when all points span this many times the bulk's range


def bulk_limits(arrays, log=False, margin=0.05):
    """Limits for an axis whose extremes would flatten the rest: a spike of a few points (25,000 J
    for one row beside runs that stay under 3,000). The bulk is the pooled finite values between
    the BULK and 1 - BULK quantiles (in decades on a log axis); when all values span more than
    SQUEEZE times the bulk's range, the limits cover the values within one bulk range of the bulk,
    with `margin`; else (or with fewer than 20 values) None: the axis needs no trimming."""
    v = np.concatenate([finite(a, log) for a in arrays] or [np.array([])])
    if v.size < 20:
        return None
    if log:
        v = np.log10(v)
    lo, hi = np.quantile(v, [BULK, 1.0 - BULK])
    width = hi - lo
    if width <= 0 or (v.max() - v.min()) <= SQUEEZE * width:
        return None
    kept = v[(v >= lo - width) & (v <= hi + width)]
    a, b = float(kept.min()), float(kept.max())
    pad = margin * (b - a) if b > a else 0.5
    a, b = a - pad, b + pad
    return (10.0 ** a, 10.0 ** b) if log else (a, b)


def name_outliers(ax, notes, fontsize=7):
    """Writes `notes` (one line each: which line runs off the axis and how far, "listing_update:
    up to 1.4e13, off the axis") in the panel's upper left corner, over a white box."""
    if not notes:
        return None
    return ax.text(0.01, 0.98, "\n".join(notes), transform=ax.transAxes, ha="left", va="top",
                   fontsize=fontsize, color="0.15", zorder=10,
                   bbox=dict(boxstyle="round,pad=0.3", facecolor="white", edgecolor="0.6", alpha=0.9))


def value_text(v):
    """A number for a label: 3 significant digits, exponent form outside [1e-2, 1e4)."""
    if v is None or not np.isfinite(v):
        return "NaN"
    if v != 0 and (abs(v) < 1e-2 or abs(v) >= 1e4):
        return f"{v:.2e}"
    return f"{v:.3g}"


def wrap(text, width):
    """`text` broken into lines of at most `width` characters (at spaces), the following lines
    indented."""
    import textwrap
    return textwrap.fill(text, max(20, width), break_long_words=False, break_on_hyphens=False,
                         subsequent_indent="  ")


def figure_legend(fig, handles, labels, fontsize=8, max_cols=3, top=0.95, slot=None):
    """A legend for the whole figure, inside the figure. In `slot`, a free cell of the panels' grid
    (an odd number of panels in two columns), when it fits there: the cell is no empty panel then.
    Else below the panels: labels wrapped to the width of their column, as many columns (at most
    max_cols) as fit, and the figure made taller by the legend's height so that the panels keep
    theirs. Lays the figure out (tight_layout); returns the legend."""
    renderer = fig.canvas.get_renderer()
    if slot is not None:
        slot.axis("off")
        fig.tight_layout(rect=(0, 0, 1, top))
        cell = slot.get_window_extent(renderer)
        chars = int(cell.width / fig.dpi * 72.0 / (0.55 * fontsize)) - 8
        legend = slot.legend(handles, [wrap(l, chars) for l in labels], loc="center", fontsize=fontsize,
                             frameon=False)
        box = legend.get_window_extent(renderer)
        if box.height <= 1.1 * cell.height and inside_figure(fig, legend):
            return legend
        legend.remove()
        fig.delaxes(slot)
    width_px = fig.get_figwidth() * fig.dpi
    legend = None
    for ncol in range(max(1, min(max_cols, len(labels))), 0, -1):
        chars = int(fig.get_figwidth() * 72.0 / (0.55 * fontsize) / ncol) - 8
        legend = fig.legend(handles, [wrap(l, chars) for l in labels], loc="lower center",
                            bbox_to_anchor=(0.5, 0.0), ncol=ncol, fontsize=fontsize, frameon=False)
        if legend.get_window_extent(renderer).width <= 0.98 * width_px or ncol == 1:
            break
        legend.remove()
    height = legend.get_window_extent(renderer).height / fig.dpi + 0.15
    old = fig.get_figheight()
    fig.set_figheight(old + height)
    fig.tight_layout(rect=(0, height / (old + height), 1, top))
    return legend


def inside_figure(fig, artist, slack=1.0):
    """Whether `artist` (a legend, a title) lies inside the figure once drawn (within `slack`
    pixels)."""
    fig.canvas.draw()
    bb = artist.get_window_extent(fig.canvas.get_renderer())
    w, h = fig.get_figwidth() * fig.dpi, fig.get_figheight() * fig.dpi
    return bb.x0 >= -slack and bb.y0 >= -slack and bb.x1 <= w + slack and bb.y1 <= h + slack


def axes_data(ax):
    """The y values an axes draws: its lines' and its bars' (patches' heights), as arrays."""
    out = [np.asarray(line.get_ydata(), dtype=float) for line in ax.get_lines()]
    bars = [p.get_height() for p in ax.patches if hasattr(p, "get_height")]
    if bars:
        out.append(np.asarray(bars, dtype=float))
    for c in ax.collections:
        offsets = np.asarray(c.get_offsets(), dtype=float)
        if offsets.ndim == 2 and offsets.shape[0] and offsets.shape[1] == 2:
            out.append(offsets[:, 1])
    return out
