"""The numba kernels of :mod:`photogram.adjust.kernels` (imported only
when they are used: numba's import and the loading of its cached machine
code cost about a second, which only large problems earn back)."""

import numba as _numba
import numpy as np

# reassociation and contraction (FMA) only: NaN and inf keep their meaning
njit = _numba.njit(cache=True, nogil=True,
                   fastmath={"reassoc", "contract", "nsz", "arcp"})


@njit
def assemble_rows(J1, J2, Je, r, point, group, A, g_e, WT, g_grp):
    """Per E-row products, accumulated. The row's reduced Jacobian is
    ``Jc = [J1 | J2]`` (two slots, e.g. station and interior orientation;
    J2 may have width 0): ``A[p] += Je^T Je``, ``g_e[p] += Je^T r``,
    ``WT[o] = Je^T Jc`` (3 x s) and ``g_grp[grp] += Jc^T r``. (The group
    Gram matrices ``Jc^T Jc`` are BLAS products, ``normal._group_grams``.)
    Rows of dimension 2 (image points) take an unrolled loop."""
    n, d, s1 = J1.shape
    s2 = J2.shape[2]
    if d == 2:
        for o in range(n):
            p = point[o]
            q = group[o]
            r0, r1 = r[o, 0], r[o, 1]
            e00, e01, e02 = Je[o, 0, 0], Je[o, 0, 1], Je[o, 0, 2]
            e10, e11, e12 = Je[o, 1, 0], Je[o, 1, 1], Je[o, 1, 2]
            g_e[p, 0] += e00 * r0 + e10 * r1
            g_e[p, 1] += e01 * r0 + e11 * r1
            g_e[p, 2] += e02 * r0 + e12 * r1
            a00 = e00 * e00 + e10 * e10
            a01 = e00 * e01 + e10 * e11
            a02 = e00 * e02 + e10 * e12
            a11 = e01 * e01 + e11 * e11
            a12 = e01 * e02 + e11 * e12
            a22 = e02 * e02 + e12 * e12
            A[p, 0, 0] += a00
            A[p, 0, 1] += a01
            A[p, 0, 2] += a02
            A[p, 1, 0] += a01
            A[p, 1, 1] += a11
            A[p, 1, 2] += a12
            A[p, 2, 0] += a02
            A[p, 2, 1] += a12
            A[p, 2, 2] += a22
            for j in range(s1):
                c0, c1 = J1[o, 0, j], J1[o, 1, j]
                g_grp[q, j] += c0 * r0 + c1 * r1
                WT[o, 0, j] = e00 * c0 + e10 * c1
                WT[o, 1, j] = e01 * c0 + e11 * c1
                WT[o, 2, j] = e02 * c0 + e12 * c1
            for j in range(s2):
                c0, c1 = J2[o, 0, j], J2[o, 1, j]
                g_grp[q, s1 + j] += c0 * r0 + c1 * r1
                WT[o, 0, s1 + j] = e00 * c0 + e10 * c1
                WT[o, 1, s1 + j] = e01 * c0 + e11 * c1
                WT[o, 2, s1 + j] = e02 * c0 + e12 * c1
        return
    s = s1 + s2
    m = s + 3
    J = np.empty((d, m))
    for o in range(n):
        p = point[o]
        q = group[o]
        for k in range(d):
            for j in range(s1):
                J[k, j] = J1[o, k, j]
            for j in range(s2):
                J[k, s1 + j] = J2[o, k, j]
            for j in range(3):
                J[k, s + j] = Je[o, k, j]
        for i in range(s):
            acc = 0.0
            for k in range(d):
                acc += J[k, i] * r[o, k]
            g_grp[q, i] += acc
        for i in range(3):
            acc = 0.0
            for k in range(d):
                acc += J[k, s + i] * r[o, k]
            g_e[p, i] += acc
            for j in range(3):
                acc = 0.0
                for k in range(d):
                    acc += J[k, s + i] * J[k, s + j]
                A[p, i, j] += acc
            for j in range(s):
                acc = 0.0
                for k in range(d):
                    acc += J[k, s + i] * J[k, j]
                WT[o, i, j] = acc


