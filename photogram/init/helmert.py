"""Seven-parameter 3D similarity (Helmert) transformation.

``dst ≈ s R src + t`` (scale ``s``, rotation ``R``, translation ``t``),
estimated in closed form (weighted Horn/Umeyama) and, for per-coordinate
weights, polished by Gauss-Newton on all seven parameters. Its main uses:
bringing a free-network adjustment into the control frame, initialising an
absolute orientation, and finding gross errors in reference coordinates from
the (standardized) residuals.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import GeometryError
from photogram.geometry.rotations import matrix_to_opk

__all__ = ["HelmertResult", "helmert", "apply_helmert", "helmert_outliers"]


@dataclass
class HelmertResult:
    """A fitted similarity ``dst ≈ scale * R @ src + t``.

    Attributes
    ----------
    scale : float
        Scale factor ``s``.
    R : ndarray (3, 3)
        Proper rotation (``det R = +1``).
    t : ndarray (3,)
        Translation.
    residuals : ndarray (n, 3)
        ``v = dst - (s R src + t)`` (observed minus computed).
    sigma0 : float
        A-posteriori standard deviation of unit weight,
        ``sqrt(sum w v^2 / (3n - 7))`` (NaN if there is no redundancy).
    standardized : ndarray (n, 3)
        Standardized (normalized) residuals ``v / (sigma0 sqrt(q_vv))``: the
        residual divided by its own a-posteriori standard deviation (Pope's
        tau statistic). NaN where the redundancy number is zero.
    redundancy : ndarray (n, 3)
        Redundancy numbers ``r = w q_vv`` (each in [0, 1], summing to 3n - 7).
    covariance : ndarray (7, 7)
        ``sigma0^2 N^-1`` of ``(s, dR_x, dR_y, dR_z, t_x, t_y, t_z)`` where
        ``dR`` is a small rotation applied on the left, ``R <- (I + [dR]x) R``.
    dof : int
        Degrees of freedom ``3n - 7``.
    weights : ndarray (n, 3)
        The weights used (per coordinate; 1 where none were given).
    """

    scale: float
    R: np.ndarray
    t: np.ndarray
    residuals: np.ndarray
    sigma0: float
    standardized: np.ndarray
    redundancy: np.ndarray
    covariance: np.ndarray
    dof: int
    weights: np.ndarray = field(repr=False)

    @property
    def angles(self) -> np.ndarray:
        """Omega-phi-kappa of ``R`` (radians), in the convention of
        :func:`photogram.geometry.rotations.matrix_to_opk`."""
        return matrix_to_opk(self.R)

    def apply(self, points) -> np.ndarray:
        """``s R points + t`` for points (..., 3)."""
        return apply_helmert(self, points)

    def inverse(self) -> "HelmertResult":
        """The inverse transformation ``src ≈ (1/s) R^T (dst - t)``.

        Only ``scale``, ``R`` and ``t`` are meaningful in the result; the
        statistics are copied from ``self`` unchanged.
        """
        s = 1.0 / self.scale
        R = self.R.T
        return HelmertResult(s, R, -s * R @ self.t, -self.residuals, self.sigma0,
                             -self.standardized, self.redundancy, self.covariance,
                             self.dof, self.weights)


def apply_helmert(result: HelmertResult, points) -> np.ndarray:
    """Apply a similarity transformation, ``X' = s R X + t``.

    Parameters
    ----------
    result : HelmertResult
        The transformation (only ``scale``, ``R``, ``t`` are used).
    points : array_like (..., 3)

    Returns
    -------
    ndarray (..., 3)
    """
    X = np.asarray(points, dtype=float)
    return result.scale * X @ result.R.T + result.t


def _skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices of vectors (..., 3) -> (..., 3, 3)."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def _umeyama(src: np.ndarray, dst: np.ndarray, w: np.ndarray,
             with_scale: bool = True) -> tuple[float, np.ndarray, np.ndarray]:
    """Weighted closed-form similarity (Umeyama 1991, eqs. 34-43).

    Minimises ``sum_i w_i |dst_i - (s R src_i + t)|^2`` with ``det R = +1``.
    ``w`` (n,) non-negative point weights. Returns ``(s, R, t)``; ``s = 1``
    when ``with_scale`` is False (rigid/Kabsch fit).
    """
    W = w.sum()
    mu_s = w @ src / W
    mu_d = w @ dst / W
    a = src - mu_s
    b = dst - mu_d
    Sigma = (b * w[:, None]).T @ a / W            # cross-covariance (3, 3)
    U, d, Vt = np.linalg.svd(Sigma)
    S = np.ones(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2] = -1.0
    R = (U * S) @ Vt
    if with_scale:
        var_s = (w * np.einsum("ij,ij->i", a, a)).sum() / W
        s = float((d * S).sum() / var_s)
    else:
        s = 1.0
    t = mu_d - s * R @ mu_s
    return s, R, t


def _check_spread(X: np.ndarray, name: str, rel_tol: float) -> None:
    """Raise GeometryError unless the points (n, 3) span at least a line
    well enough to fix a rotation (i.e. they are not collinear)."""
    A = X - X.mean(axis=0)
    sv = np.linalg.svd(A, compute_uv=False)
    if sv[0] == 0.0 or sv[1] <= rel_tol * sv[0]:
        rms = sv[1] / np.sqrt(len(X))
        raise GeometryError(
            f"Helmert transformation needs 3 non-collinear points; the {len(X)} "
            f"{name} points lie on a line (rms off-line {rms:.3g})",
            hint="add a point away from that line; a rotation about the line is "
                 "otherwise undetermined")


def helmert(src, dst, weights=None, *, max_iterations: int = 10,
            tol: float = 1e-12, collinear_tol: float = 1e-9) -> HelmertResult:
    """Estimate the 3D similarity ``dst ≈ s R src + t`` (7 parameters).

    Closed form of Umeyama (1991) / Horn (1987) with point weights: the
    rotation from the SVD of the weighted cross-covariance
    ``Σ = 1/W Σ_i w_i (d_i - μ_d)(s_i - μ_s)^T = U D V^T``,
    ``R = U diag(1, 1, det(U V^T)) V^T``, the scale
    ``s = tr(D S) / σ_s²`` and ``t = μ_d - s R μ_s`` (Umeyama eqs. 40-42).
    With per-coordinate weights (n, 3) that are not isotropic the closed form
    (using the mean weight of each point) is the start of a Gauss-Newton
    adjustment of the observation equations ``dst_i + v_i = s R src_i + t``
    with the rotation updated as ``R <- exp([δ]x) R``.

    Parameters
    ----------
    src, dst : array_like (n, 3)
        Corresponding points, ``n >= 3`` and not collinear.
    weights : array_like (n,) or (n, 3), optional
        Weights of the ``dst`` coordinates (``1 / sigma^2``); equal if None.
        Zero weight excludes a point or coordinate.
    max_iterations, tol :
        Gauss-Newton control for anisotropic weights (relative step size).
    collinear_tol : float
        Relative threshold on the second singular value of the centred
        point sets below which they count as collinear.

    Returns
    -------
    HelmertResult

    Raises
    ------
    GeometryError
        Fewer than 3 points, collinear points, or weights that leave fewer
        than 3 non-collinear points.
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    if src.ndim != 2 or src.shape[1] != 3 or src.shape != dst.shape:
        raise GeometryError(
            f"Helmert transformation needs two (n, 3) point arrays of equal "
            f"shape, got {src.shape} and {dst.shape}")
    n = len(src)
    if n < 3:
        raise GeometryError(
            f"Helmert transformation needs at least 3 points, got {n}",
            hint="a 3D similarity has 7 parameters; give 3 or more "
                 "non-collinear common points")
    if not (np.all(np.isfinite(src)) and np.all(np.isfinite(dst))):
        raise GeometryError("Helmert transformation: point coordinates contain NaN or inf",
                            hint="drop points with unknown coordinates first")
    if weights is None:
        Wc = np.ones((n, 3))
    else:
        w = np.asarray(weights, dtype=float)
        if w.shape == (n,):
            Wc = np.repeat(w[:, None], 3, axis=1)
        elif w.shape == (n, 3):
            Wc = w.copy()
        else:
            raise GeometryError(f"Helmert weights must have shape ({n},) or ({n}, 3), got {w.shape}")
        if np.any(~np.isfinite(Wc)) or np.any(Wc < 0):
            raise GeometryError("Helmert weights must be finite and non-negative")
    wp = Wc.mean(axis=1)
    used = wp > 0
    if used.sum() < 3:
        raise GeometryError(
            f"Helmert transformation needs at least 3 points with non-zero weight, "
            f"got {int(used.sum())}")
    _check_spread(src[used], "source", collinear_tol)
    _check_spread(dst[used], "target", collinear_tol)

    s, R, t = _umeyama(src[used], dst[used], wp[used])

    def jacobian(s, R):
        # d(model)/d(s, δ, t) for model = s R X + t, R <- (I + [δ]x) R
        RX = src @ R.T                                   # (n, 3)
        J = np.empty((n, 3, 7))
        J[:, :, 0] = RX
        J[:, :, 1:4] = -s * _skew(RX)                    # δ x (sRX) = -[sRX]x δ
        J[:, :, 4:7] = np.eye(3)
        return J

    anisotropic = not np.allclose(Wc, wp[:, None])
    if anisotropic:
        for _ in range(max_iterations):
            v = dst - (s * src @ R.T + t)
            J = jacobian(s, R).reshape(3 * n, 7)
            wf = Wc.reshape(-1)
            N = J.T @ (J * wf[:, None])
            dx = np.linalg.solve(N, J.T @ (wf * v.reshape(-1)))
            s += dx[0]
            d = dx[1:4]
            ang = np.linalg.norm(d)
            if ang > 0:
                K = _skew(d / ang)
                R = (np.eye(3) + np.sin(ang) * K + (1 - np.cos(ang)) * K @ K) @ R
            t = t + dx[4:]
            scale_ref = max(1.0, np.abs(t).max(), np.abs(dst).max())
            if (abs(dx[0]) / s < tol and ang < tol and
                    np.abs(dx[4:]).max() < tol * scale_ref):
                break

    v = dst - (s * src @ R.T + t)
    J = jacobian(s, R).reshape(3 * n, 7)
    wf = Wc.reshape(-1)
    N = J.T @ (J * wf[:, None])
    Ninv = np.linalg.inv(N)
    dof = 3 * int(used.sum()) - 7 - int((Wc[used] == 0).sum())
    vtpv = float((wf * v.reshape(-1) ** 2).sum())
    sigma0 = float(np.sqrt(vtpv / dof)) if dof > 0 else float("nan")
    # diag(Q_vv) = 1/w - diag(J N^-1 J^T), redundancy r = w q_vv
    qll_minus = np.einsum("ij,jk,ik->i", J, Ninv, J)
    with np.errstate(divide="ignore", invalid="ignore"):
        qvv = np.where(wf > 0, 1.0 / wf - qll_minus, 0.0)
        red = np.clip(wf * qvv, 0.0, 1.0)
        qvv = np.where(red > 1e-12, qvv, np.nan)
        stdz = v.reshape(-1) / (sigma0 * np.sqrt(qvv))
    return HelmertResult(
        scale=float(s), R=R, t=t, residuals=v, sigma0=sigma0,
        standardized=stdz.reshape(n, 3), redundancy=red.reshape(n, 3),
        covariance=(sigma0 ** 2 if dof > 0 else 1.0) * Ninv, dof=dof,
        weights=Wc)


def helmert_outliers(result: HelmertResult, k: float = 3.0,
                     sigma0: float | None = None) -> np.ndarray:
    """Indices of points whose residuals are suspiciously large.

    A point is flagged when any of its standardized residuals exceeds ``k``
    in magnitude. With ``sigma0=None`` the a-posteriori sigma0 of the fit is
    used (Pope's tau test; robust to a wrong a-priori scale of the weights,
    but a single large gross error inflates sigma0 and can hide smaller
    ones: remove the worst point and refit). Pass the a-priori sigma of unit
    weight (1.0 when the weights are ``1/sigma^2``) for Baarda's data
    snooping instead.

    Parameters
    ----------
    result : HelmertResult
    k : float
        Critical value (3 by default; 3.29 is the two-sided 0.1 % quantile).
    sigma0 : float, optional
        A-priori sigma of unit weight.

    Returns
    -------
    ndarray of int
        Point indices, worst first.
    """
    w = result.standardized
    if sigma0 is not None:
        w = w * (result.sigma0 / sigma0)
    score = np.nanmax(np.abs(np.where(np.isnan(w), 0.0, w)), axis=1)
    bad = np.nonzero(score > k)[0]
    return bad[np.argsort(-score[bad])]
