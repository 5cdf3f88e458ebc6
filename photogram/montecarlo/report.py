"""Statistics of the Monte-Carlo samples and the result files.

``summary.csv``: one row per quantity (station parameter, interior
parameter, collected point coordinate, jumper point coordinate, stick-model
parameter of an exposure): truth, mean, bias, ``sigma_mc`` (empirical,
n - 1), ``sigma_prop`` (first-order propagation through the same chain),
``ratio = sigma_mc / sigma_prop``, ``sigma_cmd`` (what the commands report)
and ``ratio_cmd``.

``table1.csv`` (the paper's Table 1): the stations and the interior
orientation (and collected points), one row per quantity.

``table2.csv`` (the paper's Table 2): the jumper points per point and axis
and the stick-model parameters, the RMS of the sigmas over the exposures,
their ratios, and the smallest and largest ratio of a single exposure.

``summary.json``: the settings, counts, timings, the band a ratio stays in
with 95 % probability if the propagated sigma is right, and the headline
ratios per group.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.special import chdtri
from scipy.stats import binom

import photogram
from photogram.project.atomic import atomic_write_text

__all__ = ["statistics", "write_report", "ratio_band", "band_warnings"]


def ratio_band(n, level=0.95):
    """The interval ``sigma_mc / sigma`` stays in with probability ``level``
    for ``n`` normal samples of true sigma ``sigma``: ``sqrt(chi2_{n-1} /
    (n-1))`` quantiles."""
    if n < 2:
        return [float("nan"), float("nan")]
    a = (1 - level) / 2
    lo = chdtri(n - 1, 1 - a) / (n - 1)
    hi = chdtri(n - 1, a) / (n - 1)
    return [float(np.sqrt(lo)), float(np.sqrt(hi))]


def band_warnings(frame, band, *, level=0.95, alpha=0.01, worst=3) -> list[str]:
    """Warnings for groups whose ratios ``sigma_mc / sigma_prop`` leave the
    band too often.

    If every propagated sigma were right, each ratio would fall outside its
    ``level`` band with probability ``1 - level``, and the number ``k`` of
    the ``n`` quantities of a group outside it would be at most binomial
    (n, 1 - level) (the quantities of a group are correlated, which widens
    the spread of ``k`` but not its mean). A group is named when ``P(K >=
    k) < alpha`` under that binomial, with its ``worst`` ratios farthest from
    the band (in log scale), so a reader sees which sigmas are too small or
    too large.

    Parameters
    ----------
    frame : pandas.DataFrame
        The summary table (:func:`statistics`): columns ``quantity``,
        ``group``, ``ratio``.
    band : sequence of 2 floats
        The band (:func:`ratio_band`); NaN bounds give no warnings.

    Returns
    -------
    list of str
        One line per group that leaves its band too often.
    """
    lo, hi = (float(b) for b in band)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return []
    out = []
    for group, part in frame.groupby("group", sort=False):
        r = part.ratio.to_numpy(dtype=float)
        keep = np.isfinite(r) & (r > 0)
        r, names = r[keep], part.quantity.to_numpy()[keep]
        outside = (r < lo) | (r > hi)
        k, n = int(outside.sum()), int(len(r))
        if k == 0 or binom.sf(k - 1, n, 1 - level) >= alpha:
            continue
        dist = np.maximum(np.log(lo / r), np.log(r / hi))
        order = np.argsort(-dist)[:min(worst, k)]
        named = ", ".join(f"{names[i]} {r[i]:.3g}" for i in order)
        side = ("too small" if np.all(r[outside] > hi) else
                "too large" if np.all(r[outside] < lo) else "too small or too large")
        out.append(f"montecarlo: {k} of {n} {group} quantities have sigma_mc/sigma_prop outside "
                   f"the {level:.0%} band {lo:.3f}..{hi:.3f} (about {(1 - level) * n:.1f} "
                   f"expected by chance): the propagated sigmas look {side}; farthest: {named}")
    return out


def statistics(chain, samples, failed, sigma_prop, sigma_cmd):
    """The summary table (reported units) as a DataFrame."""
    o = chain.outputs
    ok = ~failed & np.all(np.isfinite(samples), axis=1)
    V = samples[ok]
    f = o.factor
    truth = chain.truth * f
    mean = V.mean(0) if len(V) else np.full(len(f), np.nan)
    sd = V.std(0, ddof=1) if len(V) > 1 else np.full(len(f), np.nan)
    sp, sc = sigma_prop * f, sigma_cmd * f
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(sp > 0, sd / sp, np.nan)
        ratio_cmd = np.where(sc > 0, sd / sc, np.nan)
    return pd.DataFrame({"quantity": o.names, "group": o.groups, "unit": o.units,
                         "truth": truth, "mean": mean, "bias": mean - truth,
                         "sigma_mc": sd, "sigma_prop": sp, "ratio": ratio,
                         "sigma_cmd": sc, "ratio_cmd": ratio_cmd})


def _table2(frame):
    rows = []
    sub = frame[frame.group.isin(["jumper", "stick"])]
    if sub.empty:
        return pd.DataFrame()
    key = sub.quantity.str.replace(r"@[^.]*", "", regex=True)
    for name, part in sub.groupby(key, sort=False):
        def rms(c):
            return float(np.sqrt(np.nanmean(part[c].to_numpy() ** 2)))
        mc, pr, cm = rms("sigma_mc"), rms("sigma_prop"), rms("sigma_cmd")
        rows.append({"quantity": name, "group": part.group.iloc[0], "unit": part.unit.iloc[0],
                     "exposures": len(part), "sigma_mc": mc, "sigma_prop": pr,
                     "ratio": mc / pr if pr > 0 else np.nan,
                     "ratio_min": float(np.nanmin(part.ratio)),
                     "ratio_max": float(np.nanmax(part.ratio)),
                     "sigma_cmd": cm, "ratio_cmd": mc / cm if cm > 0 else np.nan,
                     "rms_bias": rms("bias")})
    return pd.DataFrame(rows)


def _headline(frame):
    out = {}
    for g, part in frame.groupby("group", sort=False):
        r = part.ratio.to_numpy(dtype=float)
        rc = part.ratio_cmd.to_numpy(dtype=float)
        r, rc = r[np.isfinite(r)], rc[np.isfinite(rc)]
        if not len(r):
            continue
        out[g] = {"quantities": int(len(part)),
                  "ratio": {"median": float(np.median(r)), "min": float(r.min()),
                            "max": float(r.max())},
                  "ratio_cmd": ({"median": float(np.median(rc)), "min": float(rc.min()),
                                 "max": float(rc.max())} if len(rc) else None)}
    return out


def _csv(frame):
    return frame.to_csv(index=False, float_format="%.6g")


def project_info(project) -> dict:
    """summary.json's ``project`` entry (as the other commands write it)."""
    if project is None:
        return {}
    return {"name": project.name, "path": str(project.path) if project.path else None,
            "length_unit": project.units.length, "angle_unit": project.units.angle,
            "image_unit": project.units.image}