@njit
def schur_rows(WT, Ainv, pt_ptr, pt_rows, group, pair_id, g_e, T, rhs_rows):
    """``T[pair_id[ga, gb]] += sum_p sum_{a<=b} w_ab Y_a W_b^T`` (s x s
    blocks per ordered pair of row groups) with ``Y_a = W_a A_p^-1`` and ``w = 1/2`` on the
    diagonal pairs (so that the full sum is ``T + T^T`` scattered), and
    ``rhs_rows[a] = Y_a g_e[p]`` (s) per row."""
    s = WT.shape[2]
    n_p = len(pt_ptr) - 1
    kmax = 0
    for p in range(n_p):
        kmax = max(kmax, pt_ptr[p + 1] - pt_ptr[p])
    YT = np.empty((kmax, 3, s))
    for p in range(n_p):
        lo, hi = pt_ptr[p], pt_ptr[p + 1]
        k = hi - lo
        if k == 0:
            continue
        a00, a01, a02 = Ainv[p, 0, 0], Ainv[p, 0, 1], Ainv[p, 0, 2]
        a11, a12, a22 = Ainv[p, 1, 1], Ainv[p, 1, 2], Ainv[p, 2, 2]
        e0, e1, e2 = g_e[p, 0], g_e[p, 1], g_e[p, 2]
        for ia in range(k):
            a = pt_rows[lo + ia]
            for j in range(s):
                w0, w1, w2 = WT[a, 0, j], WT[a, 1, j], WT[a, 2, j]
                y0 = a00 * w0 + a01 * w1 + a02 * w2
                y1 = a01 * w0 + a11 * w1 + a12 * w2
                y2 = a02 * w0 + a12 * w1 + a22 * w2
                YT[ia, 0, j] = y0
                YT[ia, 1, j] = y1
                YT[ia, 2, j] = y2
                rhs_rows[a, j] = y0 * e0 + y1 * e1 + y2 * e2
        for ia in range(k):
            ga = group[pt_rows[lo + ia]]
            for ib in range(ia, k):
                b = pt_rows[lo + ib]
                gb = group[b]
                w = 0.5 if ib == ia else 1.0
                q = pair_id[ga, gb]
                for i in range(s):
                    y0 = w * YT[ia, 0, i]
                    y1 = w * YT[ia, 1, i]
                    y2 = w * YT[ia, 2, i]
                    for j in range(s):
                        T[q, i, j] += y0 * WT[b, 0, j] + y1 * WT[b, 1, j] + y2 * WT[b, 2, j]


@njit
def back_rows(WT, rcols, point, x_c, out):
    """``out[p] += W_o^T x_c[rcols_o]`` for every E-row o."""
    n, _, s = WT.shape
    for o in range(n):
        p = point[o]
        for i in range(3):
            acc = 0.0
            for j in range(s):
                acc += WT[o, i, j] * x_c[rcols[o, j]]
            out[p, i] += acc


