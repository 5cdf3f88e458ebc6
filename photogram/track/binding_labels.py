"""Where the merged binding blob is and which split point is which (the
geometry of :mod:`photogram.track.bindings`, module doc steps 1 and 4):
the views' biases and the hip's 3D track (the flight direction), the blob
located in 3D from the candidates of every view, a lone ok binding checked
against it, the labels of the split points from the three views and the
jumper's right, and labels taken from neighbouring exposures."""

from __future__ import annotations

import itertools

import numpy as np

from photogram.track.rays import reprojection_residuals, triangulate

__all__ = ["label_pairs"]


def label_pairs(cameras: list, points: np.ndarray, sigma: np.ndarray, *,
                right: np.ndarray | None = None, up=(0.0, 0.0, 1.0),
                length_unit: float = 0.1, pair_distance=(0.15, 0.40),
                min_across_deg: float = 60.0, min_side: float = 0.5,
                chi2_quantile: float = 0.999, chi2_margin: float = 9.0) -> dict:
    """Which of the two split points is P3 in each view (module doc, step 4).

    Parameters
    ----------
    cameras : list of k >= 2 ViewCamera
    points : (k, 2, 2)
        Per view the two split points (in any order).
    sigma : (k,)
        Sigma (px) of a coordinate of the points of each view.
    right : (3,), optional
        The jumper's right in world coordinates (``flight x up``); without
        it the global interchange of P3 and P4 cannot be decided and the
        pair is ambiguous.
    up : (3,)
        World up (Z).
    length_unit : float
        Metres per length unit of the cameras.
    pair_distance : (float, float)
        Plausible ``|P3 - P4|`` (m).
    min_across_deg : float
        Smallest angle between ``P3 - P4`` and the flight.
    min_side : float
        Smallest component of ``unit(P3 - P4)`` along ``right``.
    chi2_quantile, chi2_margin : float
        The best assignment's chi-square must be below this quantile and
        the second best's at least ``chi2_margin`` above it.

    Returns
    -------
    dict
        ``ok`` bool; ``assign`` (k,) int: index of P3 among each view's two
        points (valid when ok); ``X`` (2, 3) P3, P4; ``chi2``,
        ``chi2_second``, ``distance`` (m), ``across_deg``, ``side``;
        ``reason`` (why not, when not ok).
    """
    from scipy.stats import chi2 as chi2_dist
    k = len(cameras)
    points = np.asarray(points, float)
    sigma = np.asarray(sigma, float)
    combos = np.array([(0,) + c for c in itertools.product((0, 1), repeat=k - 1)])  # (C, k)
    C = len(combos)
    v = np.arange(k)
    p3 = points[v[None, :], combos]                 # (C, k, 2)
    p4 = points[v[None, :], 1 - combos]
    xy = np.concatenate([p3, p4], axis=0).transpose(1, 0, 2)   # (k, 2C, 2)
    X, _ = triangulate(cameras, xy)
    res = reprojection_residuals(cameras, X, xy)                 # (k, 2C)
    chi = ((res / sigma[:, None]) ** 2).sum(0)
    chi = chi[:C] + chi[C:]
    out = {"ok": False, "assign": np.zeros(k, int), "X": np.full((2, 3), np.nan),
           "chi2": np.nan, "chi2_second": np.nan, "distance": np.nan,
           "across_deg": np.nan, "side": np.nan, "reason": ""}
    if not np.isfinite(chi).any():
        out["reason"] = "the split points do not triangulate"
        return out
    order = np.argsort(np.where(np.isfinite(chi), chi, np.inf))
    b = order[0]
    out["chi2"] = float(chi[b])
    out["chi2_second"] = float(chi[order[1]]) if C > 1 else np.inf
    assign = combos[b].copy()
    X3, X4 = X[b], X[C + b]
    D = X3 - X4
    dist = float(np.linalg.norm(D)) * length_unit
    out["distance"] = dist
    if right is not None and np.all(np.isfinite(right)):
        r = np.asarray(right, float) / np.linalg.norm(right)
        side = float(D @ r) / max(np.linalg.norm(D), 1e-12)
        if side < 0:                                  # P3 is the right one: swap everywhere
            assign, X3, X4, D, side = 1 - assign, X4, X3, -D, -side
        flight = np.cross(np.asarray(up, float), r)
        flight /= np.linalg.norm(flight)
        cosf = abs(float(D @ flight)) / max(np.linalg.norm(D), 1e-12)
        out["across_deg"] = float(np.degrees(np.arccos(min(cosf, 1.0))))
        out["side"] = side
    out["assign"], out["X"] = assign, np.stack([X3, X4])
    dof = 2 * (2 * k - 3)
    limit = float(chi2_dist.ppf(chi2_quantile, dof))
    if right is None or not np.all(np.isfinite(right)):
        out["reason"] = "no flight direction (hip not tracked): left/right undecided"
    elif out["chi2"] > limit:
        out["reason"] = f"views inconsistent (chi2 {out['chi2']:.1f} > {limit:.1f})"
    elif out["chi2_second"] - out["chi2"] < chi2_margin:
        out["reason"] = (f"assignment not clear (chi2 {out['chi2']:.1f} vs "
                         f"{out['chi2_second']:.1f})")
    elif not pair_distance[0] <= dist <= pair_distance[1]:
        out["reason"] = f"implausible distance {dist:.2f} m"
    elif out["across_deg"] < min_across_deg or out["side"] < min_side:
        out["reason"] = (f"pair not across the flight ({out['across_deg']:.0f} deg, "
                         f"side {out['side']:.2f})")
    else:
        out["ok"] = True
    return out


