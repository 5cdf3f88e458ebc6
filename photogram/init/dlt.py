"""Direct linear transformation (DLT) and the decomposition of a projection
matrix into interior and exterior orientation.

Frames (see :mod:`photogram.project.model`): ``Xc = R (X - X0)`` with the
photogrammetric camera frame (x right, y up, looking along -z) and image
coordinates with y **down**. With the axis flip ``D = diag(1, -1, -1)`` the
"computer-vision" camera frame ``D Xc`` has y down and z forward, so that an
ideal camera is the projection matrix

    P = K D R [I | -X0],   K = [[c, 0, x0], [0, c, y0], [0, 0, 1]]      (1)

and ``x = (P X̃)_1 / (P X̃)_3``, ``y = (P X̃)_2 / (P X̃)_3``, which is the
collinearity equation ``x - x0 = -c Xc_x / Xc_z``, ``y - y0 = c Xc_y / Xc_z``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from photogram.errors import GeometryError
from photogram.geometry.rotations import matrix_to_opk

__all__ = ["dlt", "dlt_project", "dlt_residuals", "decompose_projection",
           "compose_projection", "FLIP"]

#: Camera-frame axis flip between the photogrammetric frame (y up, looking
#: along -z) and the computer-vision frame (y down, looking along +z).
FLIP = np.diag([1.0, -1.0, -1.0])


def _normalizing_transform(P: np.ndarray) -> np.ndarray:
    """Hartley's conditioning: similarity T with T p̃ centred at the origin
    and mean distance sqrt(d) (d = dimension of the points (n, d))."""
    d = P.shape[1]
    mu = P.mean(axis=0)
    dist = np.linalg.norm(P - mu, axis=1).mean()
    if not dist > 0:
        return np.eye(d + 1)
    f = np.sqrt(d) / dist
    T = np.eye(d + 1)
    T[:d, :d] *= f
    T[:d, d] = -f * mu
    return T


def _design(P: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The two homogeneous DLT rows per point of ``x̃ ~ H P̃`` (eq. 7.2; the
    same for a plane-to-image homography): ``P`` (n, k) homogeneous source
    points, ``x`` (n, 3) homogeneous image points with w = 1; returns the
    (2n, 3k) design matrix in the elements of ``H`` (3, k), row-major."""
    n, k = P.shape
    A = np.zeros((n, 2, 3 * k))
    A[:, 0, 0:k] = P
    A[:, 0, 2 * k:3 * k] = -x[:, 0:1] * P
    A[:, 1, k:2 * k] = P
    A[:, 1, 2 * k:3 * k] = -x[:, 1:2] * P
    return A.reshape(2 * n, 3 * k)


def _planarity(X: np.ndarray) -> tuple[np.ndarray, float]:
    """Singular values of the centred points and rms distance to their
    best-fitting plane."""
    sv = np.linalg.svd(X - X.mean(axis=0), compute_uv=False)
    return sv, float(sv[-1] / np.sqrt(len(X)))


def dlt(X, xy, *, planarity_tol: float = 1e-3) -> np.ndarray:
    """Projection matrix by the direct linear transformation.

    Solves the homogeneous system of Abdel-Aziz & Karara (1971) in the form
    of Hartley & Zisserman (2003, alg. 7.1): for every point the two rows

        [ X̃^T   0^T  -x X̃^T ] p = 0
        [ 0^T   X̃^T  -y X̃^T ] p = 0                                   (7.2)

    in the 12 elements ``p`` of ``P`` (row-major), after conditioning both
    point sets (object points centred with mean distance sqrt(3), image
    points sqrt(2)). ``p`` is the right singular vector of the smallest
    singular value; ``P = T_img^-1 P_n T_obj`` is then scaled so that
    ``||P[2, :3]|| = 1`` and ``det P[:, :3] > 0``, which makes the third
    element of ``P X̃`` the depth of the point in front of the camera.

    Parameters
    ----------
    X : array_like (n, 3)
        Object (control) points, n >= 6, not coplanar.
    xy : array_like (n, 2)
        Their image coordinates (x right, y down). Lens distortion is not
        modelled: pass distortion-corrected coordinates for best results.
    planarity_tol : float
        Relative threshold: the points count as coplanar when the smallest
        singular value of the centred object points is below
        ``planarity_tol`` times the largest.

    Returns
    -------
    ndarray (3, 4)
        The projection matrix ``P`` of eq. (1) of this module (11 independent
        elements: the DLT's L1..L11 are ``P / P[2, 3]`` without the last).

    Raises
    ------
    GeometryError
        Fewer than 6 points, (near-)coplanar object points, or a critical
        configuration that leaves the solution undetermined.
    """
    X = np.asarray(X, dtype=float)
    xy = np.asarray(xy, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or xy.shape != (len(X), 2):
        raise GeometryError(
            f"DLT needs object points (n, 3) and image points (n, 2), got "
            f"{X.shape} and {xy.shape}")
    n = len(X)
    if n < 6:
        raise GeometryError(
            f"DLT needs at least 6 control points, got {n}",
            hint="the projection matrix has 11 unknowns and each point gives "
                 "2 equations; with known interior orientation use space "
                 "resection (3+ points) instead")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(xy))):
        raise GeometryError("DLT: coordinates contain NaN or inf",
                            hint="drop points with unknown coordinates first")
    sv, rms = _planarity(X)
    if sv[0] == 0 or sv[2] <= planarity_tol * sv[0]:
        raise GeometryError(
            f"DLT needs non-coplanar control points; the {n} points lie in a "
            f"plane (rms off-plane {rms:.3g}, {sv[2] / sv[0] if sv[0] else 0:.2g} "
            f"of their extent)",
            hint="use space resection with known interior orientation instead")
    To = _normalizing_transform(X)
    Ti = _normalizing_transform(xy)
    Xn = np.c_[X, np.ones(n)] @ To.T                     # (n, 4)
    xn = np.c_[xy, np.ones(n)] @ Ti.T                    # (n, 3), w = 1
    _, s, Vt = np.linalg.svd(_design(Xn, xn))
    if s[-2] <= 1e-10 * s[0]:
        raise GeometryError(
            f"DLT solution is not unique for these {n} points (critical "
            f"configuration: the points and the camera lie on a twisted cubic "
            f"or the points are too few or degenerate)",
            hint="add control points in other directions and depths")
    P = np.linalg.solve(Ti, Vt[-1].reshape(3, 4) @ To)
    P /= np.linalg.norm(P[2, :3])
    if np.linalg.det(P[:, :3]) < 0:
        P = -P
    return P


