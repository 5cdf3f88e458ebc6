"""Closed-form space resection: candidate exterior orientations of one image
from known object points, ideal image coordinates and the principal
distance, without approximate values.

* :func:`resection_direct` — Grunert's three-point solution (P3P) on
  well-spread triples of the points and, for planar point sets, the
  decomposition of the plane-to-image homography;
* the input checks shared with :mod:`photogram.init.resection_refine`.

Conventions as in :mod:`photogram.init.resection`: ``Xc = R (X - X0)``,
points in front of the camera have ``Xc_z < 0``, image y down.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError
from photogram.init.dlt import FLIP, _design, _normalizing_transform
from photogram.init.helmert import _umeyama
from photogram.init.rays import bearings

__all__ = ["resection_direct", "project_ideal"]


# ---------------------------------------------------------------- helpers --

def project_ideal(X, R, X0, c, x0=0.0, y0=0.0) -> np.ndarray:
    """Ideal collinearity ``x = x0 - c Xc_x/Xc_z``, ``y = y0 + c Xc_y/Xc_z``
    with ``Xc = R (X - X0)``; X (n, 3) -> (n, 2)."""
    Xc = (np.asarray(X, dtype=float) - X0) @ np.asarray(R).T
    return np.stack([x0 - c * Xc[:, 0] / Xc[:, 2], y0 + c * Xc[:, 1] / Xc[:, 2]], axis=1)


def _check_input(X, xy, need: int, what: str):
    X = np.asarray(X, dtype=float)
    xy = np.asarray(xy, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or xy.shape != (len(X), 2):
        raise GeometryError(
            f"{what} needs object points (n, 3) and image points (n, 2), got "
            f"{X.shape} and {xy.shape}")
    if len(X) < need:
        raise GeometryError(
            f"{what} needs at least {need} points, got {len(X)}",
            hint="space resection has 6 unknowns; 3 points give up to 4 "
                 "solutions, a 4th point (or more) picks the right one")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(xy))):
        raise GeometryError(f"{what}: coordinates contain NaN or inf",
                            hint="drop points with unknown coordinates first")
    return X, xy


def _check_not_collinear(X, xy, rel_tol: float = 1e-6):
    sv = np.linalg.svd(X - X.mean(axis=0), compute_uv=False)
    if sv[0] == 0 or sv[1] <= rel_tol * sv[0]:
        raise GeometryError(
            f"space resection needs 3 non-collinear object points; the "
            f"{len(X)} points lie on a line (rms off-line {sv[1] / np.sqrt(len(X)):.3g})",
            hint="a rotation about that line is undetermined: add a point away from it")
    svi = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    if svi[0] == 0 or svi[1] <= rel_tol * svi[0]:
        raise GeometryError(
            f"space resection: the {len(X)} image points are collinear although "
            f"the object points are not (the projection centre lies in their plane)",
            hint="use points that do not all lie in one plane through the camera")
    return sv


# ------------------------------------------------------------- P3P -------

def _polish_distances(s, cosines, sides2, iterations: int = 8):
    """Newton iterations on the three law-of-cosines equations
    ``s_j^2 + s_k^2 - 2 s_j s_k cos θ_i = d_i^2`` (for the pairs
    (2,3), (1,3), (1,2)); s (m, 3) candidate distances."""
    ca, cb, cg = cosines
    a2, b2, c2 = sides2
    for _ in range(iterations):
        s1, s2, s3 = s[:, 0], s[:, 1], s[:, 2]
        F = np.stack([s2 * s2 + s3 * s3 - 2 * s2 * s3 * ca - a2,
                      s1 * s1 + s3 * s3 - 2 * s1 * s3 * cb - b2,
                      s1 * s1 + s2 * s2 - 2 * s1 * s2 * cg - c2], axis=1)
        z = np.zeros_like(s1)
        J = np.stack([np.stack([z, 2 * s2 - 2 * s3 * ca, 2 * s3 - 2 * s2 * ca], 1),
                      np.stack([2 * s1 - 2 * s3 * cb, z, 2 * s3 - 2 * s1 * cb], 1),
                      np.stack([2 * s1 - 2 * s2 * cg, 2 * s2 - 2 * s1 * cg, z], 1)], 1)
        ok = np.abs(np.linalg.det(J)) > 1e-300
        ds = np.zeros_like(s)
        if ok.any():
            ds[ok] = np.linalg.solve(J[ok], F[ok][:, :, None])[:, :, 0]
        s = s - ds
    s1, s2, s3 = s[:, 0], s[:, 1], s[:, 2]
    F = np.stack([s2 * s2 + s3 * s3 - 2 * s2 * s3 * ca - a2,
                  s1 * s1 + s3 * s3 - 2 * s1 * s3 * cb - b2,
                  s1 * s1 + s2 * s2 - 2 * s1 * s2 * cg - c2], axis=1)
    return s, np.abs(F).max(axis=1) / max(a2, b2, c2)


def _p3p_grunert(Xw: np.ndarray, f: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Grunert's (1841) three-point resection in the form of Haralick et al.
    (1994, sec. 2.1).

    With side lengths ``a = |P2 P3|``, ``b = |P1 P3|``, ``c = |P1 P2|``, the
    angles α, β, γ between the rays (2,3), (1,3), (1,2) and the ratios
    ``u = s2/s1``, ``v = s3/s1`` of the unknown distances, elimination of u
    gives the quartic ``A4 v^4 + A3 v^3 + A2 v^2 + A1 v + A0 = 0``
    (Haralick et al. eq. 9); u follows from eq. (8), the distances from
    ``s1^2 = b^2 / (1 + v^2 - 2 v cos β)``. The distances are polished by
    Newton's method on the three law-of-cosines equations, and the pose by
    the absolute orientation of the points ``Xc_i = s_i f_i`` (closed-form
    rigid fit).

    Xw (3, 3) object points, f (3, 3) unit bearings (camera frame).
    Returns a list of up to 4 ``(R, X0)``.
    """
    P1, P2, P3 = Xw
    a2 = float(np.sum((P2 - P3) ** 2))
    b2 = float(np.sum((P1 - P3) ** 2))
    c2 = float(np.sum((P1 - P2) ** 2))
    ca = float(f[1] @ f[2])
    cb = float(f[0] @ f[2])
    cg = float(f[0] @ f[1])
    amc = (a2 - c2) / b2
    apc = (a2 + c2) / b2
    A4 = (amc - 1) ** 2 - 4 * c2 / b2 * ca * ca
    A3 = 4 * (amc * (1 - amc) * cb - (1 - apc) * ca * cg + 2 * c2 / b2 * ca * ca * cb)
    A2 = 2 * (amc * amc - 1 + 2 * amc * amc * cb * cb + 2 * (b2 - c2) / b2 * ca * ca
              - 4 * apc * ca * cb * cg + 2 * (b2 - a2) / b2 * cg * cg)
    A1 = 4 * (-amc * (1 + amc) * cb + 2 * a2 / b2 * cg * cg * cb - (1 - apc) * ca * cg)
    A0 = (1 + amc) ** 2 - 4 * a2 / b2 * cg * cg
    coef = np.array([A4, A3, A2, A1, A0])
    if not np.any(coef):
        return []
    roots = np.roots(coef)
    keep = np.abs(roots.imag) <= 1e-3 * np.maximum(1.0, np.abs(roots))
    v = roots.real[keep]
    v = v[v > 0]
    if v.size == 0:
        return []
    den = 2 * (cg - v * ca)
    num = (amc - 1) * v * v - 2 * amc * cb * v + 1 + amc
    with np.errstate(divide="ignore", invalid="ignore"):
        u = num / den
        s1 = np.sqrt(b2 / (1 + v * v - 2 * v * cb))
    s = np.stack([s1, u * s1, v * s1], axis=1)
    # where u is ill-determined (den ~ 0) take s2 from the c-equation
    bad = ~np.isfinite(s).all(axis=1) | (np.abs(den) < 1e-9)
    if bad.any():
        s1b = s[bad, 0]
        disc = np.maximum(s1b * s1b * (cg * cg - 1) + c2, 0.0)
        s[bad, 1] = s1b * cg + np.sqrt(disc)
    s = s[np.isfinite(s).all(axis=1)]
    if len(s) == 0:
        return []
    s, err = _polish_distances(s, (ca, cb, cg), (a2, b2, c2))
    good = (err < 1e-6) & (s > 0).all(axis=1)
    out = []
    seen = []
    for si in s[good]:
        if any(np.allclose(si, sj, rtol=1e-9, atol=0) for sj in seen):
            continue
        seen.append(si)
        Xc = si[:, None] * f
        _, R, t = _umeyama(Xw, Xc, np.ones(3), with_scale=False)
        out.append((R, -R.T @ t))
    return out


