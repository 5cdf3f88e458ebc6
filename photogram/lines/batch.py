"""Line photogrammetry for many lines at once: image lines of many groups
of points (appendix C.2, step A, eq. (C11)) and 3D lines from k image lines
each (step B, eqs. (C13)-(C14); the initial line of appendix C.3), all lines
of a batch in one vectorized evaluation.

The estimators of :func:`photogram.lines.fit_view_line` and
:func:`photogram.lines.intersect_line`: the image line by the weighted
orthogonal regression in ideal coordinates with the weights of
:func:`fit_view_line` (the limit its Gauss-Helmert iteration converges to, in
closed form); the 3D line by Gauss-Newton in the 4 local parameters of
:class:`~photogram.lines.SpaceLine` with the weights (C14), the two points per
view kept during the iteration. Ideal coordinates of any camera model come
from :func:`photogram.lines.views.ideal_coordinates` (the function
:meth:`ViewCamera.ideal` uses). Tests check them against the per-line
functions; Monte Carlo (:mod:`photogram.montecarlo.intersect`) runs them.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError

__all__ = ["local_basis_batch", "fit_lines_batch", "initial_lines_batch",
           "intersect_lines_batch"]


def local_basis_batch(D):
    """:func:`photogram.lines.local_basis` for (L, 3) unit directions."""
    idx = np.argmin(np.abs(D), axis=1)
    e = np.zeros_like(D)
    e[np.arange(len(D)), idx] = 1.0
    u = _cross(e, D)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, _cross(D, u)


def _major_axis(Sxx, Sxy, Syy):
    """Unit vector of the larger principal axis of 2x2 scatter matrices."""
    phi = 0.5 * np.arctan2(2.0 * Sxy, Sxx - Syy)
    return np.stack([np.cos(phi), np.sin(phi)], axis=-1)


def fit_lines_batch(xi, J, sigma, group, n_groups):
    """Image lines of many groups of ideal points at once (step A).

    Parameters
    ----------
    xi : (n, 2) ideal coordinates (corrected, relative to the principal point)
    J : (n, 2, 2) d ideal / d measured
    sigma : (n,) a-priori sigma of the measured coordinates
    group : (n,) group index per point, each group's points in measurement
        order (the first and last orient the line)
    n_groups : int

    Returns
    -------
    l : (G, 3) homogeneous lines ``(n_x, n_y, -d)``
    cov_l : (G, 3, 3) their covariance (rank 2)
    ends : (G, 2, 2) the extreme points projected onto the line
    """
    def gsum(v):
        return np.bincount(group, weights=v, minlength=n_groups)

    cnt = gsum(np.ones(len(group)))
    m = np.stack([gsum(xi[:, 0]), gsum(xi[:, 1])], -1) / cnt[:, None]
    u = xi - m[group]
    a = _major_axis(gsum(u[:, 0] ** 2), gsum(u[:, 0] * u[:, 1]), gsum(u[:, 1] ** 2))
    n0 = np.stack([-a[:, 1], a[:, 0]], -1)[group]                 # unweighted normal
    sig = sigma * np.linalg.norm(np.einsum("nji,nj->ni", J, n0), axis=1)
    w = 1.0 / sig ** 2
    W = gsum(w)
    xc = np.stack([gsum(w * xi[:, 0]), gsum(w * xi[:, 1])], -1) / W[:, None]
    u = xi - xc[group]
    a = _major_axis(gsum(w * u[:, 0] ** 2), gsum(w * u[:, 0] * u[:, 1]), gsum(w * u[:, 1] ** 2))
    nvec = np.stack([-a[:, 1], a[:, 0]], -1)
    t = np.stack([nvec[:, 1], -nvec[:, 0]], -1)
    # orient from the first to the last point of each group
    first = np.full(n_groups, -1)
    last = np.full(n_groups, -1)
    idx = np.arange(len(group))
    np.maximum.at(last, group, idx)
    first_rev = np.full(n_groups, len(group))
    np.minimum.at(first_rev, group, idx)
    first = first_rev
    flip = np.einsum("gi,gi->g", t, xi[last] - xi[first]) < 0
    nvec[flip] *= -1.0
    t[flip] *= -1.0
    d = np.einsum("gi,gi->g", nvec, xc)
    s = np.einsum("ni,ni->n", xi - xc[group], t[group])
    Sss = gsum(w * s * s)
    smin = np.full(n_groups, np.inf)
    smax = np.full(n_groups, -np.inf)
    np.minimum.at(smin, group, s)
    np.maximum.at(smax, group, s)
    l = np.stack([nvec[:, 0], nvec[:, 1], -d], -1)
    # covariance of (theta, d_c) -> (theta, d) -> l
    G = len(W)
    cov_c = np.zeros((G, 2, 2))
    cov_c[:, 0, 0] = 1.0 / Sss
    cov_c[:, 1, 1] = 1.0 / W
    Jd = np.zeros((G, 2, 2))
    Jd[:, 0, 0] = 1.0
    Jd[:, 1, 0] = -np.einsum("gi,gi->g", t, xc)
    Jd[:, 1, 1] = 1.0
    Jh = np.zeros((G, 3, 2))
    Jh[:, 0, 0] = -nvec[:, 1]
    Jh[:, 1, 0] = nvec[:, 0]
    Jh[:, 2, 1] = -1.0
    T = Jh @ Jd
    cov_l = T @ cov_c @ np.swapaxes(T, 1, 2)
    ends = xc[:, None, :] + np.stack([smin, smax], -1)[:, :, None] * t[:, None, :]
    return l, cov_l, ends


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


def initial_lines_batch(l, R, X0, c):
    """Initial 3D lines (L lines, k views): null space of the conditioned
    planes ``pi = P^T l`` (appendix C.3, ``method="svd"``)."""
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
    m = np.cross(x1[:, :3], x2[:, :3])
    dd = np.einsum("li,li->l", d, d)
    P = np.cross(d, m) / dd[:, None]
    D = d / np.sqrt(dd)[:, None]
    return centre + scale[:, None] * P, D


def _cross(a, b):
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _line_system(P, D, t, l, cov_l, R, X0, c, u, v):
    """Normal equations (C13)-(C14) of L lines at once: N (L,4,4), g (L,4)."""
    Y = P[:, None, None, :] + t[..., None] * D[:, None, None, :]         # (L,k,2,3)
    Xc = (Y - X0[:, :, None, :]) @ np.swapaxes(R, -1, -2)               # R (Y - X0)
    iz = 1.0 / Xc[..., 2]
    cc = c[:, :, None]
    ax, ay = -Xc[..., 0] * iz, Xc[..., 1] * iz                          # c = 1
    x, y = cc * ax, cc * ay
    l0, l1, l2 = (l[..., i:i + 1] for i in range(3))
    e = x * l0 + y * l1 + l2                                            # (L,k,2)
    # l^T dxy/dXc = c/z (-l0, l1, l0 X/z - l1 Y/z)
    ci = cc * iz
    # (arrays filled in place: np.stack costs more than the arithmetic here)
    gx = np.empty(x.shape + (3,))                                       # (L,k,2,3)
    gx[..., 0] = -l0 * ci
    gx[..., 1] = l1 * ci
    gx[..., 2] = (l0 * -ax - l1 * ay) * ci
    g2 = gx @ R                                                         # d e / dY
    # C = Xt cov Xt^T with Xt = (x, y, 1)
    Xt = np.empty(x.shape + (3,))                                       # (L,k,2,3)
    Xt[..., 0], Xt[..., 1], Xt[..., 2] = x, y, 1.0
    C = Xt @ cov_l @ np.swapaxes(Xt, -1, -2)                            # (L,k,2,2)
    det = C[..., 0, 0] * C[..., 1, 1] - C[..., 0, 1] * C[..., 1, 0]
    W = np.empty(C.shape)
    W[..., 0, 0], W[..., 0, 1] = C[..., 1, 1], -C[..., 0, 1]
    W[..., 1, 0], W[..., 1, 1] = -C[..., 1, 0], C[..., 0, 0]
    W /= det[..., None, None]
    gu = (g2 * u[:, None, None, :]).sum(-1)
    gv = (g2 * v[:, None, None, :]).sum(-1)
    A = np.empty(gu.shape + (4,))                                       # (L,k,2,4)
    A[..., 0], A[..., 1], A[..., 2], A[..., 3] = t * gu, t * gv, gu, gv
    AtW = np.swapaxes(A, -1, -2) @ W                                    # (L,k,4,2)
    N = (AtW @ A).sum(1)
    g = (AtW @ e[..., None])[..., 0].sum(1)
    chi2 = (e[..., None, :] @ W @ e[..., None])[..., 0, 0].sum(1)
    return N, g, chi2


def intersect_lines_batch(l, cov_l, ends, R, X0, c, start=None, *, max_iterations=20,
                          tol=1e-10, covariance=False):
    """3D lines from k image lines each (step B), L lines at once.

    Parameters
    ----------
    l, cov_l : (L, k, 3), (L, k, 3, 3) ideal image lines and covariances
    ends : (L, k, 2, 2) end points of the measured segments (ideal)
    R, X0, c : (L, k, 3, 3), (L, k, 3), (L, k) the views
    start : (P, D) or None
        Start lines (L, 3) each; default the SVD initial lines.
    covariance : bool
        Also return the (L, 4, 4) covariance of the local parameters at the
        returned points.

    Returns
    -------
    P, D : (L, 3) point (recentred to the middle of the measured segments)
        and unit direction; with ``covariance`` also cov (L, 4, 4) and chi2.
    """
    if start is None:
        P, D = initial_lines_batch(l, R, X0, c)
    else:
        P, D = (np.array(a, dtype=float) for a in start)
    rays = _rays(ends, R[:, :, None], c[:, :, None])                    # (L,k,2,3)
    t = _closest_t(P, D, X0, rays)
    same = np.abs(t[..., 1] - t[..., 0]) < 1e-9 * (1.0 + np.abs(t).max(-1))
    t[same] += np.array([-1.0, 1.0])
    scale = np.mean(np.linalg.norm(P[:, None] - X0, axis=-1), axis=1)
    for _ in range(max_iterations):
        u, v = local_basis_batch(D)
        N, g, _ = _line_system(P, D, t, l, cov_l, R, X0, c, u, v)
        try:
            step = -np.linalg.solve(N, g[..., None])[..., 0]
        except np.linalg.LinAlgError:
            raise GeometryError("a 3D line has singular normal equations",
                                hint="the planes of its views (nearly) coincide") from None
        D = D + step[:, 0:1] * u + step[:, 1:2] * v
        D /= np.linalg.norm(D, axis=1, keepdims=True)
        P = P + step[:, 2:3] * u + step[:, 3:4] * v
        if (np.abs(step[:, :2]).max() <= tol
                and np.all(np.abs(step[:, 2:]).max(1) <= tol * scale)):
            break
    te = _closest_t(P, D, X0, rays)
    mid = 0.5 * (te.min(axis=(1, 2)) + te.max(axis=(1, 2)))
    P = P + mid[:, None] * D
    if not covariance:
        return P, D
    u, v = local_basis_batch(D)
    t = _closest_t(P, D, X0, rays)
    same = np.abs(t[..., 1] - t[..., 0]) < 1e-9 * (1.0 + np.abs(t).max(-1))
    t[same] += np.array([-1.0, 1.0])
    N, _, chi2 = _line_system(P, D, t, l, cov_l, R, X0, c, u, v)
    return P, D, np.linalg.inv(N), chi2
