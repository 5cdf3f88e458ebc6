"""A small dense robust least-squares solver: Levenberg-Marquardt with a
soft-L1 loss and box bounds (:func:`robust_lm`), for the fits of a dozen
parameters to a few hundred or thousand pixels in
:mod:`photogram.track.ski_edges` (the two-bar model of its eqs. (1), (2)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LMResult", "robust_lm"]


@dataclass
class LMResult:
    """Result of :func:`robust_lm`: the solution ``x``, the residuals
    ``fun`` and Jacobian ``jac`` there, iterations and ``status`` (> 0
    converged, 0 the iteration limit, < 0 failed) with a message."""

    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray
    nit: int
    status: int
    message: str


def robust_lm(fun, jac, x0, lower, upper, *, f_scale: float = 1.0, max_iter: int = 60,
              xtol: float = 1e-6, ftol: float = 1e-8) -> LMResult:
    """Levenberg-Marquardt with a soft-L1 loss and box bounds, for the small
    dense fits of this module (a dozen parameters, a few thousand pixels).

    The soft-L1 cost ``sum 2 f^2 (sqrt(1 + (r/f)^2) - 1)`` (scipy's
    ``loss="soft_l1"``) is minimised by iteratively reweighted Gauss-Newton
    (weights ``1 / sqrt(1 + (r/f)^2)``, Triggs et al. 2000, sec. 6.8) with
    Marquardt's damping of the diagonal (scale invariant, as
    ``x_scale="jac"``); parameters on a bound that the gradient pushes
    outwards are held there for the step (an active set), the rest of a
    step leaving the box is projected onto it; a step
    that does not lower the cost is refused and the damping raised.
    scipy.optimize.least_squares(method="trf") solves the same problem with
    an SVD per iteration, which for these sizes costs more than the model.

    Parameters
    ----------
    fun, jac : callable
        Residuals ``(m,)`` and their Jacobian ``(m, n)`` of the parameters.
    x0, lower, upper : ndarray (n,)
    f_scale : float
        Soft-L1 scale (residuals below it count as least squares).
    max_iter : int
    xtol, ftol : float
        Stop when a step moves every parameter by less than ``xtol`` times
        (its size + xtol), or lowers the cost by less than ``ftol`` of it.

    Returns
    -------
    LMResult
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    x = np.clip(np.asarray(x0, float), lower, upper)
    inv_f2, two_f2 = 1.0 / (f_scale * f_scale), 2.0 * f_scale * f_scale

    def loss_terms(r):
        # sqrt(1 + (r/f)^2): the reciprocal weights, and the cost
        q = np.sqrt(r * r * inv_f2 + 1.0)
        return q, two_f2 * (float(q.sum()) - q.size)

    r = fun(x)
    q, cost = loss_terms(r)
    lam = 1e-3
    status, msg, it = 0, "iteration limit", 0
    J = jac(x)
    for it in range(1, max_iter + 1):
        Jw = J * (1.0 / q)[:, None]
        A = Jw.T @ J
        g = Jw.T @ r
        d = np.maximum(A.diagonal(), 1e-12)
        # parameters on a bound that the descent pushes outwards stay there
        held = ((x <= lower) & (g > 0)) | ((x >= upper) & (g < 0))
        free = None if not held.any() else ~held
        if free is None:
            Af, gf, df = A, g, d
        else:
            Af, gf, df = A[np.ix_(free, free)], g[free], d[free]
        accepted = False
        while lam < 1e10:
            M = Af + np.diag(lam * df)
            try:
                sf = np.linalg.solve(M, -gf)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            if free is None:
                xn = x + sf
            else:
                xn = x.copy()
                xn[free] += sf
            xn = np.minimum(np.maximum(xn, lower), upper)
            rn = fun(xn)
            qn, cn = loss_terms(rn)
            if cn <= cost:              # False for nan
                accepted = True
                break
            lam *= 10
        if not accepted:
            status, msg = 2, "no step lowers the cost"
            break
        moved = np.abs(xn - x)
        drop = cost - cn
        x, r, q, cost = xn, rn, qn, cn
        J = jac(x)
        lam = max(lam * 0.3, 1e-12)
        if np.all(moved <= xtol * (np.abs(x) + xtol)):
            status, msg = 3, "xtol"
            break
        if drop <= ftol * cost:
            status, msg = 2, "ftol"
            break
    # the Jacobian of the reweighted problem at the solution (J^T W J the
    # Gauss-Newton normal matrix of the robust cost)
    return LMResult(x, r, J * np.sqrt(1.0 / q)[:, None], it, status, msg)
