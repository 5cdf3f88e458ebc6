"""A small plot axes on a PDF page (the subset of matplotlib's Axes the
report uses, with the same names where they exist).

Drawing is recorded and done by :meth:`Axes.render` once the page is
complete, because the limits (and with them the data -> page transform)
are only final then, as in matplotlib. The data artists (:mod:`.artists`)
are drawn in ``zorder`` (images 0, patches 1, grid 1.5, lines 2, text 3),
clipped to the axes box; spines, ticks, labels, the legend and a colour bar
follow.
"""

from __future__ import annotations

import numpy as np

from photogram.report.pdf import artists, guides
from photogram.report.pdf.canvas import text_width
from photogram.report.pdf.colors import CYCLE
from photogram.report.pdf.ticks import log_ticks, nice_ticks, tick_labels

__all__ = ["Axes", "Transform"]

TICK_SIZE = 7.0            # tick labels (pt), as the report's matplotlib style
LABEL_SIZE = 8.0
TICK_LEN, TICK_PAD, SPINE_W = 3.5, 3.5, 0.8


class Transform:
    """Data -> page points of an axes box ``(x0, y0, w, h)`` and limits;
    ``logy`` takes log10 of y first."""

    def __init__(self, box, xlim, ylim, logy: bool = False):
        self.box, self.logy = box, logy
        x0, y0, w, h = box
        ylo, yhi = (np.log10(ylim[0]), np.log10(ylim[1])) if logy else ylim
        self.sx = w / (xlim[1] - xlim[0])
        self.sy = h / (yhi - ylo)
        self.ox, self.oy = x0 - xlim[0] * self.sx, y0 - ylo * self.sy

    def x(self, x):
        return self.ox + np.asarray(x, float) * self.sx

    def y(self, y):
        y = np.asarray(y, float)
        if self.logy:
            with np.errstate(divide="ignore", invalid="ignore"):
                y = np.where(y > 0, np.log10(np.where(y > 0, y, 1.0)), np.nan)
        return self.oy + y * self.sy

    def __call__(self, xy):
        """Page points (n, 2) of data points (n, 2)."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        if self.logy:
            return np.stack([self.x(xy[:, 0]), self.y(xy[:, 1])], axis=1)
        out = xy * (self.sx, self.sy)           # the same numbers as x() and y(),
        out += (self.ox, self.oy)               # without their stack
        return out


class Axes(artists.ArtistsMixin):
    """Axes in the box ``rect`` = (x0, y0, width, height) points of a page.

    Parameters
    ----------
    canvas : Canvas
    rect : tuple
        The box in page points (bottom-left corner, size).
    """

    native = True

    def __init__(self, canvas, rect):
        self.canvas = canvas
        self.rect = tuple(float(v) for v in rect)
        self.items: list = []               # (zorder, seq, clip, draw(tr, canvas))
        self.bounds: list = []              # data boxes for autoscaling
        self.sticky_y0 = False
        self.xlim = self.ylim = None
        self.yinverted = False
        self.logy = False
        self.equal = False
        self.visible = True
        self.grid_on, self.grid_lw = False, 0.3
        self.xticks = self.yticks = None    # (positions, labels, rotation)
        self.integer = {"x": False, "y": False}
        self.tick_sizes = {"x": TICK_SIZE, "y": TICK_SIZE}
        self.title = self.xlabel = self.ylabel = None
        self.legend_spec = None
        self.handles: list = []             # legend entries (label, style)
        self.colorbars: list = []
        self._cycle = 0

    # ---------------------------------------------------------- settings
    def set_xlim(self, lo, hi=None):
        self.xlim = tuple(lo) if hi is None else (float(lo), float(hi))

    def set_ylim(self, lo, hi=None):
        self.ylim = tuple(lo) if hi is None else (float(lo), float(hi))

    def get_xlim(self):
        return self.xlim or self._auto()[0]

    def get_ylim(self):
        return self.ylim or self._auto()[1]

    def set_aspect(self, aspect):
        self.equal = aspect == "equal"

    def set_yscale(self, scale):
        self.logy = scale == "log"

    def set_visible(self, visible):
        self.visible = bool(visible)

    def grid(self, on=True, lw=0.3, axis="both", **_):
        self.grid_on, self.grid_lw, self.grid_axis = bool(on), lw, axis

    def set_xticks(self, ticks, labels=None, rotation=0, fontsize=None, **_):
        """Ticks (and labels, rotated by ``rotation`` degrees, their ends at
        the ticks when rotated; ``fontsize`` their size)."""
        self.xticks = (np.asarray(ticks, float), labels, rotation)
        if fontsize:
            self.tick_sizes["x"] = float(fontsize)

    def set_yticks(self, ticks, labels=None, rotation=0):
        self.yticks = (np.asarray(ticks, float), labels, rotation)

    def integer_ticks(self, axis="x"):
        """Whole-number ticks only on ``axis`` (counts, iterations)."""
        self.integer[axis] = True

    def tick_params(self, axis="both", labelsize=None, **_):
        if labelsize:
            for a in ("x", "y") if axis == "both" else (axis,):
                self.tick_sizes[a] = float(labelsize)

    def ticklabel_format(self, **_):
        """Plain labels without offset are the default here."""

    def next_color(self):
        c = CYCLE[self._cycle % len(CYCLE)]
        self._cycle += 1
        return c

    def decorate(self, title=None, xlabel=None, ylabel=None, *, xpad=0.3, ypad=0.48,
                 size=None):
        """Title and axis labels at fixed distances (inches) from the box
        (as :func:`photogram.report.layout.decorate`)."""
        if title:
            self.title = (title, size or 8.5)
        if xlabel:
            self.xlabel = (xlabel, xpad)
        if ylabel:
            self.ylabel = (ylabel, ypad)

    def legend(self, loc="upper left", bbox_to_anchor=None, fontsize=7, frameon=True, **_):
        self.legend_spec = (loc, bbox_to_anchor, fontsize, frameon)

    # ------------------------------------------------------- limits, box
    def _bound(self, x, y, sticky=False):
        x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
        ok = np.isfinite(x) & np.isfinite(y)
        if ok.all() and len(ok):                # the usual case: no masked copies
            self.bounds.append((x.min(), x.max(), y.min(), y.max()))
        elif ok.any():
            self.bounds.append((x[ok].min(), x[ok].max(), y[ok].min(), y[ok].max()))
        self.sticky_y0 |= sticky

    def _auto(self):
        """Data limits with 5 % margins (matplotlib's default), y from 0
        for histograms; log y in decades."""
        if not self.bounds:
            return (0.0, 1.0), (0.0, 1.0)
        b = np.array(self.bounds)
        with np.errstate(all="ignore"):
            x0, x1, y0, y1 = (np.nanmin(b[:, 0]), np.nanmax(b[:, 1]), np.nanmin(b[:, 2]),
                              np.nanmax(b[:, 3]))
        if not np.isfinite(y0):                 # only vertical lines
            y0, y1 = 0.0, 1.0
        if not np.isfinite(x0):                 # only horizontal lines or bands
            x0, x1 = 0.0, 1.0

        def pad(lo, hi):
            d = (hi - lo) or (abs(lo) or 1.0)
            return lo - 0.05 * d, hi + 0.05 * d

        xl = pad(x0, x1)
        if self.logy:
            y0 = max(y0, 1e-300) if y0 > 0 else max(y1 * 1e-3, 1e-300)
            ly = pad(np.log10(y0), np.log10(max(y1, y0)))
            yl = (10 ** ly[0], 10 ** ly[1])
        else:
            yl = pad(y0, y1)
            if self.sticky_y0 and y0 >= 0:
                yl = (0.0, yl[1])
        return xl, yl

    def box(self):
        """The drawn box (points): ``rect`` narrowed for colour bars and
        shrunk about its centre for equal scales."""
        x0, y0, w, h = self.rect
        for cb in self.colorbars:
            w *= 1.0 - cb["fraction"] - cb["pad"]
        if self.equal:
            xl, yl = self.get_xlim(), self.get_ylim()
            ratio = abs(yl[1] - yl[0]) / max(abs(xl[1] - xl[0]), 1e-300)
            if h / w > ratio:
                nh = w * ratio
                y0, h = y0 + (h - nh) / 2, nh
            else:
                nw = h / ratio
                x0, w = x0 + (w - nw) / 2, nw
        return x0, y0, w, h

    @property
    def width_in(self):
        return self.box()[2] / 72.0

    @property
    def height_in(self):
        return self.box()[3] / 72.0

    def transform(self):
        return Transform(self.box(), self.get_xlim(), self.get_ylim(), self.logy)

    # ------------------------------------------------------------ ticks
    def _ticks(self, axis, lo, hi, length):
        given = self.xticks if axis == "x" else self.yticks
        a, b = min(lo, hi), max(lo, hi)
        if given is not None:
            t, labels, rot = given
            keep = (t >= a - 1e-9 * abs(b - a)) & (t <= b + 1e-9 * abs(b - a))
            labels = list(labels) if labels is not None else tick_labels(t)
            return t[keep], [lab for lab, k in zip(labels, keep) if k], rot
        if axis == "y" and self.logy:
            k = log_ticks(a, b)
            return 10.0 ** k, [("10", int(e)) for e in k], 0
        nbins = max(1, min(9, int(length / (self.tick_sizes[axis] * (3 if axis == "x" else 2)))))
        t = nice_ticks(a, b, nbins, self.integer[axis])
        return t, tick_labels(t), 0

    def ylabel_pad(self, size=TICK_SIZE):
        """Distance (inches) from the box to the y label that clears the
        widest y tick label, at least 0.45 (as pages_summary.tick_label_pad)."""
        yl = self.get_ylim()
        _, labels, _ = self._ticks("y", yl[0], yl[1], self.rect[3])
        chars = [len(lab) if isinstance(lab, str) else 2 + len(str(lab[1])) for lab in labels]
        return max(0.45, max(chars or [0]) * size * 0.56 / 72.0 + 0.2)

    # ----------------------------------------------------------- render
    def render(self):
        """Draw everything on the canvas."""
        if not self.visible:
            return
        c = self.canvas
        tr = self.transform()
        x0, y0, w, h = tr.box
        c.save()
        c.clip_rect(x0, y0, w, h)
        items = sorted(self.items, key=lambda it: (it[0], it[1]))
        grid_drawn = False
        for z, _, clip, draw in items:
            if not grid_drawn and z > 1.5:
                self._grid(tr)
                grid_drawn = True
            if clip:
                draw(tr, c)
        if not grid_drawn:
            self._grid(tr)
        c.restore()
        for z, _, clip, draw in items:
            if not clip:
                draw(tr, c)
        self._frame(tr)
        if self.legend_spec is not None and self.handles:
            guides.draw_legend(self, tr, *self.legend_spec)
        for cb in self.colorbars:
            guides.draw_colorbar(self, tr, cb)

    def _tick_sets(self, tr):
        x0, y0, w, h = tr.box
        xl, yl = self.get_xlim(), self.get_ylim()
        key = (tuple(tr.box), tuple(xl), tuple(yl))
        cached = getattr(self, "_tick_cache", None)
        if cached is None or cached[0] != key:     # grid and frame share them
            cached = (key, (self._ticks("x", *xl, w), self._ticks("y", *yl, h)))
            self._tick_cache = cached
        return cached[1]

    def _grid(self, tr):
        if not self.grid_on:
            return
        c = self.canvas
        (xt, _, _), (yt, _, _) = self._tick_sets(tr)
        x0, y0, w, h = tr.box
        c.stroke_style("#b0b0b0", self.grid_lw)
        px, py = tr.x(xt), tr.y(yt)
        axis = getattr(self, "grid_axis", "both")
        px, py = (px if axis in ("both", "x") else px[:0]), (py if axis in ("both", "y") else py[:0])
        a = np.concatenate([np.stack([px, np.full_like(px, y0)], 1),
                            np.stack([np.full_like(py, x0), py], 1)])
        b = np.concatenate([np.stack([px, np.full_like(px, y0 + h)], 1),
                            np.stack([np.full_like(py, x0 + w), py], 1)])
        c.segments(a, b)

    def _frame(self, tr):
        c = self.canvas
        x0, y0, w, h = tr.box
        c.stroke_style("black", SPINE_W)
        c.rect(x0, y0, w, h)
        (xt, xlab, xrot), (yt, ylab, _) = self._tick_sets(tr)
        px, py = tr.x(xt), tr.y(yt)
        c.segments(*_ticks_xy(px, y0, y0 - TICK_LEN, vertical=True))
        c.segments(*_ticks_xy(py, x0, x0 - TICK_LEN, vertical=False))
        s = self.tick_sizes["x"]
        low = y0 - TICK_LEN - TICK_PAD
        deepest = low - 0.76 * s
        sin, cos = np.sin(np.radians(xrot or 0)), np.cos(np.radians(xrot or 0))
        for x, lab in zip(px, xlab):
            if xrot == 90:                    # centred on the tick
                c.text(x + 0.35 * s, low, lab, s, ha="right", angle=90)
                deepest = min(deepest, low - text_width(lab, s))
            elif xrot:                        # the box's upper right corner at the tick
                c.text(x - 0.22 * s * sin, low - 0.76 * s * cos, lab, s, ha="right",
                       angle=xrot)
                deepest = min(deepest, low - text_width(lab, s) * sin - s * cos)
            else:
                c.text(x, low - 0.76 * s, lab, s, ha="center")
        s = self.tick_sizes["y"]
        for y, lab in zip(py, ylab):
            if isinstance(lab, tuple):        # 10^k
                exp = str(lab[1])
                ew = text_width(exp, 0.7 * s)
                right = x0 - TICK_LEN - TICK_PAD
                c.text(right, y + 0.05 * s, exp, 0.7 * s, ha="right")
                c.text(right - ew, y - 0.35 * s, "10", s, ha="right")
            else:
                c.text(x0 - TICK_LEN - TICK_PAD, y - 0.35 * s, lab, s, ha="right")
        if self.title:
            text, size = self.title
            c.text(x0, y0 + h + 0.07 * 72 + size * 0.236, text, size)
        if self.xlabel:
            text, pad = self.xlabel
            c.text(x0 + w / 2, y0 - pad * 72 - 0.76 * LABEL_SIZE, text, LABEL_SIZE,
                   ha="center")
        if self.ylabel:
            text, pad = self.ylabel
            c.text(x0 - pad * 72 - 0.236 * LABEL_SIZE, y0 + h / 2, text, LABEL_SIZE,
                   ha="center", angle=90)


def _ticks_xy(at, start, end, vertical: bool):
    """Ends ``(a, b)`` (n, 2) of tick marks at positions ``at`` from
    ``start`` to ``end`` across the axis (filled in place of four
    np.stack calls: 1 600 a report; issue 23)."""
    at = np.asarray(at, float).ravel()
    a, b = np.empty((len(at), 2)), np.empty((len(at), 2))
    i, j = (0, 1) if vertical else (1, 0)
    a[:, i] = b[:, i] = at
    a[:, j], b[:, j] = start, end
    return a, b

