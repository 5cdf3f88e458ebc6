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

__all__ = ["SchurOperator", "schur_jacobi", "pcg", "solve_reduced", "CG_CRITERIA"]


class SchurOperator:
    """``S x = N_cc x - W A^-1 W^T x`` without forming ``S``.

    The coupling E-rows' ``W_o^T`` are copied once per linearization into
    point order (:attr:`Structure.pt_rows`), so that every product streams
    through them with the point data in cache: one fused pass per product
    with numba (``W^T x``, ``A_p^-1``, ``W z`` point by point), three
    vectorized numpy steps otherwise.
    """

    def __init__(self, system, Ncc, Ainv, ordered=False):
        st = system.structure
        self.system, self.Ncc, self.Ainv = system, Ncc, Ainv
        self.n_r, self.n_e = st.n_r, st.layout.n_eliminated
        rows = st.pt_rows
        self.ptr = st.pt_ptr
        self.fast = kernels.active(st.n_e_rows)
        # numba: W_o^T copied into point order; numpy: W^T as a CSR matrix
        # (once per linearization: repeated damped solves reuse it)
        cache = system.__dict__.setdefault("_rcs_cache", {})
        self.point = getattr(system, "plan", None)          # a point_rows.PointSystem
        if self.point is not None:
            # point_rows.PointSystem: A^-1 also in its plan's point order
            # (``ordered``: given so; else gathered, and given back in
            # point-number order for the generic preconditioner)
            self.WTp, self.Wt = system.WTp, None
            self.Ainv_o = Ainv if ordered else Ainv[self.point.point]
            if ordered and not self.point.unique:
                self.Ainv = np.empty_like(Ainv)
                self.Ainv[self.point.point] = Ainv
            return
        self._index()
        if self.fast:
            if "WTp" not in cache:
                cache["WTp"] = system.WT[rows]
            self.WTp, self.Wt = cache["WTp"], None
        else:
            if "Wt" not in cache:
                cache["Wt"] = _wt_matrix(st, system.WT)
            self.WTp, self.Wt = None, cache["Wt"]

    def _index(self):
        """Reduced columns, point and group of the point-ordered rows
        (fixed: computed once per structure)."""
        st = self.system.structure
        if getattr(st, "_pt_index", None) is None:
            rows = st.pt_rows
            st._pt_index = (st.e_rcols[rows], st.e_point[rows], st.e_group[rows])
        self.rcp, self.pidx, self.grp = st._pt_index

    def w_times_e(self, y):
        """``W y`` (n_r,) for y (n_e, 3)."""
        if self.point is not None:
            return self.system.w_times_e(y)
        if not hasattr(self, "rcp"):
            self._index()
        if self.Wt is not None:
            return (self.Wt.T @ y.ravel())[:self.n_r]
        u = np.einsum("nis,ni->ns", self.WTp, y[self.pidx])
        return np.bincount(self.rcp.ravel(), weights=u.ravel(), minlength=self.n_r + 1)[:self.n_r]

    def __call__(self, x):
        x_ext = np.append(x, 0.0)
        if self.point is not None:
            return self.Ncc @ x - self.system.schur_matvec(self.Ainv_o, x)
        if self.fast:
            out = np.zeros(self.n_r + 1)
            kernels.compiled().schur_matvec(self.WTp, self.rcp, self.ptr, self.Ainv, x_ext, out)
            return self.Ncc @ x - out[:self.n_r]
        y = (self.Wt @ x_ext).reshape(self.n_e, 3)
        A = self.Ainv
        z = A[:, :, 0] * y[:, :1] + A[:, :, 1] * y[:, 1:2] + A[:, :, 2] * y[:, 2:]
        return self.Ncc @ x - self.w_times_e(z)


