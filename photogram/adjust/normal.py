"""Normal equations, assembled block by block, in the form the Schur
complement of the (3x3 block-diagonal) eliminated points needs.

With the columns split into reduced (c) and eliminated points (e), the
normal equations ``N dx = -g`` read::

    [ N_cc  W   ] [dx_c]     [g_c]
    [ W^T   A   ] [dx_e] = - [g_e]

``A`` is block diagonal (one 3x3 block per point). ``W`` is never formed as
a matrix: every row of a residual block that touches an eliminated point
(an *E-row*: an image point of an eliminated object point, a prior on it)
keeps its own ``W_o^T = Je^T Jc`` (3 x s), with ``Jc`` the Jacobian of its
``s`` reduced columns (station, interior orientation, ...; columns that are
fixed for every row of the class are left out) and ``Je`` that of its point.
The Schur complement (:mod:`schur`) sums ``W_a A_p^-1 W_b^T`` over the pairs
of E-rows of each point, a pattern that is computed once.

Rows are grouped by their reduced columns (e.g. one group per station);
``N_cc`` is summed per group (one small Gram matrix each) and scattered once.
The sparsity structure never changes between iterations, so every index is
computed once (:class:`~photogram.adjust.structure.Structure`, in
:mod:`photogram.adjust.structure`); an iteration only sums values.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from photogram.adjust import kernels
from photogram.adjust.structure import RowClass, Structure


class NormalSystem:
    """Assembled normal equations: dense ``Ncc``, the per-E-row ``WT``
    (``W_o^T``, 3 x s), the point blocks ``A``, the gradient and the cost."""

    def __init__(self, Ncc, A, g, cost, WT, structure):
        self.Ncc = Ncc            # (n_r, n_r)
        self.A = A                # (n_e, 3, 3)
        self.g = g                # (n_columns,)
        self.cost = cost          # 0.5 * sum r^2 of the whitened residuals
        self.WT = WT              # (n_e_rows, 3, s)
        self.structure = structure
        self._W = None

    @property
    def W(self):
        """``W`` (n_r x 3 n_e) as a sparse matrix (built on request; the
        solver never needs it)."""
        if self._W is None:
            st = self.structure
            n_r, n_e = st.n_r, st.layout.n_eliminated
            rows = np.broadcast_to(st.e_rcols[:, None, :], self.WT.shape)
            cols = np.broadcast_to((3 * st.e_point[:, None] + np.arange(3))[:, :, None], self.WT.shape)
            ok = rows < n_r
            self._W = sp.csr_matrix((self.WT[ok], (rows[ok], cols[ok])), shape=(n_r, 3 * n_e))
        return self._W

    def w_times_e(self, x_e):
        """``W x_e`` (n_r,) for x_e (n_e, 3)."""
        st = self.structure
        v = np.einsum("nis,ni->ns", self.WT, x_e[st.e_point])
        return np.bincount(st.e_rcols.ravel(), weights=v.ravel(), minlength=st.n_r + 1)[:st.n_r]

    def wt_times_c(self, x_c):
        """``W^T x_c`` as (n_e, 3) for x_c (n_r,)."""
        st = self.structure
        n_e = st.layout.n_eliminated
        xe = np.zeros((n_e, 3))
        if st.n_e_rows == 0:
            return xe
        x_ext = np.append(x_c, 0.0)
        if kernels.active(st.n_e_rows):
            kernels.compiled().back_rows(self.WT, st.e_rcols, st.e_point, x_ext, xe)
            return xe
        v = np.einsum("nis,ns->ni", self.WT, x_ext[st.e_rcols])
        for i in range(3):
            xe[:, i] = np.bincount(st.e_point, weights=v[:, i], minlength=n_e)
        return xe

    def quadratic(self, dx):
        """``dx^T N dx`` (= |J dx|^2) of the undamped normal equations."""
        st = self.structure
        n_r = st.n_r
        dc, de = dx[:n_r], dx[n_r:].reshape(-1, 3)
        q = float(dc @ (self.Ncc @ dc)) + float(np.einsum("ni,nij,nj->", de, self.A, de))
        if st.n_e_rows:
            q += 2.0 * float(np.sum(self.wt_times_c(dc) * de))
        return q


def assemble(structure: Structure, residuals, jacobians, sparse: bool = False) -> NormalSystem:
    """Sum ``J^T J`` and ``J^T r`` into the normal equations.

    Parameters
    ----------
    residuals : list of (N_b, d_b) whitened residuals per block.
    jacobians : list of list of (N_b, d_b, s) whitened Jacobians per slot.
    sparse : bool
        ``N_cc`` as a scipy CSR matrix instead of a dense array (the
        iterative solve of the reduced camera system,
        :mod:`photogram.adjust.rcs_iterative`: no ``n_r^2`` array).
    """
    st = structure
    lay = st.layout
    n_r, n_e = lay.n_reduced, lay.n_eliminated
    m = n_r + 1
    cost = 0.5 * sum(float(np.sum(r * r)) for r in residuals)
    A = np.zeros((n_e, 3, 3))
    g_e = np.zeros((n_e, 3))
    g_c = np.zeros(m)
    Ncc = _NccSum(m, sparse)
    s = st.s
    WT = np.zeros((st.n_e_rows, 3, s))
    G = np.zeros((st.n_groups, s, s))
    g_grp = np.zeros((st.n_groups, s))
    fast = kernels.active(st.n_e_rows)
    kern = kernels.compiled() if fast else None
    for cls in st.e_classes:
        r, parts, Je = cls.take(residuals, jacobians)
        n, sc, d = len(cls.rows), cls.s, r.shape[1]
        sl = slice(cls.offset, cls.offset + n)
        gs = slice(cls.group_offset, cls.group_offset + cls.n_groups)
        if fast:
            if len(parts) > 2:
                parts = [RowClass.joined(parts, n, d)]
            J1 = parts[0] if parts else np.zeros((n, d, 0))
            J2 = parts[1] if len(parts) > 1 else np.zeros((n, d, 0))
            if sc == s:
                kern.assemble_rows(J1, J2, Je, r, cls.point, cls.group, A, g_e, WT[sl], g_grp[gs])
            else:
                wt = np.zeros((n, 3, sc))
                gr = np.zeros((cls.n_groups, sc))
                kern.assemble_rows(J1, J2, Je, r, cls.point, cls.group, A, g_e, wt, gr)
                WT[sl, :, :sc] = wt
                g_grp[gs, :sc] += gr
            _group_grams(cls, parts, G[gs, :sc, :sc])
            continue
        Jc = RowClass.joined(parts, n, d)
        JeT = np.swapaxes(Je, 1, 2)
        if cls.flat9 is None:
            cls.flat9 = (cls.point[:, None] * 9 + np.arange(9)).ravel()
            cls.flat3 = (cls.point[:, None] * 3 + np.arange(3)).ravel()
        A += np.bincount(cls.flat9, weights=_point_grams(Je).ravel(),
                         minlength=9 * n_e).reshape(n_e, 3, 3)
        ge_rows = np.einsum("nd,ndi->ni", r, Je)
        g_e += np.bincount(cls.flat3, weights=ge_rows.ravel(), minlength=3 * n_e).reshape(n_e, 3)
        if sc == 0:
            continue
        WT[sl, :, :sc] = np.matmul(JeT, Jc)
        _group_sums(cls, Jc, r, G[gs, :sc, :sc], g_grp[gs, :sc])
    if st.n_groups:
        Ncc.add(st._g_scatter, G.ravel())
        g_c += np.bincount(st.group_cols.ravel(), weights=g_grp.ravel(), minlength=m)
    for cls in st.c_classes:
        if cls.s == 0:
            continue
        r, parts, _ = cls.take(residuals, jacobians)
        Jc = RowClass.joined(parts, len(cls.rows), r.shape[1])
        Gc = np.zeros((cls.n_groups, cls.s, cls.s))
        gc = np.zeros((cls.n_groups, cls.s))
        _group_sums(cls, Jc, r, Gc, gc)
        gcols = cls.group_cols
        idx = (gcols[:, :, None] * m + gcols[:, None, :]).ravel()
        Ncc.add(idx, Gc.ravel())
        g_c += np.bincount(gcols.ravel(), weights=gc.ravel(), minlength=m)
    g = np.concatenate([g_c[:n_r], g_e.ravel()])
    return NormalSystem(Ncc.matrix(), A, g, cost, WT, st)


class _NccSum:
    """``N_cc`` summed from flat indices ``row * m + col`` of the padded
    (n_r + 1)^2 matrix: a dense array (bincount) or, with ``sparse``, a
    CSR matrix without the padding row and column."""

    def __init__(self, m, sparse):
        self.m, self.sparse = m, sparse
        self.flat = np.zeros(0 if sparse else m * m)
        self.parts = []

    def add(self, idx, values):
        if self.sparse:
            self.parts.append((idx, values))
        else:
            self.flat += np.bincount(idx, weights=values, minlength=self.m * self.m)

    def matrix(self):
        m, n_r = self.m, self.m - 1
        if not self.sparse:
            return np.ascontiguousarray(self.flat.reshape(m, m)[:n_r, :n_r])
        if not self.parts:
            return sp.csr_matrix((n_r, n_r))
        idx = np.concatenate([p[0] for p in self.parts])
        val = np.concatenate([p[1] for p in self.parts])
        rows, cols = idx // m, idx % m
        keep = (rows < n_r) & (cols < n_r)
        return sp.csr_matrix((val[keep], (rows[keep], cols[keep])), shape=(n_r, n_r))


def _group_grams(cls, parts, G):
    """``G[group] += Jc^T Jc`` with ``Jc = [parts]``, one BLAS product per
    group and pair of parts (the rows of a group are contiguous)."""
    if not parts:
        return
    n = len(cls.rows)
    widths = [P.shape[2] for P in parts]
    offs = np.concatenate([[0], np.cumsum(widths)])
    ends = np.r_[cls.group_starts[1:], n]
    for q, (lo, hi) in enumerate(zip(cls.group_starts, ends)):
        blocks = [P[lo:hi].reshape(-1, w) for P, w in zip(parts, widths)]
        for i, a in enumerate(blocks):
            for j in range(i, len(blocks)):
                prod = a.T @ blocks[j]
                G[q, offs[i]:offs[i + 1], offs[j]:offs[j + 1]] += prod
                if j != i:
                    G[q, offs[j]:offs[j + 1], offs[i]:offs[i + 1]] += prod.T


def _point_grams(Je):
    """``Je^T Je`` (n, 3, 3) of every row, from the 6 distinct products
    (numpy's matmul of 10^5 stacked 3 x d matrices is several times
    slower)."""
    out = np.empty((len(Je), 3, 3))
    for i in range(3):
        for j in range(i, 3):
            v = np.sum(Je[:, :, i] * Je[:, :, j], axis=1)
            out[:, i, j] = v
            if j != i:
                out[:, j, i] = v
    return out


def _group_sums(cls, Jc, r, G, g):
    """Per group (contiguous rows) ``G += Jc^T Jc`` (one Gram matrix by
    BLAS each) and ``g += Jc^T r``."""
    n, d, s = Jc.shape
    grad = np.einsum("nd,nds->ns", r, Jc)
    g += np.add.reduceat(grad, cls.group_starts, axis=0)
    ends = np.r_[cls.group_starts[1:], n]
    for q, (lo, hi) in enumerate(zip(cls.group_starts, ends)):
        J = Jc[lo:hi].reshape(-1, s)
        G[q] += J.T @ J
