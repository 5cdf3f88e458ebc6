"""Covariance of all unknowns from the Schur-factorized normal equations.

With ``K = [[A, U], [U^T, D]]`` (points eliminated, ``U = [W^T, G_e]``) and
``M`` the reduced (bordered) matrix, the inverse blocks are::

    Q_cc = (M^-1)_cc
    Q_ec = -A^-1 U (M^-1)_{., c}
    Q_ee,i = A_i^-1 + (A^-1 U)_i M^-1 (A^-1 U)_i^T

(cofactors of the whitened system; multiply by sigma0^2 for covariances).
Fixed parameters get zero variance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.adjust.residual_blocks import _angle_increment_map


@dataclass
class Cofactors:
    """Cofactor matrices of the unknowns (a-priori sigma0 = 1)."""

    layout: object
    Qcc: np.ndarray           # (n_r, n_r)
    Qec: np.ndarray           # (3 n_e, n_r)
    Qee: np.ndarray           # (n_e, 3, 3)

    def block(self, cols_a, cols_b):
        """Cofactors between per-row column sets (N, sa) and (N, sb).

        Both may be reduced or eliminated; two eliminated sets must belong
        to the same point (true for every residual block of the engine).
        """
        n_r = self.layout.n_reduced
        red_a = cols_a[:, 0] < n_r
        red_b = cols_b[:, 0] < n_r
        out = np.zeros((len(cols_a), cols_a.shape[1], cols_b.shape[1]))
        m = red_a & red_b
        out[m] = self.Qcc[cols_a[m][:, :, None], cols_b[m][:, None, :]]
        m = ~red_a & red_b
        out[m] = self.Qec[cols_a[m][:, :, None] - n_r, cols_b[m][:, None, :]]
        m = red_a & ~red_b
        out[m] = np.swapaxes(self.Qec[cols_b[m][:, :, None] - n_r, cols_a[m][:, None, :]], 1, 2)
        m = ~red_a & ~red_b
        if m.any():
            out[m] = self.Qee[(cols_a[m][:, 0] - n_r) // 3]
        return out

    def of_columns(self, cols):
        """Cofactor blocks (N, s, s) of column sets (N, s)."""
        return self.block(cols, cols)


def cofactors(problem) -> Cofactors:
    """Cofactors of all unknowns at the problem's current state."""
    _, _, fact = problem.step(problem.state, 0.0)
    lay = problem.layout
    n_r = lay.n_reduced
    Minv = fact.reduced_inverse()
    Qcc = Minv[:n_r, :n_r]
    Y = fact.Y if isinstance(fact.Y, np.ndarray) else fact.Y.toarray()
    V_c = Y.T if lay.n_eliminated else np.zeros((0, n_r))   # A^-1 W^T
    if fact.AinvGe is not None:
        V = np.hstack([V_c, fact.AinvGe])
    else:
        V = V_c
    VM = V @ Minv
    Qec = -VM[:, :n_r]
    n_e = lay.n_eliminated
    Qee = fact.Ainv + np.einsum("iam,ibm->iab", VM.reshape(n_e, 3, -1), V.reshape(n_e, 3, -1))
    fixed = ~lay.free
    Qcc = Qcc.copy()
    Qcc[fixed[:n_r], :] = 0.0
    Qcc[:, fixed[:n_r]] = 0.0
    fe = fixed[n_r:]
    Qec[fe, :] = 0.0
    Qec[:, fixed[:n_r]] = 0.0
    fe3 = fe.reshape(-1, 3)
    Qee = Qee * (~fe3[:, :, None]) * (~fe3[:, None, :])
    return Cofactors(lay, Qcc, Qec, Qee)


def point_covariances(cof: Cofactors, sigma0_sq=1.0):
    """(n_p, 3, 3) covariance of every object point."""
    return sigma0_sq * cof.of_columns(cof.layout.point_cols)


def station_covariances(cof: Cofactors, R, sigma0_sq=1.0):
    """(n_s, 6, 6) covariance of (X0, Y0, Z0, omega, phi, kappa) per station.

    The rotation increment covariance is propagated to the angles with
    ``d(opk) = E delta``.
    """
    Q = cof.of_columns(cof.layout.station_cols)
    _, E = _angle_increment_map(R)
    T = np.zeros((len(R), 6, 6))
    T[:, :3, :3] = np.eye(3)
    T[:, 3:, 3:] = E
    return sigma0_sq * T @ Q @ np.swapaxes(T, 1, 2)


def camera_covariances(cof: Cofactors, sigma0_sq=1.0):
    """List of (p, p) covariances of each camera's interior parameters."""
    return [sigma0_sq * cof.Qcc[np.ix_(c, c)] for c in cof.layout.camera_cols]


def correlations(cov):
    """Correlation matrix of a covariance matrix (NaN-free: 0 where a
    variance is zero)."""
    s = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        C = cov / np.outer(s, s)
    return np.where(np.isfinite(C), C, 0.0)


def high_correlations(cov, names, threshold=0.95):
    """Pairs of parameters whose |correlation| exceeds ``threshold``."""
    C = correlations(cov)
    i, j = np.triu_indices(len(names), 1)
    sel = np.abs(C[i, j]) > threshold
    return [(names[a], names[b], float(C[a, b])) for a, b in zip(i[sel], j[sel])]
