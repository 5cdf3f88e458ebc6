"""Solution of the normal equations by the Schur complement, optionally
bordered by datum conditions (inner constraints), and the inverse needed for
the covariance of all unknowns.

Bordered system (free network, minimum-trace datum; conditions ``G^T dx = 0``)::

    [ N_cc  W    G_c ] [dx_c]   [-g_c]
    [ W^T   A    G_e ] [dx_e] = [-g_e]
    [ G_c^T G_e^T 0  ] [ k  ]   [  0 ]

Eliminating ``dx_e`` leaves ``M [dx_c; k] = rhs`` with
``M = [[S, B], [B^T, -C]]``, ``S = N_cc - Y W^T``, ``Y = W A^-1``,
``B = G_c - Y G_e``, ``C = G_e^T A^-1 G_e``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from photogram.errors import GeometryError


@dataclass
class Factorization:
    """What the covariance computation needs from the last solve."""

    Ainv: np.ndarray            # (n_e, 3, 3)
    Ainv_bsr: sp.bsr_matrix
    Y: sp.csr_matrix | np.ndarray   # W A^-1
    M: np.ndarray               # reduced (bordered) matrix
    cho: tuple | None           # Cholesky of the scaled S when not bordered
    scale: np.ndarray | None    # Jacobi scaling of the reduced system
    AinvGe: np.ndarray | None   # A^-1 G_e (3 n_e, m)
    n_reduced: int

    def reduced_inverse(self) -> np.ndarray:
        """Inverse of the (bordered) reduced matrix M."""
        d = self.scale
        if self.cho is not None:
            return d[:, None] * la.cho_solve(self.cho, np.diag(d))
        Ms = self.M * d[:, None] * d[None, :]
        return d[:, None] * np.linalg.inv(Ms) * d[None, :]


def _invert_point_blocks(A, labels=None):
    """Inverse of the 3x3 point blocks; a singular block is a point that is
    not determined (too few rays, no prior)."""
    det = np.linalg.det(A)
    scale = np.einsum("nii->n", A) ** 3 + 1e-300
    bad = np.flatnonzero(~(np.abs(det) > 1e-14 * scale))
    if len(bad):
        names = [str(labels[i]) if labels is not None else str(i) for i in bad[:5]]
        more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
        raise GeometryError(
            f"object point(s) {', '.join(names)}{more} are not determined "
            "(fewer than 2 useful rays, or rays that do not intersect)",
            hint="measure them in more images or remove them")
    return np.linalg.inv(A)


def solve(system, layout, damping=0.0, G=None, point_labels=None):
    """One Gauss-Newton (or damped, Levenberg-Marquardt) step.

    Parameters
    ----------
    system : NormalSystem
    layout : Layout
    damping : float
        Marquardt's lambda: the diagonal is multiplied by ``1 + damping``.
    G : (n_columns, m) array, optional
        Datum conditions ``G^T dx = 0`` (inner constraints).
    point_labels : sequence, optional
        Labels of the eliminated points, for messages.

    Returns
    -------
    dx : (n_columns,) step
    fact : Factorization
    """
    n_r, n_e = layout.n_reduced, layout.n_eliminated
    fixed = ~layout.free
    A = system.A.copy()
    Ncc = system.Ncc.copy()
    if damping:
        di = np.arange(3)
        A[:, di, di] *= 1.0 + damping
        Ncc[np.diag_indices(n_r)] *= 1.0 + damping
    fixed_e = fixed[n_r:].reshape(-1, 3)
    A[:, [0, 1, 2], [0, 1, 2]] += fixed_e
    Ncc[np.diag_indices(n_r)] += fixed[:n_r]
    g_c, g_e = system.g[:n_r], system.g[n_r:]

    Ainv = _invert_point_blocks(A, point_labels)
    Ainv_bsr = sp.bsr_matrix((Ainv, np.arange(n_e), np.arange(n_e + 1)), shape=(3 * n_e, 3 * n_e))
    if isinstance(system.W, np.ndarray):
        Wd = system.W.reshape(n_r, n_e, 3)
        Y = np.einsum("rpk,pkm->rpm", Wd, Ainv).reshape(n_r, 3 * n_e)
        S = Ncc - Y @ system.W.T
    else:
        Y = (system.W @ Ainv_bsr).tocsr()
        S = Ncc - (Y @ system.W.T).toarray()
    rhs_c = -g_c + Y @ g_e

    # Jacobi scaling: interior parameters (K1 ~ 1e-8 px^-2) and coordinates
    # differ by many orders of magnitude; scale the reduced system to a
    # unit diagonal before factorizing.
    d = 1.0 / np.sqrt(np.where(np.diag(S) > 0, np.diag(S), 1.0))
    Ss = S * d[:, None] * d[None, :]
    if G is None:
        try:
            cho = la.cho_factor(Ss, lower=False, check_finite=True)
        except (la.LinAlgError, ValueError):
            raise GeometryError(
                "the normal equations are singular: the network has a datum defect "
                "or parameters that cannot be determined",
                hint="add control, a distance or inner constraints, or fix interior parameters")
        dx_c = d * la.cho_solve(cho, d * rhs_c)
        k = None
        M, AinvGe = S, None
    else:
        G_c, G_e = G[:n_r], G[n_r:]
        AinvGe = (Ainv_bsr @ G_e) if n_e else np.zeros((0, G.shape[1]))
        B = G_c - Y @ G_e
        C = G_e.T @ AinvGe
        M = np.block([[S, B], [B.T, -C]])
        e = 1.0 / np.sqrt(np.maximum(np.sum((B * d[:, None]) ** 2, axis=0), 1e-300))
        dd = np.concatenate([d, e])
        rhs = np.concatenate([rhs_c, AinvGe.T @ g_e])
        try:
            sol = dd * la.solve(M * dd[:, None] * dd[None, :], dd * rhs, assume_a="sym")
        except la.LinAlgError:
            raise GeometryError("the bordered normal equations are singular",
                                hint="the datum conditions do not remove the defect")
        dx_c, k = sol[:n_r], sol[n_r:]
        cho = None
    rhs_e = -g_e - system.W.T @ dx_c
    if k is not None:
        rhs_e = rhs_e - G[n_r:] @ k
    dx_e = Ainv_bsr @ rhs_e
    dx = np.concatenate([dx_c, dx_e])
    dx[fixed] = 0.0
    if not np.all(np.isfinite(dx)):
        raise GeometryError("the adjustment produced a non-finite step (divergence)",
                            hint="check the approximate values and the datum")
    return dx, Factorization(Ainv, Ainv_bsr, Y, M, cho, d if G is None else dd, AinvGe, n_r)
