"""The tracked ski lines of one view as a sequence: what the exposures say
about each other (issue 19, item 4).

A ski's image direction changes smoothly from exposure to exposure (30 fps,
a flight of under a second): per station and ski the directions of the
sampled axes are fitted by a low-degree polynomial in time, weighted by
their sigmas. This temporal redundancy gives

* **honest sigmas**: the variance factor ``s0^2 = sum (r / sigma)^2 /
  (n - degree - 1)`` of the fit (the a posteriori variance factor of a
  least-squares adjustment, with the exposures as the redundancy) scales
  the sigmas of that ski's points by ``s0`` where it is above 1: the image
  fit's own covariance does not see its model errors (motion blur, a ski
  along the suit); it is never scaled down;
* **outliers**: an axis whose direction is off the sequence by more than
  ``k_out`` times its scaled sigma (robustly: iteratively, the worst first)
  is flagged, and so is an axis much shorter than the ski's median length
  in that view (a fit to a piece of the ski);
* **labels** where nothing else decides them (the three-view check cannot
  separate the skis in a view, or sees fewer than three views): the two
  skis of a view differ in direction (the V), and each ski's direction
  follows its own sequence, so the view's axes are compared with both
  sequences at its time, as labelled and interchanged; a clear winner is
  taken, otherwise the view is flagged (continuity, not a guess).

The direction of the points of one axis is that of their principal axis;
its sigma is that of a line fitted to ``n`` points of sigma ``s`` spread
along ``t`` (centred): ``s / sqrt(sum t^2)``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["axis_directions", "sequence_check"]


def axis_directions(table: pd.DataFrame) -> pd.DataFrame:
    """Per ``(exposure, station, line)`` of a ski table (``x, y, sigma``
    points, tail to tip): ``angle`` (rad, of the principal axis oriented
    tail to tip), ``sigma_angle`` (rad) and ``length`` (px, between the
    outermost points)."""
    rows = []
    # the rows of each group by position (the groups in order of first
    # appearance, as groupby(sort=False)), the arrays taken once
    XY = table[["x", "y"]].to_numpy(float)
    sig = table["sigma"].to_numpy()
    keys = ["exposure", "station", "line"]
    K = table[keys].to_numpy(object)
    for idx in _positions(table.groupby(keys, sort=False)):
        e, s, lab = K[idx[0]]
        # column-major, as pandas gives a group's columns: the same
        # summation order in the mean below, the same bits
        xy = np.asfortranarray(XY[idx])
        if len(xy) < 2:
            continue
        c = xy.mean(0)
        _, _, vt = np.linalg.svd(xy - c)
        u = vt[0] if vt[0] @ (xy[-1] - xy[0]) >= 0 else -vt[0]
        t = (xy - c) @ u
        rows.append((e, s, lab, float(np.arctan2(u[1], u[0])),
                     float(sig[idx[0]] / np.sqrt(max((t * t).sum(), 1e-12))),
                     float(np.ptp(t))))
    return pd.DataFrame(rows, columns=["exposure", "station", "line", "angle", "sigma_angle",
                                       "length"])


def _positions(gb) -> list:
    """Row positions of each group of ``gb`` (a DataFrameGroupBy), in the
    order its iteration yields the groups (``ngroup``'s numbers; rows of a
    missing key left out)."""
    if gb.ngroups == 0:
        return []
    ids = gb.ngroup().to_numpy()
    order = np.argsort(ids, kind="stable")
    cuts = np.cumsum(np.bincount(ids[ids >= 0], minlength=gb.ngroups))[:-1]
    return np.split(order[ids[order] >= 0], cuts)


def _fit(t, a, s, degree):
    """Weighted polynomial fit: residuals, degree used, coefficients and
    their covariance for sigmas ``s`` (unscaled)."""
    deg = min(degree, len(t) - 1)
    if deg >= 1 and len(t) > deg + 1:
        coef, cov = np.polyfit(t, a, deg, w=1 / s, cov="unscaled")
    else:
        coef = np.polyfit(t, a, deg, w=1 / s)
        V = np.vander(t, deg + 1) / s[:, None]
        cov = np.linalg.pinv(V.T @ V)
    return a - np.polyval(coef, t), deg, coef, cov


def _predict(fit, t):
    """Predicted direction and its sigma at time ``t``."""
    coef, cov, scale = fit
    v = np.vander(np.atleast_1d(float(t)), len(coef))[0]
    return float(v @ coef), float(np.sqrt(max(v @ cov @ v, 0.0)) * scale)


def _screen(dirs, order, *, degree, k_out, min_length_fraction, min_redundancy):
    """Short axes and direction outliers of every station and ski of
    ``dirs`` (:func:`axis_directions`), the variance factors and the fits
    of the sequences. Returns (dropped keys, flags, factors DataFrame,
    fits {(station, line): (coef, cov, scale, reference angle)})."""
    drop, flags, report = set(), [], []
    fit_of = {}
    for (s, lab), g in dirs.groupby(["station", "line"], sort=False):
        med = float(np.median(g["length"]))
        short = g["length"] < min_length_fraction * med
        for e, L in zip(g["exposure"][short], g["length"][short]):
            drop.add((e, s, lab))
            flags.append((e, s, lab, f"ski imaged {L:.3g} px long, less than "
                                     f"{min_length_fraction:g} of its median {med:.3g} px "
                                     "in this view"))
        g = g[~short]
        t = np.array([order[e] for e in g["exposure"]], float)
        a = np.unwrap(g["angle"].to_numpy(float))
        sig = g["sigma_angle"].to_numpy(float)
        names = g["exposure"].to_numpy()
        keep = np.ones(len(t), bool)
        s0, outliers = 1.0, 0
        while keep.sum() >= degree + 1 + min_redundancy:
            r, deg, _, _ = _fit(t[keep], a[keep], sig[keep], degree)
            z = r / sig[keep]
            dof = keep.sum() - deg - 1
            robust = max(1.0, 1.4826 * float(np.median(np.abs(z))))
            worst = int(np.argmax(np.abs(z)))
            if abs(z[worst]) > k_out * robust:
                i = np.nonzero(keep)[0][worst]
                keep[i] = False
                outliers += 1
                drop.add((names[i], s, lab))
                flags.append((names[i], s, lab,
                              f"direction {np.degrees(abs(r[worst])):.2g} deg off the "
                              f"sequence of this ski in this view ({abs(z[worst]):.3g} "
                              f"sigmas, {k_out:g} x {robust:.2g} allowed)"))
                continue
            s0 = float(np.sqrt((z ** 2).sum() / dof))
            break
        scale = max(1.0, s0)
        if keep.sum() >= 2:
            _, _, coef, cov = _fit(t[keep], a[keep], sig[keep], min(degree, keep.sum() - 2))
            fit_of[(s, lab)] = (coef, cov, scale, float(np.median(a[keep])))
        report.append((s, lab, int(keep.sum()), s0, scale, outliers))

    factors = pd.DataFrame(report, columns=["station", "line", "n", "s0", "scale", "outliers"])
    return drop, flags, factors, fit_of


def _axis_cost(r, fit, t) -> float:
    """Chi-square (1 dof) of one axis' direction (a row of
    :func:`axis_directions`) against a ski's sequence ``fit`` (coef, cov,
    scale, reference angle) at time ``t``: sigmas of the measurement
    (scaled as the sequence's) and of the prediction."""
    coef, cov, scale, ref = fit
    pred, sp = _predict((coef, cov, scale), t)
    # the measured angle on the branch of the sequence
    ang = ref + np.angle(np.exp(1j * (r.angle - ref)))
    sm = r.sigma_angle * scale
    return float((ang - pred) ** 2 / (sm ** 2 + sp ** 2))


def sequence_check(table: pd.DataFrame, exposures, *, degree: int = 3, k_out: float = 4.0,
                   min_length_fraction: float = 0.5, min_redundancy: int = 3,
                   pending: dict | None = None, alpha: float = 0.001):
    """Scale and screen the ski points of each station and ski by their
    sequence (module doc), and decide the labels of pending views.

    Parameters
    ----------
    table : DataFrame
        ``exposure, station, line, x, y, sigma`` (the tracked ski points).
    exposures : sequence
        The exposure names in time order (their index is the time).
    degree : int
        Degree of the polynomial in time.
    k_out : float
        Outlier threshold in scaled sigmas.
    min_length_fraction : float
        An axis shorter than this share of the median length of that ski in
        that view is flagged.
    min_redundancy : int
        Fewer exposures than ``degree + 1 + min_redundancy`` in a sequence:
        no scaling and no outlier test (too little redundancy).
    pending : dict {(exposure, station): str}, optional
        Views whose labels nothing else decided (the three-view check could
        not, or did not run), with why. Their axes are left out of the
        sequences; each is compared, as labelled and interchanged, with the
        sequences of the two skis in that view (their polynomials at its
        time, sigmas of the measurement and of the prediction): the
        assignment whose chi-square is within its ``1 - alpha`` quantile
        and beats the other by that quantile is taken (labels interchanged
        where needed), otherwise the view's skis are flagged; of a view so
        decided, an axis that its own direction does not tell apart (the
        1-dof quantile, both ways) is flagged too.
    alpha : float
        Test level of the pending views' decision.

    Returns
    -------
    table : DataFrame
        The points kept, sigmas scaled.
    flags : list of (exposure, station, line, reason)
    factors : DataFrame
        ``station, line, n, s0, scale, outliers``.
    decided : dict {(exposure, station): "as labelled" or "interchanged"}
        The pending views the sequences decided.
    """
    from scipy.stats import chi2
    pending = dict(pending or {})
    order = {e: i for i, e in enumerate(exposures)}
    opts = dict(degree=degree, k_out=k_out, min_length_fraction=min_length_fraction,
                min_redundancy=min_redundancy)
    dirs = axis_directions(table)
    is_pending = np.array([(e, s) in pending for e, s in zip(dirs.exposure, dirs.station)],
                          bool)
    # the sequences of the decided views first (their fits decide the rest)
    _, _, _, fit_of = _screen(dirs[~is_pending], order, **opts)
    # the pending views: as labelled or interchanged, by the sequences
    drop, flags = set(), []
    decided = {}
    relabel = {}
    for (e, s), why in pending.items():
        view = dirs[(dirs.exposure == e) & (dirs.station == s)]
        labs = list(view["line"])
        all_labs = sorted({lab for (_, lab) in fit_of} | set(labs))
        if len(all_labs) != 2 or any(fit_of.get((s, lab)) is None for lab in all_labs):
            reason = f"labels not decided: {why}; too few decided exposures in this view"
        else:
            fits = {lab: fit_of[(s, lab)] for lab in all_labs}
            other = dict(zip(all_labs, all_labs[::-1]))
            # per axis its chi-square as labelled and as the other ski
            per = np.array([[_axis_cost(r, fits[lab], order[e])
                             for lab in (r.line, other[r.line])] for r in view.itertuples()])
            costs = per.sum(0)
            q = float(chi2.ppf(1 - alpha, max(len(view), 1)))
            best = int(np.argmin(costs))
            if costs[best] <= q and costs[1 - best] - costs[best] >= q:
                # the pair's assignment is clear; each axis must be told apart
                # by its own direction too: a pair fit may lie on one ski twice
                # or run from one ski onto the other, and the clear axis then
                # decides the pair alone
                q1 = float(chi2.ppf(1 - alpha, 1))
                own, alt = per[:, best], per[:, 1 - best]
                unclear = ~((own <= q1) & (alt - own >= q1))
                decided[(e, s)] = "interchanged" if best else "as labelled"
                if best:
                    relabel[(e, s)] = other
                for r, u, c_own, c_alt in zip(view.itertuples(), unclear, own, alt):
                    if not u:
                        continue
                    lab = other[r.line] if best else r.line
                    drop.add((e, s, lab))             # its label after the relabelling
                    flags.append((e, s, lab, f"labels not decided: {why}; the sequences tell "
                                             "the view's labels apart but not this axis on its "
                                             f"own (chi2 {c_own:.3g} as {lab}, {c_alt:.3g} as "
                                             f"{other[lab]}, 1 dof)"))
                continue
            reason = (f"labels not decided: {why}; the sequences of the two skis in this "
                      f"view do not tell them apart (chi2 {costs[0]:.3g} as labelled, "
                      f"{costs[1]:.3g} interchanged, {len(view)} dof)")
        for lab in labs:
            drop.add((e, s, lab))
            flags.append((e, s, lab, reason))
    out = table.copy()
    if relabel:
        out["line"] = [relabel[(e, s)][lab] if (e, s) in relabel else lab
                       for e, s, lab in zip(out["exposure"], out["station"], out["line"])]
    # (drop holds the labels after the relabelling)
    key = list(zip(out["exposure"], out["station"], out["line"]))
    out = out.loc[np.array([k not in drop for k in key], bool)].copy()
    # then every axis kept, the decided pending views with them: outliers,
    # short axes and the variance factors
    more, more_flags, factors, _ = _screen(axis_directions(out), order, **opts)
    flags += more_flags
    key = list(zip(out["exposure"], out["station"], out["line"]))
    out = out.loc[np.array([k not in more for k in key], bool)].copy()
    scale_of = dict(zip(zip(factors.station, factors.line), factors.scale))
    out["sigma"] = out["sigma"] * [scale_of.get((s, lab), 1.0)
                                   for s, lab in zip(out["station"], out["line"])]
    return out.reset_index(drop=True), flags, factors, decided
