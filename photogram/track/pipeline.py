"""``photogram track``: from the videos of a jump to the observations of
``photogram intersect`` (issue 19, docs/track.md).

1. read the videos (:mod:`photogram.track.video`; lengths, frame sizes and
   rates checked), the seed clicks and the exposure frames
   (:mod:`photogram.track.inputs`), the oriented views of the project;
2. per camera the median background (:mod:`photogram.track.background`);
3. the markers (:func:`photogram.track.tracks.track_markers`): candidates,
   2D tracks from the seeds, sync offsets (given or estimated), 3D checks
   and the ballistic prediction; flagged, never guessed;
4. the merged binding markers split
   (:func:`photogram.track.bindings.split_merged_bindings`): two spots of
   the single markers' shape in one blob, labels from the three views and
   the jumper's right, or left ambiguous;
5. the ski lines (:func:`photogram.track.skis.track_skis`) in bands
   predicted from the binding markers, left/right by the three-view check;
6. the tables: ``jumper_points.csv`` keeps a marker of an exposure only
   where at least two stations found it (one ray fixes no point; the
   single observation stays in ``tracking.csv`` with the reason), and
   ``ski_lines.csv`` a ski only where at least two stations found it.

Offsets: ``[track] offsets = { S3 = 2 }`` means S3's video starts 2 frames
late (its frame k shows the time of frame k + 2 of a synchronous video;
``frames.csv`` gives the exposures in synchronous frames). The marker
tracker counts them against its first station (:func:`_tracker_offsets`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from photogram.errors import InputError
from photogram.track.background import estimate_background
from photogram.track.bindings import split_merged_bindings
from photogram.track.inputs import Exposures, read_exposures, read_seeds, view_cameras
from photogram.track.skis import track_skis
from photogram.track.tracks import track_markers
from photogram.track.tracks2d import TrackSettings
from photogram.track.video import read_videos

__all__ = ["TrackingRun", "track_project", "track_videos"]

_TO_M = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001}


@dataclass
class TrackingRun:
    """What ``photogram track`` found.

    Attributes
    ----------
    markers : DataFrame
        ``exposure, station, marker, x, y, sigma, status, reason``: every
        marker of every exposure and station (status ok, lost, ambiguous).
    skis : DataFrame
        ``exposure, station, line, x, y, sigma``: points along each ski.
    ski_checks : DataFrame
        ``exposure, status, swapped, detail``: the left/right check.
    ski_flags : DataFrame
        ``exposure, station, line, reason``: skis not found in an image, or
        found and left out (labels not decided, off their sequence).
    ski_sequence : DataFrame
        ``station, line, n, s0, scale, outliers``: per view and ski the
        variance factor of its directions over the exposures and the scale
        applied to its sigmas (:mod:`photogram.track.ski_sequence`).
    midpoints : DataFrame
        ``exposure, station, x, y, sigma, split``: the centre of each merged
        binding blob (the image of the binding midpoint), split or not.
    offsets : dict
        station -> frames its video starts late (the ``[track]`` convention).
    exposures : Exposures
    frames : dict station -> (F, H, W) uint8
    summary : dict
        Counts, flags, offsets, timings (and the truth check).
    log : list of str
    """

    markers: pd.DataFrame
    skis: pd.DataFrame
    ski_checks: pd.DataFrame
    ski_flags: pd.DataFrame
    offsets: dict
    exposures: Exposures
    frames: dict
    summary: dict = field(default_factory=dict)
    log: list = field(default_factory=list)
    midpoints: pd.DataFrame | None = None
    ski_sequence: pd.DataFrame | None = None

    def jumper_points(self) -> pd.DataFrame:
        """``exposure, station, point, x, y, sigma`` of the markers found in
        at least two stations at their exposure."""
        ok = self.markers[self.markers.status == "ok"]
        n = ok.groupby(["exposure", "marker"]).station.transform("size")
        ok = ok[n >= 2]
        return ok.rename(columns={"marker": "point"})[
            ["exposure", "station", "point", "x", "y", "sigma"]].reset_index(drop=True)

    def ski_lines(self) -> pd.DataFrame:
        """``exposure, station, line, x, y, sigma`` of the skis found in at
        least two stations at their exposure."""
        t = self.skis
        if not len(t):
            return t[["exposure", "station", "line", "x", "y", "sigma"]]
        views = t.groupby(["exposure", "line"]).station.transform("nunique")
        return t[views >= 2][["exposure", "station", "line", "x", "y", "sigma"]] \
            .reset_index(drop=True)


def _tracker_offsets(offsets: dict, stations: list) -> dict:
    """``[track]`` offsets (a video starting d frames late against a
    synchronous one) -> the marker tracker's (frames late against the first
    station)."""
    ref = offsets.get(stations[0], 0)
    return {s: offsets.get(s, 0) - ref for s in stations}


def track_videos(frames, cameras, seeds, exposures: Exposures, *, markers, skis, ski_markers,
                 offsets, ski_length, binding_fraction, points_per_ski, length_unit=1.0,
                 log=None):
    """The tracking chain on arrays (module doc, steps 2-4).

    Parameters
    ----------
    frames : dict station -> (F, H, W) uint8
    cameras : dict station -> ViewCamera
    seeds : DataFrame station, frame, marker, x, y
    exposures : Exposures (frames of a synchronous video)
    markers, skis, ski_markers : names (``[track]``)
    offsets : dict station -> frames late, or None to estimate them
    ski_length : in the length unit of the cameras
    binding_fraction, points_per_ski : as ``[track]``
    length_unit : metres per length unit of the cameras (0.1: dm)

    Returns
    -------
    TrackingRun (without ``summary``)
    """
    log = [] if log is None else log
    stations = list(frames)
    timings = {}
    t = time.perf_counter()
    backgrounds = {s: estimate_background(frames[s]) for s in stations}
    timings["background_s"] = time.perf_counter() - t
    given = offsets is not None
    ref_offset = (offsets or {}).get(stations[0], 0)
    ex = pd.DataFrame({"exposure": exposures.ids, "frame": exposures.frames - ref_offset})
    t = time.perf_counter()
    mt = track_markers(frames, cameras, seeds[["station", "frame", "marker", "x", "y"]],
                       list(markers), ex, backgrounds=backgrounds,
                       offsets=_tracker_offsets(offsets, stations) if given else None)
    timings["markers_s"] = time.perf_counter() - t
    log.extend(mt.notes)
    # back to the [track] convention (the first station's offset stays as given)
    used = {s: ref_offset + int(mt.offsets.get(s, 0)) for s in stations}
    if not given:
        log.append("sync offsets estimated: " + ", ".join(f"{s} {v:+d}" for s, v in used.items())
                   + (f" ({mt.sync.summary()})" if mt.sync is not None else ""))
    frames_of = {s: exposures.in_station(used[s]) for s in stations}
    t = time.perf_counter()
    table, split = split_merged_bindings(mt.table, frames, backgrounds, cameras, frames_of,
                                         pair=tuple(ski_markers), hip=markers[1],
                                         length_unit=length_unit, candidates=mt.candidates,
                                         k_sigma=TrackSettings().k_sigma)
    timings["bindings_s"] = time.perf_counter() - t
    c = split.counts
    log.append("merged binding blobs: " + ", ".join(f"{k} {v}" for k, v in c.items()))
    t = time.perf_counter()
    st = track_skis(frames, {s: backgrounds[s].median for s in stations}, cameras, table,
                    frames_of, skis=dict(zip(skis, ski_markers)), ski_length=ski_length,
                    binding_fraction=binding_fraction, points_per_ski=points_per_ski,
                    helmet=markers[0], hip=markers[1], midpoints=split.midpoints)
    timings["skis_s"] = time.perf_counter() - t
    run = TrackingRun(markers=table, skis=st.table, ski_checks=st.checks, ski_flags=st.flags,
                      offsets=used, exposures=exposures, frames=frames, log=log,
                      midpoints=split.midpoints, ski_sequence=st.sequence)
    run.summary["timings"] = timings
    return run


def track_project(project) -> TrackingRun:
    """Track the videos of a tracking project (a .prj with ``[track]``)."""
    ts = project.track
    if ts is None:
        raise InputError("the project has no [track] section", file=project.path,
                         hint="photogram track reads a tracking project (docs/track.md)")
    log = []
    t0 = time.perf_counter()
    frames, fps = read_videos({s: str(p) for s, p in ts.videos.items()}, ts.fps)
    if np.isfinite(fps) and abs(fps - ts.fps) > 1e-3 * ts.fps:
        raise InputError(f"the videos run at {fps:g} frames/s, [track] fps says {ts.fps:g}",
                         file=project.path, line=ts.where("fps"),
                         hint=f"set fps = {fps:g} in [track] (or use videos of that rate)")
    t_read = time.perf_counter() - t0
    n_frames = {s: len(v) for s, v in frames.items()}
    stations = list(frames)
    cameras = view_cameras(project, stations)
    seeds = read_seeds(ts.seeds, stations=stations, markers=list(ts.markers), n_frames=n_frames)
    exposures = read_exposures(ts.exposures, n_frames=n_frames, offsets=ts.offsets or {})
    to_unit = _TO_M[project.units.length]
    run = track_videos(frames, cameras, seeds, exposures, markers=ts.markers, skis=ts.skis,
                       ski_markers=ts.ski_markers, offsets=ts.offsets,
                       ski_length=ts.ski_length / to_unit,
                       binding_fraction=ts.binding_fraction, points_per_ski=ts.points_per_ski,
                       length_unit=to_unit, log=log)
    run.summary["timings"]["read_s"] = t_read
    run.summary["timings"]["total_s"] = time.perf_counter() - t0
    n_cam_frames = sum(n_frames.values())
    # camera frames per second of this (single-threaded) run: the rate at
    # which one core keeps up with one camera; and synchronized frame sets
    total = max(run.summary["timings"]["total_s"], 1e-9)
    run.summary["timings"]["camera_frames_per_s"] = n_cam_frames / total
    run.summary["timings"]["frame_sets_per_s"] = n_cam_frames / total / len(stations)
    run.summary.update(_summary(project, run))
    run.summary["warnings"] = [line for line in log if "not used" in line]
    if ts.truth is not None:
        from photogram.track.truth_check import compare_with_truth
        run.summary["truth"] = compare_with_truth(run, ts.truth)
    return run


def _summary(project, run: TrackingRun) -> dict:
    m = run.markers
    ts = project.track
    E, S = len(run.exposures.ids), len(run.frames)
    flagged = m[m.status != "ok"]
    jp, sl = run.jumper_points(), run.ski_lines()
    swapped = run.ski_checks[run.ski_checks.status == "swapped"] if len(run.ski_checks) else []
    return {
        "command": "track", "status": "done", "exposures": E, "stations": list(run.frames),
        "markers": list(ts.markers), "skis": list(ts.skis),
        "offsets": run.offsets, "offsets_estimated": ts.offsets is None,
        "markers_expected": int(E * S * len(ts.markers)),
        "markers_found": int((m.status == "ok").sum()),
        "flagged_markers": int(len(flagged)),
        "flags": {k: int(v) for k, v in flagged.status.value_counts().items()},
        "jumper_points_rows": int(len(jp)),
        "ski_lines_expected": int(E * S * len(ts.skis)),
        "ski_lines_found": int(run.skis.groupby(["exposure", "station", "line"]).ngroups)
        if len(run.skis) else 0,
        "ski_lines_rows": int(len(sl)),
        "ski_flags": int(len(run.ski_flags)),
        "swapped_skis": int(len(swapped)),
        "ski_checks": {str(r.exposure): str(r.status) for r in run.ski_checks.itertuples()},
        "ski_sequence": [] if run.ski_sequence is None else [
            {"station": str(r.station), "line": str(r.line), "n": int(r.n),
             "s0": round(float(r.s0), 3), "scale": round(float(r.scale), 3),
             "outliers": int(r.outliers)} for r in run.ski_sequence.itertuples()],
        "warnings": [],
    }
