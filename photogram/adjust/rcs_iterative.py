"""Iterative solution of the reduced camera system (many cameras).

The dense path (:func:`photogram.adjust.schur.solve`) forms
``S = N_cc - W A^-1 W^T`` as an ``n_r x n_r`` array and factorizes it:
``O(n_r^2)`` memory and ``O(n_r^3)`` time, which takes over beyond a few
thousand reduced columns (a few hundred cameras). This module never forms
``S``: conjugate gradients on ``S dx_c = rhs`` with the implicit product

    S x = N_cc x - W (A^-1 (W^T x))

(``O(observations)`` per step: the per-E-row ``W_o^T`` of
:class:`photogram.adjust.normal.NormalSystem`, the 3x3 point inverses and
a sparse ``N_cc``), preconditioned by the Schur-Jacobi blocks (Ceres'
``ITERATIVE_SCHUR`` with ``SCHUR_JACOBI``): for every row group (a station
and its interior orientation) the exact diagonal block

    S_gg = N_cc[g, g] - sum_p W_gp A_p^-1 W_gp^T,

inverted once per step (additive Schwarz where groups share columns, e.g.
a common interior orientation; plain Jacobi on columns of no group).

The step is inexact: CG stops when the preconditioned residual norm falls
below ``tolerance`` times that of the right-hand side (Ceres' ``eta``),
or after ``max_iterations``; the trust region judges the step by its
actual decrease as for any other.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from photogram.adjust import kernels
from photogram.errors import GeometryError

__all__ = ["SchurOperator", "schur_jacobi", "pcg", "solve_reduced"]


class SchurOperator:
    """``S x = N_cc x - W A^-1 W^T x`` without forming ``S``.

    The coupling E-rows' ``W_o^T`` are copied once per linearization into
    point order (:attr:`Structure.pt_rows`), so that every product streams
    through them with the point data in cache: one fused pass per product
    with numba (``W^T x``, ``A_p^-1``, ``W z`` point by point), three
    vectorized numpy steps otherwise.
    """

    def __init__(self, system, Ncc, Ainv):
        st = system.structure
        self.system, self.Ncc, self.Ainv = system, Ncc, Ainv
        self.n_r, self.n_e = st.n_r, st.layout.n_eliminated
        rows = st.pt_rows
        self.ptr = st.pt_ptr
        self.WTp = system.WT[rows]                          # (n, 3, s), by point
        self.rcp = st.e_rcols[rows]
        self.pidx = st.e_point[rows]
        self.grp = st.e_group[rows]
        self.fast = kernels.active(st.n_e_rows)

    def w_times_e(self, y):
        """``W y`` (n_r,) for y (n_e, 3)."""
        u = np.einsum("nis,ni->ns", self.WTp, y[self.pidx])
        return np.bincount(self.rcp.ravel(), weights=u.ravel(), minlength=self.n_r + 1)[:self.n_r]

    def __call__(self, x):
        x_ext = np.append(x, 0.0)
        if self.fast:
            out = np.zeros(self.n_r + 1)
            kernels.compiled().schur_matvec(self.WTp, self.rcp, self.ptr, self.Ainv, x_ext, out)
            return self.Ncc @ x - out[:self.n_r]
        v = np.einsum("nis,ns->ni", self.WTp, x_ext[self.rcp])
        y = np.stack([np.bincount(self.pidx, weights=v[:, i], minlength=self.n_e)
                      for i in range(3)], axis=1)
        z = np.einsum("nij,nj->ni", self.Ainv, y)
        return self.Ncc @ x - self.w_times_e(z)


def _merged_rows(op):
    """Per (group, point) the summed ``W_gp^T`` (3 x s), its group and
    point; the E-rows themselves when no point has two rows in one group
    (the plan is cached on the structure)."""
    st = op.system.structure
    plan = getattr(st, "_gp_plan", None)
    if plan is None:
        key = op.pidx * max(st.n_groups, 1) + op.grp          # point-major, sorted by point
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else None
        plan = None if starts is None or len(starts) == len(key) else starts
        st._gp_plan = ("merge", plan)
    starts = st._gp_plan[1]
    if starts is None:
        return op.WTp, op.grp, op.pidx
    return np.add.reduceat(op.WTp, starts, axis=0), op.grp[starts], op.pidx[starts]


def _ncc_group_blocks(Ncc, gc, n_r):
    """``N_cc[gc_g, gc_g]`` (n_g, s, s) with zeros at padded columns."""
    r = np.broadcast_to(gc[:, :, None], gc.shape + (gc.shape[1],))
    c = np.broadcast_to(gc[:, None, :], r.shape)
    ok = (r < n_r) & (c < n_r)
    vals = np.zeros(r.shape)
    if sp.issparse(Ncc):
        vals[ok] = np.asarray(Ncc[r[ok], c[ok]]).ravel()
    else:
        vals[ok] = Ncc[r[ok], c[ok]]
    return vals


def schur_jacobi(op):
    """The Schur-Jacobi preconditioner of a :class:`SchurOperator`: a
    function ``z = P^-1 r``."""
    system, Ncc, Ainv = op.system, op.Ncc, op.Ainv
    st = system.structure
    n_r = st.n_r
    gc = st.group_cols                                       # (n_g, s), padded with n_r
    n_g, s = gc.shape
    blocks = _ncc_group_blocks(Ncc, gc, n_r)
    if len(st.pt_rows) and s:
        WT, grp, pt = _merged_rows(op)
        if op.fast:
            kernels.compiled().jacobi_rows(WT, Ainv, grp, pt, blocks)
        else:
            Y = np.matmul(Ainv[pt], WT)                      # (n, 3, s)
            Z = np.einsum("nis,nit->nst", WT, Y).reshape(len(WT), -1)
            flat = blocks.reshape(n_g, -1)
            for k in range(s * s):
                flat[:, k] -= np.bincount(grp, weights=Z[:, k], minlength=n_g)
    pad = gc >= n_r
    blocks[:, np.arange(s), np.arange(s)] += pad
    try:
        inv = np.linalg.inv(blocks)
    except np.linalg.LinAlgError:
        inv = np.linalg.pinv(blocks, hermitian=True)
    inv[np.broadcast_to(pad[:, :, None], inv.shape)] = 0.0
    inv[np.broadcast_to(pad[:, None, :], inv.shape)] = 0.0
    covered = np.zeros(n_r + 1, dtype=bool)
    covered[gc.ravel()] = True
    loose = np.flatnonzero(~covered[:n_r])
    diag = Ncc.diagonal() if sp.issparse(Ncc) else np.diag(Ncc)
    dl = 1.0 / np.where(diag[loose] > 0, diag[loose], 1.0)
    flat_cols = gc.ravel()

    def apply(r):
        x = np.append(r, 0.0)[gc]                            # (n_g, s)
        z = np.bincount(flat_cols, weights=np.einsum("gst,gt->gs", inv, x).ravel(),
                        minlength=n_r + 1)[:n_r]
        z[loose] = r[loose] * dl
        return z
    return apply


def pcg(op, b, precond, tolerance=1e-2, max_iterations=500):
    """Preconditioned conjugate gradients for ``op(x) = b`` from ``x = 0``;
    stops when ``sqrt(r^T P^-1 r) <= tolerance * sqrt(b^T P^-1 b)``.
    Returns ``(x, iterations)``."""
    x = np.zeros_like(b)
    r = b.copy()
    z = precond(r)
    rz = float(r @ z)
    if not rz > 0.0:
        return x, 0
    stop = tolerance * tolerance * rz
    p = z.copy()
    it = 0
    for it in range(1, max_iterations + 1):
        q = op(p)
        pq = float(p @ q)
        if not pq > 0.0:
            if it == 1:
                raise GeometryError("the reduced camera system is not positive definite",
                                    hint="add a datum or check the approximate values")
            break
        alpha = rz / pq
        x += alpha * p
        r -= alpha * q
        z = precond(r)
        rz_new = float(r @ z)
        if rz_new <= stop:
            break
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, it


def solve_reduced(system, Ncc, Ainv, rhs_c, tolerance=1e-2, max_iterations=500):
    """``dx_c`` of ``S dx_c = rhs_c`` by preconditioned CG (``Ncc``
    damped, sparse or dense; ``Ainv`` the inverse damped point blocks).
    Returns ``(dx_c, cg_iterations)``."""
    op = SchurOperator(system, Ncc, Ainv)
    return pcg(op, rhs_c, schur_jacobi(op), tolerance, max_iterations)
