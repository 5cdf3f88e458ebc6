"""Spatial intersection of image rays (the ski-jump paper, appendix C.1).

Frames (see :mod:`photogram.project.model`): ``Xc = R (X - X0)`` with the
photogrammetric camera frame (x right, y up, looking along -z) and image
coordinates with y **down**. The ideal collinearity equations are

    x̄ = x - x0 = -c r1^T (X - X0) / r3^T (X - X0)
    ȳ = y - y0 = +c r2^T (X - X0) / r3^T (X - X0)                      (C1)

where ``r1, r2, r3`` are the rows of ``R``. Multiplied out they are linear in
the object point ``X`` (eq. (C5) of the paper in our sign convention):

    (x̄ r3 + c r1)^T (X - X0) = 0
    (ȳ r3 - c r2)^T (X - X0) = 0                                       (C5)

Each ray gives these two equations; with two or more rays the point follows by
linear least squares. The left-hand side of (C5) equals ``r3^T (X - X0)``
times the image residual, so the weights

    P = ((X - X0)^T r3)^-2                                              (C6)

(recomputed from the previous solution, starting with ``P = 1``) turn the
linear solution into a least-squares fit of the image residuals; at the fixed
point ``sum A^T P A`` is the Gauss-Newton normal matrix of the collinearity
equations (C1), which gives the precision estimate.

Everything is vectorized over rays: the 3x3 normal equations of all points are
accumulated at once (``np.bincount``) and solved as a stack. The ray helpers
(projection, ray directions, intersection angles) are in
:mod:`photogram.init.rays`; they are re-exported here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import GeometryError
from photogram.init.rays import (_group_sum, max_intersection_angles, project_ideal,
                                 ray_directions)

__all__ = ["IntersectionResult", "PointIntersection", "intersect", "intersect_points",
           "project_ideal", "ray_directions", "max_intersection_angles"]


# ---------------------------------------------------------------------------
# results


@dataclass
class IntersectionResult:
    """Intersected points (one row per distinct point index).

    Attributes
    ----------
    point_index : ndarray (m,) of int
        The distinct point indices, sorted; row k of every per-point array
        belongs to ``point_index[k]``.
    X : ndarray (m, 3)
        Object points (NaN where not ``valid``).
    covariance : ndarray (m, 3, 3)
        ``s^2 N^-1`` from the final weighted normal equations (C5, C6), with
        ``s`` the a-priori image sigma if one was given, else the point's
        a-posteriori ``sigma0`` (with two rays that rests on a redundancy of
        one). NaN for invalid points.
    sigma_xyz : ndarray (m, 3)
        Square roots of the covariance diagonal.
    sigma0 : ndarray (m,)
        A-posteriori standard deviation of an image coordinate,
        ``sqrt(v^T v / (2k - 3))`` for k rays (image units).
    n_rays : ndarray (m,) of int
    max_angle : ndarray (m,)
        Largest intersection angle between two rays of the point (radians).
    valid : ndarray (m,) of bool
        False for points with fewer than 2 rays or too small an intersection
        angle (only possible with ``strict=False``).
    reason : list of (str or None)
        Why a point is not valid.
    behind : ndarray (m,) of int
        Number of the point's rays whose camera sees it behind itself
        (``Xc_z >= 0``); zero for consistent data.
    residuals : ndarray (n, 2)
        Image residuals ``v = observed - computed`` per input ray, in the
        input's order (NaN for rays of invalid points).
    iterations : int
        Reweighting iterations done.
    converged : ndarray (m,) of bool
    """

    point_index: np.ndarray
    X: np.ndarray
    covariance: np.ndarray
    sigma_xyz: np.ndarray
    sigma0: np.ndarray
    n_rays: np.ndarray
    max_angle: np.ndarray
    valid: np.ndarray
    reason: list
    behind: np.ndarray
    residuals: np.ndarray
    iterations: int
    converged: np.ndarray


@dataclass
class PointIntersection:
    """One intersected point (see :func:`intersect`).

    Attributes
    ----------
    X : ndarray (3,)
    covariance : ndarray (3, 3)
    sigma_xyz : ndarray (3,)
    sigma0 : float
        A-posteriori sigma of an image coordinate (NaN with no redundancy).
    residuals : ndarray (k, 2)
        ``observed - computed`` ideal image coordinates.
    max_angle : float
        Largest intersection angle (radians).
    iterations : int
    converged : bool
    """

    X: np.ndarray
    covariance: np.ndarray
    sigma_xyz: np.ndarray
    sigma0: float
    residuals: np.ndarray
    max_angle: float
    iterations: int
    converged: bool


# ---------------------------------------------------------------------------
# the solvers


def _as_rays(xy_ideal, R, X0, c, x0y0):
    xy = np.asarray(xy_ideal, dtype=float)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise GeometryError(f"intersection: image coordinates must be (n, 2), got {xy.shape}")
    n = len(xy)
    R = np.asarray(R, dtype=float)
    if R.shape == (3, 3):
        R = np.broadcast_to(R, (n, 3, 3))
    X0 = np.asarray(X0, dtype=float)
    if X0.shape == (3,):
        X0 = np.broadcast_to(X0, (n, 3))
    c = np.broadcast_to(np.asarray(c, dtype=float), (n,))
    if R.shape != (n, 3, 3) or X0.shape != (n, 3):
        raise GeometryError(
            f"intersection: need one rotation (3, 3) and one projection centre (3,) "
            f"per ray; got {R.shape} and {X0.shape} for {n} rays")
    if x0y0 is not None:
        xy = xy - np.broadcast_to(np.asarray(x0y0, dtype=float), (n, 2))
    bad = ~(np.isfinite(xy).all(1) & np.isfinite(R).all((1, 2))
            & np.isfinite(X0).all(1) & np.isfinite(c))
    return xy, R, X0, c, bad


def intersect_points(point_index, xy_ideal, R, X0, c, x0y0=None, *,
                     sigma_image: float | None = None, min_angle_deg: float = 1.0,
                     max_iterations: int = 20, tol: float = 1e-12,
                     strict: bool = True, point_ids=None) -> IntersectionResult:
    """Intersect many points at once from their image rays (appendix C.1).

    Each ray contributes the two equations (C5); they are weighted with (C6)
    from the previous solution (``P = 1`` at the start) and the 3x3 normal
    equations ``N X = sum A^T P A X0`` of all points are accumulated by point
    and solved as a stack, until the largest change of any point is below
    ``tol`` times its distance to the cameras.

    Parameters
    ----------
    point_index : array_like (n,) of int
        Point of each ray (any integers; the result has one row per distinct
        value, sorted).
    xy_ideal : array_like (n, 2)
        Ideal (distortion-free) image coordinates; reduced to the principal
        point unless ``x0y0`` is given.
    R : array_like (n, 3, 3)
        World-to-camera rotation of each ray's station.
    X0 : array_like (n, 3)
        Projection centre of each ray's station.
    c : array_like (n,)
        Principal distance of each ray's camera (image units).
    x0y0 : array_like (n, 2) or (2,), optional
        Principal point, subtracted from ``xy_ideal``.
    sigma_image : float, optional
        A-priori sigma of an image coordinate; scales the covariance.
        Without it the covariance is scaled by each point's a-posteriori
        ``sigma0``.
    min_angle_deg : float
        Smallest acceptable largest intersection angle between two rays of a
        point (degrees). Points below it are degenerate (near-parallel rays).
    max_iterations, tol :
        Reweighting control.
    strict : bool
        Raise :class:`GeometryError` for the first degenerate point (fewer
        than two rays, near-parallel rays). With ``False`` such points come
        back with ``valid = False`` and a ``reason``.
    point_ids : sequence of str, optional
        Names for messages, indexed by ``point_index``.

    Returns
    -------
    IntersectionResult

    Raises
    ------
    GeometryError
        Malformed input; with ``strict``, a point with one ray or with rays
        intersecting at less than ``min_angle_deg``.
    """
    pidx = np.asarray(point_index)
    xy, R, X0, c, bad = _as_rays(xy_ideal, R, X0, c, x0y0)
    n = len(xy)
    if pidx.shape != (n,):
        raise GeometryError(f"intersection: point_index must have shape ({n},), got {pidx.shape}")
    if bad.any():
        k = int(np.nonzero(bad)[0][0])
        raise GeometryError(
            f"intersection: ray {k} ({_label(point_ids, pidx[k])}) has non-finite "
            f"image coordinates or orientation",
            hint="drop rays of stations that are not oriented yet")
    pts, inv = np.unique(pidx, return_inverse=True)
    inv = inv.reshape(-1)
    m = len(pts)
    n_rays = np.bincount(inv, minlength=m)
    d = ray_directions(xy, R, c)
    max_angle = max_intersection_angles(inv, d, m)
    min_angle = np.radians(min_angle_deg)

    reason: list = [None] * m
    valid = np.ones(m, dtype=bool)
    for k in np.nonzero(n_rays < 2)[0]:                # loop over bad points only
        valid[k] = False
        reason[k] = f"{_label(point_ids, pts[k])}: only {n_rays[k]} ray, needs 2"
    for k in np.nonzero((n_rays >= 2) & (max_angle < min_angle))[0]:
        valid[k] = False
        reason[k] = (f"{_label(point_ids, pts[k])}: rays nearly parallel "
                     f"(largest intersection angle {np.degrees(max_angle[k]):.3g} deg "
                     f"< {min_angle_deg:g} deg)")
    if strict and not valid.all():
        k = int(np.nonzero(~valid)[0][0])
        hint = ("a point needs rays from at least two oriented stations"
                if n_rays[k] < 2 else
                "the stations are too close together as seen from the point; "
                "use stations with a wider baseline or lower min_angle_deg")
        raise GeometryError(reason[k], hint=hint)

    r1, r2, r3 = R[:, 0, :], R[:, 1, :], R[:, 2, :]
    a1 = xy[:, :1] * r3 + c[:, None] * r1                 # (C5), x equation
    a2 = xy[:, 1:] * r3 - c[:, None] * r2                 # (C5), y equation
    b1 = np.einsum("ij,ij->i", a1, X0)
    b2 = np.einsum("ij,ij->i", a2, X0)
    outer = (a1[:, :, None] * a1[:, None, :] + a2[:, :, None] * a2[:, None, :])
    rhs_row = a1 * b1[:, None] + a2 * b2[:, None]
    w = np.ones(n)
    X = np.full((m, 3), np.nan)
    converged = np.zeros(m, dtype=bool)
    eye = np.eye(3)
    it = 0
    for it in range(1, max_iterations + 1):
        N = _group_sum(inv, w[:, None, None] * outer, m)
        rhs = _group_sum(inv, w[:, None] * rhs_row, m)
        N[~valid] = eye
        rhs[~valid] = 0.0
        X_new = np.linalg.solve(N, rhs[:, :, None])[:, :, 0]
        X_new[~valid] = np.nan
        depth = np.einsum("ij,ij->i", X_new[inv] - X0, r3)          # r3^T (X - X0)
        with np.errstate(divide="ignore"):
            w = np.where(np.abs(depth) > 0, 1.0 / np.where(depth == 0, 1.0, depth) ** 2, 0.0)
        w[~valid[inv]] = 1.0
        # rms depth of each point, the scale of the stopping rule
        dist = np.sqrt(_group_sum(inv, depth ** 2, m) / np.maximum(n_rays, 1))
        if it > 1:
            step = np.linalg.norm(X_new - X, axis=1)
            converged = valid & (step <= tol * np.maximum(dist, 1e-300))
        X = X_new
        if it > 1 and converged[valid].all():
            break

    # final weighted normal equations at the solution (C6)
    depth = np.einsum("ij,ij->i", X[inv] - X0, r3)
    with np.errstate(divide="ignore", invalid="ignore"):
        wf = 1.0 / depth ** 2
    wf[~valid[inv]] = 0.0
    N = _group_sum(inv, wf[:, None, None] * outer, m)
    N[~valid] = eye
    Q = np.linalg.inv(N)

    xy_hat = project_ideal(np.where(valid[inv, None], X[inv], 0.0), R, X0, c)
    res = xy - xy_hat
    res[~valid[inv]] = np.nan
    vtv = _group_sum(inv, np.where(valid[inv], (res ** 2).sum(1), 0.0), m)
    dof = 2 * n_rays - 3
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma0 = np.where(valid & (dof > 0), np.sqrt(vtv / np.maximum(dof, 1)), np.nan)
    scale = np.full(m, float(sigma_image)) if sigma_image is not None else sigma0
    cov = Q * (scale ** 2)[:, None, None]
    cov[~valid] = np.nan
    behind = np.bincount(inv, weights=(valid[inv] & (depth >= 0)).astype(float),
                         minlength=m).astype(int)
    sig = np.sqrt(np.einsum("kii->ki", cov))
    return IntersectionResult(point_index=pts, X=X, covariance=cov, sigma_xyz=sig,
                              sigma0=sigma0, n_rays=n_rays, max_angle=max_angle,
                              valid=valid, reason=reason, behind=behind, residuals=res,
                              iterations=it, converged=converged)


def intersect(xy_ideal, R, X0, c, x0y0=None, *, sigma_image: float | None = None,
              min_angle_deg: float = 1.0, max_iterations: int = 20,
              tol: float = 1e-12, point_id=None) -> PointIntersection:
    """Intersect one object point from k >= 2 rays (appendix C.1).

    Linear least squares of the equations (C5) with ``P = 1``, then
    iteratively reweighted with ``P = ((X - X0)^T r3)^-2`` (C6) until the
    change is insignificant. See :func:`intersect_points` for the vectorized
    version used for many points.

    Parameters
    ----------
    xy_ideal : array_like (k, 2)
        Ideal image coordinates of the point in k images, reduced to the
        principal point unless ``x0y0`` is given.
    R : array_like (k, 3, 3)
        World-to-camera rotations.
    X0 : array_like (k, 3)
        Projection centres.
    c : array_like (k,)
        Principal distances.
    x0y0 : array_like (k, 2) or (2,), optional
        Principal points.
    sigma_image : float, optional
        A-priori image sigma for the covariance (else the a-posteriori
        ``sigma0``, which with two rays rests on one redundant observation).
    min_angle_deg : float
        Rays intersecting at less than this (degrees) are rejected.
    point_id : str, optional
        Name for messages.

    Returns
    -------
    PointIntersection

    Raises
    ------
    GeometryError
        Fewer than 2 rays, or near-parallel rays.
    """
    xy = np.asarray(xy_ideal, dtype=float)
    if xy.ndim != 2:
        xy = xy.reshape(-1, 2)
    k = len(xy)
    if k < 2:
        raise GeometryError(
            f"{_label([point_id], 0)}: {k} ray, needs at least 2",
            hint="a point needs rays from at least two oriented stations")
    r = intersect_points(np.zeros(k, dtype=int), xy, R, X0, c, x0y0,
                         sigma_image=sigma_image, min_angle_deg=min_angle_deg,
                         max_iterations=max_iterations, tol=tol, strict=True,
                         point_ids=[point_id])
    return PointIntersection(X=r.X[0], covariance=r.covariance[0], sigma_xyz=r.sigma_xyz[0],
                             sigma0=float(r.sigma0[0]), residuals=r.residuals,
                             max_angle=float(r.max_angle[0]), iterations=r.iterations,
                             converged=bool(r.converged[0]))


def _name(point_ids, k) -> str:
    if point_ids is None:
        return str(k)
    try:
        return str(point_ids[int(k)])
    except (IndexError, TypeError, ValueError):
        return str(k)


def _label(point_ids, k) -> str:
    """``"point <id>"`` for messages (``"intersection"`` for an unnamed
    single point)."""
    if point_ids is not None and len(point_ids) == 1 and point_ids[0] is None:
        return "intersection"
    return f"point {_name(point_ids, k)}"