def _triples(X: np.ndarray, xy: np.ndarray) -> list[tuple[int, int, int]]:
    """Well-spread point triples: greedily maximal triangles in object space
    and in image space (vectorised over the points)."""
    out = []
    for P in (X, np.c_[xy, np.zeros(len(xy))]):
        i = int(np.argmax(np.linalg.norm(P - P.mean(axis=0), axis=1)))
        j = int(np.argmax(np.linalg.norm(P - P[i], axis=1)))
        area = np.linalg.norm(np.cross(P[j] - P[i], P - P[i]), axis=1)
        area[[i, j]] = -1.0
        k = int(np.argmax(area))
        tri = tuple(sorted((i, j, k)))
        if tri not in out:
            out.append(tri)
    return out


# ------------------------------------------------------ planar homography --

def _homography_pose(X, xy, c, x0, y0):
    """Pose from the homography between a plane and the image (Zhang 2000,
    sec. 3.1 / Hartley & Zisserman 2003, sec. 8.8).

    Plane coordinates ``(u, v)`` along the two principal directions ``E``
    of the points; normalized image coordinates ``m = ((x - x0)/c,
    (y - y0)/c, 1)`` in the y-down computer-vision frame. Then
    ``λ m = D R [e1 e2 (O - X0)] (u, v, 1)^T = H (u, v, 1)^T``; ``H`` from
    the DLT on >= 4 points, ``λ`` from the column norms, and the nearest
    rotation to ``[h1 h2 h1×h2] / λ``. Returns ``[(R, X0)]`` or ``[]``.
    """
    n = len(X)
    O = X.mean(axis=0)
    _, _, Vt = np.linalg.svd(X - O)
    E = Vt.T.copy()
    if np.linalg.det(E) < 0:
        E[:, 2] = -E[:, 2]
    uv = (X - O) @ E[:, :2]
    m = np.stack([(xy[:, 0] - x0) / c, (xy[:, 1] - y0) / c], axis=1)
    Tu = _normalizing_transform(uv)
    Tm = _normalizing_transform(m)
    U = np.c_[uv, np.ones(n)] @ Tu.T
    Mh = np.c_[m, np.ones(n)] @ Tm.T
    _, sv, Vh = np.linalg.svd(_design(U, Mh))
    if sv[-2] <= 1e-10 * sv[0]:
        return []
    H = np.linalg.solve(Tm, Vh[-1].reshape(3, 3) @ Tu)
    lam = 0.5 * (np.linalg.norm(H[:, 0]) + np.linalg.norm(H[:, 1]))
    H = H / lam
    if H[2, 2] < 0:               # centroid O must be in front (+z in CV frame)
        H = -H
    Q = np.c_[H[:, 0], H[:, 1], np.cross(H[:, 0], H[:, 1])]
    Uq, _, Vq = np.linalg.svd(Q)
    Q = Uq @ np.diag([1.0, 1.0, np.linalg.det(Uq @ Vq)]) @ Vq
    Rcv = Q @ E.T                 # = D R
    R = FLIP @ Rcv
    X0 = O - Rcv.T @ H[:, 2]
    return [(R, X0)]


