"""The inputs of ``photogram track`` besides the videos: the oriented views
of the project, the seed clicks and the frame of each exposure (docs/track.md).

Every error is one line naming the file and record, what is wrong and how to
fix it (:class:`photogram.errors.InputError`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from photogram.errors import InputError
from photogram.lines.views import ViewCamera
from photogram.project.tables import read_table

__all__ = ["view_cameras", "read_seeds", "read_exposures", "Exposures"]


def view_cameras(project, stations=None) -> dict[str, ViewCamera]:
    """The oriented views of a project's stations (``[cameras]`` interior,
    ``[stations]`` exterior orientation: the results of calibrate and
    orient), as :class:`~photogram.lines.views.ViewCamera` (world-to-camera
    rotation, projection centre, interior parameters in the image unit).

    Raises
    ------
    InputError
        A station without a position or angles (not oriented yet).
    """
    st = project.stations
    out = {}
    for i, name in enumerate(st.names):
        if stations is not None and name not in stations:
            continue
        X0, ang = np.asarray(st.position[i], float), np.asarray(st.angles[i], float)
        if not (np.all(np.isfinite(X0)) and np.all(np.isfinite(ang))):
            raise InputError(f"station {name} has no exterior orientation",
                             file=project.sources.get("stations", project.path),
                             line=int(st.record[i]) if len(st.record) else None,
                             hint="take [stations] from the results of photogram orient "
                                  "(stations.csv)")
        cam = project.cameras[st.camera[i]]
        out[name] = ViewCamera.from_angles(ang, X0, np.asarray(cam.values(), float),
                                           cam.model, name)
    return out


def read_seeds(path, *, stations, markers, n_frames: dict) -> pd.DataFrame:
    """The seed clicks: CSV ``station,frame,marker,x,y`` (pixels, the
    project's image convention), at most one per marker and station.

    Parameters
    ----------
    path : path of the CSV
    stations : the stations with a video
    markers : the marker names of ``[track]``
    n_frames : station -> number of frames of its video

    Returns
    -------
    DataFrame with columns station, frame (int), marker, x, y and ``record``
    (the line in the file, for messages).
    """
    t = read_table(path, required=("station", "frame", "marker", "x", "y"), what="seeds table")
    station, marker = t.text("station"), t.text("marker")
    frame, x, y = t.floats("frame", required=True), t.floats("x", required=True), \
        t.floats("y", required=True)
    seen = set()
    for i, (s, m, f) in enumerate(zip(station, marker, frame)):
        if s not in stations:
            raise t.error(i, f"seed of station {s!r}, which has no video",
                          hint="stations with a video: " + ", ".join(stations))
        if m not in markers:
            raise t.error(i, f"seed of marker {m!r}, which [track] markers does not name",
                          hint="markers: " + ", ".join(markers))
        if not (np.isfinite(f) and f == int(f) and 0 <= f < n_frames[s]):
            raise t.error(i, f"seed frame {f:g} is not a frame of the video of {s} "
                             f"(0..{n_frames[s] - 1})", hint="frames count from 0")
        if (s, m) in seen:
            raise t.error(i, f"a second seed of marker {m} in station {s}",
                          hint="one click per marker and station (in any one frame)")
        seen.add((s, m))
    return pd.DataFrame({"station": station, "frame": frame.astype(int), "marker": marker,
                         "x": x, "y": y, "record": t.records})


@dataclass
class Exposures:
    """The exposures (ids "001", ...) and the frame of each in a video that
    starts in sync (a station's offset is added)."""

    ids: list
    frames: np.ndarray

    def in_station(self, offset: int) -> np.ndarray:
        """The frames of the exposures in a video that starts ``offset``
        frames late (its frame k shows the time of frame k + offset)."""
        return self.frames - int(offset)


def read_exposures(path, *, n_frames: dict, offsets: dict | None) -> Exposures:
    """The exposures: CSV ``exposure,frame`` (ids as written, e.g. 001).

    Every exposure must be a frame of every video after its offset.
    """
    t = read_table(path, required=("exposure", "frame"), what="exposures table")
    ids, frame = t.text("exposure"), t.floats("frame", required=True)
    if len(set(ids)) != len(ids):
        dup = next(i for i, e in enumerate(ids) if ids.index(e) != i)
        raise t.error(dup, f"exposure {ids[dup]} is listed twice", hint="one row per exposure")
    bad = np.flatnonzero(~np.isfinite(frame) | (frame != np.round(frame)))
    if len(bad):
        raise t.error(int(bad[0]), "frame must be an integer", hint="frames count from 0")
    if np.any(np.diff(frame) <= 0):
        i = int(np.flatnonzero(np.diff(frame) <= 0)[0]) + 1
        raise t.error(i, "the exposures' frames must increase", hint="one row per frame, in order")
    frame = frame.astype(int)
    for s, n in n_frames.items():
        off = (offsets or {}).get(s, 0)
        local = frame - off
        out = np.flatnonzero((local < 0) | (local >= n))
        if len(out):
            i = int(out[0])
            raise t.error(i, f"exposure {ids[i]} (frame {frame[i]}) is not in the video of "
                             f"{s} ({n} frames, offset {off})",
                          hint="check the frames, the offsets or the video")
    return Exposures(list(ids), frame)