# ------------------------------------------------------------------ the table

def _hip_track(cams, ok, stations, names, singles, hip):
    """The views' biases (k, 2) (median reprojection residual of the single
    markers seen in three views), the hip in 3D per exposure (E, 3) and its
    velocity (E, 3) (NaN where unknown) from the ok rows ``ok`` of the
    single markers."""
    sidx = {s: i for i, s in enumerate(stations)}
    eidx = {e: i for i, e in enumerate(names)}
    midx = {m: i for i, m in enumerate(singles)}
    xy_single = np.full((len(stations), len(names), len(singles), 2), np.nan)
    for r in ok[ok.marker.isin(singles) & ok.station.isin(stations)].itertuples():
        if r.exposure in eidx:
            xy_single[sidx[r.station], eidx[r.exposure], midx[r.marker]] = (r.x, r.y)
    flat = xy_single.reshape(len(stations), -1, 2)
    Xs, nv = triangulate(cams, flat)
    bias = np.zeros((len(stations), 2))
    full = nv >= 3
    if full.any():
        for i, cam in enumerate(cams):
            q = cam.project(Xs[full])
            bias[i] = np.nanmedian(flat[i, full] - q, axis=0)
    bias = np.nan_to_num(bias)
    Xs = Xs.reshape(len(names), len(singles), 3)
    X_hip = Xs[:, midx[hip]] if hip in midx else np.full((len(names), 3), np.nan)
    vel = np.full_like(X_hip, np.nan)
    good = np.isfinite(X_hip).all(1)
    if good.sum() >= 2:
        t = np.arange(len(names))
        for j in range(3):
            vel[:, j] = np.gradient(np.interp(t, t[good], X_hip[good, j]), t)
    return bias, X_hip, vel


def _locate(cams, per_view, bias, X_hip, vel, tol, hip_distance, length_unit,
            merge_distance=0.4, merge_px=4.0):
    """The binding midpoint's image in every view (k, 2) (NaN where not
    seen), from one candidate per view (module doc, step 1); a str says why
    not."""
    k = len(cams)
    if not np.all(np.isfinite(X_hip)):
        return "hip not triangulated at this exposure"
    opts = [np.arange(-1, len(c)) for c in per_view]
    combos = np.array(list(itertools.product(*opts)))            # (C, k)
    combos = combos[(combos >= 0).sum(1) >= 2]
    if not len(combos):
        return "binding blob not seen in two views"
    xy = np.full((k, len(combos), 2), np.nan)
    for i, c in enumerate(per_view):
        sel = combos[:, i] >= 0
        xy[i, sel] = c[combos[sel, i]] - bias[i]
    X, nv = triangulate(cams, xy)
    res = reprojection_residuals(cams, X, xy)
    worst = np.nanmax(np.where(np.isfinite(res), res, -1), axis=0)
    d = np.linalg.norm(X - X_hip, axis=1) * length_unit
    behind = np.ones(len(X), bool)
    if np.all(np.isfinite(vel)) and np.linalg.norm(vel) > 0:
        behind = (X - X_hip) @ (vel / np.linalg.norm(vel)) < 0
    good = np.isfinite(X).all(1) & (worst < tol) & (d >= hip_distance[0]) \
        & (d <= hip_distance[1]) & behind
    if not good.any():
        return "binding blob not located (no consistent candidates near the hip)"
    nmax = nv[good].max()
    cand = np.nonzero(good & (nv == nmax))[0]
    rms = np.sqrt(np.nanmean(np.where(np.isfinite(res[:, cand]), res[:, cand], np.nan) ** 2,
                             axis=0))
    best = cand[np.argmin(rms)]
    # rivals: consistent points farther from the best than the pair's size
    # (nearer ones are the other marker of the pair, or the blob again)
    others = cand[np.linalg.norm(X[cand] - X[best], axis=1) * length_unit > merge_distance]
    if len(others):
        return "binding blob not located (two candidate points near the hip)"
    out = np.full((k, 2), np.nan)
    for i, c in enumerate(per_view):
        if combos[best, i] >= 0:
            # the two markers may be two candidates here: their mean
            near = np.hypot(*(c - c[combos[best, i]]).T) <= merge_px
            out[i] = c[near].mean(0)
    return out


