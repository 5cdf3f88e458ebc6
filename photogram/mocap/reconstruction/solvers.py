"""Solvers of the reconstruction energy on a batch of windows.

``solve_gauss_newton`` (the default)
    Gauss-Newton with IRLS weights and Triggs' second-order correction of
    the robust function (:meth:`photogram.mocap.reconstruction.energy.WindowBatch.linearize`).
    The continuation stages use the plain IRLS model (a majoriser: far from
    the solution the corrected model takes too long steps); the last stage
    starts with 5 IRLS iterations, which settle which detections are
    inliers, and then switches to the corrected model, which converges in
    far fewer iterations (with the corrected model from the start, 3 of the
    42 windows of the benchmark ended in a local minimum 2e-4 higher),
    until the relative energy decrease of an iteration falls below the
    tolerance or no determined position (``support``) moves by more than
    ``step_tol`` (10 micrometres; the trajectory of a joint in frames far from
    its detections may creep on for many iterations without changing the
    energy),
    Levenberg-Marquardt damping ``mu diag(H)`` per window (a step is
    accepted only if it lowers the window's energy; mu / 3 after a success,
    x 10 after a failure). The damped normal equations are solved
    approximately (relative residual 1e-3) by conjugate gradients
    preconditioned with the 3x3 diagonal block of every DCT coefficient;
    the normal matrix is applied matrix-free in the frame domain. A window
    stops when its relative energy decrease falls below the tolerance.
``solve_lbfgs``
    The paper's L-BFGS: ``scipy.optimize.minimize(method="L-BFGS-B")`` on
    the sum of the window energies with the analytic gradient
    (``maxcor`` 20, ``ftol`` = the tolerance).

Both work on all windows of a batch at once: no Python loop per window,
frame or observation.
"""

from __future__ import annotations

import numpy as np

from photogram.mocap.reconstruction.blas import one_blas_thread
from photogram.mocap.reconstruction.energy import Linearization, WindowBatch

__all__ = ["solve_gauss_newton", "solve_lbfgs", "damping_update", "moved_positions"]


