"""The sparsity structure of the normal equations, computed once per
problem (:class:`Structure`): the rows of every residual block grouped by
their reduced columns (one group per station, say) into row classes
(:class:`RowClass`), the E-rows (rows that touch an eliminated point) point
by point (:class:`Segments`), and the pairs of E-rows of each point that
the Schur complement sums over. :mod:`photogram.adjust.normal` assembles
the values of an iteration on this structure (its docstring gives the
form of the normal equations).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

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
