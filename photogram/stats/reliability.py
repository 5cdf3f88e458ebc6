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
from scipy.special import chdtrc, ndtri

from photogram.adjust.solver import solve
from photogram.stats.covariance import cofactors
from photogram.stats.leverage import leverage_diagonal


def redundancy_numbers(problem, cof=None):
    """Redundancy number of every residual of every block: list of (N, d)
    arrays (0 for observations that are not used).

    Blockwise (:func:`photogram.stats.leverage.leverage_diagonal`): each
    row needs the cofactors of its own columns only, so the memory grows
    with the observations and points."""
    cof = cof if cof is not None else cofactors(problem)
    _, Js = problem.evaluate(problem.state)
    out = []
    for k, (blk, J) in enumerate(zip(problem.blocks, Js)):
        h = leverage_diagonal(cof, J, blk.slot_cols)
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


SCALES = ("apriori", "aposteriori", "robust")


def variance_scale(problem, w=None, scale="apriori", blocks=("image points",)):
    """The factor by which the a-priori sigmas are multiplied in the tests.

    ``"apriori"``: 1 (Baarda's w-test, the a-priori sigmas are trusted);
    ``"aposteriori"``: sigma0 of the current adjustment (Pope's tau test
    with the normal quantile; inflated while blunders remain);
    ``"robust"``: ``median(|w|) / 0.6745`` over the coordinates of the active
    observations of the tested blocks (the normalized MAD; barely moved by
    a few percent of blunders).
    """
    if scale == "apriori":
        return 1.0
    if scale == "aposteriori":
        rs, _ = problem.evaluate(problem.state, jacobians=False)
        r = problem.redundancy()
        return float(np.sqrt(sum(float(np.sum(x * x)) for x in rs) / r)) if r > 0 else 1.0
    if scale == "robust":
        vals = [np.abs(w[k][problem.active[k]]).ravel() for k, b in enumerate(problem.blocks)
                if b.name in blocks and problem.active[k].any()]
        vals = np.concatenate(vals) if vals else np.zeros(0)
        return float(np.median(vals) / 0.6745) if len(vals) else 1.0
    raise ValueError(f"unknown variance scale {scale!r}; known: {', '.join(SCALES)}")


def leverages(problem, cof, k, rows):
    """``h_i = diag(J Q J^T)`` (whitened by the a-priori sigmas and variance
    factors only, not by activity or robust weights) of the records ``rows``
    of block ``k``: (len(rows), d). For an observation that is not in the
    adjustment ``1 + h_i`` is the variance factor of its predicted residual."""
    blk = problem.blocks[k]
    rows = np.asarray(rows, dtype=int)
    _, J = blk.evaluate(problem.state)
    with np.errstate(divide="ignore"):
        wgt = 1.0 / (blk.sigma[rows] * np.sqrt(problem.variance[blk.group]))
    wgt = np.where(np.isfinite(wgt), wgt, 0.0)
    free = problem.layout.free
    Jw = [Ja[rows] * wgt[:, :, None] * free[ca[rows]][:, None, :]
          for Ja, ca in zip(J, blk.slot_cols)]
    return leverage_diagonal(cof, Jw, [ca[rows] for ca in blk.slot_cols])


@dataclass
class SnoopingResult:
    alpha: float
    critical_value: float
    rejected: list = field(default_factory=list)   # dicts: block, k (its index), row, label, w
    rounds: int = 0
    scale: float = 1.0                               # final variance scale of the tests
    readmitted: list = field(default_factory=list)   # dicts: block, row, label, w
    unremovable: list = field(default_factory=list)  # above the critical value, not removable