def _lone_offsets(found, cams, bias, stations, pair_rows):
    """Where one binding of a view is ok and the other not, how far (px)
    the ok one is from the blob located in 3D (``found``, from
    :func:`_locate`; where not located in that view, the projection of its
    3D point triangulated from the views that saw it): a list of
    (station, marker, distance). ``pair_rows`` per station: {marker: table
    row (or None)} of the two bindings, or None to leave the view out."""
    out = []
    seen = np.isfinite(found).all(1)
    X_blob = None
    if seen.sum() >= 2:
        X_blob, _ = triangulate([c for c, k in zip(cams, seen) if k],
                                (found - bias)[seen][:, None])
    for i, s in enumerate(stations):
        rs = pair_rows[i]
        if rs is None or any(r is None for r in rs.values()) or \
                sum(r.status == "ok" for r in rs.values()) != 1:
            continue
        where = found[i]
        if not np.all(np.isfinite(where)) and X_blob is not None:
            # not located in this view: the blob's 3D point projected
            where = cams[i].project(X_blob)[0] + bias[i]
        if not np.all(np.isfinite(where)):
            continue
        m, r = next((m, r) for m, r in rs.items() if r.status == "ok")
        off = float(np.hypot(r.x - where[0], r.y - where[1]))
        out.append((s, m, off))
    return out


def _from_neighbours(e, i, split_views, found, X_pair, bias, sidx, cameras, cams, window,
                     min_cos, chi2_quantile):
    """Labels of exposure ``e`` (index ``i``) from the 3D pairs of its
    labelled neighbours (module doc, step 5)."""
    from scipy.stats import chi2 as chi2_dist
    out = {"ok": False, "assign": None, "chi2": np.nan, "reason": ""}
    have = np.nonzero(np.isfinite(X_pair).all(axis=(1, 2)))[0]
    near = have[np.abs(have - i) <= window]
    before, after = near[near < i], near[near > i]
    if not ((len(before) and len(after)) or (np.abs(near - i) == 1).any()):
        out["reason"] = "no labelled exposure near enough for continuity"
        return out
    D = X_pair[near, 0] - X_pair[near, 1]
    if len(before) and len(after):
        D_i = np.array([np.interp(i, near, D[:, j]) for j in range(3)])
    else:
        D_i = D[np.argmin(np.abs(near - i))]
    # the midpoint now: from this exposure's located blob centres
    xy = np.array([found[j] - bias[j] for j in range(len(cams))])[:, None, :]
    Xm, nv = triangulate(cams, xy)
    if not np.isfinite(Xm).all():
        Xm = np.array([np.interp(i, near, X_pair[near, :, j].mean(1)) for j in range(3)])[None]
    assign = []
    for s, p, sg, sep in split_views:
        q = cameras[s].project(np.vstack([Xm[0] + D_i / 2, Xm[0] - D_i / 2]))
        u, m = q[0] - q[1], p[0] - p[1]
        c = float(u @ m) / max(np.linalg.norm(u) * np.linalg.norm(m), 1e-12)
        if abs(c) < min_cos:
            ang = np.degrees(np.arccos(min(abs(c), 1.0)))
            out["reason"] = (f"continuity: the separation in {s} is {ang:.0f} deg from "
                             "the prediction")
            return out
        assign.append(0 if c > 0 else 1)
    assign = np.array(assign)
    if len(split_views) >= 2:
        vc = [cameras[s] for s, *_ in split_views]
        pts = np.array([p - bias[sidx[s]] for s, p, *_ in split_views])
        sg = np.array([v[2] for v in split_views])
        k = len(vc)
        xy = np.stack([pts[np.arange(k), assign], pts[np.arange(k), 1 - assign]], axis=1)
        X, _ = triangulate(vc, xy)
        res = reprojection_residuals(vc, X, xy)
        out["chi2"] = float(((res / sg[:, None]) ** 2).sum())
        limit = float(chi2_dist.ppf(chi2_quantile, 2 * (2 * k - 3)))
        if not out["chi2"] <= limit:
            out["reason"] = (f"continuity: views inconsistent (chi2 {out['chi2']:.1f} > "
                             f"{limit:.1f})")
            return out
    out["ok"], out["assign"] = True, assign
    return out
