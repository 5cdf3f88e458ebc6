"""Video projects ([track]) in photogram measure --serve
(photogram/serve/video.py): a small made-up track project with two
stations whose recordings are folders of PNG frames (frame k is uniform
grey level 10 k, so the frame shown is known exactly) and one AVI file;
the tracked tables in results-track/."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from serve_fixtures import tiny_video_project



@pytest.fixture
def video(tmp_path):
    from photogram.serve.session import Session
    with Session(tiny_video_project(tmp_path / "tiny")) as s:
        yield s


def test_views_are_exposure_frames_with_offsets(video):
    body = video.body()
    assert body["exposures"] == ["001", "002"]
    assert [v["id"] for v in body["views"]] == ["001/S1", "001/S2", "002/S1", "002/S2"]
    assert body["points"] == ["P1", "P2", "P3", "P4"]
    assert body["oriented"] and "oriented from the project" in body["orientation_note"]
    assert [o["view"] for o in body["observations"]] == ["001/S1", "001/S2", "002/S1"]
    assert body["lines"][0]["view"] == "001/S1" and body["lines"][0]["line"] == "L1"
    # exposure 001 = synchronous frame 3: S1 shows its frame 3, S2 (2 late) its frame 1
    for view, level in (("001/S1", 30), ("001/S2", 10), ("002/S1", 40), ("002/S2", 20)):
        img = cv2.imdecode(np.frombuffer(video.images.png(view), np.uint8), cv2.IMREAD_COLOR)
        assert img.shape == (48, 64, 3) and (img == level).all(), view


def test_edits_keep_the_exposure_and_epipolar_stays_in_it(video):
    body = video.edit({"op": "add", "view": "002/S2", "point": "P1", "x": 21, "y": 24})
    assert body["observations"][-1]["view"] == "002/S2"
    # P1 of exposure 002 may be added in S2, but not twice
    from photogram.serve.table import BadEdit
    with pytest.raises(BadEdit, match="already measured"):
        video.edit({"op": "add", "view": "002/S2", "point": "P1", "x": 1, "y": 2})
    video.save()
    text = (video.points_table.path).read_text(encoding="utf-8").splitlines()
    assert text[0] == "# tracked" and text[-1] == "002,S2,P1,21.0000,24.0000,"
    from photogram.serve.epipolar import epipolar_help
    out = epipolar_help(video, oid=0)              # 001/S1 P1
    assert [c["view"] for c in out["lines"]] == ["001/S2"]
    assert [p["view"] for p in out["predicted"]] == ["001/S2"]
    # the two rays of P1 at 001 meet at the point in front of both cameras:
    # S1 sees it at the principal point, so it lies on S1's axis, X = (0, 0, Z)
    # with S2 at x 20 px: c * 2 / (10 - Z) = 12 -> 10 - Z = 10 m
    p = out["predicted"][0]
    assert p["x"] == pytest.approx(20.0, abs=1e-6) and p["y"] == pytest.approx(24.0, abs=1e-6)


def test_missing_tracked_table_is_one_line(tmp_path):
    from photogram.errors import InputError
    from photogram.serve.session import Session
    prj = tiny_video_project(tmp_path / "tiny")
    (prj.parent / "results" / "jumper_points.csv").unlink()
    with pytest.raises(InputError) as exc:
        Session(prj)
    assert exc.value.one_line() == (f"no tracked observations "
                                    f"{prj.parent / 'results' / 'jumper_points.csv'} "
                                    f"(run photogram track {prj} first)")


def test_video_file_frames(tmp_path):
    """An AVI (MJPG) recording: the frame of the exposure, not another."""
    from photogram.serve.sources import read_frame
    path = tmp_path / "v.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (64, 48))
    for k in range(6):
        w.write(np.full((48, 64, 3), 40 * k, np.uint8))
    w.release()
    for k in (0, 3, 5):
        assert abs(float(read_frame(path, k).mean()) - 40 * k) < 3
    from photogram.errors import InputError
    with pytest.raises(InputError, match="cannot read frame 9 of video"):
        read_frame(path, 9)


def test_damaged_tracked_table_is_one_line_and_frees_the_lock(tmp_path):
    from photogram.errors import InputError
    from photogram.serve.session import Session
    prj = tiny_video_project(tmp_path / "tiny")
    table = prj.parent / "results" / "jumper_points.csv"
    good = table.read_text(encoding="utf-8")
    table.write_text(good + "002,S2,P1,1.0\n", encoding="utf-8")
    with pytest.raises(InputError) as exc:
        Session(prj)
    line = exc.value.one_line()
    assert line.startswith(f"{table}:6: this record has 4 fields but the header has 6")
    table.write_text(good, encoding="utf-8")
    Session(prj).close()           # the lock taken before reading was released
