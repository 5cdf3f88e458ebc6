"""One ski axis in an image (issue 19, item 4): :class:`BarLine`, the fitted
axis with its ends, width, grey and the covariance of its angle and shift;
where a ski is found first, before any fit (:func:`search_direction`: the
direction of a dark bar through the binding marker, :func:`extent_along`:
where it ends along that direction); the image noise of a background
difference (:func:`noise_sigma`); and the points sampled along a fitted axis
(:func:`sample_axis`). The axes are fitted in
:mod:`photogram.track.ski_edges` (its eqs. (1), (2)).

The axes become image lines measured by points (:func:`sample_axis`); eq.
(C11) of the ski-jump paper is then fitted to these points by
:func:`photogram.lines.views.fit_view_line`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import map_coordinates

__all__ = ["BarLine", "noise_sigma", "search_direction", "extent_along", "sample_axis"]


@dataclass
class BarLine:
    """One fitted ski axis in image pixels.

    ``point`` (2,) is on the axis, ``direction`` (2,) its unit direction
    (tail to tip), ``ends`` (2,) the positions of tail and tip along the
    direction from ``point``; ``width`` of the bar and ``contrast``: its
    grey (the bar replaces the background there); ``support`` the share of
    the bar's area seen in used pixels apart from the other bar (0..1); ``cov``
    (2, 2) the covariance of (angle [rad], shift across [px] at ``point``).
    """

    point: np.ndarray
    direction: np.ndarray
    ends: np.ndarray
    width: float
    contrast: float
    cov: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))
    support: float = np.nan

    @property
    def tail(self) -> np.ndarray:
        return self.point + self.ends[0] * self.direction

    @property
    def tip(self) -> np.ndarray:
        return self.point + self.ends[1] * self.direction

    @property
    def length(self) -> float:
        return float(self.ends[1] - self.ends[0])

    @property
    def normal(self) -> np.ndarray:
        return np.array([-self.direction[1], self.direction[0]])

    def distance(self, xy) -> np.ndarray:
        """Signed distances of points (n, 2) from the axis (px)."""
        return (np.atleast_2d(xy) - self.point) @ self.normal

    def sigma_across(self, t) -> np.ndarray:
        """Standard deviation across the axis at positions ``t`` along it
        (from ``point``): ``sqrt(var_d + 2 t cov + t^2 var_angle)``."""
        t = np.asarray(t, dtype=float)
        c = self.cov
        return np.sqrt(np.maximum(c[1, 1] + 2 * t * c[0, 1] + t * t * c[0, 0], 0.0))


def noise_sigma(diff: np.ndarray) -> float:
    """Robust standard deviation (1.4826 MAD) of a background difference
    image: the image noise where nothing moves."""
    d = np.asarray(diff, dtype=float)[::2, ::2].ravel()
    return float(1.4826 * np.median(np.abs(d - np.median(d)))) + 1e-6


def _sample(img, xy):
    """Bilinear samples of ``img`` at points xy (..., 2) (x = column, y = row);
    0 outside."""
    xy = np.asarray(xy, dtype=float)
    return map_coordinates(img, [xy[..., 1].ravel(), xy[..., 0].ravel()], order=1,
                           mode="constant", cval=0.0).reshape(xy.shape[:-1])


def search_direction(D, binding, toward=None, *, radius: float = 15.0,
                     step_deg: float = 0.5) -> tuple[np.ndarray, float]:
    """Direction of a dark bar through ``binding``: the angle whose two rays
    (forward and backward, 2..``radius`` px) are both dark.

    The score of a direction is the smaller of the two rays' mean darkness,
    so a leg (dark only on one side of the binding) does not win. The
    result is oriented towards ``toward`` (e.g. the helmet: the jumper leans
    over the tips).

    Returns
    -------
    direction : ndarray (2,)
    score : float
        The winning score (darkness units of ``D``).
    """
    phi = np.radians(np.arange(0.0, 180.0, step_deg))
    u = np.stack([np.cos(phi), np.sin(phi)], -1)
    r = np.arange(2.0, radius + 0.5, 0.5)
    b = np.asarray(binding, dtype=float)
    fwd = _sample(D, b + r[None, :, None] * u[:, None, :]).mean(1)
    back = _sample(D, b - r[None, :, None] * u[:, None, :]).mean(1)
    score = np.minimum(fwd, back)
    # smooth over +-1 step (noise), then the best direction
    score = (np.roll(score, 1) + 2 * score + np.roll(score, -1)) / 4
    i = int(np.argmax(score))
    d = u[i]
    if toward is not None and np.dot(np.asarray(toward, float) - b, d) < 0:
        d = -d
    return d, float(score[i])


def extent_along(D, point, direction, level, *, max_length: float = 200.0,
                 half_width: float = 2.0, gap: int = 3) -> tuple[float, float]:
    """Positions (back, forward) along a line where the dark bar ends: the
    profile (largest darkness within ``half_width`` across) drops below
    ``level`` for ``gap`` consecutive pixels."""
    p = np.asarray(point, float)
    u = np.asarray(direction, float)
    n = np.array([-u[1], u[0]])
    t = np.arange(0.0, max_length, 1.0)
    s = np.linspace(-half_width, half_width, 5)
    out = []
    for sign in (-1.0, 1.0):
        xy = p + sign * t[:, None, None] * u + s[None, :, None] * n
        prof = _sample(D, xy).max(1)
        below = prof < level
        run = np.convolve(below.astype(int), np.ones(gap, int), "valid") >= gap
        k = int(np.argmax(run)) if run.any() else len(t) - gap
        out.append(sign * t[max(k, 1)])
    return out[0], out[1]


def sample_axis(line: BarLine, n: int, shape, *, inset: float = 0.05,
                border: float = 2.0) -> np.ndarray:
    """``n`` points (n, 2) equally spaced along the visible part of an axis,
    tail to tip, ``inset`` of the length inside the ends and ``border`` px
    inside the image (``shape`` = (H, W)); empty when no part is visible."""
    H, W = shape
    a, b = line.ends
    L = b - a
    a, b = a + inset * L, b - inset * L
    p, u = line.point, line.direction
    # clip [a, b] to the image rectangle shrunk by border
    for k, (lo_, hi_) in enumerate(((border, W - 1 - border), (border, H - 1 - border))):
        if abs(u[k]) < 1e-12:
            if not lo_ <= p[k] <= hi_:
                return np.empty((0, 2))
            continue
        t1, t2 = (lo_ - p[k]) / u[k], (hi_ - p[k]) / u[k]
        a, b = max(a, min(t1, t2)), min(b, max(t1, t2))
    if b - a < 0.2 * L:
        return np.empty((0, 2))
    t = np.linspace(a, b, n)
    return p + t[:, None] * u
