"""Robust estimation by iteratively reweighted least squares (IRLS), the
loss functions of Ceres: Huber, Cauchy and soft-L1 on whitened residuals
(in units of their a-priori sigma).
"""

from __future__ import annotations

import numpy as np

from photogram.adjust.solver import solve

LOSSES = ("huber", "cauchy", "soft_l1")


def loss_weights(u, loss="huber", scale=1.5):
    """IRLS weights ``rho'(s)`` for whitened residual norms ``u`` (per
    observation record), with ``s = u^2`` and scale ``k``:

    huber  : 1 for u <= k, k/u beyond
    cauchy : 1 / (1 + (u/k)^2)
    soft_l1: 1 / sqrt(1 + (u/k)^2)
    """
    u = np.abs(np.asarray(u, dtype=float))
    t = u / scale
    if loss == "huber":
        return np.where(t <= 1.0, 1.0, 1.0 / np.maximum(t, 1e-300))
    if loss == "cauchy":
        return 1.0 / (1.0 + t * t)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + t * t)
    raise ValueError(f"unknown robust loss {loss!r}; known: {', '.join(LOSSES)}")


def robust_reweighting(problem, loss="huber", options=None, scale=1.5, blocks=("image points",),
                       max_rounds=20, tol=1e-3):
    """IRLS on the residual blocks named in ``blocks``; the weight of an
    image point depends on the norm of its whitened 2D residual.

    Returns a summary dict (rounds, number of down-weighted observations).
    """
    rounds = 0
    for rounds in range(1, max_rounds + 1):
        problem.robust_weight = [np.ones((len(b), b.dim)) for b in problem.blocks]
        rs, _ = problem.evaluate(problem.state, jacobians=False)
        changed = 0.0
        new = []
        for k, (blk, r) in enumerate(zip(problem.blocks, rs)):
            if blk.name in blocks:
                w = loss_weights(np.linalg.norm(r, axis=1), loss, scale)
                new.append(np.repeat(w[:, None], blk.dim, axis=1))
            else:
                new.append(np.ones((len(blk), blk.dim)))
        for k, w in enumerate(new):
            old = getattr(problem, "_last_robust", None)
            if old is not None:
                changed = max(changed, float(np.max(np.abs(old[k] - w), initial=0.0)))
        problem.robust_weight = new
        problem._last_robust = new
        solve(problem, options)
        if rounds > 1 and changed < tol:
            break
    down = int(sum(np.count_nonzero(w[:, 0] < 1.0) for w, b in zip(problem.robust_weight, problem.blocks)
                   if b.name in blocks))
    return {"loss": loss, "scale": scale, "rounds": rounds, "downweighted": down}
