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

The reduced camera system ``S`` is summed block by block over the pairs of
E-rows of every point (:mod:`normal`): ``S -= W_a A_p^-1 W_b^T`` at the
reduced columns of rows a and b. With numba (``photogram[fast]``) one
compiled loop does it; the numpy path multiplies, for every pair of row
groups (stations) that share points, the stacked ``A_p^-1 W_a^T`` and
``W_b^T`` of their common points with one BLAS product.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from photogram.adjust import kernels
from photogram.errors import GeometryError


class Factorization:
    """What the covariance computation needs from the last solve."""

    def __init__(self, Ainv, M, cho, scale, AinvGe, n_reduced, system=None):
        self.Ainv = Ainv            # (n_e, 3, 3)
        self.M = M                  # reduced (bordered) matrix
        self.cho = cho              # Cholesky of the scaled S when not bordered
        self.scale = scale          # Jacobi scaling of the reduced system
        self.AinvGe = AinvGe        # A^-1 G_e (3 n_e, m) or None
        self.n_reduced = n_reduced
        self.system = system        # NormalSystem (per-row W)
        self._Y = None

    @property
    def Ainv_bsr(self) -> sp.bsr_matrix:
        n_e = len(self.Ainv)
        return sp.bsr_matrix((self.Ainv, np.arange(n_e), np.arange(n_e + 1)),
                             shape=(3 * n_e, 3 * n_e))

    @property
    def Y(self) -> sp.csr_matrix:
        """``W A^-1`` (n_r x 3 n_e), sparse, built on request."""
        if self._Y is None:
            self._Y = (self.system.W @ self.Ainv_bsr).tocsr()
        return self._Y

    def solve(self, V):
        """``X = N^-1 V`` (n_columns, m) with this factorization (not
        bordered; fixed columns: zero rows of X, V's fixed rows ignored).
        E.g. the covariance of all unknowns times a few vectors."""
        if self.cho is None:
            raise ValueError("Factorization.solve needs an unbordered factorization")
        st = self.system.structure
        lay = st.layout
        n_r, n_e = self.n_reduced, len(self.Ainv)
        V = np.asarray(V, dtype=float).reshape(lay.n_columns, -1)
        V = np.where(lay.free[:, None], V, 0.0)
        m = V.shape[1]
        Ve = V[n_r:].reshape(n_e, 3, m)
        AinvVe = np.matmul(self.Ainv, Ve)
        rhs_c = V[:n_r] - _w_times(self.system, AinvVe)
        d = self.scale
        Xc = d[:, None] * la.cho_solve(self.cho, d[:, None] * rhs_c)
        Xc[~lay.free[:n_r]] = 0.0
        WtX = np.stack([self.system.wt_times_c(Xc[:, j]) for j in range(m)], axis=2)
        Xe = np.matmul(self.Ainv, Ve - WtX).reshape(3 * n_e, m)
        X = np.vstack([Xc, Xe])
        X[~lay.free] = 0.0
        return X

    def reduced_inverse(self) -> np.ndarray:
        """Inverse of the (bordered) reduced matrix M."""
        d = self.scale
        if self.cho is not None:
            return d[:, None] * la.cho_solve(self.cho, np.diag(d))
        Ms = self.M * d[:, None] * d[None, :]
        return d[:, None] * np.linalg.inv(Ms) * d[None, :]


def invert_point_blocks(A, labels=None):
    """Inverse of the 3x3 point blocks (closed form); a singular block is a
    point that is not determined (too few rays, no prior)."""
    a, b, c = A[:, 0, 0], A[:, 0, 1], A[:, 0, 2]
    d, e, f = A[:, 1, 0], A[:, 1, 1], A[:, 1, 2]
    g, h, i = A[:, 2, 0], A[:, 2, 1], A[:, 2, 2]
    c00, c01, c02 = e * i - f * h, c * h - b * i, b * f - c * e
    c10, c11, c12 = f * g - d * i, a * i - c * g, c * d - a * f
    c20, c21, c22 = d * h - e * g, b * g - a * h, a * e - b * d
    det = a * c00 + b * c10 + c * c20
    scale = (a + e + i) ** 3 + 1e-300
    bad = np.flatnonzero(~(np.abs(det) > 1e-14 * scale))
    if len(bad):
        names = [str(labels[k]) if labels is not None else str(k) for k in bad[:5]]
        more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
        raise GeometryError(
            f"object point(s) {', '.join(names)}{more} are not determined "
            "(fewer than 2 useful rays, or rays that do not intersect)",
            hint="measure them in more images or remove them")
    inv = np.stack([c00, c01, c02, c10, c11, c12, c20, c21, c22], axis=-1).reshape(-1, 3, 3)
    inv /= det[:, None, None]
    # symmetric input: return an exactly symmetric inverse
    return 0.5 * (inv + np.swapaxes(inv, 1, 2))


