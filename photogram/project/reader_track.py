"""The ``[track]`` section: markers and ski lines tracked in videos (issue 19,
docs/track.md).

A .prj with a ``[track]`` section is a tracking project: ``[project]``,
``[cameras]`` and ``[stations]`` as usual (the interior orientation of the
lab calibration, the exterior of ``photogram orient``), ``[output]``, and
no ``[observations]``: ``photogram track`` writes them (the
``jumper_points.csv`` and ``ski_lines.csv`` that ``photogram intersect``
reads). This module checks types, choices and that the files exist, every
error with file and line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from photogram.project.toml_source import Section

__all__ = ["TrackSettings", "read_track_section", "TRACK_KEYS"]

TRACK_KEYS = ("videos", "seeds", "exposures", "fps", "markers", "skis", "ski_markers",
              "offsets", "ski_length", "binding_fraction", "points_per_ski", "truth",
              "max_seed_distance")


@dataclass
class TrackSettings:
    """``[track]`` of a tracking project (paths resolved against the .prj).

    ``videos``: station -> video file or image folder; ``seeds``: the seed
    clicks (station, frame, marker, x, y); ``exposures``: the frame of each
    exposure (exposure, frame); ``markers``: the jumper points (P1 helmet,
    P2 hip, P3 right and P4 left binding); ``skis``: the right and left ski
    lines and ``ski_markers`` the binding marker of each; ``offsets``: the
    synchronisation offset of each station in frames (a station's video
    starts that many frames late), or None to estimate them;
    ``ski_length`` in metres; ``truth``: an optional folder of simulated
    truth to compare with (report only).
    """

    videos: dict = field(default_factory=dict)
    seeds: Path | None = None
    exposures: Path | None = None
    fps: float = 30.0
    markers: tuple = ("P1", "P2", "P3", "P4")
    skis: tuple = ("L1", "L2")
    ski_markers: tuple = ("P3", "P4")
    offsets: dict | None = field(default_factory=dict)
    ski_length: float = 2.63
    binding_fraction: float = 0.43
    points_per_ski: int = 15
    truth: Path | None = None
    max_seed_distance: float = 6.0
    lines: dict = field(default_factory=dict)     # key -> line in the .prj (messages)

    def where(self, key: str) -> int | None:
        return self.lines.get(key)


def _file(sec: Section, key: str, prj: Path, *, folder_ok: bool = False,
          folder_only: bool = False, value=None) -> Path:
    text = sec.string(key) if value is None else value
    p = Path(text)
    full = p if p.is_absolute() else prj.parent / p
    ok = full.is_dir() if folder_only else (full.is_file() or folder_ok and full.is_dir())
    if not ok:
        what = "folder" if folder_only else "file or image folder" if folder_ok else "file"
        raise sec.error(key, f"{key} in {sec.label}: {what} {text} not found",
                        hint="paths are relative to the folder of the .prj file"
                             + ("; make demo renders the example videos" if key == "videos"
                                else ""))
    return full


def read_track_section(sec: Section, prj: Path, stations: list[str]) -> TrackSettings:
    """``[track]`` (see :class:`TrackSettings`); ``stations``: the ids of
    the project's stations (every video must name one, every station with
    a video takes part)."""
    sec.check_keys(TRACK_KEYS, required=("videos", "seeds", "exposures"))
    out = TrackSettings()
    vids = sec.data["videos"]
    if not isinstance(vids, dict) or not vids:
        raise sec.error("videos", f"videos in {sec.label} must be a table station = path",
                        hint='e.g. videos = { S1 = "video/S1.avi", S2 = "video/S2.avi" }')
    videos = {}
    for name, value in vids.items():
        if name not in stations:
            raise sec.error("videos", f"videos in {sec.label} names station {name!r}, which "
                                      f"[stations] does not have",
                            hint="use the station ids of [stations]: " + ", ".join(stations))
        if not isinstance(value, str):
            raise sec.error("videos", f"the video of {name} in {sec.label} must be a path "
                                      f"(text)", hint=f'e.g. {name} = "video/{name}.avi"')
        videos[name] = _file(sec, "videos", prj, folder_ok=True, value=value)
    if len(videos) < 2:
        raise sec.error("videos", f"{sec.label} needs videos of at least 2 stations, not "
                                  f"{len(videos)}", hint="a 3D track needs two views")
    markers = tuple(sec.ids("markers", list(out.markers)))
    skis = tuple(sec.ids("skis", list(out.skis)))
    ski_markers = tuple(sec.ids("ski_markers", list(out.ski_markers)))
    if len(markers) != 4:
        raise sec.error("markers", f"markers in {sec.label} must name 4 points, not "
                                   f"{len(markers)}",
                        hint='markers = ["P1", "P2", "P3", "P4"] (helmet, hip, right and '
                             'left binding)')
    if len(skis) != 2 or len(ski_markers) != 2:
        key = "skis" if len(skis) != 2 else "ski_markers"
        raise sec.error(key, f"{key} in {sec.label} must name 2 entries",
                        hint='skis = ["L1", "L2"] and ski_markers = ["P3", "P4"] (right, '
                             'left)')
    for m in ski_markers:
        if m not in markers:
            raise sec.error("ski_markers", f"ski marker {m!r} in {sec.label} is not one of "
                                           f"the markers {list(markers)}",
                            hint="each ski's binding marker, e.g. P3 (right), P4 (left)")
    offsets: dict | None = {}
    if "offsets" in sec:
        value = sec.data["offsets"]
        if value == "estimate":
            offsets = None
        elif isinstance(value, dict) and all(isinstance(v, int) and not isinstance(v, bool)
                                             for v in value.values()):
            for name in value:
                if name not in videos:
                    raise sec.error("offsets", f"offsets in {sec.label} names {name!r}, which "
                                               f"has no video",
                                    hint="stations with a video: " + ", ".join(videos))
            offsets = {k: int(v) for k, v in value.items()}
        else:
            raise sec.error("offsets", f"offsets in {sec.label} must be a table station = "
                                       f"frames or \"estimate\"",
                            hint='e.g. offsets = { S3 = 2 } or offsets = "estimate"')
    lines = {k: sec.source.line_of(sec.keypath + (k,)) for k in sec.data}
    return TrackSettings(
        videos=videos, seeds=_file(sec, "seeds", prj), exposures=_file(sec, "exposures", prj),
        fps=sec.number("fps", out.fps, positive=True), markers=markers, skis=skis,
        ski_markers=ski_markers, offsets=offsets,
        ski_length=sec.number("ski_length", out.ski_length, positive=True),
        binding_fraction=sec.number("binding_fraction", out.binding_fraction, positive=True,
                                    below=1.0),
        points_per_ski=sec.integer("points_per_ski", out.points_per_ski, minimum=2),
        truth=_file(sec, "truth", prj, folder_only=True) if "truth" in sec else None,
        max_seed_distance=sec.number("max_seed_distance", out.max_seed_distance,
                                     positive=True),
        lines=lines)
