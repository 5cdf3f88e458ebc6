"""Levenberg-Marquardt on the joint pose and rotation energy
(:class:`photogram.mocap.reconstruction.joint.JointBatch`), all windows of a batch at once.

Every iteration forms the dense Gauss-Newton model of each window (about
1000 unknowns with N_Pi = N_Gamma = 11) and solves the damped system
``(H + mu diag(H)) delta = rhs`` by a block Cholesky that follows the
matrix's structure (the joints one at a time in a minimum-degree order of
the limb graph, then the cameras' Schur complement:
:mod:`photogram.mocap.reconstruction.joint_blocks`; all pending windows of
a trial at once, a loop over joints, never over windows or observations;
10 ms instead of 38 ms for 3 windows of 24 joints x 39 + 198 unknowns, the
same steps to rounding); where a pivot block is not positive definite, the dense
Cholesky of each window decides as before. As in
:mod:`photogram.mocap.reconstruction.solvers`, the first ``irls_first`` iterations use the
plain IRLS model (a majoriser of the robust term) and the later ones Triggs'
second-order correction; a step is accepted only if it lowers the window's
energy (mu / 3 after a success, x 10 after a failure); a window stops when
its relative energy decrease falls below the tolerance or no determined
joint position moves by more than ``step_tol``. Windows are processed in
chunks so that the dense matrices of a chunk stay below ~100 MB.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve

from photogram.mocap.reconstruction.blas import one_blas_thread
from photogram.mocap.reconstruction.joint import JointBatch
from photogram.mocap.reconstruction.joint_blocks import elimination_order, solve_blocks
from photogram.mocap.reconstruction.solvers import damping_update, moved_positions

__all__ = ["solve_joint", "solve_joint_lbfgs"]


def _chunks(ids, n_unknowns, budget=100e6):
    size = max(1, int(budget // (8.0 * n_unknowns * n_unknowns)))
    return [ids[i:i + size] for i in range(0, len(ids), size)]


def _mask(batch: JointBatch, nw):
    """1 for the unknowns a window may change: the pose coefficients of
    observed joints (``n_coef``), the angle coefficients of the cameras
    that are free in the window (``camera_free``)."""
    _, C, J, T, KP, KG = batch.sizes
    mp = np.broadcast_to(batch.obs.mask(KP), (nw, J, 3, KP)).reshape(nw, -1)
    free = np.ones((nw, C), bool) if batch.camera_free is None else batch.camera_free
    mc = np.repeat(free, 3 * KG, axis=1)
    return np.concatenate([mp, mc], axis=1).astype(float)


def _solve_dense(A, b):
    return cho_solve(cho_factor(A, check_finite=False), b, check_finite=False)


def _solve_free(A, b, T, J):
    """Solve with the pose unknowns eliminated frame by frame: with free
    points (pose basis = identity) the pose block of the normal matrix is
    block-diagonal over frames (3J x 3J per frame: joints coupled by the
    limbs only), so the camera unknowns are solved from the Schur complement
    and the points back-substituted."""
    nP = 3 * J * T
    idx = np.arange(nP).reshape(J, 3, T).transpose(2, 0, 1).reshape(T, 3 * J)
    blocks = A[idx[:, :, None], idx[:, None, :]]                      # (T, 3J, 3J)
    Hpc = A[idx, nP:]                                                 # (T, 3J, nC)
    inv = np.linalg.inv(blocks)
    bp = b[idx]                                                       # (T, 3J)
    IH = inv @ Hpc
    S = A[nP:, nP:] - np.einsum("tpc,tpd->cd", Hpc, IH)
    y = b[nP:] - np.einsum("tpc,tp->c", IH, bp)
    dc = _solve_dense(S, y)
    dp = np.einsum("tpq,tq->tp", inv, bp - Hpc @ dc)
    out = np.empty_like(b)
    out[idx] = dp
    out[nP:] = dc
    return out


def _steps(H, rhs, d, m, mu, p, free, T, J, nP, order):
    """The damped steps of the windows ``p`` of a chunk: all at once block
    by block (:func:`~photogram.mocap.reconstruction.joint_blocks.solve_blocks`),
    or one window at a time (free points; or where a pivot of the blocks is
    not positive definite, so that the dense Cholesky decides)."""
    steps = np.zeros((len(p), H.shape[1]))
    solved = np.zeros(len(p), bool)
    A = H[p]
    A[:, np.arange(A.shape[1]), np.arange(A.shape[1])] += mu[:, None] * d[p] * m[p]
    if not free and order is not None:
        try:
            return solve_blocks(A, rhs[p], nP, J, order), np.ones(len(p), bool)
        except (LinAlgError, np.linalg.LinAlgError):
            pass
    for n, k in enumerate(p):
        try:
            steps[n] = (_solve_free(A[n], rhs[k], T, J) if free
                        else _solve_dense(A[n], rhs[k]))
            solved[n] = True
        except (LinAlgError, np.linalg.LinAlgError):
            pass
    return steps, solved


@one_blas_thread
def solve_joint(batch: JointBatch, a, g, sigma2, lengths, lambda_rep, lambda_limbs,
                lambda_rot, max_iter=100, tol=1e-9, irls_first=5, step_tol=0.0,
                second_order=True):
    """Minimise the joint energy from coefficients ``a`` (nw, J, 3, K_Pi) and
    ``g`` (nw, C, 3, K_Gamma); returns (a, g, energies (nw,), iterations)."""
    a, g = a.copy(), g.copy()
    nw = a.shape[0]
    _, C, J, T, KP, KG = batch.sizes
    free = KP == T and np.array_equal(batch.obs.B, np.eye(T))
    nP = a[0].size
    args = (sigma2, lengths, lambda_rep, lambda_limbs, lambda_rot)
    limbs = tuple((int(x), int(y)) for x, y in np.asarray(batch.obs.limbs).reshape(-1, 2)) \
        if lambda_limbs else ()
    order = elimination_order(J, limbs) if J else None
    E = batch.energy(a, g, *args)
    mu = np.full(nw, 1e-3)
    active = np.ones(nw, bool)
    it = 0
    while active.any() and it < max_iter:
        it += 1
        corrected = second_order and it > irls_first
        for ids in _chunks(np.flatnonzero(active), nP + g[0].size):
            sub = batch.subset(ids)
            E0, H, rhs = sub.linearize(a[ids], g[ids], *args, second_order=corrected)
            m = _mask(sub, len(ids))
            H *= m[:, :, None] * m[:, None, :]
            rhs *= m
            d = np.einsum("wii->wi", H).copy()
            d += 1e-9 * d.max(axis=1, keepdims=True) + 1e-12
            H[:, np.arange(H.shape[1]), np.arange(H.shape[1])] += 1.0 - m
            accepted = np.zeros(len(ids), bool)
            pending = np.ones(len(ids), bool)
            new_a, new_g, new_E = a[ids].copy(), g[ids].copy(), E0.copy()
            for _ in range(12):
                p = np.flatnonzero(pending)
                steps, solved = _steps(H, rhs, d, m, mu[ids[p]], p, free, T, J, nP, order)
                ta = a[ids[p]] + steps[:, :nP].reshape(a[ids[p]].shape)
                tg = g[ids[p]] + steps[:, nP:].reshape(g[ids[p]].shape)
                E1 = sub.subset(p).energy(ta, tg, *args)
                ok = solved & (E1 <= E0[p])
                new_a[p[ok]], new_g[p[ok]], new_E[p[ok]] = ta[ok], tg[ok], E1[ok]
                if not damping_update(mu, ids, p, ok, accepted, pending):
                    break
            moved = moved_positions(sub.obs, new_a - a[ids])
            a[ids], g[ids] = new_a, new_g
            rel = (E0 - new_E) / np.maximum(np.abs(E0), 1e-300)
            E[ids] = new_E
            done = (accepted & ((rel < tol) | (moved < step_tol))) | ~accepted
            if second_order and it <= irls_first:
                done[:] = False
            active[ids[done]] = False
    return a, g, E, it


@one_blas_thread
def solve_joint_lbfgs(batch: JointBatch, a, g, sigma2, lengths, lambda_rep, lambda_limbs,
                      lambda_rot, max_iter=1500, tol=1e-12):
    """The paper's solver for comparison: L-BFGS (scipy, ``maxcor`` 20) on
    the sum of the window energies with the analytic gradient (``-2 rhs`` of
    :meth:`JointBatch.linearize` without the matrix), ``max_iter``
    iterations (the paper ran 1500); returns (a, g, energies, iterations)."""
    from scipy.optimize import minimize
    nw = a.shape[0]
    nP = a[0].size
    mask = _mask(batch, nw)
    args = (sigma2, lengths, lambda_rep, lambda_limbs, lambda_rot)

    def split(x):
        x = x.reshape(nw, -1)
        return x[:, :nP].reshape(a.shape), x[:, nP:].reshape(g.shape)

    def fun(x):
        E, _, rhs = batch.linearize(*split(x), *args, second_order=False, hessian=False)
        return float(np.sum(E)), (-2.0 * rhs * mask).ravel()

    x0 = np.concatenate([a.reshape(nw, -1), g.reshape(nw, -1)], axis=1).ravel()
    res = minimize(fun, x0, jac=True, method="L-BFGS-B",
                   options={"maxiter": max_iter, "maxcor": 20, "ftol": tol, "gtol": 1e-12,
                            "maxfun": 2 * max_iter})
    a1, g1 = split(res.x)
    return a1, g1, batch.energy(a1, g1, *args), int(res.nit)
