"""numba kernels of the point-ordered iterative path
(:mod:`photogram.adjust.point_rows`): the E-rows stored point by point (a
point's rows contiguous, segment i of the CSR pointer ``ptr`` holding the
rows of the i-th point of an order where neighbours share
cameras, so that the per-camera sums stay in cache; every per-point array,
``A``, ``A^-1``, ``g_e``, in segment order), so that every pass
keeps the point's data in registers and streams through ``W_o^T``; the
reduced columns of a row are those of its row group (``group_cols[g]``,
a table that stays in cache) instead of a per-row column array.

``bal_linearize`` fuses the ``bal`` camera model (the formulas of
``_numba_kernels.bal_rows``) with the assembly of the normal equations:
no Jacobian array is ever stored.
"""

import numba as _numba
import numpy as np

from photogram.adjust._numba_kernels import bal_frame_jacobian, camera_frame

njit = _numba.njit(cache=True, nogil=True,
                   fastmath={"reassoc", "contract", "nsz", "arcp"})
# a kernel's piece shared by two kernels, inlined into each (numba IR)
njit_inline = _numba.njit(cache=True, nogil=True, inline="always",
                          fastmath={"reassoc", "contract", "nsz", "arcp"})


@njit
def bal_linearize(xy, points, R, X0, io, ptr, station, camera, group,
                  A, g_e, WT, g_grp, G):
    """Residuals, Jacobians and their normal-equation sums of the ``bal``
    model in one pass over the point-ordered rows (``ptr``: CSR pointer
    per segment, ``points[i]`` the point of segment i; ``station``,
    ``camera``, ``group`` per row). Writes, in segment order,
    ``A[i] = sum Je^T Je`` and ``g_e[i] = sum Je^T r`` for every point,
    ``WT[k] = Je^T Jc`` (3 x 9, ``Jc = [station (X0, rotation) | f k1
    k2]``); adds ``Jc^T r`` to ``g_grp[g]`` and the upper triangle of
    ``Jc^T Jc`` to ``G[g]``. Returns ``sum r^2``."""
    c0 = np.empty(9)
    c1 = np.empty(9)
    total = 0.0
    for i in range(len(ptr) - 1):
        p = i
        a00 = a01 = a02 = a11 = a12 = a22 = 0.0
        ge0 = ge1 = ge2 = 0.0
        part = 0.0
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        for k in range(ptr[i], ptr[i + 1]):
            s = station[k]
            c = camera[k]
            q = group[k]
            x0, x1, x2 = camera_frame(R, X0, s, px, py, pz)
            iz = 1.0 / x2
            tx = -x0 * iz
            ty = x1 * iz
            f, k1, k2 = io[c, 0], io[c, 1], io[c, 2]
            r2 = tx * tx + ty * ty
            dd = 1.0 + r2 * (k1 + k2 * r2)
            r0 = xy[k, 0] - f * dd * tx
            r1 = xy[k, 1] - f * dd * ty
            part += r0 * r0 + r1 * r1
            j00, j01, j02, j10, j11, j12 = bal_frame_jacobian(f, k1, k2, tx, ty, iz, r2, dd)
            # point Jacobian Je (rows e0., e1.); station columns are -Je
            e00 = j00 * R[s, 0, 0] + j01 * R[s, 1, 0] + j02 * R[s, 2, 0]
            e01 = j00 * R[s, 0, 1] + j01 * R[s, 1, 1] + j02 * R[s, 2, 1]
            e02 = j00 * R[s, 0, 2] + j01 * R[s, 1, 2] + j02 * R[s, 2, 2]
            e10 = j10 * R[s, 0, 0] + j11 * R[s, 1, 0] + j12 * R[s, 2, 0]
            e11 = j10 * R[s, 0, 1] + j11 * R[s, 1, 1] + j12 * R[s, 2, 1]
            e12 = j10 * R[s, 0, 2] + j11 * R[s, 1, 2] + j12 * R[s, 2, 2]
            c0[0], c0[1], c0[2] = -e00, -e01, -e02
            c1[0], c1[1], c1[2] = -e10, -e11, -e12
            c0[3] = x1 * j02 - x2 * j01
            c0[4] = x2 * j00 - x0 * j02
            c0[5] = x0 * j01 - x1 * j00
            c1[3] = x1 * j12 - x2 * j11
            c1[4] = x2 * j10 - x0 * j12
            c1[5] = x0 * j11 - x1 * j10
            fr2 = f * r2
            c0[6], c1[6] = -dd * tx, -dd * ty
            c0[7], c1[7] = -fr2 * tx, -fr2 * ty
            c0[8], c1[8] = -fr2 * r2 * tx, -fr2 * r2 * ty
            ge0 += e00 * r0 + e10 * r1
            ge1 += e01 * r0 + e11 * r1
            ge2 += e02 * r0 + e12 * r1
            a00 += e00 * e00 + e10 * e10
            a01 += e00 * e01 + e10 * e11
            a02 += e00 * e02 + e10 * e12
            a11 += e01 * e01 + e11 * e11
            a12 += e01 * e02 + e11 * e12
            a22 += e02 * e02 + e12 * e12
            for j in range(9):
                u, v = c0[j], c1[j]
                g_grp[q, j] += u * r0 + v * r1
                WT[k, 0, j] = e00 * u + e10 * v
                WT[k, 1, j] = e01 * u + e11 * v
                WT[k, 2, j] = e02 * u + e12 * v
                for m in range(j + 1):
                    G[q, m, j] += c0[m] * u + c1[m] * v
        A[i, 0, 0] = a00
        A[i, 0, 1] = A[i, 1, 0] = a01
        A[i, 0, 2] = A[i, 2, 0] = a02
        A[i, 1, 1] = a11
        A[i, 1, 2] = A[i, 2, 1] = a12
        A[i, 2, 2] = a22
        g_e[i, 0], g_e[i, 1], g_e[i, 2] = ge0, ge1, ge2
        total += part
    return total


