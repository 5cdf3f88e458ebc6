"""Least-squares space resection with the full camera model.

:func:`refine_resection` improves an approximate exterior orientation (e.g.
from :func:`photogram.init.resection.resect`) by Gauss-Newton on the
collinearity equations of a camera model of :mod:`photogram.geometry`
(distortion included), with incremental rotations (no gimbal lock in the
iteration) and the covariance of omega-phi-kappa and the projection centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import GeometryError
from photogram.geometry.rotations import matrix_to_opk, opk_to_matrix, small_rotation
from photogram.init.resection_start import _check_input

__all__ = ["refine_resection", "ResectionResult"]


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