def removable(problem, k, i, min_rays=2, min_station_points=4):
    """Whether record ``i`` of image-point block ``k`` can be left out
    without leaving its object point with fewer than ``min_rays`` rays or its
    station with fewer than ``min_station_points`` image points (unless the
    point / station is fixed or has an active prior). A blunder in such an
    observation cannot be located by leaving it out (its redundancy is nil
    or nearly so)."""
    blk = problem.blocks[k]
    if not hasattr(blk, "point") or not hasattr(blk, "station"):
        return True
    lay = problem.layout
    p, st = int(blk.point[i]), int(blk.station[i])
    rays = pts = 0
    prior_p = prior_s = False
    for kk, b in enumerate(problem.blocks):
        act = problem.active[kk]
        if b.name == "image points":
            rays += int(np.count_nonzero(act & (b.point == p)))
            pts += int(np.count_nonzero(act & (b.station == st)))
        elif b.name == "control coordinates":
            prior_p |= bool(np.any(act & (b.point == p)))
        elif b.name == "station priors":
            prior_s |= bool(np.any(act & (b.station == st)))
    if lay.free[lay.point_cols[p]].any() and not prior_p and rays - 1 < min_rays:
        return False
    if lay.free[lay.station_cols[st]].any() and not prior_s and pts - 1 < min_station_points:
        return False
    return True


def _label(blk, i):
    return blk.labels[i] if getattr(blk, "labels", None) is not None else i


#: the block of reference (control) coordinates, tested coordinate by coordinate
CONTROL = "control coordinates"
AXES = "XYZ"


def _control_removable(problem, k, i, min_rays=2):
    """A reference coordinate of control point ``blk.point[i]`` can be left
    out when the point keeps at least ``min_rays`` active rays (the images
    then determine it)."""
    p = int(problem.blocks[k].point[i])
    rays = sum(int(np.count_nonzero(problem.active[kk] & (b.point == p)))
               for kk, b in enumerate(problem.blocks) if b.name == "image points")
    return rays >= min_rays


def _candidates(problem, w, s, k_crit, blocks, kept, result):
    """(|w|, block, row, coordinate) above the critical value: image points
    as records (coordinate -1, the larger |w| of x and y), control
    coordinates one by one (coordinate 0, 1, 2 = X, Y, Z)."""
    cands = []
    for k, blk in enumerate(problem.blocks):
        if blk.name not in blocks or not problem.active[k].any():
            continue
        if blk.name == CONTROL:
            aw = np.abs(w[k]) * (problem.active[k][:, None] & problem.coordinate_active[k]) / s
            rows = [(int(i), int(c), float(aw[i, c])) for i, c in zip(*np.nonzero(aw > k_crit))]
        else:
            aw = np.abs(w[k]).max(axis=1) * problem.active[k] / s
            rows = [(int(i), -1, float(aw[i])) for i in np.flatnonzero(aw > k_crit)]
        for i, c, wi in rows:
            if (k, i, c) in kept:
                continue
            ok = _control_removable(problem, k, i) if c >= 0 else removable(problem, k, i)
            if not ok:
                kept.add((k, i, c))
                label = f"{_label(blk, i)} {AXES[c]}" if c >= 0 else _label(blk, i)
                result.unremovable.append({"block": blk.name, "k": k, "row": i,
                                           "label": label, "w": wi})
                continue
            cands.append((wi, k, i, c))
    return _rays_before_control(problem, w, s, cands)


def _equivalent_w(T, dof):
    """The |w| of one coordinate with the same significance as the
    chi-square statistic ``T`` with ``dof`` degrees of freedom."""
    return float(0.0 - ndtri(chdtrc(dof, T) / 2.0))     # norm.isf(chi2.sf(T, dof) / 2)


def _rays_before_control(problem, w, s, cands):
    """A control coordinate candidate yields to a ray of its own point that
    explains the misfit at least as well: the ray's 2D statistic
    ``wx^2 + wy^2`` (chi-square, 2 degrees of freedom) as an equivalent
    one-coordinate |w| at least the coordinate's |w| (a blunder in a ray of
    a control point pulls the point, so a reference coordinate can show the
    largest single |w|). The candidate is then that ray."""
    out = []
    rays = {}
    for kk, b in enumerate(problem.blocks):
        if b.name == "image points":
            for i in np.flatnonzero(problem.active[kk]):
                rays.setdefault(int(b.point[i]), []).append((kk, int(i)))
    for wi, k, i, c in cands:
        if c >= 0:
            p = int(problem.blocks[k].point[i])
            best = None
            for kk, j in rays.get(p, []):
                weq = _equivalent_w(float(np.sum((w[kk][j] / s) ** 2)), 2)
                if weq >= wi and (best is None or weq > best[0]) and removable(problem, kk, j):
                    best = (weq, kk, j)
            if best is not None:
                k, i, c = best[1], best[2], -1
        if all((k, i, c) != (x[1], x[2], x[3]) for x in out):
            out.append((wi, k, i, c))
    return out


