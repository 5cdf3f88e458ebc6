"""Vanishing points and the principal distance from them.

Image lines that are images of parallel object lines meet in a vanishing
point ``v``; the ray from the projection centre through ``v`` is parallel to
the object direction. With the principal point ``p = (x0, y0)`` and the
principal distance ``c`` the ray of ``v`` is ``(v - p, c)`` (up to the sign
conventions of the axes, which cancel below), so two vanishing points of
*orthogonal* object directions satisfy

    (v1 - p)·(v2 - p) + c² = 0,   i.e.   c² = -(v1 - p)·(v2 - p)        (B2)

(the standard form, e.g. Caprile & Torre 1990, Hartley & Zisserman 2003,
sec. 8.8, eq. 8.15 with ω = K^-T K^-1 for square pixels). Three vanishing
points of mutually orthogonal directions also fix the principal point: it
is the orthocentre of their triangle.

The ski-jump paper's appendix B (eqs. (B1)-(B2)) was not available when this
was written; (B1) here is the least-squares intersection of the lines and
(B2) the relation above.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError

__all__ = ["vanishing_point", "principal_distance_from_vanishing_points",
           "calibrate_from_vanishing_points", "lines_from_points"]


def lines_from_points(segments) -> np.ndarray:
    """Homogeneous lines ``l = p̃ × q̃`` through point pairs (m, 2, 2),
    normalized so that ``a² + b² = 1`` (then ``l · (x, y, 1)`` is the signed
    distance of a point from the line). Returns (m, 3)."""
    s = np.asarray(segments, dtype=float)
    p = np.c_[s[:, 0, :], np.ones(len(s))]
    q = np.c_[s[:, 1, :], np.ones(len(s))]
    L = np.cross(p, q)
    nrm = np.linalg.norm(L[:, :2], axis=1)
    if np.any(nrm == 0):
        bad = np.nonzero(nrm == 0)[0]
        raise GeometryError(
            f"vanishing point: line(s) {bad.tolist()} are given by two equal points",
            hint="give two distinct points on each line")
    return L / nrm[:, None]


def vanishing_point(lines, *, max_distance: float = 1e6, return_covariance: bool = False,
                    sigma: float | None = None):
    """Vanishing point of image lines (eq. (B1)).

    Each line is a homogeneous vector ``l`` (``l · (x, y, 1) = 0``). For two
    lines the vanishing point is ``v = l1 × l2``; for more it minimises
    ``Σ (l_i · v)² / |v|²`` with every line normalized to a unit normal, i.e.
    ``v`` is the right singular vector of the smallest singular value of the
    stacked lines (Hartley & Zisserman 2003, sec. 4.1 / 8.6.1). Both are
    computed in conditioned coordinates (the line points translated to
    their centroid and scaled to unit mean distance) and transformed back.

    Parameters
    ----------
    lines : array_like (m, 2, 2) or (m, 3)
        Point pairs ``[[x1, y1], [x2, y2]]`` on each line, or homogeneous
        lines ``(a, b, d)``; ``m >= 2``.
    max_distance : float
        A vanishing point farther than this many times the extent of the
        lines from their centre counts as at infinity.
    return_covariance : bool
        Also return the 2x2 covariance of the vanishing point.
    sigma : float, optional
        A-priori standard deviation of the endpoint coordinates (point
        pairs) or of the line positions (homogeneous lines), image units.
        If None it is estimated from the residuals (needs m >= 3; NaN
        covariance for m = 2).

    Returns
    -------
    v : ndarray (2,)
        The vanishing point in image coordinates.
    cov : ndarray (2, 2)
        Only with ``return_covariance``. First-order covariance of ``v``: to
        first order the SVD solution is the unweighted least-squares point
        of the distances ``r_i = l_i · (v, 1)``, ``J = [a_i b_i]``, so
        ``cov = (J^T J)^-1 J^T diag(var r_i) J (J^T J)^-1``. For a line
        through two endpoints with independent coordinate errors σ,
        ``var r_i = σ² (1/2 + 2 s_i² / L_i²)`` with ``L_i`` the segment
        length and ``s_i`` the position of ``v`` along the line from the
        segment's midpoint; ``var r_i = σ²`` for homogeneous lines.
        ``σ²`` is estimated as ``Σ r_i² / (var r_i / σ²) / (m - 2)`` unless
        given.

    Raises
    ------
    GeometryError
        Fewer than 2 lines, coincident lines, or lines that are parallel in
        the image (vanishing point at infinity).
    """
    a = np.asarray(lines, dtype=float)
    if a.ndim == 3 and a.shape[1:] == (2, 2):
        L = lines_from_points(a)
        pts = a.reshape(-1, 2)
    elif a.ndim == 2 and a.shape[1] == 3:
        nrm = np.linalg.norm(a[:, :2], axis=1)
        if np.any(nrm == 0):
            raise GeometryError("vanishing point: a homogeneous line has a = b = 0 "
                                "(the line at infinity)")
        L = a / nrm[:, None]
        pts = -L[:, :2] * L[:, 2:3]        # foot points of the perpendiculars from the origin
    else:
        raise GeometryError(
            f"vanishing point: lines must be point pairs (m, 2, 2) or homogeneous "
            f"lines (m, 3), got shape {a.shape}")
    m = len(L)
    if m < 2:
        raise GeometryError(f"a vanishing point needs at least 2 lines, got {m}")
    if not np.all(np.isfinite(L)):
        raise GeometryError("vanishing point: line coordinates contain NaN or inf")
    # conditioning T: x' = f (x - mu); lines transform as l' = T^-T l
    mu = pts.mean(axis=0)
    ext = np.linalg.norm(pts - mu, axis=1).mean()
    f = 1.0 / ext if ext > 0 else 1.0
    T = np.array([[f, 0.0, -f * mu[0]], [0.0, f, -f * mu[1]], [0.0, 0.0, 1.0]])
    Ln = L @ np.linalg.inv(T)                                   # rows: (T^-T l)^T
    Ln /= np.linalg.norm(Ln[:, :2], axis=1, keepdims=True)
    if m == 2:
        v = np.cross(Ln[0], Ln[1])
        if np.linalg.norm(v) < 1e-14:
            raise GeometryError("vanishing point: the two lines coincide",
                                hint="give lines that are images of distinct parallel object lines")
    else:
        _, s, Vt = np.linalg.svd(Ln)
        if s[1] < 1e-12 * s[0]:
            raise GeometryError("vanishing point: all lines coincide",
                                hint="give lines that are images of distinct parallel object lines")
        v = Vt[-1]
    v = v / np.linalg.norm(v)
    if abs(v[2]) * max_distance <= 1.0 * np.linalg.norm(v[:2]):
        raise GeometryError(
            "vanishing point: the lines are parallel in the image (vanishing "
            "point at infinity)",
            hint="the object direction is parallel to the image plane; it gives "
                 "no principal distance — use lines of a direction seen in perspective")
    vn = v[:2] / v[2]
    vp = mu + vn / f
    if not return_covariance:
        return vp
    r = L[:, :2] @ vp + L[:, 2]                        # signed distances
    if a.ndim == 3:
        seg = a[:, 1, :] - a[:, 0, :]
        length = np.linalg.norm(seg, axis=1)
        s_along = np.einsum("ij,ij->i", vp - 0.5 * (a[:, 0, :] + a[:, 1, :]), seg) / length
        q = 0.5 + 2.0 * (s_along / length) ** 2       # var r_i / sigma^2
    else:
        q = np.ones(m)
    if sigma is not None:
        s2 = float(sigma) ** 2
    elif m > 2:
        s2 = float((r * r / q).sum() / (m - 2))
    else:
        s2 = float("nan")
    J = L[:, :2]
    Ninv = np.linalg.inv(J.T @ J)
    cov = s2 * Ninv @ (J.T @ (J * q[:, None])) @ Ninv
    return vp, cov


def principal_distance_from_vanishing_points(v1, v2, x0, y0) -> np.ndarray | float:
    """Principal distance from the vanishing points of two orthogonal object
    directions (eq. (B2)).

    ``c = sqrt(-(v1 - p)·(v2 - p))`` with ``p = (x0, y0)``: the rays
    ``(v_i - p, c)`` of orthogonal directions have a zero scalar product
    (square pixels, no skew; the y-down image axis flips both rays alike and
    cancels).

    Parameters
    ----------
    v1, v2 : array_like (..., 2)
        Vanishing points (image units), broadcast against each other.
    x0, y0 : float or array_like
        Principal point.

    Returns
    -------
    float or ndarray (...)
        Principal distance in image units.

    Raises
    ------
    GeometryError
        If ``(v1 - p)·(v2 - p) >= 0``: the directions cannot be orthogonal
        for any real principal distance (wrong pairing, wrong principal
        point, or a vanishing point too close to the principal point).
    """
    v1 = np.asarray(v1, dtype=float)
    v2 = np.asarray(v2, dtype=float)
    p = np.stack(np.broadcast_arrays(np.asarray(x0, dtype=float),
                                     np.asarray(y0, dtype=float)), axis=-1)
    prod = np.sum((v1 - p) * (v2 - p), axis=-1)
    if np.any(~(prod < 0)):
        raise GeometryError(
            f"principal distance from vanishing points: (v1 - p)·(v2 - p) = "
            f"{np.max(prod):.6g} is not negative, so the two directions cannot "
            f"be orthogonal",
            hint="the vanishing points of orthogonal directions lie on opposite "
                 "sides of the principal point; check the line groups and (x0, y0)")
    c = np.sqrt(-prod)
    return float(c) if c.ndim == 0 else c


def calibrate_from_vanishing_points(v1, v2, v3) -> dict:
    """Principal point and principal distance from the vanishing points of
    three mutually orthogonal object directions.

    The principal point is the orthocentre of the triangle ``v1 v2 v3``
    (Caprile & Torre 1990): ``(v_i - p)·(v_j - p) = -c²`` for all pairs
    gives the linear equations ``(v1 - v2)·p = v3·(v1 - v2)``,
    ``(v2 - v3)·p = v1·(v2 - v3)``; then ``c`` from eq. (B2).

    Returns
    -------
    dict
        ``x0``, ``y0``, ``c``.

    Raises
    ------
    GeometryError
        Collinear vanishing points, or an obtuse triangle (no real c).
    """
    v1, v2, v3 = (np.asarray(v, dtype=float) for v in (v1, v2, v3))
    A = np.stack([v1 - v2, v2 - v3])
    b = np.array([v3 @ (v1 - v2), v1 @ (v2 - v3)])
    scale = max(np.abs(A).max(), 1e-300)
    if abs(np.linalg.det(A)) <= 1e-12 * scale ** 2:
        raise GeometryError("the three vanishing points are collinear",
                            hint="one of the directions must not be parallel to the image plane")
    p = np.linalg.solve(A, b)
    c = principal_distance_from_vanishing_points(v1, v2, p[0], p[1])
    return {"x0": float(p[0]), "y0": float(p[1]), "c": c}
