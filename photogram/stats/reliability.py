"""Redundancy numbers, standardized residuals and Baarda's data snooping.

For whitened observations (unit a-priori weight) the redundancy number of
observation i is ``r_i = 1 - (J Q J^T)_ii`` with Q the cofactor matrix of the
unknowns; the normalized residual (w-test statistic) is
``w_i = e_i / (sigma_i sqrt(r_i))``, compared with the two-sided normal
quantile of the significance level alpha (Baarda 1968).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm

from photogram.adjust.solver import solve
from photogram.stats.covariance import cofactors


def redundancy_numbers(problem, cof=None):
    """Redundancy number of every residual of every block: list of (N, d)
    arrays (0 for observations that are not used)."""
    cof = cof if cof is not None else cofactors(problem)
    _, Js = problem.evaluate(problem.state)
    out = []
    for k, (blk, J) in enumerate(zip(problem.blocks, Js)):
        h = np.zeros((len(blk), blk.dim))
        for a, (Ja, ca) in enumerate(zip(J, blk.slot_cols)):
            for b, (Jb, cb) in enumerate(zip(J, blk.slot_cols)):
                Q = cof.block(ca, cb)
                h += np.einsum("nda,nab,ndb->nd", Ja, Q, Jb)
        used = problem.weights(k) > 0
        out.append(np.where(used, 1.0 - h, 0.0))
    return out


def normalized_residuals(problem, redundancy):
    """w-test statistics (N, d) per block: whitened residual / sqrt(r)."""
    rs, _ = problem.evaluate(problem.state, jacobians=False)
    out = []
    for r, red in zip(rs, redundancy):
        with np.errstate(divide="ignore", invalid="ignore"):
            w = r / np.sqrt(red)
        out.append(np.where(red > 1e-10, w, 0.0))
    return out


@dataclass
class SnoopingResult:
    alpha: float
    critical_value: float
    rejected: list = field(default_factory=list)   # dicts: block, row, label, w
    rounds: int = 0


def data_snooping(problem, alpha=0.001, max_rejections=None, options=None, blocks=("image points",)):
    """Iterative data snooping: while the largest |w| among the tested blocks
    exceeds the critical value, deactivate that observation (the whole
    record, e.g. both coordinates of an image point) and readjust.

    Returns
    -------
    SnoopingResult
    """
    k_crit = float(norm.ppf(1.0 - alpha / 2.0))
    result = SnoopingResult(alpha, k_crit)
    limit = max_rejections if max_rejections is not None else max(
        1, sum(len(b) for b in problem.blocks) // 10)
    while len(result.rejected) < limit:
        red = redundancy_numbers(problem)
        w = normalized_residuals(problem, red)
        best = (0.0, None, None)
        for k, blk in enumerate(problem.blocks):
            if blk.name not in blocks or not problem.active[k].any():
                continue
            aw = np.abs(w[k]).max(axis=1) * problem.active[k]
            i = int(np.argmax(aw))
            if aw[i] > best[0]:
                best = (float(aw[i]), k, i)
        if best[1] is None or best[0] <= k_crit:
            break
        _, k, i = best
        problem.active[k][i] = False
        blk = problem.blocks[k]
        label = blk.labels[i] if getattr(blk, "labels", None) is not None else i
        result.rejected.append({"block": blk.name, "row": i, "label": label, "w": best[0]})
        result.rounds += 1
        solve(problem, options)
    return result
