"""Space resection: the exterior orientation of one image from known object
points and known interior orientation.

* :func:`resection_direct` — closed-form candidates: Grunert's three-point
  solution (P3P) and, for planar point sets, the decomposition of the
  plane-to-image homography.
* :func:`resect` — picks the candidate that reprojects all points best.
* :func:`refine_resection` — Gauss-Newton least squares with the full camera
  model (distortion included) of :mod:`photogram.geometry`.

Conventions (:mod:`photogram.project.model`): ``Xc = R (X - X0)``, camera
frame x right, y up, looking along -z (points in front have ``Xc_z < 0``);
image coordinates x right, y down; ideal collinearity
``x - x0 = -c Xc_x / Xc_z``, ``y - y0 = c Xc_y / Xc_z``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import GeometryError
from photogram.geometry.rotations import matrix_to_opk, opk_to_matrix, small_rotation
from photogram.init.dlt import FLIP, _normalizing_transform
from photogram.init.helmert import _umeyama

__all__ = ["resection_direct", "resect", "refine_resection", "ResectionResult",
           "PoseEstimate", "bearings", "project_ideal"]


# ---------------------------------------------------------------- helpers --

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
    A = np.zeros((n, 2, 9))
    A[:, 0, 0:3] = U
    A[:, 0, 6:9] = -Mh[:, 0:1] * U
    A[:, 1, 3:6] = U
    A[:, 1, 6:9] = -Mh[:, 1:2] * U
    _, sv, Vh = np.linalg.svd(A.reshape(2 * n, 9))
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


# ----------------------------------------------------------- public API --

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


@dataclass
class PoseEstimate:
    """An approximate exterior orientation.

    ``R`` world-to-camera rotation, ``X0`` projection centre, ``rms``
    reprojection RMS over all points (image units, per coordinate),
    ``candidates`` the number of distinct candidates considered.
    """

    R: np.ndarray
    X0: np.ndarray
    rms: float
    candidates: int

    @property
    def angles(self) -> np.ndarray:
        """Omega-phi-kappa of ``R`` (radians)."""
        return matrix_to_opk(self.R)


def resect(X, xy_ideal, c, x0=0.0, y0=0.0) -> PoseEstimate:
    """Space resection with known interior orientation: the best closed-form
    candidate.

    All candidates of :func:`resection_direct` are scored by the RMS of the
    ideal reprojection residuals over all points (candidates putting a point
    behind the camera, ``Xc_z >= 0``, are discarded); the smallest wins. With
    exactly 3 points the choice is only possible if there is one candidate.

    Parameters
    ----------
    X, xy_ideal, c, x0, y0 :
        As in :func:`resection_direct`.

    Returns
    -------
    PoseEstimate

    Raises
    ------
    GeometryError
        As :func:`resection_direct`; also when no candidate puts all points
        in front of the camera, or when 3 points leave several candidates.
    """
    X, xy = _check_input(X, xy_ideal, 3, "space resection")
    cands = resection_direct(X, xy, c, x0, y0)
    if not cands:
        raise GeometryError(
            "space resection found no real solution",
            hint="check the principal distance and the point correspondences")
    Rs = np.stack([R for R, _ in cands])
    X0s = np.stack([X0 for _, X0 in cands])
    Xc = np.einsum("kij,knj->kni", Rs, X[None] - X0s[:, None])      # (k, n, 3)
    front = (Xc[..., 2] < 0).all(axis=1)
    if not front.any():
        raise GeometryError(
            "space resection: no solution has all points in front of the camera",
            hint="check the point correspondences and the image y axis (down)")
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = np.stack([x0 - c * Xc[..., 0] / Xc[..., 2],
                         y0 + c * Xc[..., 1] / Xc[..., 2]], axis=-1)
    rms = np.sqrt(np.mean((proj - xy) ** 2, axis=(1, 2)))
    rms[~front] = np.inf
    order = np.argsort(rms)
    best = order[0]
    # distinct candidates (the same pose found from several triples counts once)
    distinct = [order[0]]
    for k in order[1:]:
        if np.isfinite(rms[k]) and not any(
                np.allclose(Rs[k], Rs[j], atol=1e-6) and
                np.allclose(X0s[k], X0s[j], atol=1e-6 * (1 + np.abs(X0s[j]).max()))
                for j in distinct):
            distinct.append(k)
    if len(X) == 3 and len(distinct) > 1:
        raise GeometryError(
            f"space resection from 3 points is ambiguous ({len(distinct)} solutions)",
            hint="add a 4th point, or pick a solution from resection_direct() "
                 "with an approximate camera position")
    return PoseEstimate(R=Rs[best], X0=X0s[best], rms=float(rms[best]),
                        candidates=len(distinct))


@dataclass
class ResectionResult:
    """Result of :func:`refine_resection`.

    Attributes
    ----------
    angles : ndarray (3,)
        Omega, phi, kappa of ``R`` (radians).
    X0 : ndarray (3,)
        Projection centre.
    R : ndarray (3, 3)
        World-to-camera rotation.
    residuals : ndarray (n, 2)
        Image residuals of the camera model at the solution (its sign
        convention).
    sigma0 : float
        A-posteriori sigma of unit weight ``sqrt(r^T W r / (2n - 6))``
        (NaN for n = 3).
    covariance : ndarray (6, 6)
        ``sigma0^2 N^-1`` of (omega, phi, kappa, X0x, X0y, X0z) (the a-priori
        ``N^-1`` when there is no redundancy). At the gimbal lock
        (phi = +-90 deg) omega and kappa are not separable and their
        variances are unbounded; the pose itself is still fine.
    iterations : int
    converged : bool
    """

    angles: np.ndarray
    X0: np.ndarray
    R: np.ndarray
    residuals: np.ndarray
    sigma0: float
    covariance: np.ndarray
    iterations: int
    converged: bool

    @property
    def std(self) -> np.ndarray:
        """Standard deviations of (omega, phi, kappa, X0x, X0y, X0z)."""
        return np.sqrt(np.diag(self.covariance))


def _weights(sigma, n):
    if sigma is None:
        return np.ones((n, 2))
    s = np.asarray(sigma, dtype=float)
    if s.ndim == 0:
        s = np.full((n, 2), float(s))
    elif s.shape == (n,):
        s = np.repeat(s[:, None], 2, axis=1)
    elif s.shape != (n, 2):
        raise GeometryError(f"sigma must be a scalar, ({n},) or ({n}, 2), got {s.shape}")
    if np.any(~(s > 0)) or not np.all(np.isfinite(s)):
        raise GeometryError("image sigmas must be positive and finite")
    return 1.0 / s ** 2


def refine_resection(X, xy_obs, model, io, angles0, X0_0, sigma=None,
                     max_iterations: int = 20, tol: float = 1e-10) -> ResectionResult:
    """Least-squares space resection with the full camera model.

    Gauss-Newton on the collinearity equations including distortion,
    ``min Σ r^T W r`` with ``r, J = model.residuals(xy_obs, X, angles, X0,
    io)`` and the normal equations ``(J^T W J) Δ = -J^T W r`` in the six
    unknowns ``Δ = (δ, ΔX0)``, where δ is the incremental rotation of the
    model's ``"rotation"`` Jacobian, applied as ``R <- small_rotation(δ) R``
    (no gimbal lock in the iteration). A step that increases the weighted
    sum of squares is halved (at most 10 times). The covariance is
    ``sigma0^2 (J^T W J)^-1`` with the ``"angles"`` Jacobian at the
    solution.

    Parameters
    ----------
    X : array_like (n, 3), n >= 3
        Object points (fixed).
    xy_obs : array_like (n, 2)
        Observed (distorted) image coordinates.
    model :
        A camera model of :func:`photogram.geometry.camera_model`.
    io : array_like
        Interior orientation, in ``model.parameter_names`` order (fixed).
    angles0, X0_0 : array_like (3,)
        Approximate exterior orientation (e.g. from :func:`resect`).
    sigma : float or array_like (n,) or (n, 2), optional
        A-priori standard deviations of the image coordinates (weights
        ``1/sigma^2``); equal weights if None.
    max_iterations : int
    tol : float
        Convergence: ``|δ| < tol`` (radians) and ``|ΔX0| < tol * scale`` with
        scale the size of the object-point cloud and camera distance.

    Returns
    -------
    ResectionResult

    Raises
    ------
    GeometryError
        Fewer than 3 points; points behind the camera at the start or at the
        solution (chirality ``Xc_z < 0`` violated); a singular normal matrix
        (e.g. collinear points); non-finite residuals.
    """
    X, xy = _check_input(X, xy_obs, 3, "space resection")
    n = len(X)
    io = np.asarray(io, dtype=float)
    W = _weights(sigma, n)
    wf = W.reshape(-1)
    R = np.asarray(opk_to_matrix(np.asarray(angles0, dtype=float)), dtype=float)
    X0 = np.asarray(X0_0, dtype=float).copy()
    scale = max(np.linalg.norm(X - X.mean(axis=0), axis=1).max(),
                np.linalg.norm(X.mean(axis=0) - X0), 1e-300)

    def behind(R, X0):
        return int(((X - X0) @ R[2] >= 0).sum())

    k = behind(R, X0)
    if k:
        raise GeometryError(
            f"space resection: the approximate orientation puts {k} of {n} "
            f"points behind the camera (Xc_z >= 0)",
            hint="start from resect() or check the approximate angles")

    def evaluate(R, X0):
        angles = np.asarray(matrix_to_opk(R), dtype=float)
        r, jac = model.residuals(xy, X, angles, X0, io)
        r = np.asarray(r, dtype=float)
        return angles, r, jac, float((wf * r.reshape(-1) ** 2).sum())

    angles, r, jac, cost = evaluate(R, X0)
    if not np.isfinite(cost):
        raise GeometryError("space resection: residuals are not finite at the start")
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        J = np.concatenate([jac["rotation"], jac["X0"]], axis=2).reshape(2 * n, 6)
        N = J.T @ (J * wf[:, None])
        g = J.T @ (wf * r.reshape(-1))
        try:
            dx = -np.linalg.solve(N, g)
        except np.linalg.LinAlgError:
            raise GeometryError(
                "space resection: singular normal equations",
                hint="the points may be collinear or too few") from None
        step = 1.0
        for _ in range(11):
            Rn = np.asarray(small_rotation(step * dx[:3]), dtype=float) @ R
            X0n = X0 + step * dx[3:]
            trial = evaluate(Rn, X0n)
            if np.isfinite(trial[3]) and trial[3] <= cost * (1 + 1e-12) + 1e-300:
                break
            step *= 0.5
        else:
            trial = None
        small = (np.abs(dx[:3]).max() < tol and np.abs(dx[3:]).max() < tol * scale)
        if trial is None:
            converged = small or cost == 0.0
            break
        R, X0 = Rn, X0n
        angles, r, jac, cost = trial
        if small:
            converged = True
            break
    k = behind(R, X0)
    if k:
        raise GeometryError(
            f"space resection converged to an orientation with {k} of {n} "
            f"points behind the camera",
            hint="check the point correspondences and approximate orientation")
    Ja = np.concatenate([jac["angles"], jac["X0"]], axis=2).reshape(2 * n, 6)
    N = Ja.T @ (Ja * wf[:, None])
    try:
        Ninv = np.linalg.inv(N)
    except np.linalg.LinAlgError:
        Ninv = np.linalg.pinv(N)
    dof = 2 * n - 6
    sigma0 = float(np.sqrt(cost / dof)) if dof > 0 else float("nan")
    cov = (sigma0 ** 2 if dof > 0 else 1.0) * Ninv
    return ResectionResult(angles=angles, X0=X0, R=R, residuals=r, sigma0=sigma0,
                           covariance=cov, iterations=it, converged=converged)
