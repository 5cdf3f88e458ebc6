"""Straight image lines fitted to measured points (ski-jump paper, appendix
C.2, step A, eq. (C11)).

The paper fits ``y = a x + b`` by least squares with the weight

    P = (1 + a^2)^-1                                                    (C11)

per point, iterated until ``a`` converges. The weight is the inverse of the
variance of the misclosure ``y - a x - b`` when *both* coordinates carry the
error sigma, so the weighted residual is the orthogonal distance of the point
from the line. We implement this as the standard Gauss-Helmert (mixed)
adjustment of the condition ``(y + v_y) - a (x + v_x) - b = 0`` (Mikhail &
Ackermann 1976; Niemeier, Ausgleichungsrechnung, sec. 5): its equivalent
weight ``(B Q B^T)^-1`` is exactly (C11), and the iteration converges to the
orthogonal (total least-squares) regression line.

To keep every direction well conditioned the iteration runs in coordinates
centred on the weighted centroid and scaled to unit RMS radius, with the
abscissa along the coordinate of larger spread (``y = a x + b`` for flat
lines, the transposed form ``x = a y + b`` for steep ones, so that
``|a| <~ 1``). The result is kept in the normal form

    n . x = d,   n = (cos theta, sin theta)

with the homogeneous vector ``l = (n_x, n_y, -d)`` (``l . (x, y, 1) = 0``);
the paper's ``(a, b)`` are available from :meth:`ImageLine.slope_intercept`.

The iteration is :func:`photogram.lines.batch_image.fit_points_padded`, the one
implementation for one line (:func:`fit_image_line`, a batch of one) and for
many (Monte Carlo, :func:`photogram.lines.batch_image.fit_lines_batch`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.lines.batch_image import fit_points_padded

__all__ = ["ImageLine", "fit_image_line", "normalize_line", "line_distance",
           "line_angle"]


@dataclass(eq=False)
class ImageLine:
    """A straight image line fitted to points (normal form ``n . x = d``).

    Attributes
    ----------
    normal : ndarray (2,)
        Unit normal ``n = (cos theta, sin theta)``. The line direction is
        ``t = (n_y, -n_x)``, oriented from the first to the last point.
    d : float
        ``n . x = d`` for points on the line.
    centroid : ndarray (2,)
        Weighted centroid of the points (lies on the line).
    cov_centroid : ndarray (2, 2)
        Covariance of ``(theta, d_c)``, the angle and the shift of the line
        along ``n`` at the centroid; diagonal (``1/sum w s^2``, ``1/sum w``,
        ``w = 1/sigma_i^2``, ``s_i`` along-line coordinates). From the
        a-priori sigma of the points, not scaled by ``sigma0``.
    residuals : ndarray (n,)
        Signed orthogonal distances ``n . x_i - d``.
    sigma : ndarray (n,)
        A-priori sigma of each point across the line (image units).
    sigma0 : float
        A-posteriori standard deviation of unit weight,
        ``sqrt(sum (r_i / sigma_i)^2 / (n - 2))`` (about 1 when the a-priori
        sigma is right; NaN for two points).
    s_range : ndarray (2,)
        Smallest and largest along-line coordinate of the points relative to
        the centroid (the measured segment).
    transposed : bool
        True if the iteration used the paper's transposed form ``x = a y + b``.
    iterations : int
    frame : str
        ``"image"`` (the coordinates as given) or ``"ideal"`` (corrected
        coordinates relative to the principal point, see
        :func:`photogram.lines.fit_view_line`).
    station, label : str or None
        For messages.
    """

    normal: np.ndarray
    d: float
    centroid: np.ndarray
    cov_centroid: np.ndarray
    residuals: np.ndarray
    sigma: np.ndarray
    sigma0: float
    s_range: np.ndarray
    transposed: bool = False
    iterations: int = 0
    frame: str = "image"
    station: str | None = None
    label: str | None = None

    # -- geometry -----------------------------------------------------------
    @property
    def theta(self) -> float:
        return float(np.arctan2(self.normal[1], self.normal[0]))

    @property
    def direction(self) -> np.ndarray:
        """Unit direction ``t = (n_y, -n_x)``."""
        return np.array([self.normal[1], -self.normal[0]])

    @property
    def n_points(self) -> int:
        return len(self.residuals)

    @property
    def homogeneous(self) -> np.ndarray:
        """``l = (n_x, n_y, -d)`` with ``l . (x, y, 1)`` the signed distance."""
        return np.array([self.normal[0], self.normal[1], -self.d])

    @property
    def covariance(self) -> np.ndarray:
        """Covariance (2, 2) of ``(theta, d)`` (d of the origin)."""
        # d = n(theta) . x_c + d_c, dn/dtheta = (-sin, cos) = -t
        J = np.array([[1.0, 0.0], [-self.direction @ self.centroid, 1.0]])
        return J @ self.cov_centroid @ J.T

    @property
    def cov_homogeneous(self) -> np.ndarray:
        """Covariance (3, 3) of :attr:`homogeneous` (rank 2)."""
        J = np.array([[-self.normal[1], 0.0],      # dl/d(theta, d)
                      [self.normal[0], 0.0],
                      [0.0, -1.0]])
        return J @ self.covariance @ J.T

    @property
    def end_points(self) -> np.ndarray:
        """(2, 2) the extreme points projected onto the line."""
        return self.point(self.s_range)

    @property
    def length(self) -> float:
        return float(self.s_range[1] - self.s_range[0])

    def point(self, s) -> np.ndarray:
        """Point(s) ``centroid + s t`` on the line."""
        s = np.asarray(s, dtype=float)
        return self.centroid + s[..., None] * self.direction

    def distance(self, xy) -> np.ndarray:
        """Signed distances ``n . x - d`` of points (n, 2)."""
        return np.asarray(xy, dtype=float) @ self.normal - self.d

    def normal_sigma(self, s) -> np.ndarray:
        """Standard deviation of the line's position across itself at
        along-line coordinate(s) ``s`` from the centroid."""
        s = np.asarray(s, dtype=float)
        return np.sqrt(self.cov_centroid[1, 1] + s * s * self.cov_centroid[0, 0])

    def slope_intercept(self, transposed: bool = False):
        """The paper's parameters (eq. (C11)) with their covariance.

        ``y = a x + b`` (or ``x = a y + b`` with ``transposed``).

        Returns
        -------
        a, b : float
        cov : ndarray (2, 2)

        Raises
        ------
        GeometryError
            If the line is (nearly) vertical for the chosen form.
        """
        nx, ny = self.normal
        i, j = (0, 1) if transposed else (1, 0)   # y = a x + b:  -a x + y = b
        if abs(self.normal[i]) < 1e-12:
            raise GeometryError(
                "line is parallel to the image " + ("x" if transposed else "y") +
                " axis: its slope form is undefined",
                hint="use the " + ("un" if transposed else "") + "transposed form or "
                     "the normal form (theta, d)")
        ni, nj = self.normal[i], self.normal[j]
        a, b = -nj / ni, self.d / ni
        # n = (cos theta, sin theta), dn/dtheta = (-sin, cos)
        dn = np.array([-ny, nx])
        da = -(dn[j] * ni - nj * dn[i]) / ni ** 2
        db = -self.d * dn[i] / ni ** 2
        J = np.array([[da, 0.0], [db, 1.0 / ni]])
        return float(a), float(b), J @ self.covariance @ J.T


# ---------------------------------------------------------------------------
# homogeneous helpers


def normalize_line(l) -> np.ndarray:
    """Homogeneous line(s) (..., 3) scaled so that ``l1^2 + l2^2 = 1``."""
    l = np.asarray(l, dtype=float)
    nrm = np.linalg.norm(l[..., :2], axis=-1, keepdims=True)
    if np.any(nrm == 0):
        raise GeometryError("homogeneous line (0, 0, w) is the line at infinity",
                            hint="the object line passes through the projection centre")
    return l / nrm


def line_distance(l, xy) -> np.ndarray:
    """Signed distances of points (n, 2) from the homogeneous line ``l``."""
    l = normalize_line(l)
    xy = np.asarray(xy, dtype=float)
    return xy @ l[:2] + l[2]


def line_angle(l1, l2) -> float:
    """Angle (radians, in [0, pi/2]) between two homogeneous image lines."""
    a, b = normalize_line(l1)[:2], normalize_line(l2)[:2]
    return float(np.arctan2(abs(a[0] * b[1] - a[1] * b[0]), abs(a @ b)))


# ---------------------------------------------------------------------------
# the fit


def _sigmas(sigma, n) -> np.ndarray:
    s = np.broadcast_to(np.asarray(sigma, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(s) & (s > 0)):
        raise InputError("image line fit: sigma must be positive and finite",
                         hint=f"got {np.asarray(sigma)!r}")
    return s


def fit_image_line(xy, sigma=1.0, *, tol: float = 1e-13, max_iterations: int = 50,
                   max_width_ratio: float = 0.5, frame: str = "image",
                   station: str | None = None, label: str | None = None) -> ImageLine:
    """Fit a straight line to image points (appendix C.2, step A, eq. (C11)).

    Least squares with the weight ``P = (1 + a^2)^-1`` of eq. (C11),
    iterated until ``a`` converges, as the Gauss-Helmert adjustment of
    ``(y + v_y) = a (x + v_x) + b`` (see the module docstring); in centred,
    scaled coordinates and with the transposed form ``x = a y + b`` for steep
    lines, so that every direction is equally well conditioned. The result
    minimises the weighted sum of squared orthogonal distances.

    Parameters
    ----------
    xy : array_like (n, 2)
        Points, n >= 2.
    sigma : float or array_like (n,)
        A-priori standard deviation of each point coordinate (isotropic).
    tol : float
        Stop when the change of ``a`` (in the centred, scaled frame) is below
        ``tol`` in two successive iterations.
    max_iterations : int
    max_width_ratio : float
        The points must spread along the line: the RMS orthogonal residual
        over the RMS along-line spread must stay below this.
    frame, station, label :
        Stored in the result.

    Returns
    -------
    ImageLine

    Raises
    ------
    InputError
        Malformed points or sigma.
    GeometryError
        Fewer than two distinct points, or points that do not lie along a
        line.
    """
    xy = np.asarray(xy, dtype=float)
    what = f"line {label}" + (f" in {station}" if station else "") if label else "image line"
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise InputError(f"{what}: points must be (n, 2), got {xy.shape}")
    if not np.isfinite(xy).all():
        raise InputError(f"{what}: non-finite image coordinates")
    n = len(xy)
    if n < 2:
        raise GeometryError(f"{what}: {n} point measured, a line needs at least 2",
                            hint="measure at least two (better 10-20) points along the line")
    sig = _sigmas(sigma, n)
    # the one implementation: a batch of one group
    f = fit_points_padded(xy[:, None], sig[:, None], np.ones((n, 1), dtype=bool), tol=tol,
                          max_iterations=max_iterations)
    if f.rms[0] == 0.0:
        raise GeometryError(f"{what}: all {n} points coincide",
                            hint="measure points spread along the line")
    along, across = float(f.along[0]), float(f.across[0])
    if along == 0.0 or across > max_width_ratio * along:
        raise GeometryError(
            f"{what}: the {n} points do not lie along a line (spread across "
            f"{across:.3g}, along {along:.3g} image units)",
            hint="check the measurements; a line through the projection centre "
                 "images as a point")
    cov = np.diag([1.0 / f.Sss[0], 1.0 / f.W[0]])
    return ImageLine(normal=f.normal[0], d=float(f.d[0]), centroid=f.centroid[0],
                     cov_centroid=cov, residuals=f.residuals[:, 0], sigma=sig,
                     sigma0=float(f.sigma0[0]), s_range=f.s_range[0],
                     transposed=bool(f.transposed[0]), iterations=int(f.iterations[0]),
                     frame=frame, station=station, label=label)
