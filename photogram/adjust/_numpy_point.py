"""Pure-numpy twin of the point-ordered, fused BAL linearization
(:mod:`photogram.adjust._numba_point`), used by
:mod:`photogram.adjust.point_rows` when the compiled kernels are not
active (numba missing, switched off, or a problem below their row
threshold).

The same formulas as ``_numba_point.bal_linearize`` and ``bal_cost``
(the ``bal`` camera model of ``_numba_kernels.bal_rows``), vectorised over
the observations in chunks of :data:`CHUNK` rows, with the rows taken
camera group by camera group (the plan's ``gorder``):

* ``N_cc`` and ``g_c``: one BLAS Gram matrix per row group of the stacked
  ``[Jc | r]`` (2 rows per observation, 10 columns), which gives ``Jc^T
  Jc``, ``Jc^T r`` and ``r^T r`` together;
* ``W_o^T = Je^T Jc``: written into the point-ordered buffer ``WTp`` (the
  :class:`~photogram.adjust.point_rows.PointSystem`'s) and, transposed,
  into a group-ordered copy ``Wg`` (9 x 3 per row), so that both products
  of the reduced-camera-system CG, ``W^T x`` and ``W z``, are compiled
  block-sparse (BSR) products of scipy without any transpose;
* ``A_p`` and ``g_p``: the per-row upper triangle of ``Je^T Je`` and
  ``Je^T r`` (9 numbers) written in point order, then one segment sum
  (``np.add.reduceat``) per point.

No Jacobian array of all observations is ever stored.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from photogram.adjust.rcs_iterative import _cholesky3

__all__ = ["Order", "linearize", "cost", "bsr_pair", "jacobi_blocks", "CHUNK"]

#: rows per vectorised chunk (temporaries of about 100 floats per row)
CHUNK = 1 << 15

_IU = np.triu_indices(3)                 # (0,0) (0,1) (0,2) (1,1) (1,2) (2,2)


class Order:
    """The group order of a point-ordered plan (fixed per structure):
    ``gorder`` (the point-ordered rows sorted by row group, stable),
    ``gptr`` (CSR pointer of the groups in it), the segment (plan point
    index) of every row in group order, the segment starts of the non-empty
    segments, and the chunks of the group-ordered rows."""

    def __init__(self, pl, n_groups):
        n = len(pl.group)
        self.gorder = np.argsort(pl.group, kind="stable")
        counts = np.bincount(pl.group, minlength=n_groups)
        self.gptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        seg = np.repeat(np.arange(len(pl.ptr) - 1), np.diff(pl.ptr))
        self.seg = seg
        self.seg_g = seg[self.gorder]
        self.station_g = pl.station[self.gorder]
        self.camera_g = pl.camera[self.gorder]
        self.group_g = pl.group[self.gorder]
        cnt = np.diff(pl.ptr)
        self.nonempty = np.flatnonzero(cnt > 0)
        self.starts = pl.ptr[:-1][self.nonempty]
        self.chunks = [(lo, min(lo + CHUNK, n)) for lo in range(0, n, CHUNK)]
        self._xy = (None, None)

    def xy_g(self, xy):
        """The observations in group order (copied again for a new array)."""
        src, copy = self._xy
        if src is not xy:
            copy = np.ascontiguousarray(xy[self.gorder])
            self._xy = (xy, copy)
        return copy


def _frame(xy, pts, R, X0, io, seg, station, camera):
    """Camera-frame coordinates, normalized image coordinates and
    residuals of the rows (the ``bal`` model)."""
    Rg = R[station]                                            # (m, 3, 3)
    d = pts[seg] - X0[station]
    x = np.einsum("nij,nj->in", Rg, d)                         # (3, m)
    iz = 1.0 / x[2]
    tx = -x[0] * iz
    ty = x[1] * iz
    ic = io[camera]
    f, k1, k2 = ic[:, 0], ic[:, 1], ic[:, 2]
    r2 = tx * tx + ty * ty
    dd = 1.0 + r2 * (k1 + k2 * r2)
    fd = f * dd
    r0 = xy[:, 0] - fd * tx
    r1 = xy[:, 1] - fd * ty
    return Rg, x, iz, tx, ty, f, k1, k2, r2, dd, r0, r1


def cost(xy, pts, R, X0, io, pl):
    """``sum r^2`` over the point-ordered rows (``xy`` in point order,
    ``pts`` in the plan's segment order)."""
    total = 0.0
    seg = pl.numpy_order.seg
    for lo, hi in pl.numpy_order.chunks:
        r0, r1 = _frame(xy[lo:hi], pts, R, X0, io, seg[lo:hi], pl.station[lo:hi],
                        pl.camera[lo:hi])[-2:]
        total += float(r0 @ r0 + r1 @ r1)
    return total


def _jacobians(m, Rg, x, iz, tx, ty, f, k1, k2, r2, dd, r0, r1):
    """``Je`` (m, 2, 3) and ``[Jc | r]`` (m, 2, 10) of the rows (the
    formulas of ``_numba_point.bal_linearize``)."""
    dp2 = 2.0 * (k1 + 2.0 * k2 * r2)
    m00 = f * (dd + dp2 * tx * tx)
    m01 = f * dp2 * tx * ty
    m11 = f * (dd + dp2 * ty * ty)
    j = np.empty((m, 2, 3))
    j[:, 0, 0] = m00 * iz
    j[:, 0, 1] = -m01 * iz
    j[:, 0, 2] = (m00 * tx + m01 * ty) * iz
    j[:, 1, 0] = m01 * iz
    j[:, 1, 1] = -m11 * iz
    j[:, 1, 2] = (m01 * tx + m11 * ty) * iz
    Je = j[:, :, 0, None] * Rg[:, None, 0, :]                  # d r / d point: j R
    Je += j[:, :, 1, None] * Rg[:, None, 1, :]
    Je += j[:, :, 2, None] * Rg[:, None, 2, :]
    Jc = np.empty((m, 2, 10))
    np.negative(Je, out=Jc[:, :, 0:3])                         # station position
    x0, x1, x2 = x
    for k in range(2):                                         # rotation increment
        Jc[:, k, 3] = x1 * j[:, k, 2] - x2 * j[:, k, 1]
        Jc[:, k, 4] = x2 * j[:, k, 0] - x0 * j[:, k, 2]
        Jc[:, k, 5] = x0 * j[:, k, 1] - x1 * j[:, k, 0]
    fr2 = f * r2
    Jc[:, 0, 6] = -dd * tx
    Jc[:, 1, 6] = -dd * ty
    Jc[:, 0, 7] = -fr2 * tx
    Jc[:, 1, 7] = -fr2 * ty
    Jc[:, 0, 8] = Jc[:, 0, 7] * r2
    Jc[:, 1, 8] = Jc[:, 1, 7] * r2
    Jc[:, 0, 9] = r0
    Jc[:, 1, 9] = r1
    return Je, Jc


def linearize(xy, pts, R, X0, io, pl, WTp, Wg, Qp, G):
    """The fused linearization over all rows: fills ``WTp`` (n, 3, 9,
    point order), ``Wg`` (n, 9, 3, group order), ``G`` (n_g, 10, 10: the
    Gram matrix of ``[Jc | r]`` per group, summed in) and returns ``(A_o,
    g_o)`` in the plan's segment order (``Qp`` (n, 9): scratch)."""
    od = pl.numpy_order
    xy_g = od.xy_g(xy)
    gptr = od.gptr
    for lo, hi in od.chunks:
        m = hi - lo
        parts = _frame(xy_g[lo:hi], pts, R, X0, io, od.seg_g[lo:hi], od.station_g[lo:hi],
                       od.camera_g[lo:hi])
        Je, Jc = _jacobians(m, *parts)
        rows = od.gorder[lo:hi]
        WT = Je[:, 0, :, None] * Jc[:, 0, None, :9]            # (m, 3, 9): Je^T Jc
        WT += Je[:, 1, :, None] * Jc[:, 1, None, :9]
        WTp[rows] = WT
        Wg[lo:hi] = WT.transpose(0, 2, 1)
        Q = np.empty((m, 9))                                   # Je^T Je (upper), Je^T r
        e0, e1 = Je[:, 0], Je[:, 1]
        for q, (i, k) in enumerate(zip(*_IU)):
            Q[:, q] = e0[:, i] * e0[:, k] + e1[:, i] * e1[:, k]
        Q[:, 6:] = e0 * Jc[:, 0, 9:] + e1 * Jc[:, 1, 9:]
        Qp[rows] = Q
        # the groups of this chunk: one Gram matrix each
        g_lo = np.searchsorted(gptr, lo, side="right") - 1
        g_hi = np.searchsorted(gptr, hi, side="left")
        for g in range(g_lo, g_hi):
            a, b = max(gptr[g], lo) - lo, min(gptr[g + 1], hi) - lo
            if b > a:
                X = Jc[a:b].reshape(-1, 10)
                G[g] += X.T @ X
    n_seg = len(pl.ptr) - 1
    S = np.zeros((n_seg, 9))
    if len(od.starts):
        S[od.nonempty] = np.add.reduceat(Qp, od.starts, axis=0)
    A_o = np.empty((n_seg, 3, 3))
    A_o[:, _IU[0], _IU[1]] = S[:, :6]
    A_o[:, _IU[1], _IU[0]] = S[:, :6]
    return A_o, np.ascontiguousarray(S[:, 6:])


def bsr_pair(WTp, Wg, pl):
    """``W^T`` (3 n_seg x s n_g, point rows in the plan's segment order)
    and ``W`` (s n_g x 3 n_seg) as block-sparse matrices on the two
    buffers (no copy): the columns of group g are ``s g .. s g + s - 1``;
    ``x[gcols].ravel()`` maps reduced columns there."""
    od = pl.numpy_order
    n_seg, n_g = len(pl.ptr) - 1, len(od.gptr) - 1
    s = WTp.shape[2]
    WT = sp.bsr_matrix((WTp, pl.group, pl.ptr), shape=(3 * n_seg, s * n_g))
    W = sp.bsr_matrix((Wg, od.seg_g, od.gptr), shape=(s * n_g, 3 * n_seg))
    return WT, W


def jacobi_blocks(Wg, Ainv_o, pl, n_g):
    """``sum W_k A_p^-1 W_k^T`` per row group (n_g, s, s): with ``A_p^-1
    = L L^T`` every row gives ``V_k = L^T W_k^T`` (3 x s), and a group's
    sum is one BLAS Gram matrix of its stacked ``V_k``."""
    od = pl.numpy_order
    s = Wg.shape[1]
    L = _cholesky3(Ainv_o)
    out = np.zeros((n_g, s, s))
    gptr = od.gptr
    for lo, hi in od.chunks:
        Lr = L[od.seg_g[lo:hi]]                                # (m, 3, 3)
        WT = Wg[lo:hi].transpose(0, 2, 1)                      # (m, 3, s)
        V = np.empty(WT.shape)                                 # L^T W^T
        for i in range(3):
            V[:, i, :] = Lr[:, i, i, None] * WT[:, i, :]
            for k in range(i + 1, 3):
                V[:, i, :] += Lr[:, k, i, None] * WT[:, k, :]
        g_lo = np.searchsorted(gptr, lo, side="right") - 1
        g_hi = np.searchsorted(gptr, hi, side="left")
        for g in range(g_lo, g_hi):
            a, b = max(gptr[g], lo) - lo, min(gptr[g + 1], hi) - lo
            if b > a:
                X = V[a:b].reshape(-1, s)
                out[g] += X.T @ X
    return out
