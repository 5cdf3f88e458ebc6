"""Least-squares ellipse fit to edge points and the geometry of conics.

The fit is the numerically stable direct least-squares ellipse fit of
Halir & Flusser (1998, "Numerically stable direct least squares fitting of
ellipses"), itself a reformulation of Fitzgibbon, Pilu & Fisher (1999,
"Direct least square fitting of ellipses", IEEE PAMI 21(5)): the algebraic
distance is minimised under the ellipse constraint ``4AC - B^2 = 1``. The
points are centred and scaled first (Hartley-style normalisation). The
residual of each point is its Sampson distance (first-order geometric
distance, algebraic residual over the gradient norm).

Conic convention: ``A x^2 + B x y + C y^2 + D x + E y + F = 0``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["fit_ellipse", "fit_ellipses", "conic_centres", "sampson_distances", "conic_centre",
           "conic_axes", "sampson_distance", "conic_matrix",
           "conic_from_matrix"]


def fit_ellipse(xy: np.ndarray) -> np.ndarray | None:
    """Direct least-squares ellipse through points (Halir & Flusser 1998).

    Parameters
    ----------
    xy : (n, 2) array, n >= 6

    Returns
    -------
    (6,) array or None
        Conic coefficients ``A, B, C, D, E, F`` in the frame of ``xy``
        (scaled so that ``A^2 + ... + F^2 = 1``), or None when no ellipse
        fits (degenerate points).
    """
    xy = np.asarray(xy, float)
    if len(xy) < 6:
        return None
    m = xy.mean(axis=0)
    s = np.sqrt(((xy - m) ** 2).sum(axis=1).mean() / 2.0)
    if not s > 0:
        return None
    x = (xy[:, 0] - m[0]) / s
    y = (xy[:, 1] - m[1]) / s
    D1 = np.column_stack([x * x, x * y, y * y])
    D2 = np.column_stack([x, y, np.ones_like(x)])
    S1 = D1.T @ D1
    S2 = D1.T @ D2
    S3 = D2.T @ D2
    try:
        T = -np.linalg.solve(S3, S2.T)
    except np.linalg.LinAlgError:
        return None
    M = S1 + S2 @ T
    M = np.array([M[2] / 2.0, -M[1], M[0] / 2.0])
    w, v = np.linalg.eig(M)
    v = np.real(v)
    cond = 4 * v[0] * v[2] - v[1] ** 2
    ok = np.nonzero(cond > 0)[0]
    if len(ok) == 0:
        return None
    a1 = v[:, ok[0]]
    a2 = T @ a1
    A, B, C, D, E, F = np.concatenate([a1, a2])
    # back to the original frame: x' = (X - mx)/s
    A2, B2, C2 = A / s**2, B / s**2, C / s**2
    D2_ = D / s - 2 * A2 * m[0] - B2 * m[1]
    E2 = E / s - 2 * C2 * m[1] - B2 * m[0]
    F2 = (F + A2 * m[0] ** 2 + B2 * m[0] * m[1] + C2 * m[1] ** 2 - D / s * m[0]
          - E / s * m[1])
    conic = np.array([A2, B2, C2, D2_, E2, F2])
    return conic / np.linalg.norm(conic)


def conic_centre(conic: np.ndarray) -> np.ndarray:
    """Centre of a central conic: solves ``[2A B; B 2C] c = -[D; E]``."""
    A, B, C, D, E, _ = conic
    return np.linalg.solve(np.array([[2 * A, B], [B, 2 * C]]), -np.array([D, E]))


def conic_matrix(conic: np.ndarray) -> np.ndarray:
    """The symmetric 3 x 3 matrix Q with ``[x y 1] Q [x y 1]^T = 0``."""
    A, B, C, D, E, F = conic
    return np.array([[A, B / 2, D / 2], [B / 2, C, E / 2], [D / 2, E / 2, F]])


def conic_from_matrix(Q: np.ndarray) -> np.ndarray:
    """Inverse of :func:`conic_matrix`."""
    return np.array([Q[0, 0], 2 * Q[0, 1], Q[1, 1], 2 * Q[0, 2], 2 * Q[1, 2], Q[2, 2]])


def conic_axes(conic: np.ndarray) -> tuple[float, float, float]:
    """Semi-major axis, semi-minor axis and the angle (rad) of the major
    axis from +x of an ellipse; NaNs when the conic is no real ellipse."""
    Q = conic_matrix(conic)
    c = conic_centre(conic)
    F0 = c @ Q[:2, :2] @ c + 2 * Q[:2, 2] @ c + Q[2, 2]
    w, v = np.linalg.eigh(Q[:2, :2])
    with np.errstate(invalid="ignore", divide="ignore"):
        ax = np.sqrt(-F0 / w)
    if not np.all(np.isfinite(ax)):
        return float("nan"), float("nan"), float("nan")
    k = int(np.argmax(ax))                 # the major axis (either sign of the conic)
    major = v[:, k]
    return float(ax[k]), float(ax[1 - k]), float(np.arctan2(major[1], major[0]))


def sampson_distance(conic: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Signed first-order geometric distance of points from the conic."""
    A, B, C, D, E, F = conic
    x, y = xy[:, 0], xy[:, 1]
    alg = A * x * x + B * x * y + C * y * y + D * x + E * y + F
    gx = 2 * A * x + B * y + D
    gy = B * x + 2 * C * y + E
    return alg / np.maximum(np.hypot(gx, gy), 1e-300)


