"""Jumper markers tracked through synchronized videos: the marker table.

:func:`track_markers` runs the whole chain for one jump:

1. per camera, the median background and the marker candidates of every
   frame (:mod:`photogram.track.background`, :mod:`photogram.track.markers`);
2. per camera, 2D tracks from the seed clicks
   (:mod:`photogram.track.tracks2d`): prediction, gating, and a flag
   instead of a guess;
3. the sync offsets, given or estimated from the 2D tracks
   (:mod:`photogram.track.sync`);
4. **3D**, per frame of the reference camera and marker: the views whose
   2D track is ``ok`` are triangulated (:mod:`photogram.track.rays`); a view
   whose reprojection residual exceeds ``epipolar_tol`` is flagged
   ``ambiguous`` (with three views, the one whose removal leaves a
   consistent pair; otherwise all). Then every view where the marker is
   not ``ok`` is searched again around the projection of the 3D point: of
   the other views at the same instant, or, when fewer than two see it,
   of the marker's **ballistic** 3D track (a quadratic in time fitted to
   its 3D points within ``ballistic_window`` frames: constant
   acceleration, the flight under gravity and a slowly changing drag and
   lift). A single, clear blob not claimed by another marker and not
   within the gate of another marker's projection becomes ``ok``; labels so
   survive short occlusions in one camera;
5. the table of the exposures.

Nothing is guessed: a marker is ``ok`` only when one blob is clearly its
own; ``lost`` when no blob is (reason: hidden, outside the image, the track
ended), ``ambiguous`` when more than one could be (two blobs in the gate,
two markers on one blob, views that disagree). The rows' ``reason`` says
which. Bad input raises :class:`photogram.errors.InputError`: a seed click
far from every blob (station, frame, marker); a camera that sees no marker
(none of its seed clicks is near a new bright spot, or no candidate in any
frame: the camera is named; a wrong or blank video). A camera that sees
the markers at the seeds and loses them later is not an error: its rows
are ``lost`` while the other cameras go on. A marker without a seed in one
camera is not an error either (it is ``lost`` there unless the 3D
prediction finds it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from photogram.errors import InputError
from photogram.track.background import estimate_background
from photogram.track.markers import detect_markers
from photogram.track.rays import reprojection_residuals, triangulate
from photogram.track.sync import SyncResult, estimate_offsets
from photogram.track.tracks2d import (AMBIGUOUS, LOST, OK, STATUS, TrackSettings,
                                      neighbour_distance, track_station)

__all__ = ["COLUMNS", "TrackResult", "track_markers", "exposure_frames", "seed_clicks"]

#: the columns of the marker table, in order
COLUMNS = ["exposure", "station", "marker", "x", "y", "sigma", "status", "reason"]


@dataclass
class TrackResult:
    """The marker table and how it was made.

    Attributes
    ----------
    table : DataFrame with :data:`COLUMNS`
    offsets : dict station -> int
        Frames each camera started late against the reference camera:
        reference frame ``t`` is frame ``t - offsets[s]`` of camera ``s``.
    sync : SyncResult or None
        The offset estimate (None when the offsets were given).
    tracks : dict station -> Track2D
        Per video frame, after the 3D checks.
    candidates : dict station -> list of Candidates
    """

    table: pd.DataFrame
    offsets: dict
    sync: SyncResult | None = None
    tracks: dict = field(default_factory=dict)
    candidates: dict = field(default_factory=dict)


def exposure_frames(exposures) -> dict:
    """``{exposure: reference frame}`` from a mapping or a DataFrame with
    columns exposure, frame (frames.csv); exposure names as strings."""
    if isinstance(exposures, pd.DataFrame):
        if not {"exposure", "frame"} <= set(exposures.columns):
            raise InputError("the exposure table needs columns exposure, frame",
                             hint="frames.csv: exposure,frame per line")
        return {str(e): int(f) for e, f in zip(exposures["exposure"], exposures["frame"])}
    return {str(e): int(f) for e, f in dict(exposures).items()}


def seed_clicks(seeds: pd.DataFrame) -> dict:
    """``{station: {marker: (frame, (x, y))}}`` from the seed table
    (station, frame, marker, x, y)."""
    need = {"station", "frame", "marker", "x", "y"}
    if not need <= set(seeds.columns):
        raise InputError("the seed table needs columns " + ", ".join(sorted(need)),
                         hint="seeds.csv: station,frame,marker,x,y")
    out: dict = {}
    for r in seeds.itertuples(index=False):
        st, m = str(r.station), str(r.marker)
        if m in out.setdefault(st, {}):
            raise InputError(f"two seed clicks for {m} in {st}", hint="one click per marker")
        out[st][m] = (int(r.frame), (float(r.x), float(r.y)))
    return out


def _check_3d(cams, tr, offsets, F, M, tol):
    """Triangulate every marker at every reference frame from its ok views,
    flag the views that disagree; return X (T, M, 3)."""
    names = list(cams)
    T = F
    X = np.full((T, M, 3), np.nan)
    for i in range(M):
        xy = np.full((len(names), T, 2), np.nan)
        for k, s in enumerate(names):
            f = np.arange(T) - offsets[s]
            inside = (f >= 0) & (f < len(tr[s].xy))
            okv = np.zeros(T, bool)
            okv[inside] = tr[s].status[f[inside], i] == OK
            xy[k, okv] = tr[s].xy[f[okv], i]
        Xi, nv = triangulate([cams[s] for s in names], xy)
        res = reprojection_residuals([cams[s] for s in names], Xi, xy)
        bad = (np.nan_to_num(res, nan=0.0) > tol).any(axis=0)
        for t in np.nonzero(bad)[0]:
            seen = [k for k in range(len(names)) if np.isfinite(xy[k, t, 0])]
            culprit = None
            if len(seen) >= 3:
                fits = []
                for k in seen:
                    rest = [q for q in seen if q != k]
                    sub = xy[rest][:, t:t + 1]
                    Xr, _ = triangulate([cams[names[q]] for q in rest], sub)
                    rr = reprojection_residuals([cams[names[q]] for q in rest], Xr, sub)
                    rk = reprojection_residuals([cams[names[k]]], Xr, xy[[k]][:, t:t + 1])
                    if np.nanmax(rr) <= tol and rk[0, 0] > tol:
                        fits.append((k, Xr[0]))
                if len(fits) == 1:
                    culprit, X[t, i] = fits[0]
            flag = [culprit] if culprit is not None else seen
            for k in flag:
                s = names[k]
                f = t - offsets[s]
                tr[s].status[f, i] = AMBIGUOUS
                tr[s].reason[f, i] = (f"{res[k, t]:.1f} px off the other views' 3D point"
                                      if culprit is not None else
                                      f"views disagree in 3D ({np.nanmax(res[:, t]):.1f} px)")
        good = ~bad & (nv >= 2)
        X[good, i] = Xi[good]
    return X


def _ballistic(X: np.ndarray, t: int, w: int) -> np.ndarray | None:
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


def _fill_3d(cams, tr, cands, offsets, X, markers, s: TrackSettings, sizes: dict):
    """Search the views where a marker is not ok around its 3D prediction."""
    names = list(cams)
    T, M = X.shape[:2]
    for t in range(T):
        pred = {}
        for i in range(M):
            if np.isfinite(X[t, i]).all():
                pred[i] = (X[t, i], s.epipolar_tol, "the other views")
            else:
                Xb = _ballistic(X[:, i], t, s.ballistic_window)
                if Xb is not None:
                    pred[i] = (Xb, s.epipolar_tol + 2.0, "the ballistic 3D track")
        if not pred:
            continue
        for sname in names:
            f = t - offsets[sname]
            st = tr[sname]
            if not 0 <= f < len(st.xy):
                continue
            c = cands[sname][f]
            cam = cams[sname]
            q = {i: cam.project(p[0][None])[0] for i, p in pred.items()}
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
                taken = [markers[k] for k in range(M) if k != i and st.cand[f, k] == j]
                near = [markers[k] for k, qk in q.items()
                        if k != i and np.hypot(*(c.xy[j] - qk)) < gate]
                dn = neighbour_distance(c, j, s.neighbour_flux)
                if dn < s.min_separation:
                    continue
                ratio = c.flux[j] / st.flux[i] if np.isfinite(st.flux[i]) else 1.0
                if taken or near or ratio > s.merge_flux or ratio < s.low_flux \
                        or c.elongation[j] > s.max_elongation:
                    continue
                st.xy[f, i], st.sigma[f, i], st.cand[f, i] = c.xy[j], c.sigma[j], j
                st.status[f, i] = OK
                st.reason[f, i] = f"found at the 3D prediction from {source}"


def track_markers(frames: dict, cameras: dict, seeds: pd.DataFrame, markers,
                  exposures, *, backgrounds: dict | None = None,
                  offsets: dict | None = None,
                  settings: TrackSettings | None = None) -> TrackResult:
    """The marker table of one jump from synchronized videos (module doc).

    Parameters
    ----------
    frames : dict station -> (F, H, W) uint8
        The videos; the first station is the reference of the sync offsets.
    cameras : dict station -> ViewCamera
        The (estimated) orientation of every station in ``frames``.
    seeds : DataFrame
        station, frame, marker, x, y: one click per marker per station
        (frame: of that station's video; x, y: photogram image frame).
    markers : sequence of str
        Marker names in table order (P1, P2, ...).
    exposures : DataFrame (exposure, frame) or dict exposure -> frame
        The exposures, as frames of the reference camera.
    backgrounds : dict station -> Background, optional
        Estimated from the frames when not given.
    offsets : dict station -> int, optional
        Frames each camera started late against the first: reference frame
        ``t`` is frame ``t - offsets[s]`` of camera ``s``; estimated
        (:func:`photogram.track.sync.estimate_offsets`) when not given.
    settings : TrackSettings, optional

    Returns
    -------
    TrackResult
        ``table`` has the columns :data:`COLUMNS`: one row per exposure,
        station and marker; x, y, sigma NaN unless status is ok.
    """
    s = settings or TrackSettings()
    markers = [str(m) for m in markers]
    names = list(frames)
    missing = [n for n in names if n not in cameras]
    if missing:
        raise InputError("no orientation for camera " + ", ".join(missing),
                         hint="give a ViewCamera for every video")
    clicks = seed_clicks(seeds)
    unknown = sorted(set(clicks) - set(names))
    if unknown:
        raise InputError("seed clicks for unknown station " + ", ".join(unknown),
                         hint="stations: " + ", ".join(names))
    expo = exposure_frames(exposures)
    backgrounds = backgrounds or {n: estimate_background(frames[n]) for n in names}
    cands = {n: [detect_markers(fr, backgrounds[n], k=s.k_sigma, pixel_offset=s.pixel_offset)
                 for fr in frames[n]]
             for n in names}
    for n in names:
        if not any(len(c) for c in cands[n]):
            raise InputError(f"camera {n} shows no bright blob in front of the background "
                             f"in any of its {len(frames[n])} frames",
                             hint="check that the video is the right one and not blank, "
                                  "or leave the camera out")
    tr = {n: track_station(cands[n], clicks.get(n, {}), markers, n, s) for n in names}
    sync = None
    if offsets is None:
        ok_xy = {n: np.where((tr[n].status == OK)[..., None], tr[n].xy, np.nan)
                 for n in names}
        sync = estimate_offsets(ok_xy, {n: cameras[n] for n in names}, s.max_offset)
        offsets = dict(sync.offsets)
    offsets = {n: int(offsets.get(n, 0)) for n in names}
    F = len(frames[names[0]])
    cams = {n: cameras[n] for n in names}
    X = _check_3d(cams, tr, offsets, F, len(markers), s.epipolar_tol)
    sizes = {n: (frames[n].shape[2], frames[n].shape[1]) for n in names}
    _fill_3d(cams, tr, cands, offsets, X, markers, s, sizes)
    rows = []
    for e, t in expo.items():
        for n in names:
            f = t - offsets[n]
            for i, m in enumerate(markers):
                if not 0 <= f < len(tr[n].xy):
                    rows.append((e, n, m, np.nan, np.nan, np.nan, "lost",
                                 f"frame {f} is not in the video"))
                    continue
                code = int(tr[n].status[f, i])
                good = code == OK
                x, y = tr[n].xy[f, i] if good else (np.nan, np.nan)
                rows.append((e, n, m, float(x), float(y),
                             float(tr[n].sigma[f, i]) if good else np.nan,
                             STATUS[code], str(tr[n].reason[f, i])))
    table = pd.DataFrame(rows, columns=COLUMNS)
    return TrackResult(table, offsets, sync, tr, cands)
