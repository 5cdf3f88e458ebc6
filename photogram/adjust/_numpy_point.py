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

__all__ = ["Order", "linearize", "cost", "apply_blocks", "bsr_pair", "jacobi_blocks", "CHUNK"]

#: rows per vectorised chunk (temporaries of about 100 floats per row)
CHUNK = 1 << 15
_SUB = 4096                              # rows of a transposed copy (stays in L2)

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
        """The observations (n, 2) in group order (copied again for a new
        array)."""
        src, copy = self._xy
        if src is not xy:
            copy = np.ascontiguousarray(xy[self.gorder])
            self._xy = (xy, copy)
        return copy

def _frame(xy, pts, R, X0, io, seg, station, camera):
    """Camera-frame coordinates and residuals of the rows (the ``bal``
    model), every quantity a contiguous (m,) vector: ``(Rg, x, iz, tx, ty,
    f, k1, k2, r2, dd, r0, r1)`` with ``Rg`` (9, m) the rows' rotations
    and ``x`` (3, m); ``R`` as (9, n_stations), ``X0``, ``pts`` and ``io``
    as (3, n) (the transposed arrays of :func:`transposed`)."""
    Rg = np.take(R, station, axis=1)                           # (9, m)
    d = np.take(pts, seg, axis=1)
    d -= np.take(X0, station, axis=1)
    x = np.empty((3, len(seg)))
    for i in range(3):
        np.multiply(Rg[3 * i], d[0], out=x[i])
        x[i] += Rg[3 * i + 1] * d[1]
        x[i] += Rg[3 * i + 2] * d[2]
    iz = 1.0 / x[2]
    tx = -x[0] * iz
    ty = x[1] * iz
    f, k1, k2 = np.take(io, camera, axis=1)
    r2 = tx * tx + ty * ty
    dd = 1.0 + r2 * (k1 + k2 * r2)
    fd = f * dd
    r0 = xy[0] - fd * tx
    r1 = xy[1] - fd * ty
    return Rg, x, iz, tx, ty, f, k1, k2, r2, dd, r0, r1


def transposed(xy, pts, R, X0, io):
    """The model arrays in the layout of :func:`_frame`."""
    return (np.ascontiguousarray(xy.T), np.ascontiguousarray(pts.T),
            np.ascontiguousarray(R.reshape(-1, 9).T), np.ascontiguousarray(X0.T),
            np.ascontiguousarray(io.T))


def cost(xy, pts, R, X0, io, pl):
    """``sum r^2`` over the point-ordered rows (``xy`` in point order,
    ``pts`` in the plan's segment order)."""
    od = pl.numpy_order
    xyT, ptsT, RT, X0T, ioT = transposed(xy, pts, R, X0, io)
    total = 0.0
    for lo, hi in od.chunks:
        r0, r1 = _frame(xyT[:, lo:hi], ptsT, RT, X0T, ioT, od.seg[lo:hi], pl.station[lo:hi],
                        pl.camera[lo:hi])[-2:]
        total += float(r0 @ r0 + r1 @ r1)
    return total


def _jacobians(m, Rg, x, iz, tx, ty, f, k1, k2, r2, dd, r0, r1):
    """``Je`` (2, 3, m) and ``[Jc | r]`` (2, 10, m) of the rows (the
    formulas of ``_numba_point.bal_linearize``; first index: x or y
    residual)."""
    dp2 = 2.0 * (k1 + 2.0 * k2 * r2)
    m00 = f * (dd + dp2 * tx * tx)
    m01 = f * dp2 * tx * ty
    m11 = f * (dd + dp2 * ty * ty)
    j = np.empty((2, 3, m))
    np.multiply(m00, iz, out=j[0, 0])
    np.multiply(m01, -iz, out=j[0, 1])
    np.multiply(m00 * tx + m01 * ty, iz, out=j[0, 2])
    np.multiply(m01, iz, out=j[1, 0])
    np.multiply(m11, -iz, out=j[1, 1])
    np.multiply(m01 * tx + m11 * ty, iz, out=j[1, 2])
    Je = np.empty((2, 3, m))                                   # d r / d point: j R
    Jc = np.empty((2, 10, m))
    x0, x1, x2 = x
    for k in range(2):
        jk = j[k]
        for c in range(3):
            e = Je[k, c]
            np.multiply(jk[0], Rg[c], out=e)
            e += jk[1] * Rg[3 + c]
            e += jk[2] * Rg[6 + c]
            np.negative(e, out=Jc[k, c])                       # station position
        np.subtract(x1 * jk[2], x2 * jk[1], out=Jc[k, 3])      # rotation increment
        np.subtract(x2 * jk[0], x0 * jk[2], out=Jc[k, 4])
        np.subtract(x0 * jk[1], x1 * jk[0], out=Jc[k, 5])
    np.multiply(-dd, tx, out=Jc[0, 6])
    np.multiply(-dd, ty, out=Jc[1, 6])
    fr2 = f * r2
    np.multiply(-fr2, tx, out=Jc[0, 7])
    np.multiply(-fr2, ty, out=Jc[1, 7])
    np.multiply(Jc[0, 7], r2, out=Jc[0, 8])
    np.multiply(Jc[1, 7], r2, out=Jc[1, 8])
    Jc[0, 9] = r0
    Jc[1, 9] = r1
    return Je, Jc


