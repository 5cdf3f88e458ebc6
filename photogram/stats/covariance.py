"""Covariance of all unknowns from the Schur-factorized normal equations.

With ``K = [[A, U], [U^T, D]]`` (points eliminated, ``U = [W^T, G_e]``) and
``M`` the reduced (bordered) matrix, the inverse blocks are::

    Q_cc = (M^-1)_cc
    Q_ec = -A^-1 U (M^-1)_{., c}
    Q_ee,i = A_i^-1 + (A^-1 U)_i M^-1 (A^-1 U)_i^T

(cofactors of the whitened system; multiply by sigma0^2 for covariances).
Fixed parameters get zero variance.

``V_p = (A^-1 U)_p`` is never a dense matrix: it is the sum of the E-rows'
``A_p^-1 W_a^T`` (3 x s, at their reduced columns), a 3 x u_p matrix over
the u_p columns the point touches, so ``Q_ee`` and the cross cofactors of a
point with the columns asked for are computed point by point, in chunks
(:mod:`photogram.stats.point_blocks`). Cameras, stations, 3x3 point blocks,
redundancy numbers and w-tests therefore cost one inverse of the reduced
matrix plus memory that grows with the observations and points, never a
(3 n_e x n_r), (n_obs x n_obs) or (n_unknowns x n_unknowns) matrix.
"""

from __future__ import annotations

import numpy as np

import scipy.linalg as la

from photogram.adjust import kernels
from photogram.geometry import angle_increment_map
from photogram.adjust.schur import solve as schur_solve
from photogram.stats.point_blocks import PointBlocks

_potri = la.get_lapack_funcs("potri", (np.zeros((1, 1)),))


