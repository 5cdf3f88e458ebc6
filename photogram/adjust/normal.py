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
computed once (:class:`Structure`); an iteration only sums values.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from photogram.adjust import kernels


class Segments:
    """Sum rows of an (N, ...) array over groups given by integer keys
    (sorting once, then ``np.add.reduceat`` every time)."""

    def __init__(self, keys: np.ndarray):
        keys = np.asarray(keys)
        self.order = np.argsort(keys, kind="stable")
        sorted_keys = keys[self.order]
        if len(keys):
            self.starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
        else:
            self.starts = np.zeros(0, dtype=int)
        self.unique = sorted_keys[self.starts]

    def sum(self, values: np.ndarray) -> np.ndarray:
        if len(self.order) == 0:
            return np.zeros((0,) + values.shape[1:])
        return np.add.reduceat(values[self.order], self.starts, axis=0)


def pair_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One integer key per (a, b) pair of non-negative integers."""
    return a.astype(np.int64) * (int(b.max(initial=0)) + 1) + b


def _group_ids(keys, n):
    """Dense group numbers of rows identified by several integer key
    columns (combined pairwise, never overflowing)."""
    gid = np.zeros(n, dtype=np.int64)
    for k in keys:
        _, gid = np.unique(gid * (int(k.max(initial=0)) + 1) + k, return_inverse=True)
        gid = gid.astype(np.int64).ravel()
    return gid


def _slot_key(cols):
    """An integer key per row that identifies the row's columns of one
    slot: the first column where it fixes the others (every parameter
    block has its own columns), else the row's number among the distinct
    rows (shared interior parameters: instances with the same first column,
    e.g. a shared c, and different others, e.g. a principal point per
    station)."""
    first = cols[:, 0]
    if cols.shape[1] > 1 and len(first):
        _, at, inv = np.unique(first, return_index=True, return_inverse=True)
        if not np.array_equal(cols, cols[at][inv.ravel()]):
            return np.unique(cols, axis=0, return_inverse=True)[1].ravel()
    return first


class RowClass:
    """Rows of one residual block with the same reduced/eliminated slots."""

    def __init__(self, block, rows, n_block, e_slot, gather, rcols, group):
        self.block = block
        self.rows = rows
        self.identity = len(rows) == n_block and np.array_equal(rows, np.arange(n_block))
        self.e_slot = e_slot            # slot of the eliminated point, -1: none
        self.gather = gather            # [(slot, positions or None)]
        self.rcols = rcols              # (n, s) reduced columns
        self.s = rcols.shape[1]
        self.group = group              # (n,) local group, sorted
        self.n_groups = int(group[-1]) + 1 if len(group) else 0
        self.group_starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]]) if len(group) \
            else np.zeros(0, dtype=int)
        self.group_cols = rcols[self.group_starts]
        self.point = None               # (n,) eliminated point of each row
        self.offset = 0                 # first E-row
        self.flat9 = self.flat3 = None  # scatter indices of the numpy path

    def take(self, residuals, jacobians):
        """Residuals r (n, d), the Jacobians of the reduced slots (a list
        of (n, d, s_k), together Jc) and the point Jacobian Je (n, d, 3)
        (or None) of the class's rows."""
        r, Js = residuals[self.block], jacobians[self.block]
        sel = slice(None) if self.identity else self.rows
        parts = []
        for k, pos in self.gather:
            J = Js[k][sel]
            parts.append(np.ascontiguousarray(J if pos is None else J[:, :, pos]))
        Je = np.ascontiguousarray(Js[self.e_slot][sel]) if self.e_slot >= 0 else None
        return np.ascontiguousarray(r[sel]), parts, Je

    @staticmethod
    def joined(parts, n, d):
        """The reduced Jacobian Jc (n, d, s) of the parts."""
        if len(parts) == 1:
            return parts[0]
        if parts:
            return np.concatenate(parts, axis=2)
        return np.zeros((n, d, 0))