# ---------------------------------------------------------- the candidates --

def resection_direct(X, xy_ideal, c, x0=0.0, y0=0.0, *,
                     planar_tol: float = 1e-6) -> list[tuple[np.ndarray, np.ndarray]]:
    """Closed-form candidates for the exterior orientation of one image.

    Grunert's three-point solution (Haralick et al. 1994, eqs. 8-9; see
    :func:`_p3p_grunert`) on well-spread triples of the points (the largest
    triangles in object and in image space; one triple when n = 3), plus,
    for planar point sets with ``n >= 4``, the pose from the plane-to-image
    homography (Zhang 2000, eqs. 2-3). Works for planar and non-planar sets.

    Parameters
    ----------
    X : array_like (n, 3), n >= 3
        Object points.
    xy_ideal : array_like (n, 2)
        Ideal (distortion-corrected) image coordinates, y down.
    c, x0, y0 : float
        Principal distance and principal point (image units).
    planar_tol : float
        Relative planarity below which the homography candidate is added.

    Returns
    -------
    list of (R, X0)
        Candidate world-to-camera rotations (3, 3) and projection centres
        (3,), all with the triple's points in front of the camera (up to 4
        per triple; possibly duplicates across triples). The homography
        candidate, if any, is last.

    Raises
    ------
    GeometryError
        Fewer than 3 points, collinear object points, or image points on a
        line (projection centre in the plane of the points).
    """
    X, xy = _check_input(X, xy_ideal, 3, "space resection")
    sv = _check_not_collinear(X, xy)
    f = bearings(xy, c, x0, y0)
    cands = []
    for tri in _triples(X, xy):
        idx = list(tri)
        cands.extend(_p3p_grunert(X[idx], f[idx]))
    if len(X) >= 4 and sv[2] <= planar_tol * sv[0]:
        cands.extend(_homography_pose(X, xy, c, x0, y0))
    return cands
