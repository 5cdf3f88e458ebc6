"""The static scene of each camera: the snowy landing slope and the ball
targets of the field on their poles and masts, rendered once per camera.

The slope is the plane of :func:`photogram.simulation.designs.slope_height`
(35 degrees), prepared snow for |Y| <= 150 dm (bright, low-contrast grain,
grooming ridges along X, faint dyed distance lines across it every 5 m),
rougher snow beyond, a snowy forest (mid grey) beyond |Y| = 600 dm; where a ray misses the
slope it sees a hazy distant landscape below a wavy skyline and a bright
overcast sky above it. The targets are the control and tie points
of :func:`photogram.simulation.designs.field_design` drawn as dark balls;
the pole tops P1-P6 on thin poles, the mast targets F1 and F2 on masts,
F3 on a fence post.
"""

from __future__ import annotations

import numpy as np

from photogram.simulation.designs import FIELD_SEED, field_design, slope_height
from photogram.simulation.jump_video.raster import Shape, capsule_outline, paint

__all__ = ["static_points", "static_image", "TARGET_GREY"]

TARGET_GREY, POLE_GREY, MAST_GREY = 62.0, 96.0, 120.0
SLOPE_HALF_WIDTH, FOREST = 150.0, 600.0
_TABLE = 256


def static_points(seed: int = FIELD_SEED) -> tuple[list[str], np.ndarray]:
    """Ids and true coordinates (n, 3) of the field's control and tie
    points (dm), the static ball targets."""
    _, truth = field_design(seed)
    return list(truth["points"]["ids"]), np.asarray(truth["points"]["xyz"], float)


def _value_noise(x, y, scale, table):
    """Smooth value noise in [-1, 1] at world points, cell size ``scale``."""
    u, v = x / scale, y / scale
    i, j = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - i, v - j
    fu, fv = fu * fu * (3 - 2 * fu), fv * fv * (3 - 2 * fv)
    n = len(table)
    if n & (n - 1) == 0 and table.shape == (n, n):
        # a power of two: the wrapped index is the low bits (a % n for
        # negative a too), one lookup into the flat table; the wrapped
        # rows and columns are computed once for the four corners
        flat, low = table.ravel(), n - 1
        r0, r1 = (i & low) * n, ((i + 1) & low) * n
        c0, c1 = j & low, (j + 1) & low
        t00, t10, t01, t11 = flat[r0 | c0], flat[r1 | c0], flat[r0 | c1], flat[r1 | c1]
    else:
        t00, t10 = table[i % n, j % n], table[(i + 1) % n, j % n]
        t01, t11 = table[i % n, (j + 1) % n], table[(i + 1) % n, (j + 1) % n]
    top = t00 * (1 - fu) + t10 * fu
    bot = t01 * (1 - fu) + t11 * fu
    return top * (1 - fv) + bot * fv


def _slope_grey(X, Y, tables):
    """Grey level of the slope surface at world points (X, Y) (1-D); each
    noise is evaluated only where it is used (forest, slope, rough snow)."""
    out = np.empty(np.shape(X))
    forest = np.abs(Y) > FOREST
    Xf, Yf = X[forest], Y[forest]
    out[forest] = (150.0 + 20.0 * _value_noise(Xf, Yf, 12.0, tables[4])
                   + 10.0 * _value_noise(Xf, Yf, 2.5, tables[1]))
    snow = ~forest
    X, Y = X[snow], Y[snow]
    g = (212.0 + 7.0 * _value_noise(X, Y, 90.0, tables[0])
         + 3.5 * _value_noise(X, Y, 9.0, tables[1]) + 2.5 * _value_noise(X, Y, 1.6, tables[2]))
    prepared = np.abs(Y) <= SLOPE_HALF_WIDTH
    g += np.where(prepared, 1.5 * np.sin(2 * np.pi * Y / 2.5), 0.0)
    line = prepared & (np.abs(((X - 400.0) + 25.0) % 50.0 - 25.0) < 0.6)
    g -= np.where(line, 18.0, 0.0)
    rough = ~prepared
    g[rough] += -6.0 + 6.0 * _value_noise(X[rough], Y[rough], 4.0, tables[3])
    out[snow] = g
    return out


def _far(d, tables):
    """Grey of rays missing the slope: hazy landscape below the skyline,
    overcast sky above (by direction only: infinitely far)."""
    az = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    el = np.degrees(np.arcsin(np.clip(d[:, 2], -1.0, 1.0)))
    skyline = 2.0 + 1.5 * _value_noise(az, 0.0 * az, 6.0, tables[2])
    land = (150.0 + 12.0 * _value_noise(az, el, 2.0, tables[3])
            + 5.0 * _value_noise(az, el, 0.3, tables[4]) + 2.0 * el)
    sky = 226.0 + 0.4 * el
    return np.where(el < skyline, land, sky)


