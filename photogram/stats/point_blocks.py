"""Per-point blocks of the cofactors through the Schur structure, in
memory that grows with the observations and points only.

With ``ext`` the inverse of the reduced (bordered) matrix ``M`` extended by
a zero dummy row and column ``n_r`` (the padding of the E-rows' columns)
and, for an eliminated point p, ``V_p`` the 3 x u_p matrix over the u_p
distinct columns ``U_p`` the point touches::

    V_p = sum over the E-rows a of p of A_p^-1 W_a^T   (at a's reduced columns)
          + A_p^-1 G_e,p                              (at the datum columns)

the blocks of the cofactor matrix that involve the point are (module doc of
:mod:`photogram.stats.covariance`)::

    Q_ee,p    = A_p^-1 + V_p ext[U_p, U_p] V_p^T
    Q_ec[p,c] = -V_p ext[U_p, c]

Nothing of size (observations x observations), (unknowns x unknowns) or
(3 n_points x n_reduced) is formed: the points are taken in chunks (sorted
by their number of E-rows, so that a chunk's padded ``U`` is short) of at
most ``budget`` entries of ``ext[U, U]``. ``X_p = V_p ext[U_p, U_p]`` gives
``Q_ee,p`` and, for the reduced columns in ``U_p`` (every column of every
observation of the point), ``Q_ec`` without another gather.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PointBlocks"]


class PointBlocks:
    """The per-point quantities of the module doc for one factorization.

    Parameters
    ----------
    st : Structure (:class:`photogram.adjust.structure.Structure`)
    WT : (n_e_rows, 3, s) ``W_a^T`` of every E-row
    Ainv : (n_e, 3, 3) inverse point blocks
    ext : (n_r + 1 + m, n_r + 1 + m) extended inverse of M (module doc)
    AinvGe3 : (n_e, 3, m) ``A^-1 G_e`` per point (m = 0 without conditions)
    fixed : (n_columns,) bool, fixed parameters (zero cofactors)
    budget : int
        Entries of ``ext[U, U]`` gathered at once (8 bytes each).
    """

    def __init__(self, st, WT, Ainv, ext, AinvGe3, fixed, budget=2_000_000):
        self.st, self.WT, self.Ainv, self.ext = st, WT, Ainv, ext
        self.AinvGe3 = AinvGe3
        self.n_r = st.n_r
        self.m = AinvGe3.shape[2]
        self.g0 = self.n_r + 1
        self.width = ext.shape[0]
        self.budget = int(budget)
        self.fixed_c = fixed[:self.n_r]
        self.fixed_e = fixed[self.n_r:].reshape(-1, 3)
        k = np.diff(st.pt_ptr) if len(st.pt_ptr) else np.zeros(len(Ainv), dtype=np.int64)
        # an upper bound of u_p: every column of every E-row distinct
        self.u_bound = np.minimum(k * max(st.s, 1), self.n_r + 1) + self.m + 1

    # ------------------------------------------------------------------
    def chunks(self, points):
        """Split ``points`` (distinct eliminated point numbers) into chunks
        of at most ``budget`` entries of ``ext[U, U]`` (upper bound), the
        points sorted by their bound: a list of index arrays into
        ``points``."""
        points = np.asarray(points, dtype=np.int64)
        if len(points) == 0:
            return []
        ub = self.u_bound[points]
        order = np.argsort(ub, kind="stable")
        ub2 = ub[order].astype(np.int64) ** 2
        out, lo, n = [], 0, len(points)
        while lo < n:
            hi = min(n, lo + max(1, self.budget // int(ub2[lo])))
            while hi - lo > 1 and (hi - lo) * int(ub2[hi - 1]) > self.budget:
                hi = lo + max(1, (hi - lo) // 2)
            out.append(order[lo:hi])
            lo = hi
        return out

    def chunk(self, P, products=True):
        """``(U, V, X, keys, start)`` of the points ``P``: ``U`` (n, u)
        columns (padded with the dummy column), ``V`` (n, 3, u), ``X = V
        ext[U, U]`` (n, 3, u), ``keys`` the sorted ``local * width +
        column`` of the distinct columns and ``start`` (n,) each point's
        first key (``X`` None when not ``products``)."""
        st, W = self.st, self.width
        n = len(P)
        ptr = st.pt_ptr
        counts = ptr[P + 1] - ptr[P]
        first = np.cumsum(counts) - counts
        which = np.repeat(np.arange(n), counts)
        rows = st.pt_rows[np.repeat(ptr[P] - first, counts) + np.arange(int(counts.sum()))]
        Z = np.matmul(self.Ainv[st.e_point[rows]], self.WT[rows])        # (c, 3, s)
        keys = (which[:, None] * W + st.e_rcols[rows]).ravel()
        vals = np.swapaxes(Z, 1, 2).reshape(-1, 3)
        if self.m:
            gk = (np.arange(n)[:, None] * W + self.g0 + np.arange(self.m)).ravel()
            keys = np.concatenate([keys, gk])
            vals = np.concatenate([vals, np.swapaxes(self.AinvGe3[P], 1, 2).reshape(-1, 3)])
        if len(keys) == 0:
            keys, vals = np.arange(n) * W + self.n_r, np.zeros((n, 3))
        uniq, inv = np.unique(keys, return_inverse=True)
        inv = inv.ravel()
        Vf = np.stack([np.bincount(inv, weights=vals[:, i], minlength=len(uniq))
                       for i in range(3)], axis=1)
        lp = uniq // W
        start = np.searchsorted(lp, np.arange(n))
        upos = np.arange(len(uniq)) - start[lp]
        u = int(upos.max()) + 1
        U = np.full((n, u), self.n_r, dtype=np.int64)
        U[lp, upos] = uniq % W
        V = np.zeros((n, 3, u))
        V[lp, :, upos] = Vf
        X = np.matmul(V, self.ext[U[:, :, None], U[:, None, :]]) if products else None
        return U, V, X, uniq, start

    # ------------------------------------------------------------------
    def point_cofactors(self):
        """``Q_ee`` (n_e, 3, 3) of every eliminated point (fixed coordinates
        not yet zeroed)."""
        n_e = len(self.Ainv)
        Qee = self.Ainv.copy()
        pts = np.arange(n_e)
        for idx in self.chunks(pts):
            P = pts[idx]
            _, V, X, _, _ = self.chunk(P)
            Qee[P] += np.matmul(X, np.swapaxes(V, 1, 2))
        return Qee

    def cross(self, points, cols):
        """``Q_ec`` (len(points), 3, sr): the cross cofactors of the
        eliminated points ``points`` (one per query row) and the reduced
        columns ``cols`` (len(points), sr) of the same row; zero for fixed
        parameters."""
        points = np.asarray(points, dtype=np.int64)
        cols = np.asarray(cols, dtype=np.int64).reshape(len(points), -1)
        out = np.zeros((len(points), 3, cols.shape[1]))
        if len(points) == 0 or cols.shape[1] == 0:
            return out
        pts, inv = np.unique(points, return_inverse=True)
        inv = inv.ravel()
        parts = self.chunks(pts)
        part_of = np.empty(len(pts), dtype=np.int64)
        local_of = np.empty(len(pts), dtype=np.int64)
        for j, idx in enumerate(parts):
            part_of[idx] = j
            local_of[idx] = np.arange(len(idx))
        row_part = part_of[inv]
        order = np.argsort(row_part, kind="stable")
        bounds = np.searchsorted(row_part[order], np.arange(len(parts) + 1))
        for j, idx in enumerate(parts):
            q = order[bounds[j]:bounds[j + 1]]
            out[q] = self._cross_chunk(pts[idx], local_of[inv[q]], cols[q])
        out *= ~self.fixed_e[points][:, :, None]
        out *= ~self.fixed_c[cols][:, None, :]
        return out

    def _cross_chunk(self, P, local, cols):
        """Cross cofactors of query rows whose points are the chunk ``P``
        (``local``: their index in P)."""
        U, V, X, keys, start = self.chunk(P)
        W = self.width
        want = local[:, None] * W + cols
        at = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
        found = keys[at] == want
        pos = np.where(found, at - start[local][:, None], 0)
        out = -np.swapaxes(X[local[:, None], :, pos], 1, 2)          # (q, 3, sr)
        # columns the point does not touch (fixed ones are zero anyway)
        qi, ci = np.nonzero(~found & ~self.fixed_c[cols])
        out *= found[:, None, :]
        step = max(1, self.budget // (4 * U.shape[1]))
        for lo in range(0, len(qi), step):
            q, c = qi[lo:lo + step], ci[lo:lo + step]
            e = self.ext[U[local[q]], cols[q, c][:, None]]              # (k, u)
            out[q, :, c] = -np.einsum("kiu,ku->ki", V[local[q]], e)
        return out

    def ce_times(self, Ne):
        """``sum_p Q_ce[:, p] Ne[p]`` (n_r, q) for ``Ne`` (n_e, 3, q): the
        reduced cofactors times a matrix over the points' coordinates, as
        ``-ext[:n_r] Y`` with ``Y = sum_p V_p^T Ne[p]`` (scattered to the
        point's columns)."""
        Ne = np.asarray(Ne, dtype=float) * ~self.fixed_e[:, :, None]
        q = Ne.shape[2]
        Y = np.zeros((self.width, q))
        pts = np.arange(len(self.Ainv))
        for idx in self.chunks(pts):
            P = pts[idx]
            U, V, _, _, _ = self.chunk(P, products=False)
            contrib = np.matmul(np.swapaxes(V, 1, 2), Ne[P])            # (n, u, q)
            flat = U.ravel()
            for j in range(q):
                Y[:, j] += np.bincount(flat, weights=contrib[:, :, j].ravel(),
                                       minlength=self.width)
        out = -(self.ext[:self.n_r] @ Y)
        out[self.fixed_c] = 0.0
        return out

    def joint(self, points):
        """The joint cofactor matrix (3 n, 3 n) of the eliminated points
        ``points`` (n of them, in this order), cross blocks between points
        included: ``Q_pq = [p == q] A_p^-1 + V_p ext[U_p, U_q] V_q^T``.
        Its size grows with n^2: for chosen points, not all of them."""
        points = np.asarray(points, dtype=np.int64)
        n = len(points)
        U, V, _, _, _ = self.chunk(points, products=False)
        cols, inv = np.unique(U, return_inverse=True)
        inv = inv.reshape(U.shape)
        Vd = np.zeros((n, 3, len(cols)))
        for i in range(3):                 # duplicate dummy entries carry zeros
            np.add.at(Vd[:, i, :], (np.arange(n)[:, None], inv), V[:, i, :])
        Vd = Vd.reshape(3 * n, len(cols))
        Q = Vd @ self.ext[np.ix_(cols, cols)] @ Vd.T
        idx = 3 * np.arange(n)[:, None, None] + np.arange(3)
        Q[idx, np.swapaxes(idx, 1, 2)] += self.Ainv[points]
        keep = ~self.fixed_e[points].ravel()
        return Q * keep[:, None] * keep[None, :]
