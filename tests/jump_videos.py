"""The rendered jump videos of :mod:`photogram.simulation.jump_video`, the
normal and the harsh set, rendered once per test session.

Rendering a set costs 8-11 s CPU, and five test modules (test_track_bindings,
_command, _markers, _skis, _tracks) track the same two sets; they used to
render them again each. :func:`rendered_videos` renders a set the first time
it is asked for and keeps it; its frames are read-only arrays, so that no
test can change the frames another one sees (a write raises). The frames are
those of ``render_jump_videos(VideoSettings())`` and
``render_jump_videos(harsh_settings())`` bit for bit: rendering is seeded
per station and frame."""

from __future__ import annotations

from functools import lru_cache

import pytest

SETS = ("normal", "harsh")


@lru_cache(maxsize=len(SETS))
def _render(kind: str):
    from photogram.simulation.jump_video import VideoSettings, harsh_settings, render_jump_videos
    v = render_jump_videos({"normal": VideoSettings, "harsh": harsh_settings}[kind]())
    for frames in v.frames.values():
        frames.flags.writeable = False
    return v


def rendered_videos(kind: str):
    """The rendered ``kind`` set ("normal" or "harsh"): a
    :class:`~photogram.simulation.jump_video.JumpVideos` shared by the whole
    session (do not change it; its frames are read-only)."""
    pytest.importorskip("photogram.simulation.jump_video")
    if kind not in SETS:
        raise ValueError(f"kind must be one of {SETS}, not {kind!r}")
    return _render(kind)


@lru_cache(maxsize=len(SETS))
def _written(kind: str, folder: str):
    from photogram.simulation.jump_video import write_jump_videos
    return write_jump_videos(rendered_videos(kind), folder)


def written_videos(kind: str, tmp_path_factory):
    """The ``kind`` set written as by ``photogram.simulation.jump_video``
    (S1-S3.avi, seeds.csv, frames.csv, truth) into a folder of the session,
    once; tests that change files copy it first."""
    folder = tmp_path_factory.getbasetemp() / f"jump-videos-{kind}" / "video"
    return _written(kind, str(folder))


MARKERS = ("P1", "P2", "P3", "P4")


@lru_cache(maxsize=len(SETS))
def _tracked(kind: str):
    from photogram.track.background import estimate_background
    from photogram.track.tracks import track_markers
    v = rendered_videos(kind)
    ref = v.exposure_frames[next(iter(v.frames))]            # frames of the first camera
    ex = {f"{i + 1:03d}": int(f) for i, f in enumerate(ref)}
    bgs = {s: estimate_background(F) for s, F in v.frames.items()}
    return bgs, track_markers(v.frames, v.cameras, v.seeds, list(MARKERS), ex, backgrounds=bgs)


def tracked_markers(kind: str):
    """``(backgrounds, TrackResult)``: the ``kind`` set's backgrounds
    (:func:`~photogram.track.background.estimate_background` per camera)
    and ``track_markers`` of its frames, cameras and seed clicks, markers
    P1-P4, the exposures as frames of the first camera, the sync offsets
    estimated, default settings; computed once per session for
    tests/test_track_tracks.py and tests/test_track_bindings.py (they ran
    the same call, 1-2 s CPU a set, and got the same table). Read-only:
    copy the table before changing it."""
    return _tracked(kind)
