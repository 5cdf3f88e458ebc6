"""Video projects (``[track]``, docs/track.md) in ``photogram measure
--serve``: one view per exposure and station, showing the exposure's frame
of the station's recording in colour.

The exposures are the project's exposures table (``exposure, frame`` in
synchronous frames); a station whose video starts ``d`` frames late
(``[track] offsets``, else the offsets ``photogram track`` estimated and
wrote into its summary.json, else 0) shows frame ``frame - d``
(:meth:`photogram.track.inputs.Exposures.in_station`). The tables edited
are what ``photogram track`` wrote into its output folder:
``jumper_points.csv`` (exposure, station, point, x, y, sigma) and
``ski_lines.csv`` (exposure, station, line, x, y, sigma).
"""

from __future__ import annotations

import json
from pathlib import Path

from photogram.errors import InputError
from photogram.project.tables import read_table
from photogram.serve.sources import View

__all__ = ["video_views", "track_tables"]

def _offsets(project) -> dict:
    given = project.track.offsets
    if isinstance(given, dict) and given:
        return {k: int(v) for k, v in given.items()}
    summary = project.output_folder() / "summary.json"
    try:
        data = json.loads(summary.read_text(encoding="utf-8"))
        return {str(k): int(v) for k, v in (data.get("offsets") or {}).items()}
    except (OSError, ValueError, TypeError, AttributeError):
        return {}


def video_views(project) -> tuple[list[View], list[str]]:
    """The views (exposure-major, stations in the project's order) and the
    exposure ids of a ``[track]`` project.

    Raises
    ------
    InputError
        No exposures table in ``[track]``, or it cannot be read.
    """
    tr = project.track
    if tr.exposures is None:
        raise InputError("the [track] section names no exposures table (exposures = ...)",
                         file=project.path, hint="give exposures = \"video/frames.csv\"")
    t = read_table(tr.exposures, required=("exposure", "frame"), what="exposures table")
    ids, frames = t.text("exposure"), t.floats("frame", required=True)
    offsets = _offsets(project)
    st = project.stations
    views = []
    for e, f in zip(ids, frames):
        for name, cam in zip(st.names, st.camera):
            size = project.cameras[cam].image_size or (0, 0)
            video = tr.videos.get(name)
            v = View(id=f"{e}/{name}", station=name, exposure=e, video=video,
                     frame=int(f) - offsets.get(name, 0), width=int(size[0]), height=int(size[1]))
            if video is None:
                v.error = f"no video for station {name} in [track] videos"
            views.append(v)
    return views, list(ids)


def track_tables(project) -> tuple[Path, Path | None]:
    """The points and lines tables ``photogram track`` wrote (module doc).

    Raises
    ------
    InputError
        No jumper_points.csv in the output folder.
    """
    folder = project.output_folder()
    points = folder / "jumper_points.csv"
    if not points.is_file():
        raise InputError(f"no tracked observations {points}",
                         hint=f"run photogram track {project.path} first")
    lines = folder / "ski_lines.csv"
    return points, (lines if lines.is_file() else None)
