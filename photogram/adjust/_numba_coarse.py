"""numba kernel of the two-level preconditioner
(:mod:`photogram.adjust.rcs_coarse`): the (group, cluster) blocks of
``W A^-1 W^T P`` in one pass over the point-ordered E-rows (the numpy twin
is :func:`photogram.adjust.rcs_coarse._coupling_numpy`), alone or fused
with the Schur-Jacobi pass (:func:`jacobi_rhs_coupling`)."""

import numba as _numba
import numpy as np

from photogram.adjust._numba_point import jacobi_rows, njit_inline

njit = _numba.njit(cache=True, nogil=True,
                   fastmath={"reassoc", "contract", "nsz", "arcp"})


@njit_inline
def _work_arrays(ptr, nsl):
    """Work arrays for the clusters of one point: ``Y`` and ``Z`` (k x 3 x
    nsl) and the cluster ids ``cl`` (k), k the most rows of a point."""
    kmax = 1
    for i in range(len(ptr) - 1):
        kmax = max(kmax, ptr[i + 1] - ptr[i])
    return (np.zeros((kmax, 3, nsl)), np.zeros((kmax, 3, nsl)),
            np.empty(kmax, dtype=np.int64))


@njit_inline
def _cluster_sums(WT, group, cluster, slots, lo, hi, Y, cl):
    """``Y[m] = sum of W_o^T[:, slots]`` over the rows ``lo:hi`` of one
    point whose group lies in cluster ``cl[m]``; returns the number of
    clusters ``nk`` that see the point."""
    nsl = len(slots)
    nk = 0
    for k in range(lo, hi):
        c = cluster[group[k]]
        m = -1
        for q in range(nk):
            if cl[q] == c:
                m = q
                break
        if m < 0:
            m = nk
            cl[m] = c
            nk += 1
            for a in range(3):
                for j in range(nsl):
                    Y[m, a, j] = 0.0
        for a in range(3):
            for j in range(nsl):
                Y[m, a, j] += WT[k, a, slots[j]]
    return nk


@njit_inline
def _add_coupling(WT, group, lo, hi, nk, cl, lookup, Z, out):
    """``out[lookup[g, cl[m]]] += W_o Z[m]`` for the rows ``lo:hi`` of one
    point (group g) and its ``nk`` clusters."""
    s = WT.shape[2]
    nsl = Z.shape[2]
    for k in range(lo, hi):
        g = group[k]
        for m in range(nk):
            b = lookup[g, cl[m]]
            for u in range(s):
                w0, w1, w2 = WT[k, 0, u], WT[k, 1, u], WT[k, 2, u]
                for j in range(nsl):
                    out[b, u, j] += w0 * Z[m, 0, j] + w1 * Z[m, 1, j] + w2 * Z[m, 2, j]


@njit
def coupling_blocks(WT, group, ptr, Ainv, cluster, lookup, slots, out):
    """``out[lookup[g, c]] += W_o A_p^-1 Y_pc`` for every row o (group g)
    of every point p and every cluster c that sees p, with
    ``Y_pc = sum of W_o'^T[:, slots] over the rows o' of p in cluster c``
    (3 x k). ``Ainv`` in segment order (``ptr``: the rows of segment i)."""
    nsl = len(slots)
    Y, Z, cl = _work_arrays(ptr, nsl)
    for i in range(len(ptr) - 1):
        lo, hi = ptr[i], ptr[i + 1]
        nk = _cluster_sums(WT, group, cluster, slots, lo, hi, Y, cl)
        for m in range(nk):
            for a in range(3):
                for j in range(nsl):
                    Z[m, a, j] = (Ainv[i, a, 0] * Y[m, 0, j] + Ainv[i, a, 1] * Y[m, 1, j]
                                  + Ainv[i, a, 2] * Y[m, 2, j])
        _add_coupling(WT, group, lo, hi, nk, cl, lookup, Z, out)


@njit
def mark_blocks(group, ptr, cluster, seen):
    """``seen[g, c] = True`` for every row group g and cluster c that see
    a common point (the (group, cluster) blocks of ``W A^-1 W^T P``)."""
    for i in range(len(ptr) - 1):
        for k in range(ptr[i], ptr[i + 1]):
            c = cluster[group[k]]
            for q in range(ptr[i], ptr[i + 1]):
                seen[group[q], c] = True


@njit
def jacobi_rhs_coupling(WT, group, ptr, Ainv, g_e, blocks, rhs_g, cluster, lookup, slots,
                        out):
    """The fused pass: :func:`photogram.adjust._numba_point.jacobi_rhs`
    (``blocks[g] -= W_k A_p^-1 W_k^T``, upper triangle, and ``rhs_g[g] +=
    W_k A_p^-1 g_e[p]``) and :func:`coupling_blocks` (``out``) in one
    stream over ``W_o^T``: a point's rows are read once from memory for
    the cluster sums ``Y_pc`` and once more from cache for the per-row
    products of both."""
    s = WT.shape[2]
    nsl = len(slots)
    Y, Z, cl = _work_arrays(ptr, nsl)
    R = np.empty((3, s))
    for i in range(len(ptr) - 1):
        lo, hi = ptr[i], ptr[i + 1]
        nk = _cluster_sums(WT, group, cluster, slots, lo, hi, Y, cl)
        b00, b01, b02 = Ainv[i, 0, 0], Ainv[i, 0, 1], Ainv[i, 0, 2]
        b10, b11, b12 = Ainv[i, 1, 0], Ainv[i, 1, 1], Ainv[i, 1, 2]
        b20, b21, b22 = Ainv[i, 2, 0], Ainv[i, 2, 1], Ainv[i, 2, 2]
        for m in range(nk):
            for j in range(nsl):
                y0, y1, y2 = Y[m, 0, j], Y[m, 1, j], Y[m, 2, j]
                Z[m, 0, j] = b00 * y0 + b01 * y1 + b02 * y2
                Z[m, 1, j] = b10 * y0 + b11 * y1 + b12 * y2
                Z[m, 2, j] = b20 * y0 + b21 * y1 + b22 * y2
        jacobi_rows(WT, group, lo, hi, Ainv, g_e, i, R, blocks, rhs_g)
        _add_coupling(WT, group, lo, hi, nk, cl, lookup, Z, out)