_invert_point_blocks = invert_point_blocks


def reduced_camera_system(system, Ainv, Ncc):
    """``S = Ncc - W A^-1 W^T`` and ``W A^-1 g_e`` (n_r,)."""
    st = system.structure
    n_r = st.n_r
    n_e = st.layout.n_eliminated
    g_e = system.g[n_r:].reshape(n_e, 3)
    if st.n_e_rows == 0 or st.s == 0:
        return Ncc.copy(), np.zeros(n_r)
    if kernels.active(st.n_e_rows):
        ga, gb, pair_id, reverse, scatter = st.group_pairs()
        s = st.s
        T = np.zeros((len(ga), s, s))
        rhs_rows = np.zeros((st.n_e_rows, s))
        kernels.compiled().schur_rows(system.WT, Ainv, st.pt_ptr, st.pt_rows, st.e_group, pair_id, g_e,
                           T, rhs_rows)
        U = T + np.swapaxes(T[reverse], 1, 2)
        m = n_r + 1
        full = np.bincount(scatter, weights=U.ravel(), minlength=m * m).reshape(m, m)
        rhs = np.bincount(st.e_rcols.ravel(), weights=rhs_rows.ravel(), minlength=m)
        return Ncc - full[:n_r, :n_r], rhs[:n_r]
    YT = np.matmul(Ainv[st.e_point], system.WT)                 # (n, 3, s): A^-1 W_o^T
    v = np.einsum("nis,ni->ns", YT, g_e[st.e_point])
    rhs = np.bincount(st.e_rcols.ravel(), weights=v.ravel(), minlength=n_r + 1)[:n_r]
    a, b, starts, ends, g1, g2 = st.pair_plan()
    s = st.s
    blocks = np.empty((len(starts), s, s))
    WT = system.WT
    for q in range(len(starts)):
        ia, ib = a[starts[q]:ends[q]], b[starts[q]:ends[q]]
        blocks[q] = YT[ia].reshape(-1, s).T @ WT[ib].reshape(-1, s)
    m = n_r + 1
    c1, c2 = st.group_cols[g1], st.group_cols[g2]
    idx = c1[:, :, None] * m + c2[:, None, :]
    off = g1 != g2
    idx_t = c2[off][:, :, None] * m + c1[off][:, None, :]
    flat = np.concatenate([idx.ravel(), idx_t.ravel()])
    vals = np.concatenate([blocks.ravel(), np.swapaxes(blocks[off], 1, 2).ravel()])
    T = np.bincount(flat, weights=vals, minlength=m * m).reshape(m, m)
    return Ncc - T[:n_r, :n_r], rhs


def damped(system, layout, damping=0.0):
    """``Ncc`` and ``A`` with Marquardt's damping (diagonal x (1 + damping))
    and a unit diagonal for fixed parameters."""
    n_r = layout.n_reduced
    fixed = ~layout.free
    A = system.A.copy()
    di = np.arange(3)
    if damping:
        A[:, di, di] *= 1.0 + damping
    A[:, di, di] += fixed[n_r:].reshape(-1, 3)
    if sp.issparse(system.Ncc):
        d = system.Ncc.diagonal()
        return (system.Ncc + sp.diags(d * damping + fixed[:n_r])).tocsr(), A
    Ncc = system.Ncc.copy()
    if damping:
        Ncc[np.diag_indices(n_r)] *= 1.0 + damping
    Ncc[np.diag_indices(n_r)] += fixed[:n_r]
    return Ncc, A


RCS_METHODS = ("dense", "iterative")


