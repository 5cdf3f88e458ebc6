"""Leverages ``h = diag(J Q J^T)`` of the rows of a residual block,
blockwise.

For a row with reduced columns ``c`` (station, interior orientation, ...;
Jacobian ``J_c``) and an eliminated point ``p`` (Jacobian ``J_e``)::

    h = diag(J_c Q_cc[c, c] J_c^T + 2 J_e Q_ec[p, c] J_c^T + J_e Q_ee,p J_e^T)

with ``Q_cc`` the reduced cofactors, ``Q_ee,p`` the point's 3x3 block and
``Q_ec[p, c]`` its cross cofactors with the row's own columns only
(:meth:`photogram.stats.covariance.Cofactors.cross`). The rows are taken in
chunks, sorted by point (a chunk then needs the per-point quantities of few
points), so the memory grows with the chunk, not with the observations
times the unknowns. The redundancy number of a (whitened) observation is
``1 - h``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["leverage_diagonal"]


def leverage_diagonal(cof, J, slot_cols, chunk_entries=1_000_000):
    """``diag(J Q J^T)`` (N, d) of every row of one residual block.

    Parameters
    ----------
    cof : Cofactors
    J : list of (N, d, s_k) Jacobians, one per slot
    slot_cols : list of (N, s_k) column numbers, one per slot
    chunk_entries : int
        About how many cofactor entries a chunk of rows gathers.
    """
    n_r = cof.layout.n_reduced
    N, d = len(slot_cols[0]), J[0].shape[1]
    h = np.zeros((N, d))
    if N == 0:
        return h
    red = np.stack([c[:, 0] < n_r for c in slot_cols], axis=1)
    code = red.astype(np.int64) @ (1 << np.arange(len(slot_cols), dtype=np.int64))
    for pat in np.unique(code):
        rows = np.flatnonzero(code == pat)
        rs = [k for k in range(len(slot_cols)) if (pat >> k) & 1]
        es = [k for k in range(len(slot_cols)) if not (pat >> k) & 1]
        if len(es) == 1:          # sorted by point: a chunk touches few points
            pts = slot_cols[es[0]][rows, 0]
            rows = rows[np.argsort(pts, kind="stable")]
        width = sum(slot_cols[k].shape[1] for k in range(len(slot_cols)))
        step = max(1, chunk_entries // (width * width))
        for lo in range(0, len(rows), step):
            q = rows[lo:lo + step]
            h[q] = _rows(cof, [J[k][q] for k in rs], [slot_cols[k][q] for k in rs],
                         [J[k][q] for k in es], [slot_cols[k][q] for k in es])
    return h


def _quad(Ja, Q, Jb):
    """``diag(Ja Q Jb^T)`` per row: (n, d)."""
    return np.sum(np.matmul(Ja, Q) * Jb, axis=2)


def _rows(cof, Jr, cr, Je, ce):
    """Leverages of rows with the reduced slots ``Jr``/``cr`` and the
    eliminated slots ``Je``/``ce`` (at most one per row in the engine;
    more are summed pairwise through :meth:`Cofactors.block`)."""
    n, d = len((Jr or Je)[0]), (Jr or Je)[0].shape[1]
    h = np.zeros((n, d))
    if Jr:
        Jc = np.concatenate(Jr, axis=2) if len(Jr) > 1 else Jr[0]
        cc = np.concatenate(cr, axis=1) if len(cr) > 1 else cr[0]
        h += _quad(Jc, cof.Qcc[cc[:, :, None], cc[:, None, :]], Jc)
    for a, (Ja, ca) in enumerate(zip(Je, ce)):
        for b, (Jb, cb) in enumerate(zip(Je, ce)):
            h += _quad(Ja, cof.block(ca, cb), Jb)
        if Jr:
            h += 2.0 * _quad(Ja, cof.block(ca, cc), Jc)
    return h
