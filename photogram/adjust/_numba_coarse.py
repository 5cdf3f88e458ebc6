"""numba kernel of the two-level preconditioner
(:mod:`photogram.adjust.rcs_coarse`): the (group, cluster) blocks of
``W A^-1 W^T P`` in one pass over the point-ordered E-rows (the numpy twin
is :func:`photogram.adjust.rcs_coarse._coupling_numpy`)."""

import numba as _numba
import numpy as np

njit = _numba.njit(cache=True, nogil=True,
                   fastmath={"reassoc", "contract", "nsz", "arcp"})


@njit
def coupling_blocks(WT, group, ptr, Ainv, cluster, lookup, slots, out):
    """``out[lookup[g, c]] += W_o A_p^-1 Y_pc`` for every row o (group g)
    of every point p and every cluster c that sees p, with
    ``Y_pc = sum of W_o'^T[:, slots] over the rows o' of p in cluster c``
    (3 x k). ``Ainv`` in segment order (``ptr``: the rows of segment i)."""
    s = WT.shape[2]
    nsl = len(slots)
    kmax = 0
    for i in range(len(ptr) - 1):
        kmax = max(kmax, ptr[i + 1] - ptr[i])
    Y = np.zeros((max(kmax, 1), 3, nsl))
    Z = np.zeros((max(kmax, 1), 3, nsl))
    cl = np.empty(max(kmax, 1), dtype=np.int64)
    for i in range(len(ptr) - 1):
        lo, hi = ptr[i], ptr[i + 1]
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
        for m in range(nk):
            for a in range(3):
                for j in range(nsl):
                    Z[m, a, j] = (Ainv[i, a, 0] * Y[m, 0, j] + Ainv[i, a, 1] * Y[m, 1, j]
                                  + Ainv[i, a, 2] * Y[m, 2, j])
        for k in range(lo, hi):
            g = group[k]
            for m in range(nk):
                b = lookup[g, cl[m]]
                for u in range(s):
                    w0, w1, w2 = WT[k, 0, u], WT[k, 1, u], WT[k, 2, u]
                    for j in range(nsl):
                        out[b, u, j] += w0 * Z[m, 0, j] + w1 * Z[m, 1, j] + w2 * Z[m, 2, j]


@njit
def mark_blocks(group, ptr, cluster, seen):
    """``seen[g, c] = True`` for every row group g and cluster c that see
    a common point (the (group, cluster) blocks of ``W A^-1 W^T P``)."""
    for i in range(len(ptr) - 1):
        for k in range(ptr[i], ptr[i + 1]):
            c = cluster[group[k]]
            for q in range(ptr[i], ptr[i + 1]):
                seen[group[q], c] = True
