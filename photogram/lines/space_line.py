"""3D lines from image lines (ski-jump paper, appendix C.2, step B).

**Step B, eqs. (C13)-(C14).** Image line j (ideal coordinates, view j)
defines the plane ``pi_j = P_j^T l_j`` through the projection centre
(views.py). The object line lies in every plane: for two points ``Y_1, Y_2``
of the line

    pi_j . (Y_k, 1) = Xc_z(Y_k) * (l_j . (x_k, 1)) = 0,    k = 1, 2    (C13)

where ``x_k = (x̄_k, ȳ_k)`` is the ideal image of ``Y_k``. Divided by the
depth (the weight ``Xc_z^-2``, as (C6) for points) the condition is the
signed image distance ``e_jk = l_j . (x_k, 1)`` of the projected line point
from the measured line, whose covariance is propagated from the line fit,

    C_j = X_j^T Sigma_lj X_j,    X_j = [(x_1, 1), (x_2, 1)]              (C14)

(the Gauss-Helmert weight ``(B Sigma B^T)^-1`` of the conditions). The 4
parameters of the line follow by Gauss-Newton with the weights ``C_j^-1``
from the initial solution (appendix C.3, initial.py). ``Y_1, Y_2`` are the
points of the initial line closest to the rays of the measured segment's end
points, kept (as line parameters t) during the iteration; the estimate does
not depend on that choice (any two distinct points of the line give an
equivalent pair of conditions with equivalent weights). Convergence is
quadratic for well-intersecting planes and linear (but fast) when a
direction of the line is weakly determined, e.g. a ski nearly parallel to
the baseline of two of the three cameras. With two views the solution is
the exact intersection of the two planes; the covariance is then the
propagated one and the redundancy ``2 k - 4`` is zero.

The estimator is :func:`photogram.lines.batch.intersect_lines_full`, the
one implementation for one line (:func:`intersect_line`, a batch of one)
and for many (Monte Carlo, :func:`photogram.lines.batch.intersect_lines_batch`).

The one-step solution, eq. (C15), is in :mod:`photogram.lines.one_step`;
:func:`~photogram.lines.from_points.intersect_line_from_points` runs either
from measured points.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.init.intersection import project_ideal
from photogram.lines.batch import intersect_lines_full
from photogram.lines.initial import (_homogeneous, _views, check_plane_geometry, line_planes,
                                     plane_angles)
from photogram.lines.plucker import SpaceLine, point_on_line, project_line_batch
from photogram.lines.views import fit_view_line

__all__ = ["LineIntersection", "intersect_line", "intersect_line_from_points"]


@dataclass(eq=False)
class LineIntersection:
    """A 3D line estimated from image lines.

    Attributes
    ----------
    line : SpaceLine
        With its 4x4 covariance (a-priori sigma of the image points; multiply
        by ``sigma0**2`` for the a-posteriori one). Its point is the point of
        the line closest to the centre of the measured segments.
    label : str or None
    stations : list of str
    method : str
        ``"two-step"`` (C13-C14) or ``"one-step"`` (C15).
    chi2 : float
        Weighted sum of squared residuals (a-priori sigma).
    redundancy : int
        ``2 k - 4`` (two-step) or ``sum n_j - 4`` (one-step).
    sigma0 : float
        ``sqrt(chi2 / redundancy)`` (NaN without redundancy).
    residuals : dict {station: ndarray}
        Two-step: distances (image units) of the measured segment's end
        points from the projected 3D line (2,); one-step: the orthogonal
        distances of all points (n_j,).
    plane_angles : ndarray (k, k)
        Angles between the planes of the views (radians).
    best_pair : tuple of str
        The two stations whose planes meet at the largest angle.
    extent : dict {station: ndarray (2,)}
        Line parameters ``t`` of the measured segment's end points (the
        points of the line closest to their rays).
    iterations : int
    converged : bool
    """

    line: SpaceLine
    label: str | None
    stations: list
    method: str
    chi2: float
    redundancy: int
    sigma0: float
    residuals: dict
    plane_angles: np.ndarray
    best_pair: tuple
    extent: dict
    iterations: int
    converged: bool
    image_lines: dict = field(default_factory=dict, repr=False)

    @property
    def max_plane_angle(self) -> float:
        return float(self.plane_angles.max())

    @property
    def segment(self) -> np.ndarray:
        """(2, 3) end points of the union of the measured segments."""
        t = np.concatenate(list(self.extent.values()))
        return point_on_line(self.line, np.array([t.min(), t.max()]))

    @property
    def length(self) -> float:
        t = np.concatenate(list(self.extent.values()))
        return float(t.max() - t.min())


# ---------------------------------------------------------------------------
# helpers


def _closest_t(L: SpaceLine, X0, rays) -> np.ndarray:
    """Parameters t of the points of L closest to the rays ``X0 + s r``;
    ``X0`` (..., 3), ``rays`` (..., m, 3) unit -> (..., m)."""
    w0 = L.point - np.asarray(X0, dtype=float)
    b = rays @ L.direction
    d = w0 @ L.direction
    e = np.einsum("...mi,...i->...m", rays, w0)
    den = 1.0 - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 1e-14, (b * e - d[..., None]) / den, -d[..., None])


class _Views:
    """The views of one line stacked into arrays (k views)."""

    def __init__(self, names, lines, cams):
        for n, line in zip(names, lines):
            if not hasattr(line, "cov_homogeneous"):
                raise InputError(f"intersect_line needs fitted image lines (ImageLine) with "
                                 f"their covariance; got {type(line).__name__} for {n}",
                                 hint="fit the points with fit_view_line")
            _homogeneous(line)                      # checks the frame
        self.names, self.lines, self.cams = names, lines, cams
        self.R = np.array([c.R for c in cams])
        self.X0 = np.array([c.X0 for c in cams])
        self.c = np.array([c.c for c in cams], dtype=float)
        self.l = np.array([line.homogeneous for line in lines])
        self.cov_l = np.array([line.cov_homogeneous for line in lines])
        self.ends = np.array([line.end_points for line in lines])            # (k, 2, 2)
        self.rays = np.array([c.rays(e) for c, e in zip(cams, self.ends)])    # (k, 2, 3)

    def extent(self, L) -> dict:
        t = np.sort(_closest_t(L, self.X0, self.rays), axis=1)
        return dict(zip(self.names, t))

    def end_point_residuals(self, L) -> dict:
        l, _ = project_line_batch(L, self.R, self.X0, self.c, names=self.names)
        d = np.einsum("kpi,ki->kp", self.ends, l[:, :2]) + l[:, 2:3]
        return dict(zip(self.names, d))


def _recentre(L, extent) -> SpaceLine:
    t = np.concatenate(list(extent.values()))
    return L.recentred(L.point + 0.5 * (t.min() + t.max()) * L.direction)


def _scale(L, cams) -> float:
    return float(np.mean([np.linalg.norm(L.point - c.X0) for c in cams]))


def _solve(N, g, what):
    try:
        return np.linalg.solve(N, g)
    except np.linalg.LinAlgError:
        raise GeometryError(f"{what}: singular normal equations",
                            hint="the planes of the views (nearly) coincide") from None


# ---------------------------------------------------------------------------
# step B (C13)-(C14)


def intersect_line(lines, cameras, *, label: str | None = None,
                   initial: SpaceLine | None = None, min_plane_angle_deg: float = 1.0,
                   strict: bool = True, max_iterations: int = 50,
                   tol: float = 1e-10) -> LineIntersection:
    """3D line from k >= 2 image lines, eqs. (C13)-(C14) (module docstring).

    Parameters
    ----------
    lines : dict {station: ImageLine} or sequence
        Lines fitted in ideal coordinates (:func:`fit_view_line`), with
        their covariance.
    cameras : dict {station: ViewCamera} or sequence
    label : str, optional
        Name of the line for messages (default: the lines' label).
    initial : SpaceLine, optional
        Start value (default the SVD initial line of appendix C.3,
        :func:`~photogram.lines.batch.initial_lines_batch`).
    min_plane_angle_deg : float
        The best pair of planes must meet at least at this angle.
    strict : bool
        With False the plane-angle check is skipped (used by the ski check
        to score inconsistent label assignments).
    max_iterations, tol :
        Gauss-Newton control: stop when the rotation is below ``tol`` rad and
        the shift below ``tol`` times the distance to the cameras.

    Returns
    -------
    LineIntersection

    Raises
    ------
    GeometryError
        A line in fewer than 2 images, or (nearly) coincident planes (line
        parallel to the baseline or in an epipolar plane), naming the
        stations.
    """
    names, lines, cams = _views(lines, cameras)
    if label is None:
        label = next((l.label for l in lines if getattr(l, "label", None)), None)
    planes = line_planes(lines, cams) if len(lines) else np.zeros((0, 4))
    pair, _ = check_plane_geometry(planes, names, label,
                                   min_plane_angle_deg if strict else -1.0)
    what = f"line {label}" if label else "line"
    views = _Views(names, lines, cams)
    # the one implementation: a batch of one line
    start = None if initial is None else (initial.point[None], initial.direction[None])
    out = intersect_lines_full(views.l[None], views.cov_l[None], views.ends[None],
                               views.R[None], views.X0[None], views.c[None], start,
                               max_iterations=max_iterations, tol=tol, what=what)
    L = SpaceLine(out.P[0], out.D[0], covariance=out.cov[0], label=label)
    chi2, it, converged = float(out.chi2[0]), int(out.iterations[0]), bool(out.converged[0])
    extent = views.extent(L)
    r = 2 * len(lines) - 4
    return LineIntersection(
        line=L, label=label, stations=names, method="two-step", chi2=chi2, redundancy=r,
        sigma0=float(np.sqrt(chi2 / r)) if r > 0 else float("nan"),
        residuals=views.end_point_residuals(L),
        plane_angles=plane_angles(planes), best_pair=(names[pair[0]], names[pair[1]]),
        extent=extent, iterations=it, converged=converged,
        image_lines=dict(zip(names, lines)))


# ---------------------------------------------------------------------------
# one step (C15)


def _sigma_of(sigma, name, n):
    s = sigma.get(name, 1.0) if isinstance(sigma, dict) else sigma
    s = np.broadcast_to(np.asarray(s, dtype=float), (n,))
    if not np.all(np.isfinite(s) & (s > 0)):
        raise InputError(f"sigma of the image points in {name} must be positive and finite")
    return s


def _check_count(points_by_view, label):
    k = len(points_by_view)
    if k < 2:
        where = f" ({', '.join(points_by_view)})" if k else ""
        what = f"line {label}" if label else "the line"
        raise GeometryError(
            f"{what} is measured in {k} image{'' if k == 1 else 's'}{where}; "
            f"a 3D line needs at least 2 images",
            hint="measure it in a second (better a third) oriented image")