def dlt_project(P, X) -> np.ndarray:
    """Image coordinates ``(P X̃)_{1,2} / (P X̃)_3`` of points X (n, 3)."""
    P = np.asarray(P, dtype=float)
    X = np.asarray(X, dtype=float)
    h = X @ P[:, :3].T + P[:, 3]
    return h[..., :2] / h[..., 2:3]


def dlt_residuals(P, X, xy) -> np.ndarray:
    """Reprojection residuals ``xy - project(P, X)`` (observed minus computed),
    (n, 2), in image units."""
    return np.asarray(xy, dtype=float) - dlt_project(P, X)


def compose_projection(c, x0, y0, R, X0, *, cy=None, skew=0.0) -> np.ndarray:
    """Projection matrix ``P = K D R [I | -X0]`` (eq. (1) of this module)
    from interior orientation (``c``, or ``c`` and ``cy`` for different
    scales in x and y, and ``skew``) and exterior orientation (world-to-
    camera ``R``, projection centre ``X0``)."""
    K = np.array([[c, skew, x0], [0.0, c if cy is None else cy, y0], [0.0, 0.0, 1.0]])
    M = K @ FLIP @ np.asarray(R, dtype=float)
    return np.c_[M, -M @ np.asarray(X0, dtype=float)]


def decompose_projection(P) -> dict:
    """Interior and exterior orientation from a projection matrix.

    RQ decomposition (Hartley & Zisserman 2003, sec. 6.2.4) of the left
    3x3 block ``M = K Q``, with ``K`` upper triangular with positive
    diagonal and ``Q`` a rotation (the overall sign of ``P`` is chosen so
    that ``det M > 0``). By eq. (1) of this module ``Q = D R``, hence
    ``R = D Q`` with ``D = diag(1, -1, -1)``, and the projection centre is
    the right null vector of ``P``: ``X0 = -M^-1 p4``.

    Parameters
    ----------
    P : array_like (3, 4)

    Returns
    -------
    dict
        ``c`` (mean of ``cx`` and ``cy``), ``cx``, ``cy`` (principal
        distance in x and y image units), ``aspect`` (``cy / cx``), ``skew``
        (``K[0, 1]``; 0 for a true camera), ``x0``, ``y0`` (principal point),
        ``K`` (3x3, ``K[2, 2] = 1``), ``R`` (world-to-camera, photogrammetric
        frame), ``angles`` (omega, phi, kappa of ``R``) and ``X0`` (3,).

    Raises
    ------
    GeometryError
        If ``M`` is singular (the camera centre is at infinity).
    """
    P = np.asarray(P, dtype=float)
    if P.shape != (3, 4) or not np.all(np.isfinite(P)):
        raise GeometryError(f"a projection matrix must be a finite (3, 4) array, got shape {P.shape}")
    M = P[:, :3]
    detM = np.linalg.det(M)
    if abs(detM) <= 1e-14 * np.linalg.norm(M) ** 3:
        raise GeometryError("projection matrix has a singular left 3x3 block "
                            "(affine camera or projection centre at infinity)",
                            hint="check the control points; the DLT needs a perspective view")
    if detM < 0:
        P = -P
        M = -M
    Kq, Q = scipy.linalg.rq(M)
    S = np.sign(np.diag(Kq))
    K = Kq * S                        # scale columns
    Q = S[:, None] * Q                # scale rows: K Q unchanged
    K = K / K[2, 2]
    R = FLIP @ Q
    X0 = -np.linalg.solve(M, P[:, 3])
    cx, cy = float(K[0, 0]), float(K[1, 1])
    return {
        "c": 0.5 * (cx + cy), "cx": cx, "cy": cy, "aspect": cy / cx,
        "skew": float(K[0, 1]), "x0": float(K[0, 2]), "y0": float(K[1, 2]),
        "K": K, "R": R, "angles": matrix_to_opk(R), "X0": X0,
    }