@njit
def bal_cost(xy, points, R, X0, io, ptr, station, camera):
    """``sum r^2`` of the ``bal`` model over the point-ordered rows (the
    residuals of :func:`bal_linearize`, nothing stored)."""
    total = 0.0
    for i in range(len(ptr) - 1):
        p = i
        part = 0.0
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        for k in range(ptr[i], ptr[i + 1]):
            s = station[k]
            c = camera[k]
            x0, x1, x2 = camera_frame(R, X0, s, px, py, pz)
            iz = 1.0 / x2
            tx = -x0 * iz
            ty = x1 * iz
            r2 = tx * tx + ty * ty
            fd = io[c, 0] * (1.0 + r2 * (io[c, 1] + io[c, 2] * r2))
            r0 = xy[k, 0] - fd * tx
            r1 = xy[k, 1] - fd * ty
            part += r0 * r0 + r1 * r1
        total += part
    return total


@njit
def matvec(WT, group, gcols, ptr, Ainv, x, out):
    """``out += W A^-1 W^T x`` point by point (``Ainv`` in segment order;
    ``x`` padded with a zero
    at the dummy column ``n_r``; the columns of row k are
    ``gcols[group[k]]``)."""
    s = WT.shape[2]
    for i in range(len(ptr) - 1):
        lo, hi = ptr[i], ptr[i + 1]
        if hi == lo:
            continue
        p = i
        y0 = y1 = y2 = 0.0
        for k in range(lo, hi):
            g = group[k]
            for j in range(s):
                xv = x[gcols[g, j]]
                y0 += WT[k, 0, j] * xv
                y1 += WT[k, 1, j] * xv
                y2 += WT[k, 2, j] * xv
        z0 = Ainv[p, 0, 0] * y0 + Ainv[p, 0, 1] * y1 + Ainv[p, 0, 2] * y2
        z1 = Ainv[p, 1, 0] * y0 + Ainv[p, 1, 1] * y1 + Ainv[p, 1, 2] * y2
        z2 = Ainv[p, 2, 0] * y0 + Ainv[p, 2, 1] * y1 + Ainv[p, 2, 2] * y2
        for k in range(lo, hi):
            g = group[k]
            for j in range(s):
                out[gcols[g, j]] += WT[k, 0, j] * z0 + WT[k, 1, j] * z1 + WT[k, 2, j] * z2


@njit
def back(WT, group, gcols, ptr, x, out):
    """``out[i] = sum_k W_k^T x[gcols[group[k]]]`` over the rows of every
    segment i (``x`` padded)."""
    s = WT.shape[2]
    for i in range(len(ptr) - 1):
        p = i
        y0 = y1 = y2 = 0.0
        for k in range(ptr[i], ptr[i + 1]):
            g = group[k]
            for j in range(s):
                xv = x[gcols[g, j]]
                y0 += WT[k, 0, j] * xv
                y1 += WT[k, 1, j] * xv
                y2 += WT[k, 2, j] * xv
        out[p, 0], out[p, 1], out[p, 2] = y0, y1, y2