@njit
def point_cofactors(WT, Ainv, pt_ptr, pt_rows, rcols, Minv, AinvGe, g0, Qee):
    """``Qee[p] = A_p^-1 + V_p Minv V_p^T`` with ``V_p = [sum_a Z_a E_a,
    A_p^-1 G_e,p]``, ``Z_a = A_p^-1 W_a^T`` (3 x s) at the columns
    ``rcols_a`` and the bordered columns ``g0, g0 + 1, ...`` of Minv
    (whose row and column ``n_r`` is the zero dummy of the padding)."""
    s = WT.shape[2]
    m = AinvGe.shape[2]
    n_p = len(pt_ptr) - 1
    kmax = 0
    for p in range(n_p):
        kmax = max(kmax, pt_ptr[p + 1] - pt_ptr[p])
    Z = np.empty((kmax, 3, s))
    X = np.empty((3, m))
    for p in range(n_p):
        lo, hi = pt_ptr[p], pt_ptr[p + 1]
        k = hi - lo
        for i in range(3):
            for j in range(3):
                Qee[p, i, j] = Ainv[p, i, j]
        for ia in range(k):
            a = pt_rows[lo + ia]
            for i in range(3):
                for j in range(s):
                    Z[ia, i, j] = (Ainv[p, i, 0] * WT[a, 0, j] + Ainv[p, i, 1] * WT[a, 1, j]
                                   + Ainv[p, i, 2] * WT[a, 2, j])
        for i in range(3):
            for c in range(m):
                X[i, c] = 0.0
        for ia in range(k):
            a = pt_rows[lo + ia]
            for ib in range(k):
                b = pt_rows[lo + ib]
                for u in range(s):
                    cu = rcols[a, u]
                    for v in range(s):
                        mv = Minv[cu, rcols[b, v]]
                        if mv == 0.0:
                            continue
                        for i in range(3):
                            zi = Z[ia, i, u] * mv
                            for j in range(3):
                                Qee[p, i, j] += zi * Z[ib, j, v]
            for u in range(s):
                cu = rcols[a, u]
                for c in range(m):
                    mv = Minv[cu, g0 + c]
                    for i in range(3):
                        X[i, c] += Z[ia, i, u] * mv
        if m:
            for i in range(3):
                for j in range(3):
                    acc = 0.0
                    for c in range(m):
                        acc += X[i, c] * AinvGe[p, j, c] + AinvGe[p, i, c] * X[j, c]
                        for e in range(m):
                            acc += AinvGe[p, i, c] * Minv[g0 + c, g0 + e] * AinvGe[p, j, e]
                    Qee[p, i, j] += acc


_inline = _numba.njit(inline="always", cache=True, nogil=True,
                      fastmath={"reassoc", "contract", "nsz", "arcp"})


@_inline
def camera_frame(R, X0, s, px, py, pz):
    """The point (px, py, pz) in station ``s``'s camera frame,
    ``R_s (X - X0_s)``."""
    d0 = px - X0[s, 0]
    d1 = py - X0[s, 1]
    d2 = pz - X0[s, 2]
    x0 = R[s, 0, 0] * d0 + R[s, 0, 1] * d1 + R[s, 0, 2] * d2
    x1 = R[s, 1, 0] * d0 + R[s, 1, 1] * d1 + R[s, 1, 2] * d2
    x2 = R[s, 2, 0] * d0 + R[s, 2, 1] * d1 + R[s, 2, 2] * d2
    return x0, x1, x2


@_inline
def bal_frame_jacobian(f, k1, k2, tx, ty, iz, r2, dd):
    """The ``bal`` residual's Jacobian with respect to the camera-frame
    point, ``-(M dt/dXc)`` with ``M = d(xy)/dt = f (dd I + dp2 t t^T)`` and
    ``dt/dXc = [[-iz, 0, -tx iz], [0, iz, -ty iz]]``: rows (j00, j01, j02)
    and (j10, j11, j12)."""
    dp2 = 2.0 * (k1 + 2.0 * k2 * r2)
    m00 = f * (dd + dp2 * tx * tx)
    m01 = f * dp2 * tx * ty
    m11 = f * (dd + dp2 * ty * ty)
    return (m00 * iz, -m01 * iz, (m00 * tx + m01 * ty) * iz,
            m01 * iz, -m11 * iz, (m01 * tx + m11 * ty) * iz)


