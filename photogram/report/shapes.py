"""Small geometric helpers of the report: convex hulls, areas, error
ellipses, round scale factors."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["convex_hull", "polygon_area", "ellipse", "nice", "coverage_fraction",
           "segments_path", "cell_means", "ray_counts", "ray_layer", "native_ray_layer",
           "convex_grid_mask", "unique_rows"]


def convex_hull(xy) -> np.ndarray:
    """Convex hull (k, 2), counter-clockwise, of points (n, 2) (Andrew's
    monotone chain); fewer than 3 distinct points are returned as they are.

    Points strictly inside the polygon of the eight extreme points (in x, y,
    x + y, x - y) cannot be hull vertices and are dropped first, vectorized
    (Akl-Toussaint), so the Python chain only sees the few near the rim.
    """
    pts = np.asarray(xy, float).reshape(-1, 2)
    if len(pts) > 32:       # before sorting (the sort of rows was most of the time)
        pts = pts[~_inside_extremes(pts)]
    pts = unique_rows(pts)
    if len(pts) < 3:
        return pts
    return _monotone_chain(pts)


def unique_rows(pts) -> np.ndarray:
    """The distinct rows of ``pts`` (n, 2), sorted by x, then y: what
    ``np.unique(pts, axis=0)`` gives for finite values, through one
    ``np.lexsort`` (``np.unique`` with an axis sorts a structured view,
    about three times slower on the report's small hulls; issue 23)."""
    pts = np.asarray(pts, float).reshape(-1, 2)
    if len(pts) < 2:
        return pts.copy()
    s = pts[np.lexsort((pts[:, 1], pts[:, 0]))]
    keep = np.empty(len(s), bool)
    keep[0] = True
    np.not_equal(s[1:, 0], s[:-1, 0], out=keep[1:])
    keep[1:] |= s[1:, 1] != s[:-1, 1]
    return s[keep]


def _monotone_chain(pts) -> np.ndarray:
    """Andrew's monotone chain of sorted unique points (n >= 3)."""
    def half(points):
        out = []                              # (x, y) tuples: no numpy per step
        for p in points:
            while len(out) >= 2:
                (ox, oy), (ax, ay) = out[-2], out[-1]
                if (ax - ox) * (p[1] - oy) - (ay - oy) * (p[0] - ox) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    xy = [tuple(p) for p in np.asarray(pts, float).tolist()]
    lower, upper = half(xy), half(xy[::-1])
    return np.array(lower[:-1] + upper[:-1], dtype=float).reshape(-1, 2)


def _inside_extremes(pts) -> np.ndarray:
    """Mask of the points strictly inside (by a margin far above rounding)
    the convex polygon of the eight extreme points of ``pts`` (in any order,
    repeats allowed: such points are never hull vertices)."""
    x, y = pts[:, 0], pts[:, 1]
    s, d = x + y, x - y
    picks = [x.argmin(), x.argmax(), y.argmin(), y.argmax(), s.argmin(), s.argmax(),
             d.argmin(), d.argmax()]
    ext = unique_rows(pts[picks])
    if len(ext) < 3:
        return np.zeros(len(pts), bool)
    poly = _monotone_chain(ext)
    if len(poly) < 3:
        return np.zeros(len(pts), bool)
    a, b = poly, np.concatenate([poly[1:], poly[:1]])
    cross = ((b[:, 0] - a[:, 0]) * (y[:, None] - a[:, 1])
             - (b[:, 1] - a[:, 1]) * (x[:, None] - a[:, 0]))
    scale = float(max(x.max() - x.min(), y.max() - y.min())) ** 2
    return (cross > 1e-9 * scale).all(axis=1)


def polygon_area(poly) -> float:
    poly = np.asarray(poly, float)
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def coverage_fraction(hulls, fmt, n=200) -> float:
    """Fraction of the format ``(w, h)`` covered by the union of convex
    polygons, on an ``n`` x ``n`` raster: the grid points inside any of
    them by the rule of :func:`convex_grid_mask`, for all polygons at once
    (per grid row and polygon the span of columns between its two edge
    crossings, the spans added up row by row; issue 23)."""
    w, h = fmt
    xs, ys = (np.arange(n) + 0.5) * w / n, (np.arange(n) + 0.5) * h / n
    polys = [np.asarray(p, float) for p in hulls if len(p) >= 3]
    if not polys:
        return 0.0
    a = np.concatenate(polys)
    b = np.concatenate([np.concatenate([p[1:], p[:1]]) for p in polys])
    starts = np.cumsum([0] + [len(p) for p in polys[:-1]])
    y = ys[:, None]
    lo, hi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
    crosses = (y >= lo) & (y < hi)                                # (rows, edges)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = a[:, 0] + (y - a[:, 1]) / (b[:, 1] - a[:, 1]) * (b[:, 0] - a[:, 0])
    left = np.minimum.reduceat(np.where(crosses, x, np.inf), starts, axis=1)   # (rows, polys)
    right = np.maximum.reduceat(np.where(crosses, x, -np.inf), starts, axis=1)
    first = np.searchsorted(xs, left.ravel(), side="right")      # first column with x > left
    stop = np.searchsorted(xs, right.ravel(), side="left")       # first column with x >= right
    ok = first < stop
    row = np.repeat(np.arange(n) * (n + 1), len(polys))[ok]
    size = n * (n + 1)
    diff = (np.bincount(row + first[ok], minlength=size)
            - np.bincount(row + stop[ok], minlength=size)).reshape(n, n + 1)
    return float((np.cumsum(diff, axis=1)[:, :n] > 0).mean())


def convex_grid_mask(poly, xs, ys) -> np.ndarray:
    """Mask (len(ys), len(xs)) of the grid points ``(xs[j], ys[i])`` inside
    the convex polygon ``poly`` (k, 2): per grid row the span between the two
    edges it crosses (the crossing rule: an edge counts for the rows with
    ``min(y_a, y_b) <= y < max(y_a, y_b)``), vectorized over rows and edges."""
    poly = np.asarray(poly, float)
    a, b = poly, np.roll(poly, -1, axis=0)
    y = np.asarray(ys, float)[:, None]
    lo, hi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
    crosses = (y >= lo) & (y < hi)                                # (rows, edges)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (y - a[:, 1]) / (b[:, 1] - a[:, 1])
    x = np.where(crosses, a[:, 0] + t * (b[:, 0] - a[:, 0]), np.nan)
    some = crosses.any(axis=1)
    left = np.where(some, np.nanmin(np.where(some[:, None], x, 0.0), axis=1), np.inf)
    right = np.where(some, np.nanmax(np.where(some[:, None], x, 0.0), axis=1), -np.inf)
    xs = np.asarray(xs, float)[None, :]
    return (xs > left[:, None]) & (xs < right[:, None])


def ellipse(cov2) -> tuple[float, float, float]:
    """Semi-axes (a >= b) and the angle of a (degrees from the first axis)
    of the 1-sigma error ellipse of a 2x2 covariance."""
    cov2 = np.asarray(cov2, float)
    vals, vecs = np.linalg.eigh(0.5 * (cov2 + cov2.T))
    vals = np.clip(vals, 0, None)
    a, b = math.sqrt(vals[1]), math.sqrt(vals[0])
    return a, b, math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))


