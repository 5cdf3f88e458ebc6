"""Videos of a mocap image source must run at the project's frame rate
(issue 20, bad input): one line naming the camera, before any detector
runs."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from photogram.errors import InputError
from photogram.mocap.sources import open_source


def _video(path, fps, n=5):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (64, 48))
    for _ in range(n):
        w.write(np.zeros((48, 64, 3), np.uint8))
    w.release()
    return path


def _settings(tmp_path, cameras, fps=25.0):
    def error(keypath, what, hint=None):
        return InputError(what, file=tmp_path / "m.prj", line=7, hint=hint)
    src = SimpleNamespace(kind="mediapipe", cameras=cameras, path=None, skeleton=None,
                          network=None)
    return SimpleNamespace(source=src, fps=fps, error=error, skeleton=None)


def test_a_video_at_another_frame_rate_is_named(tmp_path):
    cams = {"C1": _video(tmp_path / "c1.avi", 25.0), "C2": _video(tmp_path / "c2.avi", 30.0)}
    with pytest.raises(InputError, match=r"camera C2: its video c2.avi runs at 30 frames/s, "
                                         r"the project at fps = 25") as exc:
        open_source(_settings(tmp_path, cams), ["C1", "C2"], tmp_path)
    assert exc.value.line == 7


def test_videos_at_the_project_rate_pass_the_check(tmp_path):
    cams = {"C1": _video(tmp_path / "c1.avi", 25.0), "C2": _video(tmp_path / "c2.avi", 25.0)}
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        # past the rate check, the detector is created: without the extra
        # that is the one-line "needs the optional package" error
        with pytest.raises(InputError, match="mediapipe"):
            open_source(_settings(tmp_path, cams), ["C1", "C2"], tmp_path)
    else:
        assert open_source(_settings(tmp_path, cams), ["C1", "C2"], tmp_path).cameras == \
            ["C1", "C2"]
