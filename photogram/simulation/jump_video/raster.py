"""Drawing on a supersampled region of interest: polygons, capsules and
area-sampled discs.

Pixel convention: the centre of image pixel (column i, row j) is at (x, y) =
(i, j); the pixel covers [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]. A region
``(x0, y0, x1, y1)`` is the pixels x0 <= i < x1, y0 <= j < y1; its canvas
has ``ss x ss`` cells per pixel, cell (u, v) centred at image point
``(x0 - 0.5 + (u + 0.5) / ss, y0 - 0.5 + (v + 0.5) / ss)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Shape", "Disc", "capsule_outline", "disc_outline", "paint", "disc_coverage",
           "bounding_box"]

SHIFT = 4                 # fractional bits of the polygon vertices handed to OpenCV
_CIRCLE = np.exp(2j * np.pi * np.arange(24) / 24)


@dataclass
class Shape:
    """A filled convex polygon (n, 2) in image px, grey level and depth (dm
    along the viewing direction: far shapes are painted first)."""

    outline: np.ndarray
    grey: float
    depth: float


@dataclass
class Disc:
    """An area-sampled disc (centre (2,), radius px, grey): painted after
    all shapes of its group (a marker on the suit's surface)."""

    centre: np.ndarray
    radius: float
    grey: float


def disc_outline(centre, radius) -> np.ndarray:
    """24 points (24, 2) on a circle (px)."""
    z = complex(centre[0], centre[1]) + radius * _CIRCLE
    return np.stack([z.real, z.imag], axis=1)


def capsule_outline(a, b, ra, rb) -> np.ndarray:
    """Outline points (48, 2) of a capsule between image points ``a`` and
    ``b`` with end radii ``ra``, ``rb`` (px): its convex hull is the shape."""
    return np.vstack([disc_outline(a, ra), disc_outline(b, rb)])


def bounding_box(points, size, margin: int = 2):
    """Integer region (x0, y0, x1, y1) around image points (n, 2), clipped
    to the image ``size`` (w, h); None when empty."""
    if len(points) == 0:
        return None
    lo = np.floor(points.min(axis=0)).astype(int) - margin
    hi = np.ceil(points.max(axis=0)).astype(int) + margin + 1
    x0, y0 = max(lo[0], 0), max(lo[1], 0)
    x1, y1 = min(hi[0], size[0]), min(hi[1], size[1])
    if x1 <= x0 or y1 <= y0:
        return None
    return int(x0), int(y0), int(x1), int(y1)


def _to_canvas(xy, box, ss):
    return (np.asarray(xy, float) - [box[0] - 0.5, box[1] - 0.5]) * ss - 0.5


def disc_coverage(centre, radius, box, ss: int, q: int = 16):
    """Area coverage of a disc on the canvas of ``box``.

    Exact across rows (the disc's vertical extent at each sample column is
    intersected with each cell analytically), midpoint-sampled along x at
    ``q`` columns per cell (``ss q`` per pixel): the area is within ~1e-3 of
    pi r^2 for r ~ 1.3 px. Returns ``(v0, u0, cov)`` with ``cov`` a float32
    block whose top-left cell is canvas cell (u0, v0), or None if the disc
    misses the canvas.
    """
    w, h = (box[2] - box[0]) * ss, (box[3] - box[1]) * ss
    cu, cv = _to_canvas(centre, box, ss) + 0.5          # cell u spans [u, u + 1]
    r = radius * ss
    u0, v0 = max(int(np.floor(cu - r)), 0), max(int(np.floor(cv - r)), 0)
    u1, v1 = min(int(np.ceil(cu + r)) + 1, w), min(int(np.ceil(cv + r)) + 1, h)
    if u1 <= u0 or v1 <= v0:
        return None
    xs = (np.arange(u0 * q, u1 * q) + 0.5) / q
    half = np.sqrt(np.maximum(r * r - (xs - cu) ** 2, 0.0))
    rows = np.arange(v0, v1, dtype=float)[:, None]
    overlap = np.clip(np.minimum(cv + half, rows + 1) - np.maximum(cv - half, rows), 0.0, None)
    cov = overlap.reshape(v1 - v0, u1 - u0, q).mean(axis=2).astype(np.float32)
    return v0, u0, cov


def paint(base, box, shapes, discs, ss: int = 4) -> np.ndarray:
    """The region ``box`` of the float image ``base`` with the shapes
    painted far to near and then the discs, area-averaged to pixels.

    Returns the (y1 - y0, x1 - x0) float32 block; ``base`` is not changed.
    """
    import cv2
    x0, y0, x1, y1 = box
    canvas = np.repeat(np.repeat(base[y0:y1, x0:x1].astype(np.float32), ss, 0), ss, 1)
    for s in sorted(shapes, key=lambda s: -s.depth):
        pts = _to_canvas(s.outline, box, ss)
        hull = cv2.convexHull(np.rint(pts * (1 << SHIFT)).astype(np.int32))
        cv2.fillConvexPoly(canvas, hull, float(s.grey), cv2.LINE_8, SHIFT)
    for d in discs:
        hit = disc_coverage(d.centre, d.radius, box, ss)
        if hit is None:
            continue
        v0, u0, cov = hit
        block = canvas[v0:v0 + cov.shape[0], u0:u0 + cov.shape[1]]
        block += cov * (np.float32(d.grey) - block)
    h, w = y1 - y0, x1 - x0
    return canvas.reshape(h, ss, w, ss).mean(axis=(1, 3))