def _ideal_rows(camera, xs, ys, step: int = 8, rows: int = 128):
    """Ideal coordinates of the sample grid xs x ys, ``rows`` rows of ys at a
    time (each ``(rows * len(xs), 2)``, in the order of the grid's points,
    row by row): the camera model's correction on a coarse grid (every
    ``step`` px), bilinearly interpolated (the correction is smooth: < 1e-3
    px error)."""
    from scipy.interpolate import RegularGridInterpolator
    gx = np.arange(xs.min() - step, xs.max() + 2 * step, step)
    gy = np.arange(ys.min() - step, ys.max() + 2 * step, step)
    gxx, gyy = np.meshgrid(gx, gy)
    ideal = camera.ideal(np.column_stack([gxx.ravel(), gyy.ravel()]))
    interp = [RegularGridInterpolator((gy, gx), ideal[:, k].reshape(len(gy), len(gx)))
              for k in range(2)]
    for r in range(0, len(ys), rows):
        xx, yy = np.meshgrid(xs, ys[r:r + rows])
        q = np.column_stack([yy.ravel(), xx.ravel()])
        yield np.column_stack([f(q) for f in interp])


def _background(camera, size, rng, ss: int = 2) -> np.ndarray:
    """Ray-traced slope (float image, h x w), ``ss x ss`` samples per px;
    traced a band of rows at a time (the rays of the whole image at once
    took ~0.3 GB)."""
    w, h = size
    tables = [rng.uniform(-1.0, 1.0, (_TABLE, _TABLE)) for _ in range(5)]
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    xs = (np.arange(w)[:, None] + sub).ravel()
    ys = (np.arange(h)[:, None] + sub).ravel()
    # plane Z = slope_height(X): n . X = k with n = (tan a, 0, 1)
    n = np.array([-(slope_height(1.0) - slope_height(0.0)), 0.0, 1.0])
    k = float(slope_height(0.0))
    bands = []
    for ideal in _ideal_rows(camera, xs, ys):
        d = camera.rays(ideal)
        t = (k - n @ camera.X0) / (d @ n)
        hit = camera.X0 + t[:, None] * d
        front = t > 0
        grey = np.empty(len(t))
        grey[front] = _slope_grey(hit[front, 0], hit[front, 1], tables)
        grey[~front] = _far(d[~front], tables)
        bands.append(grey)
    return np.concatenate(bands).reshape(h, ss, w, ss).mean(axis=(1, 3))


def _target_shapes(camera, ids, X, radius):
    """Shapes of the ball targets, their poles, masts and post."""
    foot = X.copy()
    foot[:, 2] = slope_height(X[:, 0])
    parts = []                                       # (A, B, r, grey)
    for i, pid in enumerate(ids):
        if pid[0] == "P":
            parts.append((foot[i], X[i] - [0, 0, radius], 0.25, POLE_GREY))
        elif pid in ("F1", "F2"):
            parts.append((foot[i], X[i] + [0, 0, 25.0], 1.0, MAST_GREY))
        elif pid == "F3":
            parts.append((foot[i], X[i] - [0, 0, radius], 0.4, POLE_GREY))
    A = np.array([p[0] for p in parts])
    B = np.array([p[1] for p in parts])
    Xs = np.vstack([X, A, B])
    xy = camera.project(Xs)
    depth = -((Xs - camera.X0) @ camera.R.T)[:, 2]
    f = camera.c / depth
    n, m = len(X), len(parts)
    shapes = [Shape(capsule_outline(xy[i], xy[i], radius * f[i], radius * f[i]),
                    TARGET_GREY, depth[i]) for i in range(n)]
    for j, (_, _, r, g) in enumerate(parts):
        a, b = n + j, n + m + j
        shapes.append(Shape(capsule_outline(xy[a], xy[b], r * f[a], r * f[b]), g,
                            0.5 * (depth[a] + depth[b])))
    return shapes


def static_image(camera, size, *, target_radius: float, seed: int) -> np.ndarray:
    """The static scene of one camera (float image h x w, grey 0-255; a
    read-only array cached per camera, size, radius and seed)."""
    key = (camera.name, camera.X0.tobytes(), camera.R.tobytes(), camera.io.tobytes(),
           tuple(size), float(target_radius), int(seed))
    if key not in _CACHE:
        if len(_CACHE) >= 12:
            _CACHE.pop(next(iter(_CACHE)))
        img = _static_image(camera, size, target_radius, seed)
        img.flags.writeable = False
        _CACHE[key] = img
    return _CACHE[key]


_CACHE: dict = {}


def _static_image(camera, size, target_radius, seed):
    rng = np.random.default_rng([seed, 7])
    bg = _background(camera, size, rng)
    ids, X = static_points()
    shapes = _target_shapes(camera, ids, X, target_radius)
    return paint(bg, (0, 0, size[0], size[1]), shapes, []).astype(np.float64)
