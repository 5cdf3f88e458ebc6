"""Line photogrammetry, the one implementation: image lines of many groups
of points (appendix C.2, step A, eq. (C11); in
:mod:`photogram.lines.batch_image`) and, here, 3D lines from k image lines
each (step B, eqs. (C13)-(C14); the initial line of appendix C.3), all lines
of a batch in one vectorized evaluation.

The commands' per-line functions are batches of one:
:func:`photogram.lines.intersect_line` runs :func:`intersect_lines_full`;
Monte Carlo (:mod:`photogram.montecarlo.intersect`) runs
:func:`intersect_lines_batch` for all lines of a run (and the image lines by
:func:`photogram.lines.batch_image.fit_lines_batch`).

**3D lines** (eqs. (C13)-(C14)): Gauss-Newton in the 4 local parameters of
:class:`~photogram.lines.SpaceLine` with the weights ``C_j^-1`` of (C14),
the two points per view (closest to the rays of the measured segment's end
points) kept during the iteration, each line stopped by its own rule
(rotation below ``tol`` rad and shift below ``tol`` times the distance to
the cameras), then recentred to the middle of the measured segments; the
covariance and chi2 of (C14) there.

Ideal coordinates of any camera model come from
:func:`photogram.lines.views.ideal_coordinates` (the function
:meth:`ViewCamera.ideal` uses).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from photogram.errors import GeometryError

__all__ = ["local_basis_batch", "initial_lines_batch", "intersect_lines_full",
           "intersect_lines_batch"]


_AXIS_CROSS = np.array([[0, 2, 1], [2, 0, 0], [1, 0, 0]])   # e_i x D = S[i] * D[T[i]]
_AXIS_SIGN = np.array([[0.0, -1.0, 1.0], [1.0, 0.0, -1.0], [-1.0, 1.0, 0.0]])


def local_basis_batch(D):
    """:func:`photogram.lines.local_basis` for (L, 3) unit directions:
    ``u = e x D / |e x D|`` with e the world axis least aligned with D,
    ``v = D x u`` (``e x D`` as a signed permutation of D, exactly the
    cross product)."""
    idx = np.argmin(np.abs(D), axis=1)
    u = np.take_along_axis(D, _AXIS_CROSS[idx], axis=1) * _AXIS_SIGN[idx]
    u /= np.sqrt((u * u).sum(1))[:, None]
    return u, _cross(D, u)


# ---------------------------------------------------------------------------
# step B (C13)-(C14)


def _rays(xy, R, c):
    """Unit world directions of ideal image points: ``R^T (x, -y, -c)``."""
    dc = np.stack([xy[..., 0], -xy[..., 1], -np.broadcast_to(c, xy.shape[:-1])], -1)
    d = np.einsum("...ji,...j->...i", R, dc)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _closest_t(P, D, X0, rays):
    """Parameters t (L, k, 2) of the points of the lines closest to rays."""
    w0 = P[:, None, :] - X0                                    # (L, k, 3)
    b = np.einsum("lkmi,li->lkm", rays, D)
    dd = np.einsum("lki,li->lk", w0, D)
    e = np.einsum("lkmi,lki->lkm", rays, w0)
    den = 1.0 - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 1e-14, (b * e - dd[..., None]) / den, -dd[..., None])


def _two_points(P, D, X0, rays):
    """Parameters t (L, k, 2) of the two points Y_1, Y_2 per view: the
    points of the line closest to the rays of the segment's end points
    (moved apart by +-1 where they coincide)."""
    t = _closest_t(P, D, X0, rays)
    same = np.abs(t[..., 1] - t[..., 0]) < 1e-9 * (1.0 + np.abs(t).max(-1))
    t[same] += np.array([-1.0, 1.0])
    return t


def initial_lines_batch(l, R, X0, c):
    """Initial 3D lines (L lines, k views), appendix C.3 (``method="svd"`` of
    :func:`photogram.lines.initial_line_homogeneous`): the null space of the
    planes ``pi = P^T l`` conditioned by the centroid and RMS radius of the
    projection centres; the point closest to that centroid."""
    K = np.stack([-c, c, np.ones_like(c)], -1)                  # (L, k, 3)
    nrm = np.einsum("lkji,lkj->lki", R, K * l)                   # R^T K l
    pi4 = -np.einsum("lki,lki->lk", X0, nrm)
    s = np.linalg.norm(nrm, axis=-1)
    nrm, pi4 = nrm / s[..., None], pi4 / s
    centre = X0.mean(1)
    scale = np.sqrt(((X0 - centre[:, None]) ** 2).sum(-1).mean(1))
    scale = np.where(scale > 0, scale, 1.0)
    Pc = np.concatenate([nrm * scale[:, None, None],
                         (np.einsum("lki,li->lk", nrm, centre) + pi4)[..., None]], -1)
    Pc /= np.linalg.norm(Pc, axis=-1, keepdims=True)
    _, _, Vt = np.linalg.svd(Pc)
    x1, x2 = Vt[:, -2], Vt[:, -1]
    d = x1[:, 3:4] * x2[:, :3] - x2[:, 3:4] * x1[:, :3]
    m = _cross(x1[:, :3], x2[:, :3])
    dd = (d * d).sum(1)
    P = _cross(d, m) / dd[:, None]
    D = d / np.sqrt(dd)[:, None]
    return centre + scale[:, None] * P, D


def _cross(a, b):
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _line_system(P, D, t, l, cov_l, R, X0, c, u, v):
    """Normal equations of (C13)-(C14) of L lines at once: N (L,4,4),
    g (L,4), chi2 (L,).

    The conditions are the signed distances ``e = l . (x, 1)`` of the ideal
    images ``x`` of the points ``Y = P + t D`` from the image lines ((C13)
    divided by the depth), their covariance ``C = X^T Sigma_l X``,
    ``X = [(x_1, 1), (x_2, 1)]`` (C14), the weights ``W = C^-1``; the design
    matrix by the analytic derivative ``de/dY = l^T dx/dXc R`` and
    ``dY/d(alpha, beta, gamma, delta) = (t u, t v, u, v)``.
    (Written out element by element: for these small arrays numpy's stacked
    matrix products cost more than the arithmetic.)
    """
    L, k = t.shape[:2]
    RP = np.einsum("lkij,lkj->lki", R, P[:, None, :] - X0)[:, :, None, :]   # R (P - X0)
    RD = np.einsum("lkij,lj->lki", R, D)[:, :, None, :]
    Xc = RP + t[..., None] * RD                                  # R (Y - X0)   (L,k,2,3)
    iz = 1.0 / Xc[..., 2]
    cc = c[:, :, None]
    ax, ay = -Xc[..., 0] * iz, Xc[..., 1] * iz                   # c = 1
    x, y = cc * ax, cc * ay
    l0, l1, l2 = (l[..., i:i + 1] for i in range(3))
    e = x * l0 + y * l1 + l2                                     # (L,k,2)
    # l^T dxy/dXc = c/z (-l0, l1, l0 X/z - l1 Y/z); times R u, R v
    ci = cc * iz
    g0, g1, g2 = -l0 * ci, l1 * ci, (l0 * -ax - l1 * ay) * ci
    Ru = np.einsum("lkij,lj->lki", R, u)
    Rv = np.einsum("lkij,lj->lki", R, v)
    gu = g0 * Ru[..., 0:1] + g1 * Ru[..., 1:2] + g2 * Ru[..., 2:3]
    gv = g0 * Rv[..., 0:1] + g1 * Rv[..., 1:2] + g2 * Rv[..., 2:3]
    # C = Xt Sigma_l Xt^T, Xt = (x, y, 1) per point (C14)
    S = cov_l[..., None]                                         # (L,k,3,3,1)
    Sx0 = S[:, :, 0, 0] * x + S[:, :, 0, 1] * y + S[:, :, 0, 2]
    Sx1 = S[:, :, 1, 0] * x + S[:, :, 1, 1] * y + S[:, :, 1, 2]
    Sx2 = S[:, :, 2, 0] * x + S[:, :, 2, 1] * y + S[:, :, 2, 2]
    Cpp = x * Sx0 + y * Sx1 + Sx2                                # C_11, C_22
    C01 = x[..., 0] * Sx0[..., 1] + y[..., 0] * Sx1[..., 1] + Sx2[..., 1]
    det = Cpp[..., 0] * Cpp[..., 1] - C01 * C01
    W00, W11, W01 = Cpp[..., 1] / det, Cpp[..., 0] / det, -C01 / det
    A = np.empty((L, k, 2, 4))
    A[..., 0], A[..., 1], A[..., 2], A[..., 3] = t * gu, t * gv, gu, gv
    WA = np.empty((L, k, 2, 4))
    WA[:, :, 0] = W00[..., None] * A[:, :, 0] + W01[..., None] * A[:, :, 1]
    WA[:, :, 1] = W01[..., None] * A[:, :, 0] + W11[..., None] * A[:, :, 1]
    N = np.swapaxes(A.reshape(L, 2 * k, 4), 1, 2) @ WA.reshape(L, 2 * k, 4)
    We = np.empty((L, k, 2))
    We[..., 0] = W00 * e[..., 0] + W01 * e[..., 1]
    We[..., 1] = W01 * e[..., 0] + W11 * e[..., 1]
    g = (A * We[..., None]).sum((1, 2))
    chi2 = (e * We).sum((1, 2))
    return N, g, chi2


def intersect_lines_full(l, cov_l, ends, R, X0, c, start=None, *, max_iterations: int = 50,
                         tol: float = 1e-10, covariance: bool = True, what: str = "line"):
    """3D lines from k image lines each (step B, eqs. (C13)-(C14)), L lines
    at once; the estimator of :func:`photogram.lines.intersect_line`.

    Gauss-Newton in the local parameters ``(alpha, beta, gamma, delta)`` of
    each line (:meth:`photogram.lines.SpaceLine.update`) from the start
    lines, the two points per view fixed at the start; each line stops on
    its own when the rotation is below ``tol`` rad and the shift below
    ``tol`` times the mean distance of its start point from the cameras.
    Then the point is moved to the middle of the measured segments (the
    points of the line closest to the rays of their end points) and, with
    ``covariance``, the normal matrix of (C14) is evaluated there with two
    new points per view.

    Parameters
    ----------
    l, cov_l : (L, k, 3), (L, k, 3, 3) ideal image lines and covariances
    ends : (L, k, 2, 2) end points of the measured segments (ideal)
    R, X0, c : (L, k, 3, 3), (L, k, 3), (L, k) the views
    start : (P, D) or None
        Start lines (L, 3) each; default :func:`initial_lines_batch`.
    max_iterations, tol :
        Gauss-Newton control.
    covariance : bool
        Also the covariance (L, 4, 4) of the local parameters at the
        returned points and chi2 (L,).
    what : str
        The lines' name in the GeometryError of singular normal equations.

    Returns
    -------
    SimpleNamespace
        ``P``, ``D`` (L, 3) point and unit direction, ``iterations`` (L,),
        ``converged`` (L,) bool, ``rays`` (L, k, 2, 3) of the end points;
        with ``covariance`` also ``cov`` (L, 4, 4), ``chi2`` (L,).
    """
    if start is None:
        P, D = initial_lines_batch(l, R, X0, c)
    else:
        P, D = (np.array(a, dtype=float) for a in start)
    n = len(P)
    rays = _rays(ends, R[:, :, None], c[:, :, None])                    # (L,k,2,3)
    t = _two_points(P, D, X0, rays)
    dX = P[:, None] - X0
    scale = np.sqrt((dX * dX).sum(-1)).mean(1)
    its = np.zeros(n, dtype=int)
    converged = np.zeros(n, dtype=bool)
    active = np.ones(n, dtype=bool)
    for it in range(1, max_iterations + 1):
        u, v = local_basis_batch(D)
        N, g, _ = _line_system(P, D, t, l, cov_l, R, X0, c, u, v)
        try:
            step = -np.linalg.solve(N, g[..., None])[..., 0]
        except np.linalg.LinAlgError:
            raise GeometryError(f"{what}: singular normal equations",
                                hint="the planes of the views (nearly) coincide") from None
        Dn = D + step[:, 0:1] * u + step[:, 1:2] * v
        Dn /= np.sqrt((Dn * Dn).sum(1))[:, None]
        Pn = P + step[:, 2:3] * u + step[:, 3:4] * v
        small = ((np.abs(step[:, :2]).max(1) <= tol)
                 & (np.abs(step[:, 2:]).max(1) <= tol * scale))
        if active.all():
            P, D = Pn, Dn
        else:
            P, D = np.where(active[:, None], Pn, P), np.where(active[:, None], Dn, D)
        its[active] = it
        converged |= active & small
        active &= ~small
        if not active.any():
            break
    te = _closest_t(P, D, X0, rays)
    mid = P + (0.5 * (te.min(axis=(1, 2)) + te.max(axis=(1, 2))))[:, None] * D
    P = P + ((mid - P) * D).sum(1)[:, None] * D
    out = SimpleNamespace(P=P, D=D, iterations=its, converged=converged, rays=rays)
    if covariance:
        u, v = local_basis_batch(D)
        N, _, out.chi2 = _line_system(P, D, _two_points(P, D, X0, rays), l, cov_l, R, X0, c,
                                      u, v)
        out.cov = np.linalg.inv(N)
    return out


def intersect_lines_batch(l, cov_l, ends, R, X0, c, start=None, *, max_iterations=50,
                          tol=1e-10, covariance=False):
    """3D lines from k image lines each (step B), L lines at once:
    :func:`intersect_lines_full` as arrays.

    Parameters
    ----------
    l, cov_l, ends, R, X0, c, start, max_iterations, tol :
        As :func:`intersect_lines_full`.
    covariance : bool
        Also return the (L, 4, 4) covariance of the local parameters at the
        returned points and chi2 (L,).

    Returns
    -------
    P, D : (L, 3) point (recentred to the middle of the measured segments)
        and unit direction; with ``covariance`` also cov (L, 4, 4) and chi2.
    """
    out = intersect_lines_full(l, cov_l, ends, R, X0, c, start, max_iterations=max_iterations,
                               tol=tol, covariance=covariance, what="a 3D line")
    if not covariance:
        return out.P, out.D
    return out.P, out.D, out.cov, out.chi2