def _wt_matrix(st, WT):
    """``W^T`` as a CSR matrix (3 n_e x (n_r + 1), the last column the
    padding dummy): row ``3 p + i`` holds ``WT[o, i, :]`` of every
    coupling E-row o of point p. The pattern (where each entry of ``WT``
    goes) is computed once per structure; then one scatter per
    linearization (the numpy path's products are scipy's compiled sparse
    products)."""
    s = WT.shape[2]
    plan = getattr(st, "_wt_plan", None)
    if plan is None:
        ptr, pt_rows = st.pt_ptr, st.pt_rows
        n = len(pt_rows)
        n_e = len(ptr) - 1
        c = np.diff(ptr)
        rows = np.sort(pt_rows)                                  # E-row order
        k = np.empty(st.n_e_rows, dtype=np.int64)
        k[pt_rows] = np.arange(n)
        k = k[rows]                                              # place in point order
        p = st.e_point[rows]
        base = 3 * s * ptr[p] + (k - ptr[p]) * s
        dest = (base[:, None, None] + (np.arange(3) * s)[None, :, None] * c[p][:, None, None]
                + np.arange(s)[None, None, :])
        itype = np.int32 if 3 * s * n < 2 ** 31 - 1 else np.int64
        dest = dest.astype(itype).ravel()
        indices = np.empty(3 * s * n, dtype=itype)
        indices[dest] = np.broadcast_to(st.e_rcols[rows][:, None, :], (len(rows), 3, s)).ravel()
        indptr = (3 * s * ptr[:-1, None] + np.arange(3)[None, :] * s * c[:, None]).ravel()
        indptr = np.append(indptr, 3 * s * n).astype(itype)
        whole = len(rows) == st.n_e_rows
        plan = (dest, indices, indptr, n_e, None if whole else rows)
        st._wt_plan = plan
    dest, indices, indptr, n_e, rows = plan
    data = np.empty(len(dest))
    data[dest] = (WT if rows is None else WT[rows]).ravel()
    Wt = sp.csr_matrix((3 * n_e, st.n_r + 1))
    Wt.data, Wt.indices, Wt.indptr = data, indices, indptr
    return Wt


def _merged_rows_plan(op):
    """Starts of the (group, point) runs of the point-ordered coupling
    rows, or None when every point has at most one row per group."""
    st = op.system.structure
    if getattr(st, "_gp_plan", None) is None:
        key = op.pidx * max(st.n_groups, 1) + op.grp          # sorted by point, then group
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else None
        st._gp_plan = ("merge", None if starts is None or len(starts) == len(key) else starts)
    return st._gp_plan[1]


def _merged_rows(op):
    """Per (group, point) the summed ``W_gp^T`` (3 x s), its group and
    point; the point-ordered E-rows themselves when no point has two rows
    in one group."""
    starts = _merged_rows_plan(op)
    WTp = op.WTp if op.WTp is not None and op.point is None else \
        op.system.WT[op.system.structure.pt_rows]
    if starts is None:
        return WTp, op.grp, op.pidx
    return np.add.reduceat(WTp, starts, axis=0), op.grp[starts], op.pidx[starts]


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


def _cholesky3(A):
    """Lower Cholesky factors (n, 3, 3) of SPD 3x3 blocks (closed form)."""
    L = np.zeros_like(A)
    L[:, 0, 0] = l00 = np.sqrt(A[:, 0, 0])
    L[:, 1, 0] = l10 = A[:, 1, 0] / l00
    L[:, 2, 0] = l20 = A[:, 2, 0] / l00
    L[:, 1, 1] = l11 = np.sqrt(np.maximum(A[:, 1, 1] - l10 * l10, 0.0))
    L[:, 2, 1] = l21 = (A[:, 2, 1] - l20 * l10) / np.where(l11 > 0, l11, 1.0)
    L[:, 2, 2] = np.sqrt(np.maximum(A[:, 2, 2] - l20 * l20 - l21 * l21, 0.0))
    return L


def _group_schur_grams(system, Ainv):
    """``sum_o W_o A_p^-1 W_o^T`` per row group (n_g, s, s), numpy path:
    with ``A_p^-1 = L L^T`` every row gives ``V_o = L^T W_o^T`` (3 x s) and
    a group's sum is one BLAS Gram matrix of its stacked ``V_o`` (the
    E-rows of a group are contiguous)."""
    st = system.structure
    rows = np.sort(st.pt_rows)
    WT = system.WT if len(rows) == st.n_e_rows else system.WT[rows]
    grp = st.e_group[rows]
    L = _cholesky3(Ainv)[st.e_point[rows]]                   # (n, 3, 3)
    V = np.empty_like(WT)
    for i in range(3):
        V[:, i, :] = sum(L[:, k, i, None] * WT[:, k, :] for k in range(i, 3))
    n_g, s = st.group_cols.shape
    out = np.zeros((n_g, s, s))
    starts = np.flatnonzero(np.r_[True, grp[1:] != grp[:-1]])
    ends = np.r_[starts[1:], len(grp)]
    for g, lo, hi in zip(grp[starts], starts, ends):
        Vg = V[lo:hi].reshape(-1, s)
        out[g] += Vg.T @ Vg
    return out