def _reject(problem, k, i, c, wi):
    """Take record ``i`` of block ``k`` (or only its coordinate ``c``) out;
    the rejection record."""
    blk = problem.blocks[k]
    if c < 0:
        problem.active[k][i] = False
        return {"block": blk.name, "k": k, "row": i, "label": _label(blk, i), "w": wi}
    problem.coordinate_active[k][i, c] = False
    return {"block": blk.name, "k": k, "row": i, "coordinate": AXES[c],
            "label": f"{_label(blk, i)} {AXES[c]}", "w": wi}


def _put_back(problem, rec):
    if "coordinate" in rec:
        problem.coordinate_active[rec["k"]][rec["row"], AXES.index(rec["coordinate"])] = True
    else:
        problem.active[rec["k"]][rec["row"]] = True


def data_snooping(problem, alpha=0.001, max_rejections=None, options=None,
                  blocks=("image points", CONTROL), scale="apriori", per_round="one",
                  readmit=False, swap_rays=0):
    """Iterative data snooping: while the largest |w| among the tested blocks
    exceeds the critical value, deactivate that observation (the whole
    record, e.g. both coordinates of an image point; a reference coordinate
    of a control point on its own, "M3 Z") and readjust.

    Image points and the reference (control) coordinates of the weighted
    datum are tested in the same w-test, each with its own redundancy
    number: a wrong control coordinate is named and taken out instead of
    the good rays of its point. A control coordinate is only taken out
    while its point keeps 2 rays.

    Parameters
    ----------
    alpha : float
        Significance level of one test (one coordinate); the critical value
        is the two-sided normal quantile.
    scale : "apriori" | "aposteriori" | "robust"
        What the a-priori sigmas are multiplied by in the test (see
        :func:`variance_scale`); recomputed every round. ``"apriori"`` is
        Baarda's w-test; the others suit data whose a-priori sigmas are off
        (CAMCAL: sigma0 1.6).
    per_round : "one" | "point"
        ``"one"``: the classical procedure, one rejection per readjustment.
        ``"point"``: every round rejects, among the observations above the
        critical value, the worst of each object point and station whose
        |w| is at least half the largest (a blunder spreads into the other
        rays of its point and the other points of its image, never by more
        than it shows itself); many fewer readjustments with many blunders.
    swap_rays : int
        For every rejected observation of an object point that keeps at
        most this many active rays, try rejecting each other ray of the
        point instead; keep the configuration of least cost. With three
        rays a blunder smears into the others and the largest |w| may be a
        good ray; 0 (default) skips this.
    readmit : bool
        After the rejections, test every rejected observation against the
        cleaned adjustment (predicted residual, variance ``1 + h``) and put
        back those below the critical value; repeated until nothing changes.

    Returns
    -------
    SnoopingResult
    """
    k_crit = float(ndtri(1.0 - alpha / 2.0))            # norm.ppf
    result = SnoopingResult(alpha, k_crit)
    kept = set()        # above the critical value but not removable
    limit = max_rejections if max_rejections is not None else max(
        1, sum(len(b) for b in problem.blocks) // 10)
    while len(result.rejected) < limit:
        red = redundancy_numbers(problem)
        w = normalized_residuals(problem, red)
        s = variance_scale(problem, w, scale, blocks)
        result.scale = s
        cands = _candidates(problem, w, s, k_crit, blocks, kept, result)
        if not cands:
            break
        cands.sort(reverse=True)
        if per_round == "one":
            chosen = cands[:1]
        elif per_round == "point":
            chosen, seen_pt, seen_st = [], set(), set()
            top = cands[0][0]
            for wi, k, i, c in cands:
                blk = problem.blocks[k]
                pt = ("p", int(blk.point[i])) if hasattr(blk, "point") else ("r", k, i)
                st = ("s", int(blk.station[i])) if hasattr(blk, "station") else ("r", k, i)
                if wi < 0.5 * top or pt in seen_pt or st in seen_st:
                    continue
                seen_pt.add(pt), seen_st.add(st)
                chosen.append((wi, k, i, c))
        else:
            raise ValueError(f"per_round must be 'one' or 'point', not {per_round!r}")
        chosen = chosen[:limit - len(result.rejected)]
        for wi, k, i, c in chosen:
            if c < 0 and not removable(problem, k, i):       # two of the chosen share a point
                continue
            result.rejected.append(_reject(problem, k, i, c, wi))
        result.rounds += 1
        solve(problem, options)
    if readmit and result.rejected:
        _readmit(problem, result, options, scale, blocks)
    if swap_rays and result.rejected:
        swap_within_points(problem, result.rejected, options, swap_rays)
    return result


def swap_within_points(problem, rejected, options, max_rays=4):
    """Local search for weakly separable blunders: for every rejected image
    point whose object point keeps at most ``max_rays`` active rays, try
    each other active ray of that point rejected instead (same number of
    observations); keep the swap that lowers the cost. ``rejected`` (dicts
    with k, row, label) is updated in place. Returns the number of swaps."""
    swaps = 0
    for rec in rejected:
        k, i = rec["k"], rec["row"]
        blk = problem.blocks[k]
        if not hasattr(blk, "point") or "coordinate" in rec:
            continue
        p = int(blk.point[i])
        others = [(kk, int(j)) for kk, b in enumerate(problem.blocks) if b.name == "image points"
                  for j in np.flatnonzero(problem.active[kk] & (b.point == p))]
        if not others or len(others) > max_rays:
            continue
        best = (problem.cost(problem.state), None, problem.state)
        start = problem.state
        for kk, j in others:
            problem.active[k][i] = True
            problem.active[kk][j] = False
            problem.state = start
            try:
                solve(problem, options)
                c = problem.cost(problem.state)
            except Exception:       # the swap leaves something undetermined
                c = np.inf
            if c < best[0] * (1 - 1e-9):
                best = (c, (kk, j), problem.state)
            problem.active[kk][j] = True
            problem.active[k][i] = False
        problem.state = best[2]
        if best[1] is not None:
            kk, j = best[1]
            problem.active[k][i] = True
            problem.active[kk][j] = False
            rec.update({"k": kk, "row": j, "block": problem.blocks[kk].name,
                        "label": _label(problem.blocks[kk], j), "swapped_from": rec["label"]})
            swaps += 1
    if swaps:
        solve(problem, options)
    return swaps


def _readmit(problem, result, options, scale, blocks, max_rounds=20):
    """Put back rejected observations whose predicted residual passes."""
    for _ in range(max_rounds):
        cof = cofactors(problem)
        red = redundancy_numbers(problem, cof)
        w = normalized_residuals(problem, red)
        s = variance_scale(problem, w, scale, blocks)
        back = []
        by_block = {}
        for j, rej in enumerate(result.rejected):
            k = rej["k"]
            by_block.setdefault(k, []).append(j)
        for k, js in by_block.items():
            blk = problem.blocks[k]
            rows = np.array([result.rejected[j]["row"] for j in js])
            e, _ = blk.evaluate(problem.state, jacobians=False)
            with np.errstate(divide="ignore"):
                wgt = 1.0 / (blk.sigma[rows] * np.sqrt(problem.variance[blk.group]))
            h = leverages(problem, cof, k, rows)
            t = np.abs(e[rows] * wgt) / np.sqrt(1.0 + h) / s
            for j, tj in zip(js, t):
                rec = result.rejected[j]
                tj = tj[AXES.index(rec["coordinate"])] if "coordinate" in rec else tj.max()
                if tj < result.critical_value:
                    back.append((j, k, float(tj)))
        if not back:
            break
        # one per object point and round, the best fitting first: two
        # rejected rays of one point each look fine while the other is out
        back.sort(key=lambda x: x[2])
        seen, keep = set(), []
        for j, k, tj in back:
            blk = problem.blocks[k]
            pt = int(blk.point[result.rejected[j]["row"]]) if hasattr(blk, "point") else ("r", k, j)
            if pt in seen:
                continue
            seen.add(pt)
            keep.append((j, k, tj))
        back = keep
        for j, k, tj in back:
            _put_back(problem, result.rejected[j])
            result.readmitted.append(dict(result.rejected[j], w=tj))
        drop = {j for j, _, _ in back}
        result.rejected = [r for j, r in enumerate(result.rejected) if j not in drop]
        solve(problem, options)