class Cofactors:
    """Cofactor matrices of the unknowns (a-priori sigma0 = 1).

    ``Qcc`` (n_r, n_r) of the reduced unknowns (interior and exterior
    orientation, coupled points) and ``Qee`` (n_e, 3, 3) of every eliminated
    point are computed at once; the cross cofactors of points and reduced
    unknowns only for the (point, columns) pairs asked for (:meth:`cross`,
    :meth:`block`), through the Schur structure
    (:class:`photogram.stats.point_blocks.PointBlocks`), so that a problem
    with 10^5 points never forms a 3 n_e x n_r matrix. :attr:`Qec` still
    builds that matrix on request (small problems, tests).
    """

    def __init__(self, layout, Qcc, Qec, Qee, qec_rows=None, cross=None, ce_times=None):
        self.layout = layout
        self.Qcc = Qcc
        self.Qee = Qee
        self._Qec = Qec
        self._qec_rows = qec_rows       # callable: points -> (len, 3, n_r)
        self._cross = cross             # callable: (points, cols) -> (len, 3, sr)
        self._ce_times = ce_times       # callable: (n_e, 3, q) -> (n_r, q)
        self._blocks = None             # PointBlocks of the factorization (joint_points)

    @property
    def Qec(self) -> np.ndarray:
        """(3 n_e, n_r) cross cofactors of eliminated points and reduced
        unknowns (dense; built on first use)."""
        if self._Qec is None:
            n_e = self.layout.n_eliminated
            self._Qec = self._qec_rows(np.arange(n_e)).reshape(3 * n_e, -1)
        return self._Qec

    def _qec_of_points(self, points):
        if self._Qec is not None or self._qec_rows is None:
            Q = self.Qec
            return Q.reshape(self.layout.n_eliminated, 3, -1)[points]
        return self._qec_rows(points)

    def cross(self, points, cols, chunk_entries=4_000_000):
        """Cross cofactors (len(points), 3, sr) of the eliminated points
        ``points`` (one per row) and the reduced columns ``cols`` (len, sr)
        of the same row."""
        points = np.asarray(points, dtype=np.int64)
        cols = np.asarray(cols, dtype=np.int64).reshape(len(points), -1)
        if self._cross is not None and self._Qec is None:
            return self._cross(points, cols)
        out = np.zeros((len(points), 3, cols.shape[1]))    # whole rows, chunk by chunk
        pts, inv = np.unique(points, return_inverse=True)
        inv = inv.ravel()
        order = np.argsort(inv, kind="stable")
        bounds = np.searchsorted(inv[order], np.arange(len(pts) + 1))
        step = max(1, chunk_entries // (3 * max(self.layout.n_reduced, 1)))
        for lo in range(0, len(pts), step):
            Q = self._qec_of_points(pts[lo:lo + step])                # (c, 3, n_r)
            q = order[bounds[lo]:bounds[min(lo + step, len(pts))]]
            out[q] = Q[(inv[q] - lo)[:, None, None], np.arange(3)[None, :, None],
                       cols[q][:, None, :]]
        return out

    def ce_times(self, Ne, chunk_entries=4_000_000):
        """``sum_p Q_ce[:, p] Ne[p]`` (n_r, q): the cofactors of the reduced
        unknowns and the eliminated points times ``Ne`` (n_e, 3, q)."""
        Ne = np.asarray(Ne, dtype=float)
        if self._ce_times is not None and self._Qec is None:
            return self._ce_times(Ne)
        n_e, n_r = self.layout.n_eliminated, self.layout.n_reduced
        out = np.zeros((n_r, Ne.shape[2]))
        step = max(1, chunk_entries // (3 * max(n_r, 1)))
        for lo in range(0, n_e, step):
            Q = self._qec_of_points(np.arange(lo, min(lo + step, n_e)))   # (c, 3, n_r)
            out += np.einsum("cin,ciq->nq", Q, Ne[lo:lo + step])
        return out

    def joint_points(self, points):
        """The joint cofactors (3 n, 3 n) of the points ``points`` (point
        numbers of the layout), the cross blocks between points included:
        the full covariance of chosen points, on request (n^2 memory)."""
        lay = self.layout
        cols = lay.point_cols[np.asarray(points, dtype=np.int64)].ravel()
        n_r = lay.n_reduced
        if self._blocks is not None and self._Qec is None and np.all(cols >= n_r):
            return self._blocks.joint((cols[::3] - n_r) // 3)
        raise NotImplementedError("joint point cofactors need the Schur factorization of "
                                  "eliminated points (cofactors(problem))")

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
        for mask, ce, cr, swap in ((~red_a & red_b, cols_a, cols_b, False),
                                   (red_a & ~red_b, cols_b, cols_a, True)):
            if not mask.any():
                continue
            ce, cr = ce[mask], cr[mask]
            Q = self.cross((ce[:, 0] - n_r) // 3, cr)                  # (len, 3, sr)
            vals = np.take_along_axis(Q, ((ce - n_r) % 3)[:, :, None], axis=1)
            out[mask] = np.swapaxes(vals, 1, 2) if swap else vals
        m = ~red_a & ~red_b
        if m.any():
            out[m] = self.Qee[(cols_a[m][:, 0] - n_r) // 3]
        return out

    def of_columns(self, cols):
        """Cofactor blocks (N, s, s) of column sets (N, s)."""
        return self.block(cols, cols)


def cofactors(problem, G=None) -> Cofactors:
    """Cofactors of all unknowns at the problem's current state.

    Parameters
    ----------
    problem : Problem
    G : (n_columns, m) array, optional
        Datum conditions for the covariance instead of the problem's own
        (e.g. the inner constraints of a gauge-free problem such as a BAL
        problem: the minimum-trace covariance).
    """
    from photogram.adjust.solver import single_thread_blas
    with single_thread_blas():
        return _cofactors(problem, problem.G if G is None else G)


def _cofactors(problem, G):
    system = problem.linearize(problem.state)
    _, fact = schur_solve(system, problem.layout, 0.0, G, problem.point_labels)
    lay = problem.layout
    n_r, n_e = lay.n_reduced, lay.n_eliminated
    st = system.structure
    fixed = ~lay.free
    ext = _extended_inverse(fact, n_r, fixed[:n_r])
    m = ext.shape[0] - n_r - 1
    AinvGe3 = (fact.AinvGe.reshape(n_e, 3, m) if fact.AinvGe is not None
               else np.zeros((n_e, 3, 0)))
    blocks = PointBlocks(st, system.WT, fact.Ainv, ext, AinvGe3, fixed)
    Qee = _point_cofactors(st, system.WT, fact.Ainv, ext, AinvGe3, n_r + 1, blocks)
    Qcc = ext[:n_r, :n_r]                     # a view: fixed rows and columns are zero
    fe3 = fixed[n_r:].reshape(-1, 3)
    Qee = Qee * (~fe3[:, :, None]) * (~fe3[:, None, :])

    def qec_rows(points):
        return _qec_rows(st, system.WT, fact.Ainv, ext, AinvGe3, n_r, points, fixed)

    cof = Cofactors(lay, Qcc, None, Qee, qec_rows, blocks.cross, blocks.ce_times)
    cof._blocks = blocks
    cof.factorization = fact
    return cof


def _extended_inverse(fact, n_r, fixed_c):
    """``M^-1`` with a zero dummy row/column ``n_r`` (the padding of the
    E-rows' columns) before the datum conditions (from ``n_r + 1``); the
    rows and columns of fixed parameters zero (they are decoupled in M:
    nothing else changes). One (n_r + 1 + m)^2 matrix; the inverse of a
    Cholesky factor in place (LAPACK potri) when M is not bordered."""
    if fact.cho is not None:
        c, lower = fact.cho
        Minv, info = _potri(c, lower=lower)
        if info:
            raise np.linalg.LinAlgError(f"potri failed (info {info})")
        Minv = np.tril(Minv) if lower else np.triu(Minv)
        Minv += Minv.T
        Minv[np.diag_indices(len(Minv))] *= 0.5
        d = fact.scale
        Minv *= d[:, None]
        Minv *= d[None, :]
    else:
        Minv = fact.reduced_inverse()
    m = Minv.shape[0] - n_r
    ext = np.zeros((n_r + 1 + m, n_r + 1 + m))
    ext[:n_r, :n_r] = Minv[:n_r, :n_r]
    if m:
        ext[:n_r, n_r + 1:] = Minv[:n_r, n_r:]
        ext[n_r + 1:, :n_r] = Minv[n_r:, :n_r]
        ext[n_r + 1:, n_r + 1:] = Minv[n_r:, n_r:]
    del Minv
    ext[:n_r][fixed_c] = 0.0
    ext[:, :n_r][:, fixed_c] = 0.0
    return ext


def s_transform(cof, T, Tp, QTp, layout=None):
    """Cofactors in another datum (an S-transformation, Baarda): from the
    cofactors ``Q1`` of a regular datum to those of the datum
    ``Tp^T dx = 0`` (e.g. minimum trace over chosen points),
    ``Q2 = S Q1 S^T`` with ``S = I - T (Tp^T T)^-1 Tp^T``.

    Parameters
    ----------
    cof : Cofactors of the first datum
    T : (n_columns, k) the gauge motions (``datum.similarity_motions``)
    Tp : (n_columns, k) the conditions of the new datum (T restricted to
        the datum points)
    QTp : (n_columns, k) ``Q1 Tp`` (``Factorization.solve``)
    layout : Layout of the result (default: cof's)

    Only the blocks are transformed (``Q2[a,b] = Q1[a,b] - U_a T_b^T -
    T_a U_b^T + T_a H T_b^T``, ``U = Q1 Tp K^T``, ``K = (Tp^T T)^-1``,
    ``H = K Tp^T U``); nothing of size n_columns^2 is formed.
    """
    lay = layout or cof.layout
    n_r = lay.n_reduced
    K = np.linalg.inv(Tp.T @ T)
    U = QTp @ K.T
    H = K @ (Tp.T @ U)
    Tc, Uc = T[:n_r], U[:n_r]
    Qcc = cof.Qcc - Uc @ Tc.T - Tc @ Uc.T + Tc @ H @ Tc.T
    pc = lay.point_cols
    elim = ~lay.reduced_points
    Te, Ue = T[pc[elim]], U[pc[elim]]                       # (n_e, 3, k)
    Qee = (cof.Qee - Te @ np.swapaxes(Ue, 1, 2) - Ue @ np.swapaxes(Te, 1, 2)
           + Te @ H @ np.swapaxes(Te, 1, 2))
    old = cof._qec_of_points

    def qec_rows(points):
        Tq, Uq = Te[points], Ue[points]
        return (old(points) - Uq @ Tc.T - Tq @ Uc.T + Tq @ (H @ Tc.T))

    def cross(points, cols):
        Tq, Uq = Te[points], Ue[points]                        # (n, 3, k)
        Tk, Uk = np.swapaxes(Tc[cols], 1, 2), np.swapaxes(Uc[cols], 1, 2)   # (n, k, sr)
        return cof.cross(points, cols) - Uq @ Tk - Tq @ Uk + Tq @ (H @ Tk)

    def ce_times(Ne):
        UN = np.einsum("pik,piq->kq", Ue, Ne)
        TN = np.einsum("pik,piq->kq", Te, Ne)
        return cof.ce_times(Ne) - Tc @ UN - Uc @ TN + Tc @ (H.T @ TN)

    return Cofactors(lay, Qcc, None, Qee, qec_rows, cross, ce_times)


def _point_cofactors(st, WT, Ainv, ext, AinvGe3, g0, blocks):
    """``Q_ee,p = A_p^-1 + V_p M^-1 V_p^T`` for every eliminated point:
    compiled (summed over the pairs of E-rows of each point) or numpy
    (:meth:`PointBlocks.point_cofactors`, chunks of points)."""
    n_e = len(Ainv)
    if st.n_e_rows == 0 or st.s == 0:
        Qee = Ainv.copy()
        if AinvGe3.shape[2]:
            MGG = ext[g0:, g0:]
            Qee += AinvGe3 @ MGG @ np.swapaxes(AinvGe3, 1, 2)
        return Qee
    if kernels.active(st.n_e_rows):
        Qee = np.empty((n_e, 3, 3))
        kernels.compiled().point_cofactors(WT, Ainv, st.pt_ptr, st.pt_rows, st.e_rcols, ext,
                                np.ascontiguousarray(AinvGe3), g0, Qee)
        return Qee
    return blocks.point_cofactors()


def _qec_rows(st, WT, Ainv, ext, AinvGe3, n_r, points, fixed, chunk_entries=4_000_000):
    """``Q_ec`` rows (len(points), 3, n_r) of the given eliminated points:
    ``-(V_p M^-1)`` restricted to the reduced columns, chunk by chunk."""
    points = np.asarray(points, dtype=np.int64)
    width = ext.shape[0]
    g0 = n_r + 1
    out = np.zeros((len(points), 3, n_r))
    if len(points) == 0:
        return out
    fe3 = fixed[n_r:].reshape(-1, 3)
    fixed_c = fixed[:n_r]
    ptr = st.pt_ptr
    step = max(1, chunk_entries // (3 * width))
    for lo in range(0, len(points), step):
        P = points[lo:lo + step]
        V = np.zeros((len(P), 3, width))
        counts = ptr[P + 1] - ptr[P]
        if counts.sum():
            which = np.repeat(np.arange(len(P)), counts)
            pos = np.repeat(ptr[P], counts) + np.arange(counts.sum()) - np.repeat(
                np.cumsum(counts) - counts, counts)
            rows = st.pt_rows[pos]
            Z = np.matmul(Ainv[st.e_point[rows]], WT[rows])                # (c, 3, s)
            idx = (which[:, None, None] * 3 + np.arange(3)[None, :, None]) * width \
                + st.e_rcols[rows][:, None, :]
            V = np.bincount(idx.ravel(), weights=Z.ravel(),
                            minlength=len(P) * 3 * width).reshape(len(P), 3, width)
        if AinvGe3.shape[2]:
            V[:, :, g0:] = AinvGe3[P]
        Q = -(V.reshape(-1, width) @ ext[:, :n_r]).reshape(len(P), 3, n_r)
        Q *= ~fe3[P][:, :, None]
        Q[:, :, fixed_c] = 0.0
        out[lo:lo + step] = Q
    return out


def point_covariances(cof: Cofactors, sigma0_sq=1.0):
    """(n_p, 3, 3) covariance of every object point."""
    return sigma0_sq * cof.of_columns(cof.layout.point_cols)


def station_covariances(cof: Cofactors, R, sigma0_sq=1.0):
    """(n_s, 6, 6) covariance of (X0, Y0, Z0, omega, phi, kappa) per station.

    The rotation increment covariance is propagated to the angles with
    ``d(opk) = E delta``.
    """
    Q = cof.of_columns(cof.layout.station_cols)
    _, E = angle_increment_map(R)
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