def write_report(folder, chain, samples, failed, sigma_prop, sigma_cmd, info, project=None):
    """Write summary.csv, table1.csv, table2.csv, samples.csv, summary.json;
    return the summary dict. ``project`` (the Monte-Carlo project) gives
    summary.json its ``project`` entry, which the report's header reads."""
    folder = Path(folder)
    frame = statistics(chain, samples, failed, sigma_prop, sigma_cmd)
    t1 = frame[frame.group.isin(["station", "interior", "point"])]
    t2 = _table2(frame)
    atomic_write_text(folder / "summary.csv", _csv(frame))
    atomic_write_text(folder / "table1.csv", _csv(t1))
    if not t2.empty:
        atomic_write_text(folder / "table2.csv", _csv(t2))
    cols = ["run"] + list(chain.outputs.names) + ["failed"]
    data = pd.DataFrame(samples, columns=cols[1:-1])
    data.insert(0, "run", np.arange(len(samples)))
    data["failed"] = failed.astype(int)
    atomic_write_text(folder / "samples.csv", data.to_csv(index=False, float_format="%.10g"))
    s = chain.settings
    n_ok = int((~failed).sum())
    summary = {
        "command": "montecarlo", "status": "ok", "software_version": photogram.__version__,
        "project": project_info(project),
        "warnings": (list(getattr(project, "warnings", None) or []) +
                     band_warnings(frame, ratio_band(n_ok))),
        "runs": int(len(samples)), "failed": int(failed.sum()),
        "seed": int(info.get("seed", 0)), "perturb": list(s.perturb), "truth": s.truth,
        "chain": {"orient": s.orient, "calibrate": s.calibrate, "intersect": s.intersect,
                  "interior_covariance": s.interior_covariance, "points": list(s.points),
                  "align": s.align},
        "ratio_band_95": ratio_band(n_ok),
        "headline": _headline(frame),
        "table2": t2.to_dict(orient="records") if not t2.empty else [],
        "execution": info,
    }
    atomic_write_text(folder / "summary.json",
                      json.dumps(summary, indent=1, default=_json_default) + "\n")
    return summary


def _json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)
