"""Image lines of many groups of points at once (appendix C.2, step A,
eq. (C11)): the one implementation of the image-line fit.

:func:`photogram.lines.fit_image_line` (and
:func:`photogram.lines.fit_view_line`) run :func:`fit_points_padded` on one
group; Monte Carlo runs :func:`fit_lines_batch` over all lines of a run.

The Gauss-Helmert iteration of ``(q + v_q) = a (p + v_p) + b`` with the
equivalent weight ``w_i / (1 + a^2)`` in centred coordinates scaled to unit
RMS radius, the transposed form for steep lines
(:mod:`photogram.lines.image_line`), each group stopped by its own rule (two
small steps of ``a`` in a row). The a-priori sigma across the line of
corrected points is ``sigma_i |J_i^T n|`` with the normal n of the
unweighted principal axis (:func:`across_sigma`). The 3D lines (step B) are
in :mod:`photogram.lines.batch`.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

__all__ = ["fit_lines_padded", "line_layout", "across_sigma", "fit_points_padded", "fit_lines_batch",
           "image_line_arrays"]


def _major_axis(Sxx, Sxy, Syy):
    """Unit vector of the larger principal axis of 2x2 scatter matrices."""
    phi = 0.5 * np.arctan2(2.0 * Sxy, Sxx - Syy)
    return np.stack([np.cos(phi), np.sin(phi)], axis=-1)


# ---------------------------------------------------------------------------
# step A (C11)


def line_layout(group, n_groups):
    """Where the points of G groups go in the padded layout of
    :func:`fit_points_padded`: ``(src, mask)`` with ``padded = values[src]``
    (m, G), point i of group g at ``[i, g]`` in measurement order, padding
    repeating the group's first point; ``mask`` (m, G) the real points.
    Depends on the groups only: callers with fixed groups (Monte Carlo)
    compute it once."""
    group = np.asarray(group)
    order = np.argsort(group, kind="stable")
    cnt = np.bincount(group, minlength=n_groups)
    start = np.cumsum(cnt) - cnt
    rows = np.arange(len(group)) - start[group[order]]
    mask = np.zeros((int(cnt.max()), n_groups), dtype=bool)
    mask[rows, group[order]] = True
    src = np.broadcast_to(order[start], mask.shape).copy()
    src[rows, group[order]] = order
    return src, mask


def across_sigma(xi, J, sigma, mask):
    """A-priori sigma across the line of corrected points (m, G):
    ``sigma_i |J_i^T n|``, n the normal of the principal axis of the
    (unweighted) corrected points of each group.

    Parameters
    ----------
    xi : (m, G, 2) ideal coordinates, point i of group g at ``[i, g]``
        (padded, any finite values where not ``mask``)
    J : (m, G, 2, 2) d ideal / d measured
    sigma : (m, G) a-priori sigma of the measured coordinates
    mask : (m, G) real (not padding) points
    """
    if mask.all():
        u = xi - xi.sum(0) / len(xi)
    else:
        x = np.where(mask[..., None], xi, 0.0)
        u = np.where(mask[..., None], xi - x.sum(0) / mask.sum(0)[:, None], 0.0)
    a = _major_axis((u[..., 0] ** 2).sum(0), (u[..., 0] * u[..., 1]).sum(0),
                    (u[..., 1] ** 2).sum(0))
    n0, n1 = -a[:, 1], a[:, 0]
    Jn0 = J[..., 0, 0] * n0 + J[..., 1, 0] * n1                     # J^T n
    Jn1 = J[..., 0, 1] * n0 + J[..., 1, 1] * n1
    return sigma * np.sqrt(Jn0 * Jn0 + Jn1 * Jn1)


def fit_points_padded(xy, sig, mask, *, tol: float = 1e-13, max_iterations: int = 50,
                      residuals: bool = True):
    """Straight lines fitted to G groups of points at once, eq. (C11).

    The Gauss-Helmert adjustment of :func:`photogram.lines.fit_image_line`
    (module docstring of :mod:`photogram.lines.image_line`) for every group,
    each with its own stopping rule: the change of ``a`` (centred, scaled
    frame) below ``tol (1 + |a|)`` and that of ``b`` below ``tol`` in two
    successive iterations.

    Parameters
    ----------
    xy : (m, G, 2) points, point i of group g at ``[i, g]``, padded to the
        longest group (any finite values where not ``mask``)
    sig : (m, G) a-priori sigma of each point (isotropic), positive where
        ``mask``
    mask : (m, G) bool, the real points, first in each column; each group's
        first and last points orient the line, all groups need at least 2
    tol, max_iterations :
        Stopping rule and the most iterations.
    residuals : bool
        Also the residuals and the quantities from them (``residuals``,
        ``sigma0``, ``along``, ``across``; else None).

    Returns
    -------
    SimpleNamespace
        ``normal`` (G, 2), ``d`` (G,), ``centroid`` (G, 2), ``Sss`` and ``W``
        (G,) (``cov (theta, d_c) = diag(1/Sss, 1/W)``), ``residuals`` and
        ``s`` (m, G) (along-line coordinates from the centroid; zero at
        padding), ``s_range`` (G, 2), ``sigma0``, ``along``, ``across``,
        ``rms`` (G,), ``transposed`` (G,) bool, ``iterations`` (G,) int. A
        group whose points coincide has ``rms == 0`` and NaN results.
    """
    m, G = mask.shape
    full = bool(mask.all())                 # no padding: skip the masking
    cnt = mask.sum(0)
    w = 1.0 / sig ** 2 if full else np.where(mask, 1.0 / np.where(mask, sig, 1.0) ** 2, 0.0)
    W = w.sum(0)
    x, y = xy[..., 0].copy(), xy[..., 1].copy()        # (m, G) planes: faster arithmetic
    xc = np.stack([(w * x).sum(0) / W, (w * y).sum(0) / W], -1)
    dx, dy = x - xc[:, 0], y - xc[:, 1]
    if not full:
        dx[~mask] = 0.0
        dy[~mask] = 0.0
    rms = np.sqrt((w * (dx ** 2 + dy ** 2)).sum(0) / W)
    with np.errstate(divide="ignore", invalid="ignore"):
        ux, uy = dx / rms, dy / rms
    transposed = (w * uy ** 2).sum(0) > (w * ux ** 2).sum(0)
    p = np.where(transposed, uy, ux)
    q = np.where(transposed, ux, uy)

    # Gauss-Helmert iteration of q + v_q = a (p + v_p) + b, Q = sigma_i^2 I:
    # equivalent weight (B Q B^T)^-1 = w_i / (1 + a^2)  (C11)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (w * p * q).sum(0) / (w * p * p).sum(0)            # P = 1: ordinary LS
    ok = np.isfinite(a)
    a = np.where(ok, a, 0.0)
    b = np.zeros(G)
    vp = np.zeros((m, G))
    its = np.zeros(G, dtype=int)
    was_small = np.zeros(G, dtype=bool)
    active = ok.copy()
    all_ok = bool(ok.all())
    # the five sums of an iteration in one reduction: P B0^2, P B0 mis,
    # P mis, P B0, P
    prod = np.empty((5, m, G))
    P, PB0 = prod[4], prod[3]
    mis, B0, tmp = (np.empty((m, G)) for _ in range(3))
    all_active = all_ok
    for it in range(1, max_iterations + 1):
        aa = 1.0 + a * a
        np.divide(w, aa, out=P)
        np.multiply(a, p, out=mis)
        np.subtract(q, mis, out=mis)
        mis -= b                                           # w = f(l + v0) - B v0
        # A = (A0, -1), A0 = -(p + v_p) = -B0; the signs are taken out of the
        # sums below (exactly)
        np.add(p, vp, out=B0)
        np.multiply(P, B0, out=PB0)
        np.multiply(PB0, B0, out=prod[0])
        np.multiply(PB0, mis, out=prod[1])
        np.multiply(P, mis, out=prod[2])
        n00, r0, r1, n01, n11 = prod.sum(1)
        # the 2x2 normal equations by Cramer's rule
        det = n00 * n11 - n01 * n01
        if not all_ok:
            det[~ok] = 1.0
        da = (r0 * n11 - n01 * r1) / det
        db = (n00 * r1 - n01 * r0) / det
        # lam = (A dx + w) / (B B^T) = (A0 da - db + mis) / (1 + a^2)
        np.multiply(B0, da, out=tmp)
        tmp += db
        np.subtract(mis, tmp, out=tmp)
        tmp /= aa
        an, bn = a + da, b + db
        # the steps alternate large/small (a and v take turns), so stop after
        # two small ones in a row
        is_small = (np.abs(da) <= tol * (1.0 + np.abs(an))) & (np.abs(db) <= tol)
        if all_active:
            np.multiply(a, tmp, out=vp)                    # v = -B^T lam, B = (-a, 1)
            a, b = an, bn
            its[:] = it
        else:
            vp = np.where(active, a * tmp, vp)
            a, b = np.where(active, an, a), np.where(active, bn, b)
            its[active] = it
        active &= ~(is_small & was_small)
        was_small = is_small
        all_active = bool(active.all())
        if not all_active and not active.any():
            break
    a = np.where(ok, a, np.nan)

    nrm = np.hypot(a, 1.0)
    nvec = np.empty((G, 2))
    nvec[:, 0] = np.where(transposed, 1.0, -a)
    nvec[:, 1] = np.where(transposed, -a, 1.0)
    nvec /= nrm[:, None]
    d = b / nrm * rms + (nvec[:, 0] * xc[:, 0] + nvec[:, 1] * xc[:, 1])
    t = np.stack([nvec[:, 1], -nvec[:, 0]], -1)
    i_last = np.maximum(cnt - 1, 0), np.arange(G)
    flip = t[:, 0] * (x[i_last] - x[0]) + t[:, 1] * (y[i_last] - y[0]) < 0
    sgn = np.where(flip, -1.0, 1.0)
    nvec, d, t = nvec * sgn[:, None], d * sgn, t * sgn[:, None]
    s = dx * t[:, 0] + dy * t[:, 1]
    Sss = (w * s * s).sum(0)
    r = along = across = sigma0 = None
    if residuals:
        r = x * nvec[:, 0] + y * nvec[:, 1] - d
        if not full:
            r[~mask] = 0.0
        wrr = (w * r * r).sum(0)
        along = np.sqrt(Sss / W)
        across = np.sqrt(wrr / W)
        dof = cnt - 2
        with np.errstate(divide="ignore", invalid="ignore"):
            sigma0 = np.where(dof > 0, np.sqrt(wrr / dof), np.nan)
    if full:
        s_range = np.stack([s.min(0), s.max(0)], -1)
    else:
        s_range = np.stack([np.where(mask, s, np.inf).min(0),
                            np.where(mask, s, -np.inf).max(0)], -1)
    return SimpleNamespace(normal=nvec, d=d, centroid=xc, Sss=Sss, W=W, residuals=r, s=s,
                           s_range=s_range, sigma0=sigma0, along=along, across=across,
                           rms=rms, transposed=transposed, iterations=its)


def fit_lines_batch(xi, J, sigma, group, n_groups, *, layout=None, tol: float = 1e-13,
                    max_iterations: int = 50):
    """Image lines of many groups of ideal points at once (step A): the
    estimator of :func:`photogram.lines.fit_view_line` (:func:`across_sigma`
    and :func:`fit_points_padded`).

    Parameters
    ----------
    xi : (n, 2) ideal coordinates (corrected, relative to the principal point)
    J : (n, 2, 2) d ideal / d measured
    sigma : (n,) a-priori sigma of the measured coordinates
    group : (n,) group index per point, each group's points in measurement
        order (the first and last orient the line)
    n_groups : int
    layout : tuple, optional
        :func:`line_layout` of ``group`` (computed if not given).
    tol, max_iterations :
        Gauss-Helmert control (:func:`fit_points_padded`).

    Returns
    -------
    l : (G, 3) homogeneous lines ``(n_x, n_y, -d)``
    cov_l : (G, 3, 3) their covariance (rank 2)
    ends : (G, 2, 2) the extreme points projected onto the line
    """
    src, mask = layout if layout is not None else line_layout(group, n_groups)
    sg = np.broadcast_to(np.asarray(sigma, dtype=float), (len(xi),))[src]
    return fit_lines_padded(xi[src], J[src], sg, mask, tol=tol, max_iterations=max_iterations)


def fit_lines_padded(xi, J, sigma, mask, *, tol: float = 1e-13, max_iterations: int = 50):
    """:func:`fit_lines_batch` of points already in the padded layout of
    :func:`line_layout`: ``xi`` (m, G, 2), ``J`` (m, G, 2, 2), ``sigma``
    (m, G), ``mask`` (m, G) (a caller that computes its ideal coordinates
    in that layout saves the gathers)."""
    f = fit_points_padded(xi, across_sigma(xi, J, sigma, mask), mask, tol=tol,
                          max_iterations=max_iterations, residuals=False)
    return image_line_arrays(f)


def image_line_arrays(f):
    """Homogeneous lines ``l = (n_x, n_y, -d)`` (G, 3), their covariance
    (G, 3, 3) (rank 2, propagated from ``diag(1/Sss, 1/W)`` of
    ``(theta, d_c)``) and the end points (G, 2, 2) of fitted lines ``f``
    (:func:`fit_points_padded`); as :class:`~photogram.lines.ImageLine`'s
    ``homogeneous``, ``cov_homogeneous`` and ``end_points``."""
    nvec, xc = f.normal, f.centroid
    n0, n1 = nvec[:, 0], nvec[:, 1]
    t0, t1 = n1, -n0                                       # direction t = (n_y, -n_x)
    l = np.stack([n0, n1, -f.d], -1)
    # (theta, d_c) -> (theta, d): d = n(theta) . x_c + d_c, dn/dtheta = -t;
    # dl/d(theta, d) = ((-n_y, n_x, 0), (0, 0, -1)); written out
    vt, vd = 1.0 / f.Sss, 1.0 / f.W
    j = -(t0 * xc[:, 0] + t1 * xc[:, 1])
    cov_l = np.empty((len(nvec), 3, 3))
    cov_l[:, 0, 0] = n1 * n1 * vt
    cov_l[:, 0, 1] = cov_l[:, 1, 0] = -n1 * n0 * vt
    cov_l[:, 1, 1] = n0 * n0 * vt
    cov_l[:, 0, 2] = cov_l[:, 2, 0] = n1 * j * vt
    cov_l[:, 1, 2] = cov_l[:, 2, 1] = -n0 * j * vt
    cov_l[:, 2, 2] = j * j * vt + vd
    t = np.stack([t0, t1], -1)
    ends = xc[:, None, :] + f.s_range[:, :, None] * t[:, None, :]
    return l, cov_l, ends
