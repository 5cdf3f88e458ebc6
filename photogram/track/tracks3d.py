"""The 3D stage of the marker tracker: correspondences checked across the
cameras, and markers found again at their 3D prediction.

The cameras' orientation is the *estimated* one (of the field's bundle):
its errors shift a marker's reprojection by a few pixels, nearly the same
for all markers at one instant (the jumper spans a few tens of pixels) and
slowly changing as the jumper crosses the image. :func:`view_bias`
estimates that systematic part per camera as a robust quadratic in time of
the reprojection residual vectors of all markers seen in three views; the
checks below work on the observations less that bias, so a tolerance of a
few pixels separates a wrong correspondence from the orientation's error
(without it, an orientation 0.05 gon off flags every marker).

:func:`check_3d`: per reference frame and marker, the views whose 2D track
is ``ok`` are triangulated (:mod:`photogram.track.rays`); a view whose
residual, or whose residual against the point of the other views
(:func:`left_out_residuals`), exceeds ``epipolar_tol`` is flagged
``ambiguous``: with three views the one whose removal leaves a consistent
pair, otherwise all.

:func:`fill_3d`: every view where a marker is not ``ok`` is searched again
around the projection (plus the bias) of its 3D point: of the other views
at that instant, or, when fewer than two see it, of the marker's
**ballistic** 3D track (a quadratic in time fitted to its 3D points within
``ballistic_window`` frames: constant acceleration, the flight under
gravity with slowly changing drag and lift). A single clear blob within
``fill_gate`` px, not claimed by another marker, not within the gate of
another marker's projection, not overlapping a comparable blob, of the
marker's flux and round, becomes ``ok``: labels survive an occlusion or an
ambiguous stretch in one camera when the others see the marker.
"""

from __future__ import annotations

import numpy as np

from photogram.track.rays import reprojection_residuals, triangulate
from photogram.track.tracks2d import AMBIGUOUS, LOST, OK, TrackSettings, neighbour_distance

__all__ = ["observations", "view_bias", "left_out_residuals", "check_3d", "fill_3d",
           "ballistic"]


def observations(tr: dict, offsets: dict, T: int, i: int) -> np.ndarray:
    """Marker ``i``'s ok positions (S, T, 2) per station (in ``tr``'s order)
    and reference frame; NaN elsewhere."""
    names = list(tr)
    xy = np.full((len(names), T, 2), np.nan)
    for k, s in enumerate(names):
        f = np.arange(T) - offsets[s]
        inside = (f >= 0) & (f < len(tr[s].xy))
        okv = np.zeros(T, bool)
        okv[inside] = tr[s].status[f[inside], i] == OK
        xy[k, okv] = tr[s].xy[f[okv], i]
    return xy


def _robust_quadratic(t: np.ndarray, r: np.ndarray, T: int) -> np.ndarray:
    """(T, 2) values of a quadratic in t fitted to r (n, 2), twice with the
    points more than max(1 px, 3 x their RMS) off dropped; constant outside
    the fitted range."""
    keep = np.ones(len(t), bool)
    deg = min(2, len(np.unique(t)) - 1)
    for _ in range(3):
        V = np.vander(t[keep].astype(float), deg + 1)
        coef, *_ = np.linalg.lstsq(V, r[keep], rcond=None)
        dev = np.hypot(*(r - np.vander(t.astype(float), deg + 1) @ coef).T)
        rms = np.sqrt(np.mean(dev[keep] ** 2))
        new = dev <= max(1.0, 3.0 * rms)
        if new.sum() < 6 or np.array_equal(new, keep):
            break
        keep = new
    tt = np.clip(np.arange(T), t[keep].min(), t[keep].max()).astype(float)
    return np.vander(tt, deg + 1) @ coef