def solve(system, layout, damping=0.0, G=None, point_labels=None, method="dense",
          cg_tolerance=0.1, cg_max_iterations=500, cg_criterion="residual",
          cg_preconditioner="schur_jacobi", coarse_cluster_size=64):
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
    method : "dense" or "iterative"
        The reduced camera system: formed and factorized by a dense
        Cholesky (exact; the factorization serves the covariance), or
        solved by conjugate gradients on the implicit Schur complement
        with the Schur-Jacobi preconditioner
        (:mod:`photogram.adjust.rcs_iterative`; inexact to
        ``cg_tolerance`` by ``cg_criterion``, see
        :func:`photogram.adjust.rcs_iterative.pcg`; not with datum conditions ``G``, no
        factorization: ``fact`` is None).
    cg_preconditioner : "schur_jacobi", "two_level" or "adaptive"
        With ``coarse_cluster_size``: the preconditioner of the iterative
        solve (:func:`photogram.adjust.rcs_coarse.preconditioner`).

    Returns
    -------
    dx : (n_columns,) step
    fact : Factorization (None with ``method="iterative"``)
    """
    if method not in RCS_METHODS:
        raise ValueError(f"unknown reduced-camera-system method {method!r}")
    n_r, n_e = layout.n_reduced, layout.n_eliminated
    fixed = ~layout.free
    if method == "iterative" and G is None and hasattr(system, "solve_iterative"):
        # photogram.adjust.point_rows.PointSystem: everything in its point order
        return system.solve_iterative(layout, damping, cg_tolerance, cg_max_iterations,
                                      point_labels, cg_criterion,
                                      (cg_preconditioner, coarse_cluster_size)), None
    Ncc, A = damped(system, layout, damping)
    g_c, g_e = system.g[:n_r], system.g[n_r:]
    Ainv = invert_point_blocks(A, point_labels)
    if method == "iterative":
        if G is not None:
            raise ValueError("the iterative reduced-camera-system solve takes no datum "
                             "conditions G (use method='dense')")
        return _solve_iterative(system, Ncc, Ainv, layout, cg_tolerance, cg_max_iterations,
                                cg_criterion, (cg_preconditioner, coarse_cluster_size))
    S, YGe = reduced_camera_system(system, Ainv, Ncc)
    rhs_c = -g_c + YGe

    # Jacobi scaling: interior parameters (K1 ~ 1e-8 px^-2) and coordinates
    # differ by many orders of magnitude; scale the reduced system to a
    # unit diagonal before factorizing.
    diag = np.diag(S)
    d = 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0))
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
        Ge3 = G_e.reshape(n_e, 3, -1)
        AinvGe3 = np.matmul(Ainv, Ge3)
        AinvGe = AinvGe3.reshape(3 * n_e, -1)
        B = G_c - _w_times(system, AinvGe3)
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
    rhs_e = -g_e.reshape(n_e, 3) - system.wt_times_c(dx_c)
    if k is not None:
        rhs_e = rhs_e - (G[n_r:] @ k).reshape(n_e, 3)
    dx_e = np.matmul(Ainv, rhs_e[:, :, None])[:, :, 0].ravel()
    dx = np.concatenate([dx_c, dx_e])
    dx[fixed] = 0.0
    if not np.all(np.isfinite(dx)):
        raise GeometryError("the adjustment produced a non-finite step (divergence)",
                            hint="check the approximate values and the datum")
    return dx, Factorization(Ainv, M, cho, d if G is None else dd, AinvGe, n_r, system)


def _solve_iterative(system, Ncc, Ainv, layout, tolerance, max_iterations, criterion,
                     precond=("schur_jacobi", 64)):
    """The step by conjugate gradients on the reduced camera system
    (``precond``: the preconditioner's kind and cluster size)."""
    from photogram.adjust import rcs_coarse, rcs_iterative
    n_r, n_e = layout.n_reduced, layout.n_eliminated
    g_c, g_e = system.g[:n_r], system.g[n_r:].reshape(n_e, 3)
    op = rcs_iterative.SchurOperator(system, Ncc, Ainv)
    rhs_c = -g_c + op.w_times_e(np.einsum("nij,nj->ni", Ainv, g_e))
    rhs_c[~layout.free[:n_r]] = 0.0
    dx_c, steps = rcs_iterative.pcg(op, rhs_c, rcs_coarse.preconditioner(op, *precond),
                                    tolerance, max_iterations, criterion)
    rcs_coarse.record(op, steps)
    rhs_e = -g_e - system.wt_times_c(dx_c)
    dx_e = np.matmul(Ainv, rhs_e[:, :, None])[:, :, 0].ravel()
    dx = np.concatenate([dx_c, dx_e])
    dx[~layout.free] = 0.0
    if not np.all(np.isfinite(dx)):
        raise GeometryError("the adjustment produced a non-finite step (divergence)",
                            hint="check the approximate values and the datum")
    return dx, None


def _w_times(system, X):
    """``W X`` (n_r, m) for X (n_e, 3, m)."""
    st = system.structure
    n_r = st.n_r
    if st.n_e_rows == 0:
        return np.zeros((n_r, X.shape[2]))
    v = np.einsum("nis,nim->nsm", system.WT, X[st.e_point])     # (n, s, m)
    out = np.zeros((n_r + 1, X.shape[2]))
    np.add.at(out, st.e_rcols.ravel(), v.reshape(-1, X.shape[2]))
    return out[:n_r]