def linearize(xy, pts, R, X0, io, pl, WTp, Wg, Qp, G):
    """The fused linearization over all rows: fills ``WTp`` (n, 3, 9,
    point order), ``Wg`` (n, 9, 3, group order), ``G`` (n_g, 10, 10: the
    Gram matrix of ``[Jc | r]`` per group, summed in) and returns ``(A_o,
    g_o)`` in the plan's segment order (``Qp`` (9, n): scratch)."""
    od = pl.numpy_order
    xyT, ptsT, RT, X0T, ioT = transposed(od.xy_g(xy), pts, R, X0, io)
    gptr = od.gptr
    n = len(WTp)
    WT27 = WTp.reshape(n, 27)
    for lo, hi in od.chunks:
        m = hi - lo
        parts = _frame(xyT[:, lo:hi], ptsT, RT, X0T, ioT, od.seg_g[lo:hi], od.station_g[lo:hi],
                       od.camera_g[lo:hi])
        Je, Jc = _jacobians(m, *parts)
        rows = od.gorder[lo:hi]
        e0, e1 = Je[0], Je[1]
        WT = np.empty((3, 9, m))                               # Je^T Jc
        for q, (i, k) in enumerate(zip(*_IU)):                 # Je^T Je (upper), = -WT[:, :3]
            a = Qp[q, rows] = e0[i] * e0[k] + e1[i] * e1[k]
            np.negative(a, out=WT[i, k])
            if i != k:
                WT[k, i] = WT[i, k]
        for i in range(3):
            Qp[6 + i, rows] = e0[i] * Jc[0, 9] + e1[i] * Jc[1, 9]
            np.multiply(e0[i], Jc[0, 3:9], out=WT[i, 3:])
            WT[i, 3:] += e1[i] * Jc[1, 3:9]
        WT27[rows] = WT.reshape(27, m).T
        Wg[lo:hi] = WT.transpose(2, 1, 0)
        # the groups of this chunk: one Gram matrix each
        g_lo = np.searchsorted(gptr, lo, side="right") - 1
        g_hi = np.searchsorted(gptr, hi, side="left")
        for g in range(g_lo, g_hi):
            a, b = max(gptr[g], lo) - lo, min(gptr[g + 1], hi) - lo
            if b > a:
                X0g, X1g = Jc[0, :, a:b], Jc[1, :, a:b]
                G[g] += X0g @ X0g.T + X1g @ X1g.T
    n_seg = len(pl.ptr) - 1
    S = np.zeros((9, n_seg))
    if len(od.starts):
        S[:, od.nonempty] = np.add.reduceat(Qp, od.starts, axis=1)
    A_o = np.empty((n_seg, 3, 3))
    A_o[:, _IU[0], _IU[1]] = S[:6].T
    A_o[:, _IU[1], _IU[0]] = S[:6].T
    return A_o, np.ascontiguousarray(S[6:].T)


def apply_blocks(M, v):
    """``M[i] @ v[i]`` for 3x3 blocks ``M`` (n, 3, 3) and ``v`` (n, 3)."""
    return M[:, :, 0] * v[:, :1] + M[:, :, 1] * v[:, 1:2] + M[:, :, 2] * v[:, 2:]


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
    sum is the sum of three BLAS Gram matrices of its stacked ``V_k``
    rows."""
    od = pl.numpy_order
    s = Wg.shape[1]
    L = _cholesky3(Ainv_o)
    LT = np.ascontiguousarray(L.reshape(-1, 9).T)              # (9, n_seg)
    out = np.zeros((n_g, s, s))
    gptr = od.gptr
    for lo, hi in od.chunks:
        m = hi - lo
        Lr = np.take(LT, od.seg_g[lo:hi], axis=1)              # (9, m): L[a, b] at 3 a + b
        V = np.empty((3, s, m))                                # L^T W^T
        for c in range(0, m, _SUB):                            # transposed in cache-sized parts
            W = np.ascontiguousarray(Wg[lo + c:min(lo + c + _SUB, hi)].transpose(2, 1, 0))
            Lc = Lr[:, c:c + _SUB]
            for i in range(3):
                Vi = V[i, :, c:c + _SUB]
                np.multiply(Lc[3 * i + i], W[i], out=Vi)
                for k in range(i + 1, 3):
                    Vi += Lc[3 * k + i] * W[k]
        g_lo = np.searchsorted(gptr, lo, side="right") - 1
        g_hi = np.searchsorted(gptr, hi, side="left")
        for g in range(g_lo, g_hi):
            a, b = max(gptr[g], lo) - lo, min(gptr[g + 1], hi) - lo
            if b > a:
                for i in range(3):
                    X = V[i, :, a:b]
                    out[g] += X @ X.T
    return out
