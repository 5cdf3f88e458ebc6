"""Cofactors of the stations of rig images (derived stations,
:mod:`photogram.adjust.build_rigs`): their columns are held fixed in the
adjustment; their pose is the composition of their frame's and their
sensor's (``R = R_s R_f``, ``X0 = X0_f + R_f^T X0_s``), so their cofactors
follow by first-order propagation, ``Q' = A Q A^T``, with ``A`` the identity
except the derived stations' rows, which hold the composition's Jacobian by
the engine's increments (``dX0``, ``delta`` with ``R = expm([delta]x) R0``)::

    dX0   = dX0_f + R_f^T [X0_s]x d_f + R_f^T dX0_s
    delta = R_s d_f + d_s

(the second from ``R_s expm([d_f]x) R_f = expm([R_s d_f]x) R_s R_f``; the
first from ``R_f^T expm(-[d_f]x) X0_s = R_f^T (X0_s + X0_s x d_f)``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from photogram.adjust.board_blocks import _cross_matrix

__all__ = ["composition_jacobian", "with_rig_cofactors"]


def composition_jacobian(R_frame, X0_sensor, R_sensor) -> np.ndarray:
    """(n, 6, 12) Jacobian of the composed station (dX0, delta) by the
    frame's (dX0_f, d_f) and the sensor's (dX0_s, d_s) increments (module
    doc)."""
    n = len(R_frame)
    RfT = np.swapaxes(R_frame, 1, 2)
    T = np.zeros((n, 6, 12))
    T[:, :3, :3] = np.eye(3)
    T[:, :3, 3:6] = RfT @ _cross_matrix(X0_sensor)
    T[:, :3, 6:9] = RfT
    T[:, 3:, 3:6] = R_sensor
    T[:, 3:, 9:] = np.eye(3)
    return T


def _propagation(layout, state) -> sp.csr_matrix:
    """``A`` (n_reduced, n_reduced) of the module doc."""
    d, f, s = layout.derived
    n_r = layout.n_reduced
    T = composition_jacobian(state.R[f], state.X0[s], state.R[s])
    rows = np.repeat(layout.station_cols[d][:, :, None], 12, axis=2)
    src = np.concatenate([layout.station_cols[f], layout.station_cols[s]], axis=1)
    cols = np.repeat(src[:, None, :], 6, axis=1)
    keep = np.ones(n_r, bool)
    keep[layout.station_cols[d].ravel()] = False
    eye = np.flatnonzero(keep)
    return sp.csr_matrix((np.r_[np.ones(len(eye)), T.ravel()],
                          (np.r_[eye, rows.ravel()], np.r_[eye, cols.ravel()])),
                         shape=(n_r, n_r))


def with_rig_cofactors(cof, problem) -> None:
    """Fill the cofactors of the derived stations of ``problem`` into
    ``cof`` (:class:`photogram.stats.covariance.Cofactors`), also their
    cross cofactors with every other unknown (points included)."""
    layout = problem.layout
    if layout.derived is None:
        return
    A = _propagation(layout, problem.state)
    cof.Qcc = np.asarray((A @ (A @ cof.Qcc).T).T)
    inner = cof._qec_rows
    if inner is not None:
        def qec_rows(points):
            Q = inner(points)                        # (len, 3, n_r)
            return np.asarray((A @ Q.reshape(-1, Q.shape[-1]).T).T).reshape(Q.shape)
        cof._qec_rows = qec_rows
    if cof._Qec is not None:
        cof._Qec = np.asarray((A @ cof._Qec.T).T)
    if cof._ce_times is not None:
        inner_times = cof._ce_times
        cof._ce_times = lambda Ne: np.asarray(A @ inner_times(Ne))
    if cof._cross is not None:
        cof._cross = _mapped_cross(cof._cross, A)


def _mapped_cross(inner, A):
    """The cross cofactors ``Q_ec A^T`` at given columns: each column c
    of a row expands to the (at most 12) columns of ``A``'s row c."""
    A = sp.csr_matrix(A)
    nnz = np.diff(A.indptr)
    width = max(int(nnz.max(initial=1)), 1)
    pos = np.arange(A.shape[0])[:, None]
    k = np.arange(width)[None, :]
    take = np.minimum(A.indptr[:-1][:, None] + k, max(len(A.indices) - 1, 0))
    ok = k < nnz[:, None]
    cols_of = np.where(ok, A.indices[take], pos)                  # (n_r, width)
    vals_of = np.where(ok, A.data[take], 0.0)

    def cross(points, cols):
        n, sr = cols.shape
        Q = inner(points, cols_of[cols].reshape(n, sr * width)).reshape(n, 3, sr, width)
        return np.einsum("nisw,nsw->nis", Q, vals_of[cols])

    return cross