class Structure:
    """Precomputed plan for the normal equations and the Schur complement
    of a set of residual blocks with fixed slot columns.

    Parameters
    ----------
    layout : Layout
    slot_cols : list of list of (N_b, s) int arrays
        For every residual block, the columns of each of its slots.
    """

    def __init__(self, layout, slot_cols):
        self.layout = layout
        self.slot_cols = slot_cols
        n_r = layout.n_reduced
        self.n_r = n_r
        free = layout.free
        self.e_classes, self.c_classes = [], []
        for bi, slots in enumerate(slot_cols):
            if not slots or len(slots[0]) == 0:
                continue
            n_block = len(slots[0])
            red = np.stack([c[:, 0] < n_r for c in slots], axis=1)
            if np.any((~red).sum(axis=1) > 1):
                raise ValueError("two eliminated points in one residual; "
                                 "mark them as reduced points")
            code = red.astype(np.int64) @ (1 << np.arange(len(slots), dtype=np.int64))
            for pat in np.unique(code):
                rows = np.flatnonzero(code == pat)
                is_red = [bool((pat >> k) & 1) for k in range(len(slots))]
                e_slot = is_red.index(False) if not all(is_red) else -1
                gather, cols, keys = [], [], []
                for k, c in enumerate(slots):
                    if not is_red[k]:
                        continue
                    ck = c[rows]
                    keep = np.flatnonzero(free[ck].any(axis=0))
                    if len(keep) == 0:
                        continue
                    gather.append((k, None if len(keep) == ck.shape[1] else keep))
                    cols.append(ck[:, keep])
                    keys.append(_slot_key(ck))
                rcols = np.hstack(cols) if cols else np.zeros((len(rows), 0), dtype=np.int64)
                group = _group_ids(keys, len(rows))
                order = np.argsort(group, kind="stable")
                cls = RowClass(bi, rows[order], n_block, e_slot, gather,
                               rcols[order].astype(np.int64), group[order])
                if e_slot >= 0:
                    cls.point = ((slots[e_slot][cls.rows, 0] - n_r) // 3).astype(np.int64)
                    self.e_classes.append(cls)
                else:
                    self.c_classes.append(cls)
        # all E-rows: reduced columns padded to s with the dummy column n_r
        self.s = max((c.s for c in self.e_classes), default=0)
        n_e_rows, g_off = 0, 0
        for c in self.e_classes:
            c.offset = n_e_rows
            c.group_offset = g_off
            n_e_rows += len(c.rows)
            g_off += c.n_groups
        self.n_e_rows = n_e_rows
        self.n_groups = g_off
        self.e_rcols = np.full((n_e_rows, self.s), n_r, dtype=np.int64)
        self.e_point = np.zeros(n_e_rows, dtype=np.int64)
        self.e_group = np.zeros(n_e_rows, dtype=np.int64)
        self.group_cols = np.full((g_off, self.s), n_r, dtype=np.int64)
        coupling = np.zeros(n_e_rows, dtype=bool)
        for c in self.e_classes:
            sl = slice(c.offset, c.offset + len(c.rows))
            self.e_rcols[sl, :c.s] = c.rcols
            self.e_point[sl] = c.point
            self.e_group[sl] = c.group + c.group_offset
            self.group_cols[c.group_offset:c.group_offset + c.n_groups, :c.s] = c.group_cols
            coupling[sl] = c.s > 0
        # E-rows that couple their point to reduced columns, by point (CSR)
        rows = np.flatnonzero(coupling)
        order = np.argsort(self.e_point[rows], kind="stable")
        self.pt_rows = rows[order].astype(np.int64)
        counts = np.bincount(self.e_point[self.pt_rows], minlength=layout.n_eliminated)
        self.pt_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        m = n_r + 1
        gc = self.group_cols
        self._g_scatter = (gc[:, :, None] * m + gc[:, None, :]).ravel()
        self._pairs = None
        self._group_pairs = None

    def group_pairs(self):
        """Ordered pairs of row groups that share a point (both orders and
        the diagonal): ``(ga, gb, pair_id, reverse, scatter)`` with
        ``pair_id[ga, gb]`` the pair's number (-1: none), ``reverse`` the
        number of (gb, ga) and ``scatter`` the flat positions of each
        pair's s x s block in the (n_r + 1)^2 reduced matrix."""
        if self._group_pairs is None:
            ng = self.n_groups
            rows = self.pt_rows
            inc = sp.csr_matrix((np.ones(len(rows)), (self.e_group[rows], self.e_point[rows])),
                                shape=(ng, self.layout.n_eliminated))
            P = (inc @ inc.T).tocoo()
            ga, gb = P.row.astype(np.int64), P.col.astype(np.int64)
            order = np.lexsort((gb, ga))
            ga, gb = ga[order], gb[order]
            pair_id = np.full((ng, ng), -1, dtype=np.int64)
            pair_id[ga, gb] = np.arange(len(ga))
            reverse = pair_id[gb, ga]
            m = self.n_r + 1
            gc = self.group_cols
            scatter = (gc[ga][:, :, None] * m + gc[gb][:, None, :]).ravel()
            self._group_pairs = (ga, gb, pair_id, reverse, scatter)
        return self._group_pairs

    # ------------------------------------------------------------------
    def point_pairs(self, budget=4_000_000):
        """All ordered pairs (a, b) of coupling E-rows of the same point
        (a == b included), in chunks of whole points of about ``budget``
        pairs: yields ``(point, a, b)`` arrays."""
        ptr, rows = self.pt_ptr, self.pt_rows
        k = np.diff(ptr)
        n_p = len(k)
        cum = np.concatenate([[0], np.cumsum(k.astype(np.int64) ** 2)])
        lo = 0
        while lo < n_p:
            hi = int(np.searchsorted(cum, cum[lo] + budget, side="right")) - 1
            hi = min(max(hi, lo + 1), n_p)
            kk = k[lo:hi]
            sq = kk * kk
            reps = np.repeat(np.arange(hi - lo), sq)
            local = np.arange(len(reps)) - np.repeat(np.cumsum(sq) - sq, sq)
            kr = np.maximum(kk[reps], 1)
            base = ptr[lo:hi][reps]
            yield lo + reps, rows[base + local // kr], rows[base + local % kr]
            lo = hi

    def pair_plan(self):
        """Pairs (a, b) of E-rows of the same point with group(a) <= group(b)
        (both orders within one group), sorted by group pair: arrays ``a``,
        ``b``, segment starts and the group pair of every segment. Built on
        first use (the numpy Schur complement), in chunks of points."""
        if self._pairs is not None:
            return self._pairs
        grp = self.e_group
        a_all, b_all = [], []
        for _, a, b in self.point_pairs():
            keep = grp[a] <= grp[b]
            a_all.append(a[keep])
            b_all.append(b[keep])
        a = np.concatenate(a_all) if a_all else np.zeros(0, dtype=np.int64)
        b = np.concatenate(b_all) if b_all else np.zeros(0, dtype=np.int64)
        key = grp[a] * max(self.n_groups, 1) + grp[b]
        order = np.argsort(key, kind="stable")
        a, b, key = a[order], b[order], key[order]
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else np.zeros(0, int)
        ends = np.r_[starts[1:], len(key)]
        g1 = key[starts] // max(self.n_groups, 1)
        g2 = key[starts] % max(self.n_groups, 1)
        self._pairs = (a, b, starts, ends, g1, g2)
        return self._pairs


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