def schur_jacobi(op, coupling=None):
    """The Schur-Jacobi preconditioner of a :class:`SchurOperator`: a
    function ``z = P^-1 r``. ``coupling``: the blocks'
    ``-sum W A^-1 W^T`` part when already summed (n_g, s, s)."""
    system, Ncc, Ainv = op.system, op.Ncc, op.Ainv
    st = system.structure
    n_r = st.n_r
    gc = st.group_cols                                       # (n_g, s), padded with n_r
    n_g, s = gc.shape
    blocks = _ncc_group_blocks(Ncc, gc, n_r)
    if coupling is not None:
        blocks += coupling
    elif len(st.pt_rows) and s:
        if not hasattr(op, "rcp"):
            op._index()
        if not op.fast and _merged_rows_plan(op) is None:
            blocks -= _group_schur_grams(system, Ainv)
        else:
            WT, grp, pt = _merged_rows(op)
            if op.fast:
                kernels.compiled().jacobi_rows(WT, Ainv, grp, pt, blocks)
            else:
                Y = np.matmul(Ainv[pt], WT)                  # (n, 3, s)
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


CG_CRITERIA = ("residual", "model")


def pcg(op, b, precond, tolerance=0.1, max_iterations=500, criterion="residual"):
    """Preconditioned conjugate gradients for ``op(x) = b`` from ``x = 0``.
    Returns ``(x, iterations)``.

    ``criterion="residual"``: stop when ``sqrt(r^T P^-1 r) <= tolerance *
    sqrt(b^T P^-1 b)``. ``criterion="model"``: Ceres' truncated-Newton
    test for Levenberg-Marquardt steps (Nash and Sofer 1990; Ceres'
    ``ConjugateGradientsSolver`` with ``q_tolerance = eta``): with the
    quadratic model ``Q(x) = x^T S x - 2 b^T x = -x^T (b + r)``, stop at
    step i when ``i (Q_i - Q_{i-1}) / Q_i < tolerance``, i.e. when the
    last step's share of the model decrease so far, times i, is small.

    A preconditioner with a ``measure`` attribute (a function ``r ->
    J r``, e.g. :class:`photogram.adjust.rcs_coarse.TwoLevel`) has the
    residual test taken in that norm, ``sqrt(r^T J r)``, instead of its
    own: the same test whichever preconditioner runs."""
    if criterion not in CG_CRITERIA:
        raise ValueError(f"unknown CG criterion {criterion!r} ({', '.join(CG_CRITERIA)})")
    x = np.zeros_like(b)
    r = b.copy()
    z = precond(r)
    rz = float(r @ z)
    if not rz > 0.0:
        return x, 0
    measure = getattr(precond, "measure", None)
    stop = tolerance * tolerance * (rz if measure is None else float(r @ measure(r)))
    model = criterion == "model"
    q0 = 0.0
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
        if model:
            q1 = -float(x @ (b + r))
            if q1 < 0.0 and it * (q1 - q0) / q1 < tolerance:
                break
            q0 = q1
        z = precond(r)
        rz_new = float(r @ z)
        if not model and (rz_new if measure is None else float(r @ measure(r))) <= stop:
            break
        if rz_new == 0.0:
            break
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, it


def solve_reduced(system, Ncc, Ainv, rhs_c, tolerance=0.1, max_iterations=500,
                  criterion="residual"):
    """``dx_c`` of ``S dx_c = rhs_c`` by preconditioned CG (``Ncc``
    damped, sparse or dense; ``Ainv`` the inverse damped point blocks).
    Returns ``(dx_c, cg_iterations)``."""
    op = SchurOperator(system, Ncc, Ainv)
    return pcg(op, rhs_c, schur_jacobi(op), tolerance, max_iterations, criterion)
