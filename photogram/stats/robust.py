"""Robust estimation by iteratively reweighted least squares (IRLS), the
loss functions of Ceres: Huber, Cauchy and soft-L1, and Tukey's biweight, on
whitened residuals (in units of their a-priori sigma, or of a robust scale
estimated from the residuals: ``scale_estimate="mad"``).

:func:`robust_cleaning` turns the robust fit into a decision: it flags the
observations the robust solution does not fit (normalized residual beyond
the critical value of ``alpha``), removes them and readjusts by least
squares, then puts back those whose predicted residual passes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtri

from photogram.adjust.solver import solve
from photogram.project.model import ROBUST_FUNCTIONS

#: the losses (the same list as the project reader accepts)
LOSSES = ROBUST_FUNCTIONS

# tuning constants for 95 % efficiency under normal errors (in sigma)
TUNING = {"huber": 1.345, "cauchy": 2.385, "soft_l1": 1.5, "tukey": 4.685}
# robust_reweighting's default (in a-priori sigma): 1.5 as before; Tukey's
# biweight rejects everything beyond its constant, so it keeps its own
DEFAULT_SCALE = {"huber": 1.5, "cauchy": 1.5, "soft_l1": 1.5, "tukey": 4.685}


def loss_weights(u, loss="huber", scale=1.5):
    """IRLS weights ``rho'(s)`` for whitened residual norms ``u`` (per
    observation record), with ``s = u^2`` and scale ``k``:

    huber  : 1 for u <= k, k/u beyond
    cauchy : 1 / (1 + (u/k)^2)
    soft_l1: 1 / sqrt(1 + (u/k)^2)
    tukey  : (1 - (u/k)^2)^2 for u <= k, 0 beyond (redescending)
    """
    u = np.abs(np.asarray(u, dtype=float))
    t = u / scale
    if loss == "huber":
        return np.where(t <= 1.0, 1.0, 1.0 / np.maximum(t, 1e-300))
    if loss == "cauchy":
        return 1.0 / (1.0 + t * t)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + t * t)
    if loss == "tukey":
        return np.where(t < 1.0, (1.0 - t * t) ** 2, 0.0)
    raise ValueError(f"unknown robust loss {loss!r}; known: {', '.join(LOSSES)}")


def _mad_scale(norms, dim):
    """Normalized MAD of whitened residual norms of ``dim``-vectors: the
    median of a chi(dim) variable is 1.1774 for dim 2, 0.6745 for dim 1."""
    med = {1: 0.6745, 2: 1.1774, 3: 1.5382}.get(dim, np.sqrt(dim))
    return float(np.median(norms) / med) if len(norms) else 1.0


def robust_reweighting(problem, loss="huber", options=None, scale=None, blocks=("image points",),
                       max_rounds=20, tol=1e-3, scale_estimate=None, warm_start=None):
    """IRLS on the residual blocks named in ``blocks``; the weight of an
    image point depends on the norm of its whitened 2D residual.

    ``scale`` is the tuning constant of the loss in sigma (default
    :data:`DEFAULT_SCALE`); with
    ``scale_estimate="mad"`` the sigma is re-estimated every round as the
    normalized median absolute residual of the active observations of the
    tested blocks (robust against the outliers and against wrong a-priori
    sigmas), otherwise it is the a-priori sigma. ``warm_start`` (e.g.
    ``"huber"``) runs that (monotone) loss first, which keeps a
    redescending loss (tukey, cauchy) away from the least-squares start
    that the blunders have pulled.

    Returns a summary dict (rounds, number of down-weighted observations,
    final scale).
    """
    if warm_start and warm_start != loss:
        robust_reweighting(problem, warm_start, options, TUNING.get(warm_start, scale), blocks,
                           max_rounds, tol, scale_estimate)
    if loss not in LOSSES:
        raise ValueError(f"unknown robust loss {loss!r}; known: {', '.join(LOSSES)}")
    scale = DEFAULT_SCALE[loss] if scale is None else scale
    rounds = 0
    sigma = 1.0
    old = None
    for rounds in range(1, max_rounds + 1):
        saved = problem.robust_weight
        problem.robust_weight = [np.ones((len(b), b.dim)) for b in problem.blocks]
        rs, _ = problem.evaluate(problem.state, jacobians=False)
        problem.robust_weight = saved
        norms = [np.linalg.norm(r, axis=1) for r in rs]
        if scale_estimate == "mad":
            sel = [n[problem.active[k]] for k, (b, n) in enumerate(zip(problem.blocks, norms))
                   if b.name in blocks]
            sigma = _mad_scale(np.concatenate(sel) if sel else np.zeros(0),
                               next((b.dim for b in problem.blocks if b.name in blocks), 2))
        elif scale_estimate is not None:
            raise ValueError(f"scale_estimate must be None or 'mad', not {scale_estimate!r}")
        new = []
        for k, (blk, n) in enumerate(zip(problem.blocks, norms)):
            if blk.name in blocks:
                w = loss_weights(n, loss, scale * sigma)
                new.append(np.repeat(w[:, None], blk.dim, axis=1))
            else:
                new.append(np.ones((len(blk), blk.dim)))
        _keep_determined(problem, new, norms, blocks, scale * sigma)
        changed = (max(float(np.max(np.abs(o - w), initial=0.0)) for o, w in zip(old, new))
                   if old is not None else np.inf)
        problem.robust_weight = new
        problem._last_robust = new
        old = new
        solve(problem, options)
        if changed < tol:
            break
    down = int(sum(np.count_nonzero(w[:, 0] < 1.0) for w, b in zip(problem.robust_weight, problem.blocks)
                   if b.name in blocks))
    return {"loss": loss, "scale": scale, "rounds": rounds, "downweighted": down, "sigma": sigma}


def _keep_determined(problem, weights, norms, blocks, k, min_rays=2, min_station_points=4):
    """Give back a weight to the rays a redescending loss (Tukey) zeroed
    where that would leave a free object point with fewer than ``min_rays``
    weighted rays, or a station with fewer than ``min_station_points``
    weighted image points: such rays get the Huber weight ``k / u`` (a
    point with one blunder among its 3 rays cannot say which ray is bad;
    with weight 0 on all of them it would be undetermined). ``weights``
    (per block, (N, d)) is changed in place."""
    lay = problem.layout
    img = [kk for kk, b in enumerate(problem.blocks)
           if b.name in blocks and hasattr(b, "point") and hasattr(b, "station")]
    if not img:
        return
    n_p, n_s = len(lay.point_cols), len(lay.station_cols)
    rays = np.zeros(n_p, int)
    good_rays = np.zeros(n_p, int)
    pts = np.zeros(n_s, int)
    good_pts = np.zeros(n_s, int)
    for kk in img:
        b, act = problem.blocks[kk], problem.active[kk]
        good = act & (weights[kk][:, 0] > 0)
        rays += np.bincount(b.point[act], minlength=n_p)
        good_rays += np.bincount(b.point[good], minlength=n_p)
        pts += np.bincount(b.station[act], minlength=n_s)
        good_pts += np.bincount(b.station[good], minlength=n_s)
    free_p = lay.free[lay.point_cols].any(axis=1)
    free_s = lay.free[lay.station_cols].any(axis=1)
    weak_p = free_p & (good_rays < np.minimum(rays, min_rays))
    weak_s = free_s & (good_pts < np.minimum(pts, min_station_points))
    if not (weak_p.any() or weak_s.any()):
        return
    for kk in img:
        b, act = problem.blocks[kk], problem.active[kk]
        back = act & (weights[kk][:, 0] == 0) & (weak_p[b.point] | weak_s[b.station])
        if back.any():
            w = loss_weights(norms[kk][back], "huber", k)
            weights[kk][back] = w[:, None]


@dataclass
class CleaningResult:
    loss: str
    alpha: float
    critical_value: float
    sigma: float = 1.0                               # robust scale of the flagging test
    flagged: list = field(default_factory=list)      # dicts: block, row, label, w (removed)
    readmitted: list = field(default_factory=list)
    unremovable: list = field(default_factory=list)  # flagged, but needed for the geometry
    snooped: int = 0                                 # of ``flagged``: found by the final snooping
    irls: dict = field(default_factory=dict)


def robust_cleaning(problem, loss="huber", alpha=0.001, options=None, blocks=("image points",),
                    scale=None, scale_estimate="mad", warm_start="huber", readmit=True,
                    test_scale="aposteriori", swap_rays=4, final_snooping=True):
    """Robust estimation as a blunder detector, then a clean least-squares
    adjustment.

    1. IRLS with ``loss`` (tuning constant ``scale``, default
       :data:`TUNING`, in units of the MAD scale), after a Huber warm start
       for the redescending losses;
    2. flag every observation record whose residual at the robust solution,
       normalized by its a-priori sigma, the robust scale and the square root
       of its least-squares redundancy number, exceeds the two-sided normal
       quantile of ``alpha`` in either coordinate;
    3. remove the flagged observations, drop the robust weights and
       readjust by least squares;
    4. (``readmit``) test every flagged observation against that adjustment
       (predicted residual, variance ``1 + h``, scale ``test_scale`` as in
       :func:`photogram.stats.reliability.variance_scale`) and put back
       those that pass;
    5. (``swap_rays``) for flagged observations of points with at most that
       many remaining rays, try the point's other rays instead
       (:func:`photogram.stats.reliability.swap_within_points`);
    6. (``final_snooping``) data snooping on the cleaned adjustment (scale
       ``test_scale``, several rejections per round) catches what the robust
       fit left: a blunder whose ray was put back while another ray of its
       point was out.

    The problem ends as an ordinary (weights 1) least-squares adjustment
    without the flagged observations.
    """
    from photogram.stats.reliability import (
        _label, _readmit, SnoopingResult, redundancy_numbers, removable, swap_within_points)
    k_crit = float(ndtri(1.0 - alpha / 2.0))            # norm.ppf
    res = CleaningResult(loss, alpha, k_crit)
    red = redundancy_numbers(problem)            # least squares, before reweighting
    tune = scale if scale is not None else TUNING[loss]
    res.irls = robust_reweighting(problem, loss, options, tune, blocks, scale_estimate=scale_estimate,
                                  warm_start=warm_start if loss in ("tukey", "cauchy") else None)
    saved = problem.robust_weight
    problem.robust_weight = [np.ones((len(b), b.dim)) for b in problem.blocks]
    rs, _ = problem.evaluate(problem.state, jacobians=False)
    stats = []
    for k, (blk, r) in enumerate(zip(problem.blocks, rs)):
        if blk.name not in blocks:
            stats.append(None)
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(red[k] > 1e-10, r / np.sqrt(np.maximum(red[k], 1e-10)), 0.0)
        stats.append(w)
    act = [np.abs(w[problem.active[k]]).ravel() for k, w in enumerate(stats) if w is not None]
    act = np.concatenate(act) if act else np.zeros(0)
    res.sigma = float(np.median(act) / 0.6745) if len(act) else 1.0
    del saved
    cand = []
    for k, w in enumerate(stats):
        if w is None:
            continue
        t = np.abs(w).max(axis=1) / res.sigma
        cand += [(float(t[i]), k, int(i)) for i in np.flatnonzero((t > k_crit) & problem.active[k])]
    for t, k, i in sorted(cand, reverse=True):        # the worst first, over all blocks
        blk = problem.blocks[k]
        if not removable(problem, k, i):
            res.unremovable.append({"block": blk.name, "k": k, "row": i, "label": _label(blk, i), "w": t})
            continue
        problem.active[k][i] = False
        res.flagged.append({"block": blk.name, "k": k, "row": i, "label": _label(blk, i), "w": t})
    solve(problem, options)
    if readmit and res.flagged:
        snoop = SnoopingResult(alpha, k_crit, rejected=list(res.flagged))
        _readmit(problem, snoop, options, test_scale, blocks)
        res.flagged, res.readmitted = snoop.rejected, snoop.readmitted
    if swap_rays and res.flagged:
        swap_within_points(problem, res.flagged, options, swap_rays)
    if final_snooping:
        from photogram.stats.reliability import data_snooping
        snoop = data_snooping(problem, alpha, options=options, blocks=blocks, scale=test_scale,
                              per_round="point", readmit=readmit, swap_rays=swap_rays)
        res.flagged += snoop.rejected
        res.snooped = len(snoop.rejected)
    return res
