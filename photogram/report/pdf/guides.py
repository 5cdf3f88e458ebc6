"""The guides of a native :class:`~photogram.report.pdf.axes.Axes`: its
legend (one sample and label per handle, framed, at a matplotlib-style
location) and its colour bar (a ramp image with ticks and a label)."""

from __future__ import annotations

import numpy as np

from photogram.report.pdf.artists import _dash
from photogram.report.pdf.canvas import text_width
from photogram.report.pdf.colors import colormap

__all__ = ["draw_legend", "draw_colorbar"]


def draw_legend(ax, tr, loc, anchor, fontsize, frameon):
    c = ax.canvas
    x0, y0, w, h = tr.box
    fs = fontsize
    row = 1.4 * fs
    sample = 2.0 * fs
    width = sample + 0.8 * fs + max(text_width(lab, fs) for lab, _ in ax.handles) + 0.8 * fs
    height = row * len(ax.handles) + 0.6 * fs
    if anchor is not None:
        left, top = x0 + anchor[0] * w, y0 + anchor[1] * h
    elif loc == "upper right":
        left, top = x0 + w - width - 4, y0 + h - 4
    else:
        left, top = x0 + 4, y0 + h - 4
    if frameon:
        c.fill_style("white", 0.8)
        c.stroke_style("0.8", 0.8)
        c.rect(left, top - height, width, height, fill=True, stroke=True)
    for i, (lab, st) in enumerate(ax.handles):
        yb = top - 0.3 * fs - (i + 1) * row + 0.35 * row
        xs = left + 0.5 * fs
        if st.get("patch"):
            c.fill_style(st["color"], st.get("alpha"))
            c.rect(xs, yb - 0.1 * fs, sample, 0.7 * fs, fill=True, stroke=False)
        else:
            ym = yb + 0.3 * fs
            if st.get("ls"):
                c.stroke_style(st["color"], st["lw"], _dash(st["ls"], st["lw"]))
                c.line(xs, ym, xs + sample, ym)
            if st.get("marker"):
                size = min(st["ms"], 6.0) * (0.5 if st["marker"] == "." else 1.0)
                c.fill_style(st["color"])
                c.stroke_style(st["color"], 0.5)
                c.markers([[xs + sample / 2, ym]], st["marker"], size)
        c.text(xs + sample + 0.6 * fs, yb, lab, fs)


def draw_colorbar(ax, tr, cb):
    """A vertical colour bar right of the (narrowed) axes box."""
    from photogram.report.pdf.ticks import nice_ticks, tick_labels

    c = ax.canvas
    x0, y0, w, h = tr.box
    full = ax.rect[2]
    left = x0 + w + cb["pad"] * full
    bw = min(cb["fraction"] * full, h / 20.0)
    ramp = colormap(cb["cmap"], np.linspace(cb["vmax"], cb["vmin"], 256)[:, None],
                    cb["vmin"], cb["vmax"])
    c.image(ramp, left, y0, bw, h, interpolate=True)
    c.stroke_style("black", 0.8)
    c.rect(left, y0, bw, h)
    t = nice_ticks(cb["vmin"], cb["vmax"], max(2, min(9, int(h / 14))))
    py = y0 + (t - cb["vmin"]) / ((cb["vmax"] - cb["vmin"]) or 1.0) * h
    c.segments(np.stack([np.full_like(py, left + bw), py], 1),
               np.stack([np.full_like(py, left + bw + 3.5), py], 1))
    labels = tick_labels(t)
    for y, lab in zip(py, labels):
        c.text(left + bw + 7, y - 0.35 * ax.tick_sizes["y"], lab, ax.tick_sizes["y"])
    if cb["label"]:
        widest = max([text_width(lab, ax.tick_sizes["y"]) for lab in labels] or [0])
        c.text(left + bw + 12 + widest + 0.76 * 8, y0 + h / 2, cb["label"], 8, ha="center",
               angle=90)