def fit_ellipses(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fit_ellipse` for many point sets at once (vectorised).

    Parameters
    ----------
    x, y : (n, m) arrays
        Point coordinates of n sets of m points.
    w : (n, m) bool or float
        Which points take part (weights).

    Returns
    -------
    conics : (n, 6), ok : (n,) bool
        Coefficients as in :func:`fit_ellipse`; ``ok`` False where fewer than
        6 points or no ellipse fits.
    """
    w = np.asarray(w, float)
    x = np.where(w > 0, x, 0.0)
    y = np.where(w > 0, y, 0.0)
    sw = w.sum(axis=1)
    n = len(x)
    conics = np.full((n, 6), np.nan)
    ok = sw >= 6
    if not ok.any():
        return conics, ok
    sw1 = np.maximum(sw, 1)
    mx = (w * x).sum(axis=1) / sw1
    my = (w * y).sum(axis=1) / sw1
    s = np.sqrt((w * ((x - mx[:, None]) ** 2 + (y - my[:, None]) ** 2)).sum(axis=1) / sw1 / 2)
    ok &= s > 0
    s = np.where(s > 0, s, 1.0)
    u = (x - mx[:, None]) / s[:, None]
    v = (y - my[:, None]) / s[:, None]
    D1 = np.stack([u * u, u * v, v * v], axis=2)
    D2 = np.stack([u, v, np.ones_like(u)], axis=2)
    S1 = np.einsum("nki,nkj,nk->nij", D1, D1, w)
    S2 = np.einsum("nki,nkj,nk->nij", D1, D2, w)
    S3 = np.einsum("nki,nkj,nk->nij", D2, D2, w)
    S3[~ok] = np.eye(3)
    det = np.linalg.det(S3)
    ok &= np.abs(det) > 1e-12
    S3[~ok] = np.eye(3)
    T = -np.linalg.solve(S3, np.transpose(S2, (0, 2, 1)))
    M = S1 + S2 @ T
    M = np.stack([M[:, 2] / 2.0, -M[:, 1], M[:, 0] / 2.0], axis=1)
    M[~ok] = np.eye(3)
    _, vec = np.linalg.eig(M)
    vec = np.real(vec)
    cond = 4 * vec[:, 0, :] * vec[:, 2, :] - vec[:, 1, :] ** 2          # (n, 3)
    good = cond > 0
    ok &= good.any(axis=1)
    k = np.argmax(good, axis=1)
    a1 = np.take_along_axis(vec, k[:, None, None].repeat(3, axis=1), 2)[..., 0]
    a2 = np.einsum("nij,nj->ni", T, a1)
    A, B, C = a1.T
    D, E, F = a2.T
    A2, B2, C2 = A / s**2, B / s**2, C / s**2
    D2_ = D / s - 2 * A2 * mx - B2 * my
    E2 = E / s - 2 * C2 * my - B2 * mx
    F2 = F + A2 * mx**2 + B2 * mx * my + C2 * my**2 - D / s * mx - E / s * my
    out = np.column_stack([A2, B2, C2, D2_, E2, F2])
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    conics[ok] = out[ok]
    return conics, ok


def conic_centres(conics: np.ndarray) -> np.ndarray:
    """:func:`conic_centre` of many conics (n, 6) -> (n, 2); NaN if not central."""
    A, B, C, D, E, _ = conics.T
    det = 4 * A * C - B * B
    with np.errstate(invalid="ignore", divide="ignore"):
        x = (B * E - 2 * C * D) / det
        y = (B * D - 2 * A * E) / det
    return np.column_stack([x, y])


def sampson_distances(conics: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """:func:`sampson_distance` of point sets (n, m) from their conics (n, 6)."""
    A, B, C, D, E, F = (c[:, None] for c in conics.T)
    alg = A * x * x + B * x * y + C * y * y + D * x + E * y + F
    gx = 2 * A * x + B * y + D
    gy = B * x + 2 * C * y + E
    return alg / np.maximum(np.hypot(gx, gy), 1e-300)
