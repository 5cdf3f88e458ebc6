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
  in that view (a fit to a piece of the ski).

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
    for (e, s, lab), g in table.groupby(["exposure", "station", "line"], sort=False):
        xy = g[["x", "y"]].to_numpy(float)
        if len(xy) < 2:
            continue
        c = xy.mean(0)
        _, _, vt = np.linalg.svd(xy - c)
        u = vt[0] if vt[0] @ (xy[-1] - xy[0]) >= 0 else -vt[0]
        t = (xy - c) @ u
        rows.append((e, s, lab, float(np.arctan2(u[1], u[0])),
                     float(g["sigma"].iloc[0] / np.sqrt(max((t * t).sum(), 1e-12))),
                     float(np.ptp(t))))
    return pd.DataFrame(rows, columns=["exposure", "station", "line", "angle", "sigma_angle",
                                       "length"])


def _fit(t, a, s, degree):
    """Weighted polynomial fit; residuals of all points."""
    deg = min(degree, len(t) - 1)
    coef = np.polyfit(t, a, deg, w=1 / s)
    return a - np.polyval(coef, t), deg


def sequence_check(table: pd.DataFrame, exposures, *, degree: int = 3, k_out: float = 4.0,
                   min_length_fraction: float = 0.5, min_redundancy: int = 3):
    """Scale and screen the ski points of each station and ski by their
    sequence (module doc).

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

    Returns
    -------
    table : DataFrame
        The points kept, sigmas scaled.
    flags : list of (exposure, station, line, reason)
    factors : DataFrame
        ``station, line, n, s0, scale, outliers``.
    """
    order = {e: i for i, e in enumerate(exposures)}
    dirs = axis_directions(table)
    drop, flags, report = set(), [], []
    scale_of = {}
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
            r, deg = _fit(t[keep], a[keep], sig[keep], degree)
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
        scale_of[(s, lab)] = scale
        report.append((s, lab, int(keep.sum()), s0, scale, outliers))
    out = table.copy()
    key = list(zip(out["exposure"], out["station"], out["line"]))
    out = out[[k not in drop for k in key]].copy()
    out["sigma"] = out["sigma"] * [scale_of.get((s, lab), 1.0)
                                   for s, lab in zip(out["station"], out["line"])]
    factors = pd.DataFrame(report, columns=["station", "line", "n", "s0", "scale", "outliers"])
    return out.reset_index(drop=True), flags, factors