def _inv3(A):
    """Inverses of 3x3 matrices stored as A[..., i, j, k] (k: batch, last);
    a singular block (a coefficient no term constrains: its determinant
    underflows to 0) gets 0, so that the preconditioner leaves it alone
    instead of filling the step with NaN (issue 22: NaN coefficients of an
    unobserved joint were accepted, the energy became NaN later)."""
    a, b, c = A[..., 0, 0, :], A[..., 0, 1, :], A[..., 0, 2, :]
    d, e, f = A[..., 1, 0, :], A[..., 1, 1, :], A[..., 1, 2, :]
    g, h, i = A[..., 2, 0, :], A[..., 2, 1, :], A[..., 2, 2, :]
    co = np.empty_like(A)
    co[..., 0, 0, :], co[..., 0, 1, :], co[..., 0, 2, :] = e * i - f * h, c * h - b * i, b * f - c * e
    co[..., 1, 0, :], co[..., 1, 1, :], co[..., 1, 2, :] = f * g - d * i, a * i - c * g, c * d - a * f
    co[..., 2, 0, :], co[..., 2, 1, :], co[..., 2, 2, :] = d * h - e * g, b * g - a * h, a * e - b * d
    det = a * co[..., 0, 0, :] + b * co[..., 1, 0, :] + c * co[..., 2, 0, :]
    ok = np.isfinite(det) & (det != 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(ok[..., None, None, :], co / np.where(ok, det, 1.0)[..., None, None, :],
                        0.0)


def _pcg(lin, damp, Pinv, rhs, tol=1e-3, max_iter=60):
    """Preconditioned conjugate gradients on (H + diag(damp)) x = rhs for
    all windows at once, restricted to the coefficients of ``lin.mask``;
    preconditioner: the 3x3 block per coefficient."""
    mask = lin.mask

    def prec(R):
        return (Pinv[:, :, :, 0] * R[:, :, None, 0] + Pinv[:, :, :, 1] * R[:, :, None, 1]
                + Pinv[:, :, :, 2] * R[:, :, None, 2]) * mask

    def dot(A, B):
        return np.sum(A * B, axis=(1, 2, 3))

    x = np.zeros_like(rhs)
    rhs = rhs * mask
    r = rhs.copy()
    z = prec(r)
    p = z.copy()
    rz = dot(r, z)
    r0 = np.sqrt(dot(rhs, rhs))
    live = r0 > 0
    for it in range(max_iter):
        Ap = (lin.matvec(p) + damp * p) * mask
        pAp = dot(p, Ap)
        alpha = np.where(live & (pAp > 0), rz / np.where(pAp > 0, pAp, 1.0), 0.0)
        x += alpha[:, None, None, None] * p
        r -= alpha[:, None, None, None] * Ap
        live &= np.sqrt(dot(r, r)) > tol * r0
        if not live.any():
            break
        z = prec(r)
        rz_new = dot(r, z)
        beta = np.where(live, rz_new / np.where(rz != 0, rz, 1.0), 0.0)
        p = z + beta[:, None, None, None] * p
        rz = rz_new
    return x, it + 1


@one_blas_thread
def solve_gauss_newton(batch: WindowBatch, a, sigma2, L, lam_rep, lam_limbs, max_iter, tol,
                        second_order=True, irls_first: int = 5, step_tol: float = 0.0):
    """IRLS Gauss-Newton / Levenberg-Marquardt, all windows at once; with
    ``second_order`` the first ``irls_first`` iterations still use the plain
    IRLS model (module doc)."""
    nw = a.shape[0]
    mu = np.full(nw, 1e-3)
    active = np.ones(nw, bool)
    E = batch.energy(a, sigma2, L, lam_rep, lam_limbs)
    it = 0
    while active.any() and it < max_iter:
        it += 1
        ids = np.flatnonzero(active)
        sub = batch.subset(ids)
        lin = sub.linearize(a[ids], sigma2, L, lam_rep, lam_limbs,
                            second_order and it > irls_first)
        E0 = lin.E
        D = lin.block_diagonal()                                   # (n, J, 3, 3, k)
        dd = np.stack([D[:, :, c, c] for c in range(3)], axis=2)   # (n, J, 3, k)
        floor = 1e-9 * dd.reshape(len(ids), -1).max(axis=1)[:, None, None, None] + 1e-300
        pending = np.ones(len(ids), bool)
        new_a, new_E = a[ids].copy(), E0.copy()
        accepted = np.zeros(len(ids), bool)
        for _ in range(12):
            p = np.flatnonzero(pending)
            damp = mu[ids[p]][:, None, None, None] * (dd[p] + floor[p])
            Dd = D[p].copy()
            for c in range(3):
                Dd[:, :, c, c] += damp[:, :, c]
            lp = _subset_lin(lin, p)
            step, _ = _pcg(lp, damp, _inv3(Dd), lin.rhs[p])
            trial = a[ids[p]] + step
            E1 = sub.subset(p).energy(trial, sigma2, L, lam_rep, lam_limbs)
            ok = E1 <= E0[p]
            new_a[p[ok]], new_E[p[ok]] = trial[ok], E1[ok]
            if not damping_update(mu, ids, p, ok, accepted, pending):
                break
        moved = moved_positions(sub, new_a - a[ids])
        a[ids] = new_a
        rel = (E0 - new_E) / np.maximum(np.abs(E0), 1e-300)
        E[ids] = new_E
        done = (accepted & ((rel < tol) | (moved < step_tol))) | (~accepted)
        done &= not second_order or it > irls_first
        active[ids[done]] = False
    return a, E, it


def damping_update(mu, ids, p, ok, accepted, pending) -> bool:
    """Levenberg-Marquardt bookkeeping after trial steps of the windows
    ``ids[p]`` (``ok``: lowered their energy): mu / 3 after a success, x 10
    after a failure, a window stays pending until it succeeds or mu reaches
    1e10. Returns whether any window is still pending."""
    accepted[p[ok]] = True
    mu[ids[p[ok]]] = np.maximum(mu[ids[p[ok]]] / 3.0, 1e-12)
    mu[ids[p[~ok]]] *= 10.0
    pending[p[ok]] = False
    pending &= mu[ids] < 1e10
    return bool(pending.any())


def moved_positions(batch: WindowBatch, step) -> np.ndarray:
    """Largest position change of a step per window, over the frames where
    each joint is determined (``batch.support``; all frames without it)."""
    d = np.abs(batch.positions(step)).max(axis=2)                 # (n, J, T)
    if batch.support is not None:
        d = np.where(batch.support, d, 0.0)
    return d.reshape(len(d), -1).max(axis=1)


def _subset_lin(lin, p):
    if len(p) == lin.M.shape[0]:
        return lin
    return Linearization(E=lin.E[p], M=lin.M[p], B=lin.B, rhs=lin.rhs[p], limbs=lin.limbs,
                     limb_u=None if lin.limb_u is None else lin.limb_u[p],
                     limb_w=lin.limb_w if np.isscalar(lin.limb_w) else lin.limb_w[p],
                     mask=lin.mask[p])


@one_blas_thread
def solve_lbfgs(batch: WindowBatch, a, sigma2, L, lam_rep, lam_limbs, max_iter, tol,
                second_order=None, step_tol=None):
    """The paper's L-BFGS on the sum of the window energies."""
    from scipy.optimize import minimize

    shape = a.shape
    keep = np.broadcast_to(batch.mask(shape[-1]), shape)

    def fun(x):
        E, G = batch.gradient(x.reshape(shape), sigma2, L, lam_rep, lam_limbs)
        return float(np.sum(E)), np.where(keep, G, 0.0).ravel()

    res = minimize(fun, a.ravel(), jac=True, method="L-BFGS-B",
                   options={"maxiter": 20 * max_iter, "maxcor": 20, "ftol": tol,
                            "gtol": 1e-12, "maxfun": 40 * max_iter})
    a = res.x.reshape(shape)
    return a, batch.energy(a, sigma2, L, lam_rep, lam_limbs), int(res.nit)