@njit
def bal_rows(xy, points, R, X0, io, point, station, camera, r, JX, JS, JI, jac):
    """The ``bal`` camera model (:mod:`photogram.geometry.bal_model`) for
    every observation, indexed (no gathered copies): residual ``xy -
    f d t`` and, with ``jac``, its Jacobians with respect to the point
    (n,2,3), the station (X0, rotation increment) (n,2,6) and (f, k1, k2)
    (n,2,3)."""
    n = len(point)
    for o in range(n):
        p = point[o]
        s = station[o]
        c = camera[o]
        x0, x1, x2 = camera_frame(R, X0, s, points[p, 0], points[p, 1], points[p, 2])
        iz = 1.0 / x2
        tx = -x0 * iz
        ty = x1 * iz
        f, k1, k2 = io[c, 0], io[c, 1], io[c, 2]
        r2 = tx * tx + ty * ty
        dd = 1.0 + r2 * (k1 + k2 * r2)
        r[o, 0] = xy[o, 0] - f * dd * tx
        r[o, 1] = xy[o, 1] - f * dd * ty
        if not jac:
            continue
        j00, j01, j02, j10, j11, j12 = bal_frame_jacobian(f, k1, k2, tx, ty, iz, r2, dd)
        for i in range(3):
            a = j00 * R[s, 0, i] + j01 * R[s, 1, i] + j02 * R[s, 2, i]
            b = j10 * R[s, 0, i] + j11 * R[s, 1, i] + j12 * R[s, 2, i]
            JX[o, 0, i] = a
            JX[o, 1, i] = b
            JS[o, 0, i] = -a
            JS[o, 1, i] = -b
        # rotation increment: row i is Xc x J_i
        JS[o, 0, 3] = x1 * j02 - x2 * j01
        JS[o, 0, 4] = x2 * j00 - x0 * j02
        JS[o, 0, 5] = x0 * j01 - x1 * j00
        JS[o, 1, 3] = x1 * j12 - x2 * j11
        JS[o, 1, 4] = x2 * j10 - x0 * j12
        JS[o, 1, 5] = x0 * j11 - x1 * j10
        JI[o, 0, 0] = -dd * tx
        JI[o, 1, 0] = -dd * ty
        JI[o, 0, 1] = -f * r2 * tx
        JI[o, 1, 1] = -f * r2 * ty
        JI[o, 0, 2] = -f * r2 * r2 * tx
        JI[o, 1, 2] = -f * r2 * r2 * ty


@njit
def schur_matvec(WT, rcols, ptr, Ainv, x, out):
    """``out += W A^-1 W^T x`` point by point (E-rows in point order,
    ``ptr`` their CSR pointer; ``x`` padded with a zero at the dummy
    column)."""
    s = WT.shape[2]
    for p in range(len(ptr) - 1):
        lo, hi = ptr[p], ptr[p + 1]
        if hi == lo:
            continue
        y0 = y1 = y2 = 0.0
        for o in range(lo, hi):
            for j in range(s):
                xv = x[rcols[o, j]]
                y0 += WT[o, 0, j] * xv
                y1 += WT[o, 1, j] * xv
                y2 += WT[o, 2, j] * xv
        z0 = Ainv[p, 0, 0] * y0 + Ainv[p, 0, 1] * y1 + Ainv[p, 0, 2] * y2
        z1 = Ainv[p, 1, 0] * y0 + Ainv[p, 1, 1] * y1 + Ainv[p, 1, 2] * y2
        z2 = Ainv[p, 2, 0] * y0 + Ainv[p, 2, 1] * y1 + Ainv[p, 2, 2] * y2
        for o in range(lo, hi):
            for j in range(s):
                out[rcols[o, j]] += WT[o, 0, j] * z0 + WT[o, 1, j] * z1 + WT[o, 2, j] * z2


@njit
def jacobi_rows(WT, Ainv, group, point, blocks):
    """``blocks[group_o] -= W_o A_p^-1 W_o^T`` (s x s) for every row o
    (the Schur-Jacobi diagonal blocks)."""
    n, _, s = WT.shape
    Y = np.empty((3, s))
    for o in range(n):
        p = point[o]
        g = group[o]
        for i in range(3):
            for j in range(s):
                Y[i, j] = Ainv[p, i, 0] * WT[o, 0, j] + Ainv[p, i, 1] * WT[o, 1, j] \
                    + Ainv[p, i, 2] * WT[o, 2, j]
        for a in range(s):
            w0, w1, w2 = WT[o, 0, a], WT[o, 1, a], WT[o, 2, a]
            for b in range(a, s):
                v = w0 * Y[0, b] + w1 * Y[1, b] + w2 * Y[2, b]
                blocks[g, a, b] -= v
                if b != a:
                    blocks[g, b, a] -= v
