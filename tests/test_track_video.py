"""photogram.track.video: frames from video files and image folders, and the
checks that the cameras' recordings fit together (issue 19)."""

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")

from photogram.errors import InputError
from photogram.track.video import check_videos, read_frames, read_videos


def _frames(n=6, shape=(48, 64), seed=0):
    rng = np.random.default_rng(seed)
    base = rng.integers(40, 200, shape).astype(np.uint8)
    out = np.repeat(base[None], n, axis=0)
    for i in range(n):                       # a bright square moving right
        out[i, 10:16, 5 + 6 * i:11 + 6 * i] = 250
    return out


def _write_avi(path, frames, fps=30.0):
    h, w = frames.shape[1:]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    assert vw.isOpened()
    for f in frames:
        vw.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
    vw.release()


def _write_folder(path, frames):
    path.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(path / f"{i:06d}.png"), f)


def test_image_folder_is_read_exactly_in_name_order(tmp_path):
    fr = _frames()
    _write_folder(tmp_path / "S1", fr)
    got, fps = read_frames(tmp_path / "S1")
    assert got.dtype == np.uint8 and got.shape == fr.shape
    np.testing.assert_array_equal(got, fr)
    assert np.isnan(fps)
    assert read_frames(tmp_path / "S1", fps=25)[1] == 25.0


def test_colour_images_become_grey(tmp_path):
    fr = _frames(3)
    (tmp_path / "c").mkdir()
    for i, f in enumerate(fr):
        cv2.imwrite(str(tmp_path / "c" / f"{i:06d}.png"), cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
    got, _ = read_frames(tmp_path / "c")
    assert got.ndim == 3
    np.testing.assert_array_equal(got, fr)


def test_mjpg_video_frames_and_rate(tmp_path):
    fr = _frames(8)
    _write_avi(tmp_path / "S1.avi", fr, fps=30)
    got, fps = read_frames(tmp_path / "S1.avi")
    assert got.shape == fr.shape and got.dtype == np.uint8
    assert fps == pytest.approx(30.0)
    # MJPG is lossy (the random texture is its worst case): close, not equal,
    # and the moving square in the right place in the right frame
    assert np.abs(got.astype(int) - fr.astype(int)).mean() < 6.0
    for i in range(8):
        assert got[i, 11:15, 6 + 6 * i:10 + 6 * i].mean() > 230


def test_missing_and_unreadable_inputs_name_the_file(tmp_path):
    with pytest.raises(InputError, match="nope.avi"):
        read_frames(tmp_path / "nope.avi")
    bad = tmp_path / "broken.avi"
    bad.write_bytes(b"this is not a video")
    with pytest.raises(InputError, match="broken.avi") as e:
        read_frames(bad)
    assert "\n" not in str(e.value)
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="empty"):
        read_frames(tmp_path / "empty")
    _write_folder(tmp_path / "S2", _frames(2))
    (tmp_path / "S2" / "000002.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="000002.png"):
        read_frames(tmp_path / "S2")


def test_check_videos_names_the_odd_file_and_the_fix():
    a = (_frames(6), 30.0)
    assert check_videos({"S1": a, "S2": a}) == 30.0
    files = {"S1": "S1.avi", "S2": "S2.avi", "S3": "S3.avi"}
    with pytest.raises(InputError, match=r"S3.avi: 5 frames, S1.avi has 6") as e:
        check_videos({"S1": a, "S2": a, "S3": (_frames(5), 30.0)}, files)
    assert "cut the synchronized recordings" in str(e.value)
    with pytest.raises(InputError, match=r"S2.avi: 25 frames/s, S1.avi has 30"):
        check_videos({"S1": a, "S2": (_frames(6), 25.0)}, files)
    with pytest.raises(InputError, match="S2.avi: frames are 32x48"):
        check_videos({"S1": a, "S2": (_frames(6, (48, 32)), 30.0)}, files)
    # the documented tolerance: 0.1 % (29.97 against 30 is not the same rate)
    assert check_videos({"S1": a, "S2": (_frames(6), 30.02)}) == 30.0
    with pytest.raises(InputError):
        check_videos({"S1": a, "S2": (_frames(6), 29.97)})
    # an image folder has no rate: not compared
    assert check_videos({"S1": (_frames(6), float("nan")), "S2": a}) == 30.0


def test_read_videos_reads_and_checks(tmp_path):
    _write_avi(tmp_path / "S1.avi", _frames(6))
    _write_folder(tmp_path / "S2", _frames(6))
    frames, fps = read_videos({"S1": tmp_path / "S1.avi", "S2": tmp_path / "S2"})
    assert set(frames) == {"S1", "S2"} and fps == pytest.approx(30.0)
    _write_folder(tmp_path / "S3", _frames(4))
    with pytest.raises(InputError, match="S3"):
        read_videos({"S1": tmp_path / "S1.avi", "S3": tmp_path / "S3"})
