"""Jumper markers tracked through synchronized videos: the marker table.

:func:`track_markers` runs the whole chain for one jump:

1. per camera, the median background and the marker candidates of every
   frame (:mod:`photogram.track.background`, :mod:`photogram.track.markers`);
2. per camera, 2D tracks from the seed clicks
   (:mod:`photogram.track.tracks2d`): prediction, gating, and a flag
   instead of a guess;
3. the sync offsets, given or estimated from the 2D tracks
   (:mod:`photogram.track.sync`; an estimate that is not clear is an
   :class:`InputError` naming the camera: a wrong offset would put every
   row of that camera at the wrong instant);
4. **3D** (:mod:`photogram.track.tracks3d`): the systematic reprojection
   error of the estimated orientation per camera, then per reference frame
   and marker the ``ok`` views are triangulated and checked (a view that
   disagrees is flagged ``ambiguous``), and every view where the marker is
   not ``ok`` is searched again at the projection of its 3D point (from the
   other views, or from its ballistic 3D track): labels survive short
   occlusions in one camera;
5. the sigmas: a marker's centre sigma is at least the scatter of its own
   track about a local quadratic in time
   (:func:`photogram.track.tracks2d.scatter_sigma`);
6. the table of the exposures.

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
from photogram.track.sync import SyncResult, estimate_offsets
from photogram.track.tracks2d import OK, STATUS, TrackSettings, scatter_sigma, track_station
from photogram.track.tracks3d import check_3d, fill_3d, view_bias

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
    notes: list = field(default_factory=list)     # e.g. a seed click that was not used


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
        sync = estimate_offsets(ok_xy, {n: cameras[n] for n in names}, s.max_offset,
                                max_cost=s.sync_tol)
        for n, clear in sync.clear.items():
            if not clear:
                c = sync.cost[n]
                ranked = sorted(c, key=c.get)[:2]
                raise InputError(
                    f"the sync offset of camera {n} is not clear: median epipolar distance "
                    + ", ".join(f"{c[d]:.2f} px at offset {d}" for d in ranked),
                    hint="the orientation may not fit the markers; give the offsets, "
                         "the frames each camera started late")
        offsets = dict(sync.offsets)
    offsets = {n: int(offsets.get(n, 0)) for n in names}
    F = len(frames[names[0]])
    cams = {n: cameras[n] for n in names}
    bias = view_bias(cams, tr, offsets, F, len(markers))
    X = check_3d(cams, tr, offsets, F, len(markers), s.epipolar_tol, bias)
    sizes = {n: (frames[n].shape[2], frames[n].shape[1]) for n in names}
    fill_3d(cams, tr, cands, offsets, X, markers, s, sizes, bias)
    # the sigma of a track is at least its own scatter (tracks2d.scatter_sigma)
    for n in names:
        for i in range(len(markers)):
            ok = tr[n].status[:, i] == OK
            emp = scatter_sigma(tr[n].xy[:, i], ok)
            if np.isfinite(emp):
                tr[n].sigma[ok, i] = np.maximum(tr[n].sigma[ok, i], emp)
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
    return TrackResult(table, offsets, sync, tr, cands, [n for t in tr.values() for n in t.notes])
