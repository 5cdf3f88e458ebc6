"""Normal equations, assembled block by block, and their solution by the
Schur complement of the (3x3 block-diagonal) eliminated point part.

With the columns split into reduced (c) and eliminated points (e), the
normal equations ``N dx = -g`` read::

    [ N_cc  W   ] [dx_c]     [g_c]
    [ W^T   A   ] [dx_e] = - [g_e]

``A`` is block diagonal (one 3x3 block per point). Eliminating ``dx_e``
gives the reduced system ``S dx_c = -(g_c - W A^-1 g_e)`` with
``S = N_cc - W A^-1 W^T``, solved by Cholesky; then
``dx_e = -A^-1 (g_e + W^T dx_c)``. Cost grows linearly with the points.

The sparsity structure never changes between iterations, so every index
needed to scatter the per-observation products is computed once
(:class:`Structure`); an iteration only sums values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


DENSE_LIMIT = 4_000_000   # entries of W (n_reduced x 3 n_points) kept dense


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


@dataclass
class _PairPlan:
    block: int            # residual block number
    a: int                # slot numbers
    b: int
    rows: np.ndarray      # observation rows of the block this pair uses
    segments: Segments
    first_cols_a: np.ndarray  # (n_pairs, s_a) columns of slot a per pair
    first_cols_b: np.ndarray  # (n_pairs, s_b)


class Structure:
    """Precomputed scatter plan for the normal equations of a set of
    residual blocks with fixed slot columns.

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
        self.cc_plans, self.ce_plans, self.ee_plans = [], [], []
        w_rows, w_cols = [], []
        for bi, slots in enumerate(slot_cols):
            for a, cols_a in enumerate(slots):
                red_a = cols_a[:, 0] < n_r
                for b, cols_b in enumerate(slots):
                    red_b = cols_b[:, 0] < n_r
                    if a == b:
                        rows = np.flatnonzero(~red_a)
                        if len(rows):
                            keys = (cols_a[rows, 0] - n_r) // 3
                            self.ee_plans.append(self._plan(bi, a, b, rows, keys, cols_a, cols_b))
                    elif np.any(~red_a & ~red_b):
                        raise ValueError("two eliminated points in one residual; "
                                         "mark them as reduced points")
                    rows = np.flatnonzero(red_a & red_b)
                    if len(rows):
                        keys = pair_keys(cols_a[rows, 0], cols_b[rows, 0])
                        self.cc_plans.append(self._plan(bi, a, b, rows, keys, cols_a, cols_b))
                    rows = np.flatnonzero(red_a & ~red_b)
                    if len(rows):
                        keys = pair_keys(cols_a[rows, 0], cols_b[rows, 0])
                        plan = self._plan(bi, a, b, rows, keys, cols_a, cols_b)
                        self.ce_plans.append(plan)
                        ra = plan.first_cols_a[:, :, None]
                        cb = plan.first_cols_b[:, None, :] - n_r
                        w_rows.append(np.broadcast_to(ra, ra.shape[:2] + (cb.shape[2],)).ravel())
                        w_cols.append(np.broadcast_to(cb, (ra.shape[0], ra.shape[1], cb.shape[2])).ravel())
        n_e3 = 3 * layout.n_eliminated
        rows = np.concatenate(w_rows) if w_rows else np.zeros(0, dtype=int)
        cols = np.concatenate(w_cols) if w_cols else np.zeros(0, dtype=int)
        flat = rows.astype(np.int64) * max(n_e3, 1) + cols
        uniq, self.w_inverse = np.unique(flat, return_inverse=True)
        self.w_nnz = len(uniq)
        self.W_pattern = sp.csr_matrix(
            (np.zeros(len(uniq)), (uniq // max(n_e3, 1), uniq % max(n_e3, 1))),
            shape=(n_r, n_e3))
        self.W_pattern.sort_indices()
        # map from sorted-unique order to CSR data order (identical for CSR
        # built from sorted row-major keys, checked here)
        coo = self.W_pattern.tocoo()
        assert np.array_equal(coo.row.astype(np.int64) * max(n_e3, 1) + coo.col, uniq)
        # small problems: W as a dense array (BLAS beats sparse products)
        self.dense = n_r * n_e3 <= DENSE_LIMIT
        self.w_flat = uniq

    @staticmethod
    def _plan(bi, a, b, rows, keys, cols_a, cols_b):
        seg = Segments(keys)
        first = rows[seg.order[seg.starts]]
        return _PairPlan(bi, a, b, rows, seg, cols_a[first], cols_b[first])


@dataclass
class NormalSystem:
    """Assembled normal equations: dense N_cc, sparse W, blocks A, gradient."""

    Ncc: np.ndarray       # (n_r, n_r)
    W: sp.csr_matrix | np.ndarray   # (n_r, 3 n_e), dense for small problems
    A: np.ndarray         # (n_e, 3, 3)
    g: np.ndarray         # (n_columns,)
    cost: float           # 0.5 * sum r^2 of the whitened residuals


def assemble(structure: Structure, residuals, jacobians) -> NormalSystem:
    """Sum ``J^T J`` and ``J^T r`` into the normal equations.

    Parameters
    ----------
    residuals : list of (N_b, d_b) whitened residuals per block.
    jacobians : list of list of (N_b, d_b, s) whitened Jacobians per slot.
    """
    lay = structure.layout
    n_r, n_e = lay.n_reduced, lay.n_eliminated
    g = np.zeros(lay.n_columns)
    cost = 0.0
    for r, Js, cols in zip(residuals, jacobians, structure.slot_cols):
        cost += 0.5 * float(np.sum(r * r))
        for J, c in zip(Js, cols):
            g += np.bincount(c.ravel(), weights=np.matmul(r[:, None, :], J)[:, 0].ravel(),
                             minlength=lay.n_columns)
    Ncc = np.zeros(n_r * n_r)
    for plan in structure.cc_plans:
        blocks = _pair_products(plan, jacobians)
        idx = plan.first_cols_a[:, :, None] * n_r + plan.first_cols_b[:, None, :]
        Ncc += np.bincount(idx.ravel(), weights=blocks.ravel(), minlength=n_r * n_r)
    A = np.zeros((n_e, 3, 3))
    for plan in structure.ee_plans:
        keys = plan.segments.unique
        A[keys] += _pair_products(plan, jacobians)
    w_vals = [_pair_products(plan, jacobians).ravel() for plan in structure.ce_plans]
    data = np.bincount(structure.w_inverse,
                       weights=np.concatenate(w_vals) if w_vals else np.zeros(0),
                       minlength=structure.w_nnz)
    if structure.dense:
        W = np.zeros(structure.W_pattern.shape)
        W.ravel()[structure.w_flat] = data
    else:
        W = structure.W_pattern.copy()
        W.data = data
    return NormalSystem(Ncc.reshape(n_r, n_r), W, A, g, cost)


def _pair_products(plan, jacobians):
    Ja = jacobians[plan.block][plan.a][plan.rows]
    Jb = jacobians[plan.block][plan.b][plan.rows]
    prod = np.matmul(np.swapaxes(Ja, 1, 2), Jb)      # batched J_a^T J_b
    return plan.segments.sum(prod)