def ellipses(cov2) -> np.ndarray:
    """:func:`ellipse` of many 2x2 covariances at once: ``(n, 3)`` rows of
    ``a, b, angle`` (the same numbers, one batched eigen-decomposition)."""
    cov2 = np.asarray(cov2, float).reshape(-1, 2, 2)
    vals, vecs = np.linalg.eigh(0.5 * (cov2 + np.swapaxes(cov2, 1, 2)))
    vals = np.clip(vals, 0, None)
    return np.stack([np.sqrt(vals[:, 1]), np.sqrt(vals[:, 0]),
                     np.degrees(np.arctan2(vecs[:, 1, 1], vecs[:, 0, 1]))], axis=1)


def largest_ray_angles(rays, point, n_points) -> np.ndarray:
    """Largest angle (degrees) between two rays of each point.

    Parameters
    ----------
    rays : (m, 3) array
        Ray directions (camera centre minus point; any length).
    point : (m,) int array
        Index of each ray's point, 0 .. ``n_points - 1``.
    n_points : int

    Returns
    -------
    (n_points,) array
        NaN for points with fewer than two rays or non-finite rays. Points
        are taken together by their number of rays (one batched product per
        ray count instead of a loop over points).
    """
    out = np.full(n_points, np.nan)
    if not len(rays):
        return out
    with np.errstate(invalid="ignore", divide="ignore"):
        u = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    order = np.argsort(point, kind="stable")
    u, point = u[order], np.asarray(point)[order]
    count = np.bincount(point, minlength=n_points)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    for n in np.unique(count[count >= 2]):
        pts = np.flatnonzero(count == n)
        U = u[start[pts, None] + np.arange(n)]                    # (k, n, 3)
        cos = np.clip(np.einsum("kid,kjd->kij", U, U), -1.0, 1.0)
        out[pts] = np.degrees(np.arccos(cos.reshape(len(pts), -1).min(axis=1)))
    return out


