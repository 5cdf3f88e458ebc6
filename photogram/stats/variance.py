"""Variance-component estimation for groups of observations.

Iterated as in appendix D.3 of the ski-jump paper, generalized to any
number of groups (Förstner's simplified estimator): for group g with
weighted sum of squares ``Omega_g = v_g^T P_g v_g`` and partial redundancy
``r_g = sum of the redundancy numbers of its observations``, the variance
factor is ``s_g^2 = Omega_g / r_g``; the weights of the group are divided by
``s_g^2`` and the adjustment repeated until every factor is 1 within a
tolerance. The product of the factors is the estimated variance of unit
weight of each group.
"""

from __future__ import annotations

import numpy as np

from photogram.adjust.solver import solve
from photogram.stats.reliability import redundancy_numbers


def group_factors(problem):
    """Current ``(Omega_g, r_g, s_g^2)`` per variance group."""
    red = redundancy_numbers(problem)
    rs, _ = problem.evaluate(problem.state, jacobians=False)
    out = {}
    for blk, r, rn in zip(problem.blocks, rs, red):
        om, rg = out.get(blk.group, (0.0, 0.0, None))[:2]
        out[blk.group] = (om + float(np.sum(r * r)), rg + float(np.sum(rn)), None)
    return {g: (om, rg, om / rg if rg > 1e-9 else float("nan")) for g, (om, rg, _) in out.items()}


def estimate_variance_components(problem, options=None, max_rounds=20, tol=0.01):
    """Iterate variance components to convergence, updating
    ``problem.variance`` (the variance factor of each group, relative to its
    a-priori sigmas) in place.

    Groups with too little redundancy (r_g < 1) keep their a-priori weight.

    Returns
    -------
    history : list of dict group -> s_g^2 (one per round)
    """
    history = []
    for _ in range(max_rounds):
        factors = group_factors(problem)
        step = {g: f for g, (_, rg, f) in factors.items() if rg >= 1.0 and np.isfinite(f) and f > 0}
        history.append({g: problem.variance[g] * f for g, f in step.items()})
        if all(abs(f - 1.0) < tol for f in step.values()):
            break
        for g, f in step.items():
            problem.variance[g] *= f
        solve(problem, options)
    return history