def view_bias(cams: dict, tr: dict, offsets: dict, T: int, M: int,
              min_points: int = 6) -> np.ndarray:
    """Systematic reprojection residual (observed minus projected) per
    station and reference frame, (S, T, 2) px (module doc); zero for a
    station with fewer than ``min_points`` three-view points."""
    names = list(cams)
    cl = [cams[s] for s in names]
    ts, rs = [[] for _ in names], [[] for _ in names]
    for i in range(M):
        xy = observations(tr, offsets, T, i)
        three = np.isfinite(xy[..., 0]).all(axis=0)
        if not three.any():
            continue
        X, _ = triangulate(cl, xy[:, three])
        for k, cam in enumerate(cl):
            good = np.isfinite(X).all(axis=1)
            q = cam.project(X[good])
            ts[k].append(np.nonzero(three)[0][good])
            rs[k].append(xy[k, three][good] - q)
    bias = np.zeros((len(names), T, 2))
    for k in range(len(names)):
        if not ts[k]:
            continue
        t, r = np.concatenate(ts[k]), np.concatenate(rs[k])
        if len(t) >= min_points:
            bias[k] = _robust_quadratic(t, r, T)
    return bias


def left_out_residuals(cams: list, xy: np.ndarray) -> np.ndarray:
    """Residual (px) of each view at each instant against the point
    triangulated from the OTHER views ``(K, T)``, NaN where the view is
    missing or fewer than two others see the point. The joint residuals
    spread a wrong view's error over all views, the more so the weaker the
    geometry (cameras on one side of the hill: a marker taken up 5.6 px off
    in S2 left joint residuals of 1.2-2.5 px, below the tolerance); the
    left-out residual shows it whole (the other two predicted S2 to 0.14
    px), as in data snooping with one observation removed."""
    K = len(cams)
    out = np.full(xy.shape[:2], np.nan)
    if K < 3:
        return out
    for k in range(K):
        rest = [q for q in range(K) if q != k]
        X, nv = triangulate([cams[q] for q in rest], xy[rest])
        r = reprojection_residuals([cams[k]], X, xy[[k]])[0]
        out[k] = np.where(nv >= 2, r, np.nan)
    return out


def check_3d(cams: dict, tr: dict, offsets: dict, T: int, M: int, tol: float,
             bias: np.ndarray) -> np.ndarray:
    """Triangulate every marker at every reference frame from its ok views
    (less the bias) and flag the views that disagree (module doc); returns
    the 3D points (T, M, 3), NaN where fewer than two consistent views."""
    names = list(cams)
    cl = [cams[s] for s in names]
    X = np.full((T, M, 3), np.nan)
    for i in range(M):
        xy = observations(tr, offsets, T, i) - bias
        Xi, nv = triangulate(cl, xy)
        res = reprojection_residuals(cl, Xi, xy)
        bad = (np.nan_to_num(res, nan=0.0) > tol).any(axis=0)
        bad |= (np.nan_to_num(left_out_residuals(cl, xy), nan=0.0) > tol).any(axis=0)
        for t in np.nonzero(bad)[0]:
            seen = [k for k in range(len(names)) if np.isfinite(xy[k, t, 0])]
            culprit = None
            if len(seen) >= 3:
                fits = []
                for k in seen:
                    rest = [q for q in seen if q != k]
                    sub = xy[rest][:, t:t + 1]
                    Xr, _ = triangulate([cl[q] for q in rest], sub)
                    rr = reprojection_residuals([cl[q] for q in rest], Xr, sub)
                    rk = reprojection_residuals([cl[k]], Xr, xy[[k]][:, t:t + 1])
                    if np.nanmax(rr) <= tol and rk[0, 0] > tol:
                        fits.append((k, Xr[0]))
                if len(fits) == 1:
                    culprit, X[t, i] = fits[0]
            for k in ([culprit] if culprit is not None else seen):
                s = names[k]
                f = t - offsets[s]
                tr[s].status[f, i] = AMBIGUOUS
                tr[s].reason[f, i] = (f"{res[k, t]:.1f} px off the other views' 3D point"
                                      if culprit is not None else
                                      f"views disagree in 3D ({np.nanmax(res[:, t]):.1f} px)")
        good = ~bad & (nv >= 2)
        X[good, i] = Xi[good]
    return X


def ballistic(X: np.ndarray, t: int, w: int) -> np.ndarray | None:
    """Quadratic-in-time fit of the 3D points X (T, 3) within w frames of t
    (not t itself), evaluated at t; None without 3 points on both sides
    or 4 on one."""
    lo, hi = max(0, t - w), min(len(X), t + w + 1)
    ts = np.array([u for u in range(lo, hi) if u != t and np.isfinite(X[u]).all()])
    if len(ts) < 3 or (not ((ts < t).any() and (ts > t).any()) and len(ts) < 4):
        return None
    V = np.vander(ts - t, 3)
    coef, *_ = np.linalg.lstsq(V, X[ts], rcond=None)
    return coef[-1]