@njit
def jacobi_rhs(WT, group, ptr, Ainv, g_e, blocks, rhs_g):
    """One pass for the Schur-Jacobi blocks and the reduced right-hand
    side: ``blocks[g] -= W_k A_p^-1 W_k^T`` (s x s) and ``rhs_g[g] +=
    W_k A_i^-1 g_e[i]`` (s) for every row k of segment i (one row per
    group and point; ``Ainv`` and ``g_e`` in segment order)."""
    Y = np.empty((3, WT.shape[2]))
    for i in range(len(ptr) - 1):
        jacobi_rows(WT, group, ptr[i], ptr[i + 1], Ainv, g_e, i, Y, blocks, rhs_g)


@njit_inline
def jacobi_rows(WT, group, lo, hi, Ainv, g_e, p, Y, blocks, rhs_g):
    """:func:`jacobi_rhs` for the rows ``lo:hi`` of point ``p`` (``Y``: a
    3 x s work array)."""
    s = WT.shape[2]
    b00, b01, b02 = Ainv[p, 0, 0], Ainv[p, 0, 1], Ainv[p, 0, 2]
    b10, b11, b12 = Ainv[p, 1, 0], Ainv[p, 1, 1], Ainv[p, 1, 2]
    b20, b21, b22 = Ainv[p, 2, 0], Ainv[p, 2, 1], Ainv[p, 2, 2]
    e0, e1, e2 = g_e[p, 0], g_e[p, 1], g_e[p, 2]
    for k in range(lo, hi):
        g = group[k]
        for j in range(s):
            w0, w1, w2 = WT[k, 0, j], WT[k, 1, j], WT[k, 2, j]
            y0 = b00 * w0 + b01 * w1 + b02 * w2
            y1 = b10 * w0 + b11 * w1 + b12 * w2
            y2 = b20 * w0 + b21 * w1 + b22 * w2
            Y[0, j], Y[1, j], Y[2, j] = y0, y1, y2
            rhs_g[g, j] += y0 * e0 + y1 * e1 + y2 * e2
        for a in range(s):
            w0, w1, w2 = WT[k, 0, a], WT[k, 1, a], WT[k, 2, a]
            for b in range(a, s):
                blocks[g, a, b] -= w0 * Y[0, b] + w1 * Y[1, b] + w2 * Y[2, b]


@njit
def damped_inverse(A, damping, fixed, out):
    """``out[p]`` = inverse of ``A[p]`` with its diagonal times ``1 +
    damping`` plus ``fixed[p]`` (the closed form of
    ``schur.invert_point_blocks``, symmetrized). Returns the number of
    blocks whose determinant is not above ``1e-14 trace^3`` (their
    ``out`` is not valid; the caller reports them)."""
    bad = 0
    f = 1.0 + damping
    for p in range(A.shape[0]):
        a = A[p, 0, 0] * f + fixed[p, 0]
        e = A[p, 1, 1] * f + fixed[p, 1]
        i = A[p, 2, 2] * f + fixed[p, 2]
        b, c, d = A[p, 0, 1], A[p, 0, 2], A[p, 1, 0]
        ff, g, h = A[p, 1, 2], A[p, 2, 0], A[p, 2, 1]
        c00, c01, c02 = e * i - ff * h, c * h - b * i, b * ff - c * e
        c10, c11, c12 = ff * g - d * i, a * i - c * g, c * d - a * ff
        c20, c21, c22 = d * h - e * g, b * g - a * h, a * e - b * d
        det = a * c00 + b * c10 + c * c20
        tr = a + e + i
        if not abs(det) > 1e-14 * (tr * tr * tr + 1e-300):
            bad += 1
            continue
        w = 1.0 / det
        out[p, 0, 0] = c00 * w
        out[p, 1, 1] = c11 * w
        out[p, 2, 2] = c22 * w
        out[p, 0, 1] = out[p, 1, 0] = 0.5 * (c01 + c10) * w
        out[p, 0, 2] = out[p, 2, 0] = 0.5 * (c02 + c20) * w
        out[p, 1, 2] = out[p, 2, 1] = 0.5 * (c12 + c21) * w
    return bad