#: layers with more elements than this are rasterized in the PDF (one image
#: instead of thousands of vector paths); smaller ones stay vector graphics
DENSE = 2500


def dense(n: int) -> bool:
    """Whether a layer of ``n`` elements is drawn rasterized (see DENSE)."""
    return n > DENSE


def nice(x: float) -> float:
    """The number 1, 2 or 5 x 10^k closest below ``x`` (> 0)."""
    if not (x > 0 and math.isfinite(x)):
        return 1.0
    e = math.floor(math.log10(x))
    m = x / 10 ** e
    return (5 if m >= 5 else 2 if m >= 2 else 1) * 10.0 ** e


def segments_path(a, b):
    """One matplotlib Path of the line segments ``a[i] -> b[i]`` (n, 2):
    MOVETO a[i], LINETO b[i]. Drawn as one PathPatch it looks the same as a
    LineCollection of the segments (one colour, no transparency) but costs
    one path instead of n (matplotlib builds and draws a Path per segment of
    a collection). Not simplified, so no segment is merged or dropped."""
    from matplotlib.path import Path

    a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
    verts = np.empty((2 * len(a), 2))
    verts[0::2], verts[1::2] = a, b
    codes = np.tile(np.array([Path.MOVETO, Path.LINETO], dtype=Path.code_type), len(a))
    path = Path(verts, codes)
    path.should_simplify = False
    return path


