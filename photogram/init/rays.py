"""Image rays and their projections, vectorized over rays.

The ideal collinearity equations of :mod:`photogram.init.intersection`
(frames of :mod:`photogram.project.model`: ``Xc = R (X - X0)``, camera frame
x right, y up, looking along -z; image coordinates y **down**):

    x̄ = -c Xc_x / Xc_z,   ȳ = c Xc_y / Xc_z                                (C1)

:func:`project_ideal` evaluates them (with their Jacobian),
:func:`bearings` and :func:`ray_directions` invert them to unit rays in the
camera and the world frame, and :func:`max_intersection_angles` measures
how well the rays of each point intersect. Shared by the intersection, the
relative orientation, the resection and the approximation chain.
"""

from __future__ import annotations

import numpy as np

__all__ = ["project_ideal", "bearings", "ray_directions", "max_intersection_angles"]


def project_ideal(X, R, X0, c, *, jacobians: bool = False):
    """Ideal collinearity projection (C1), vectorized over rays.

    Parameters
    ----------
    X : array_like (n, 3)
        Object points.
    R : array_like (n, 3, 3) or (3, 3)
        World-to-camera rotations.
    X0 : array_like (n, 3) or (3,)
        Projection centres.
    c : array_like (n,) or float
        Principal distances.
    jacobians : bool
        Also return ``d(x̄, ȳ)/dXc`` (n, 2, 3) and the camera coordinates.

    Returns
    -------
    xy : ndarray (n, 2)
        Image coordinates reduced to the principal point, ``(x̄, ȳ)``.
    J_c : ndarray (n, 2, 3)
        Only with ``jacobians``: derivative with respect to the camera
        coordinates ``Xc``.
    Xc : ndarray (n, 3)
        Only with ``jacobians``: the camera coordinates.
    """
    X = np.asarray(X, dtype=float)
    R = np.broadcast_to(np.asarray(R, dtype=float), X.shape[:-1] + (3, 3))
    X0 = np.asarray(X0, dtype=float)
    c = np.broadcast_to(np.asarray(c, dtype=float), X.shape[:-1])
    Xc = np.einsum("...ij,...j->...i", R, X - X0)
    z = Xc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = np.stack([-c * Xc[..., 0] / z, c * Xc[..., 1] / z], axis=-1)
        if not jacobians:
            return xy
        J = np.zeros(X.shape[:-1] + (2, 3))
        J[..., 0, 0] = -c / z
        J[..., 0, 2] = c * Xc[..., 0] / z ** 2
        J[..., 1, 1] = c / z
        J[..., 1, 2] = -c * Xc[..., 1] / z ** 2
    return xy, J, Xc


def bearings(xy, c, x0=0.0, y0=0.0) -> np.ndarray:
    """Unit ray directions in the photogrammetric camera frame.

    Inverting the ideal collinearity equations with ``Xc_z = -c``:
    ``d = (x - x0, -(y - y0), -c) / |.|``.

    Parameters
    ----------
    xy : array_like (n, 2)
        Ideal (distortion-free) image coordinates, y down.
    c, x0, y0 : float
        Principal distance and principal point, in image units.

    Returns
    -------
    ndarray (n, 3)
    """
    xy = np.asarray(xy, dtype=float)
    d = np.stack([xy[:, 0] - x0, -(xy[:, 1] - y0), np.full(len(xy), -float(c))], axis=1)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def ray_directions(xy_ideal, R, c) -> np.ndarray:
    """Unit ray directions in the world frame, ``R^T (x̄, -ȳ, -c) / |.|``.

    Parameters
    ----------
    xy_ideal : array_like (n, 2)
        Ideal image coordinates reduced to the principal point.
    R : array_like (n, 3, 3)
        World-to-camera rotations.
    c : array_like (n,)
        Principal distances.

    Returns
    -------
    ndarray (n, 3)
    """
    xy = np.asarray(xy_ideal, dtype=float)
    c = np.broadcast_to(np.asarray(c, dtype=float), xy.shape[:-1])
    d_cam = np.stack([xy[..., 0], -xy[..., 1], -c], axis=-1)
    d = np.einsum("...ji,...j->...i", np.asarray(R, dtype=float), d_cam)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _group_sum(inv: np.ndarray, values: np.ndarray, m: int) -> np.ndarray:
    """Sum rows of ``values`` (n, ...) into ``m`` groups given by ``inv`` (n,)."""
    flat = values.reshape(len(values), -1)
    out = np.empty((m, flat.shape[1]))
    for j in range(flat.shape[1]):           # loop over components, not rows
        out[:, j] = np.bincount(inv, weights=flat[:, j], minlength=m)
    return out.reshape((m,) + values.shape[1:])


def _pairs_within_groups(inv: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """All index pairs (i, j), i < j, of rows that belong to the same group."""
    order = np.argsort(inv, kind="stable")
    counts = np.bincount(inv, minlength=m)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    g = inv[order]
    local = np.arange(len(order)) - starts[g]
    npair = counts[g] - 1 - local                  # partners after this row
    total = int(npair.sum())
    if total == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    a = np.repeat(np.arange(len(order)), npair)
    first = np.repeat(np.cumsum(npair) - npair, npair)
    b = a + 1 + (np.arange(total) - first)
    return order[a], order[b]


def max_intersection_angles(point_index, directions, m: int | None = None) -> np.ndarray:
    """Largest angle (radians) between any two rays of each point.

    Parameters
    ----------
    point_index : array_like (n,) of int
        Group (point) index 0..m-1 of each ray.
    directions : array_like (n, 3)
        Unit ray directions.
    m : int, optional
        Number of points (default ``max(point_index) + 1``).

    Returns
    -------
    ndarray (m,)
        Zero for points with fewer than two rays.
    """
    inv = np.asarray(point_index, dtype=int)
    d = np.asarray(directions, dtype=float)
    if m is None:
        m = int(inv.max()) + 1 if len(inv) else 0
    out = np.zeros(m)
    i, j = _pairs_within_groups(inv, m)
    if len(i):
        cr = np.linalg.norm(np.cross(d[i], d[j]), axis=1)
        dt = np.einsum("ij,ij->i", d[i], d[j])
        np.maximum.at(out, inv[i], np.arctan2(cr, dt))
    return out