def _predictions(X: np.ndarray, s: TrackSettings) -> list:
    """Per frame ``t`` the 3D predictions ``{marker: (X, gate, source)}``
    of :func:`fill_3d`: the point of the other views where it has one,
    else the ballistic 3D track (a wider gate)."""
    T, M = X.shape[:2]
    preds = []
    for t in range(T):
        pred = {}
        for i in range(M):
            if np.isfinite(X[t, i]).all():
                pred[i] = (X[t, i], s.fill_gate, "the other views")
            else:
                Xb = ballistic(X[:, i], t, s.ballistic_window)
                if Xb is not None:
                    pred[i] = (Xb, s.fill_gate + 2.0, "the ballistic 3D track")
        preds.append(pred)
    return preds


def _project_predictions(cams: dict, tr: dict, offsets: dict, preds: list,
                         bias: np.ndarray) -> dict:
    """``{(station index, t): {marker: image point + bias}}`` of the
    predictions ``preds`` in every view whose video has the frame: one
    projection (one Newton inversion of the distortion) per station for
    all its frames instead of one per frame and marker. The points are
    those a per-point projection gives to the last steps of Newton's
    method (below 1e-12 of the image scale), which here only gate the
    candidates."""
    out = {}
    for k, (sname, cam) in enumerate(cams.items()):
        n_frames = len(tr[sname].xy)
        keys = [(t, i) for t, pred in enumerate(preds) if 0 <= t - offsets[sname] < n_frames
                for i in pred]
        if not keys:
            continue
        q = cam.project(np.array([preds[t][i][0] for t, i in keys]))
        for (t, i), qi in zip(keys, q):
            out.setdefault((k, t), {})[i] = qi + bias[k, t]
    return out


def fill_3d(cams: dict, tr: dict, cands: dict, offsets: dict, X: np.ndarray,
            markers: list, s: TrackSettings, sizes: dict, bias: np.ndarray) -> None:
    """Search the views where a marker is not ok around its 3D prediction
    (module doc); updates ``tr`` in place."""
    names = list(cams)
    T, M = X.shape[:2]
    preds = _predictions(X, s)
    q_all = _project_predictions(cams, tr, offsets, preds, bias)
    for t, pred in enumerate(preds):
        if not pred:
            continue
        for k, sname in enumerate(names):
            f = t - offsets[sname]
            st = tr[sname]
            if not 0 <= f < len(st.xy):
                continue
            c = cands[sname][f]
            q = q_all[(k, t)]
            w, h = sizes[sname]
            for i, (_, gate, source) in pred.items():
                if st.status[f, i] == OK:
                    continue
                qi = q[i]
                if not (0 <= qi[0] < w and 0 <= qi[1] < h):
                    st.reason[f, i] = "predicted outside the image"
                    st.status[f, i] = LOST
                    continue
                if not len(c):
                    continue
                d = np.hypot(*(c.xy - qi).T)
                inside = np.nonzero(d < gate)[0]
                if len(inside) != 1:
                    if len(inside) > 1 and st.status[f, i] == LOST:
                        st.status[f, i] = AMBIGUOUS
                        st.reason[f, i] += f"; {len(inside)} blobs at the 3D prediction"
                    continue
                j = inside[0]
                taken = [markers[m] for m in range(M) if m != i and st.cand[f, m] == j]
                near = [markers[m] for m, qm in q.items()
                        if m != i and np.hypot(*(c.xy[j] - qm)) < gate]
                ratio = c.flux[j] / st.flux[i] if np.isfinite(st.flux[i]) else 1.0
                if taken or near or ratio > s.merge_flux or ratio < s.low_flux \
                        or c.elongation[j] > s.max_elongation \
                        or neighbour_distance(c, j, s.neighbour_flux) < s.min_separation:
                    continue
                st.xy[f, i], st.sigma[f, i], st.cand[f, i] = c.xy[j], c.sigma[j], j
                st.status[f, i] = OK
                st.reason[f, i] = f"found at the 3D prediction from {source}"