def cell_means(xy, v, size, ncols: int = 24):
    """Residual vectors averaged per cell of a grid of square cells over
    the image format.

    Parameters
    ----------
    xy : array_like (n, 2)
        Image positions (points outside the format count in the nearest
        border cell).
    v : array_like (n, 2)
        Residual vectors at ``xy``.
    size : (width, height)
        The image format.
    ncols : int
        Cells across the width; the rows follow from the cells being square.

    Returns
    -------
    centres : ndarray (m, 2)
        Centres of the m cells holding at least one point, row by row.
    means : ndarray (m, 2)
        Mean residual vector of each of them.
    counts : ndarray (nrows, ncols)
        Points per cell (row 0 at y = 0).
    """
    xy, v = np.asarray(xy, float).reshape(-1, 2), np.asarray(v, float).reshape(-1, 2)
    w, h = float(size[0]), float(size[1])
    cell = w / ncols
    nrows = max(1, math.ceil(h / cell - 1e-9))
    ix = np.clip(np.floor(xy[:, 0] / cell).astype(int), 0, ncols - 1)
    iy = np.clip(np.floor(xy[:, 1] / cell).astype(int), 0, nrows - 1)
    k = iy * ncols + ix
    n = np.bincount(k, minlength=nrows * ncols)
    sums = np.stack([np.bincount(k, v[:, j], minlength=nrows * ncols) for j in (0, 1)], axis=1)
    full = np.flatnonzero(n)
    centres = np.stack([(full % ncols + 0.5) * cell, (full // ncols + 0.5) * cell], axis=1)
    return centres, sums[full] / n[full, None], n.reshape(nrows, ncols)


def ray_counts(a, b, extent, shape, chunk: int = 1_000_000) -> np.ndarray:
    """How many of the segments ``a[i] -> b[i]`` cross each pixel of a grid.

    Every segment is walked as a digital line (DDA): one sample per pixel
    step along its longer axis and one at its end (unless that falls in the
    pixel of the step before), so a segment counts once in each pixel
    column (or row) it crosses, as a one-pixel aliased line. Samples outside
    the grid are dropped.

    Parameters
    ----------
    a, b : array_like (n, 2)
        Segment ends in data coordinates.
    extent : (x0, x1, y0, y1)
        The data rectangle the grid covers.
    shape : (rows, cols)
        Grid size in pixels; row 0 is at ``y0`` (``imshow(origin="lower")``).
    chunk : int
        Samples handled at once (bounds the memory).

    Returns
    -------
    ndarray (rows, cols) of int
    """
    a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
    rows, cols = int(shape[0]), int(shape[1])
    x0, x1, y0, y1 = (float(v) for v in extent)
    scale = np.array([cols / (x1 - x0), rows / (y1 - y0)])
    pa = (a - [x0, y0]) * scale                     # pixel coordinates
    pb = (b - [x0, y0]) * scale
    ok = np.all(np.isfinite(pa) & np.isfinite(pb), axis=1)
    pa, pb = pa[ok], pb[ok]
    d = pb - pa
    length = np.abs(d).max(axis=1)                  # along the longer axis, in pixels
    steps = np.ceil(length).astype(np.int64) + 1
    # x and y as separate contiguous columns, updated in place (issue 23: a
    # third of the time of the (n, 2) version; the same numbers bit for bit)
    ax, ay, dx, dy = (np.ascontiguousarray(v) for v in (pa[:, 0], pa[:, 1], d[:, 0], d[:, 1]))
    div = np.maximum(length, 1e-300)
    counts = np.zeros(rows * cols, np.int64)
    ends = np.cumsum(steps)
    start = 0
    while start < len(steps):                       # segments in chunks of samples
        stop = int(np.searchsorted(ends, ends[start - 1] + chunk if start else chunk,
                                   side="right"))
        stop = max(stop, start + 1)
        n = steps[start:stop]
        seg = np.repeat(np.arange(start, stop), n)
        first = np.cumsum(n) - n
        k = np.arange(int(n.sum()), dtype=np.int64)
        k -= np.repeat(first, n)
        t = np.minimum(k, length[seg])              # one pixel steps, the last to the end
        t /= div[seg]
        ix = dx[seg]
        ix *= t
        ix += ax[seg]
        ix = np.floor(ix, out=ix).astype(np.int64)
        iy = dy[seg]
        iy *= t
        iy += ay[seg]
        iy = np.floor(iy, out=iy).astype(np.int64)
        keep = (ix >= 0) & (ix < cols) & (iy >= 0) & (iy < rows)
        last = (first + n - 1)[n > 1]               # the end in the pixel of the step before
        keep[last[(ix[last] == ix[last - 1]) & (iy[last] == iy[last - 1])]] = False
        iy *= cols
        iy += ix
        counts += np.bincount(iy[keep], minlength=rows * cols)
        start = stop
    return counts.reshape(rows, cols)


def ray_layer(ax, a, b, color, alpha: float, dpi: float = 100.0, **kwargs):
    """Draw many segments as one image: each pixel gets the colour with the
    opacity of its stacked lines, ``1 - (1 - alpha)^count``
    (:func:`ray_counts`), as a collection of lines of opacity ``alpha``
    composites. Call after the axes limits are final.
    Returns the AxesImage."""
    from matplotlib.colors import to_rgb

    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    bbox = ax.get_window_extent().transformed(ax.figure.dpi_scale_trans.inverted())
    shape = (max(int(round(bbox.height * dpi)), 1), max(int(round(bbox.width * dpi)), 1))
    counts = ray_counts(a, b, (x0, x1, y0, y1), shape)
    rgba = np.empty(shape + (4,))
    rgba[..., :3] = to_rgb(color)
    rgba[..., 3] = 1.0 - (1.0 - alpha) ** counts
    return ax.imshow(rgba, extent=(x0, x1, y0, y1), origin="lower", interpolation="nearest",
                     aspect="auto", **kwargs)


def native_ray_layer(ax, a, b, color, alpha: float, dpi: float = 100.0, zorder=1.0):
    """:func:`ray_layer` on a native axes (:mod:`photogram.report.pdf.axes`):
    the same counts and opacity, one RGBA image."""
    from photogram.report.pdf.colors import rgb

    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    shape = (max(int(round(ax.height_in * dpi)), 1), max(int(round(ax.width_in * dpi)), 1))
    counts = ray_counts(a, b, (x0, x1, y0, y1), shape)
    rgba = np.empty(shape + (4,))
    rgba[..., :3] = rgb(color)
    rgba[..., 3] = 1.0 - (1.0 - alpha) ** counts
    return ax.imshow(rgba, extent=(x0, x1, y0, y1), origin="lower", aspect="auto",
                     zorder=zorder)
