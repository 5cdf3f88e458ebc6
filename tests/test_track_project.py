"""The tracking project (issue 19): the [track] section, the seed clicks
and the exposure frames are read with one-line errors naming file and line;
the oriented views come from the project's cameras and stations."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from photogram.errors import InputError
from photogram.project import read_project
from photogram.track.inputs import read_exposures, read_seeds, view_cameras

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def oriented(oriented_projects):
    """(lab cameras.toml, field stations.csv) of the session's oriented chain."""
    return (oriented_projects / "lab" / "results" / "cameras.toml",
            oriented_projects / "field" / "results" / "stations.csv")


def _project(tmp_path, oriented, track_extra="", videos=("S1", "S2", "S3"), more=""):
    LAB, FIELD = oriented
    v = tmp_path / "video"
    v.mkdir(exist_ok=True)
    for s in videos:
        (v / f"{s}.avi").write_bytes(b"")
    (v / "seeds.csv").write_text("station,frame,marker,x,y\nS1,3,P1,100.5,200.25\n")
    (v / "frames.csv").write_text("exposure,frame\n001,2\n002,3\n003,4\n")
    vids = ", ".join(f'{s} = "video/{s}.avi"' for s in videos)
    text = f"""[project]
name = "t"
length_unit = "dm"
angle_unit = "gon"
image_unit = "px"

[cameras.K1]
from = "{LAB}"
[cameras.K2]
from = "{LAB}"
[cameras.K3]
from = "{LAB}"

[stations]
file = "{FIELD}"
{more}
[track]
videos = {{ {vids} }}
seeds = "video/seeds.csv"
exposures = "video/frames.csv"
{track_extra}
[output]
folder = "out"
"""
    prj = tmp_path / "track.prj"
    prj.write_text(text)
    return prj


def test_a_tracking_project_reads_its_section_and_views(tmp_path, oriented):
    p = read_project(_project(tmp_path, oriented, 'offsets = { S3 = 2 }\nfps = 29.97'))
    t = p.track
    assert set(t.videos) == {"S1", "S2", "S3"} and t.offsets == {"S3": 2}
    assert t.fps == 29.97 and t.markers == ("P1", "P2", "P3", "P4")
    assert t.ski_markers == ("P3", "P4")
    cams = view_cameras(p)
    # the field's adjusted stations reproject the field's own observations
    pts = pd.read_csv(ROOT / "projects/field/truth/points.csv", comment="#")
    obs = pd.read_csv(ROOT / "projects/field/field_image_points.csv", comment="#")
    m = obs.merge(pts, left_on="point", right_on="id")
    for s, cam in cams.items():
        o = m[m.station == s]
        err = cam.project(o[["X", "Y", "Z"]].to_numpy()) - o[["x", "y"]].to_numpy()
        assert np.sqrt((err ** 2).mean()) < 1.0        # 0.33 px noise, adjusted orientation
    assert read_project(_project(tmp_path, oriented, 'offsets = "estimate"')).track.offsets is None


@pytest.mark.parametrize("extra, words", [
    ('offsets = { S4 = 1 }', "S4"),
    ('markers = ["P1", "P2"]', "4 points"),
    ('ski_markers = ["P3", "P9"]', "P9"),
    ('unknown_key = 1', "unknown_key"),
    ('truth = "nowhere"', "not found"),
])
def test_bad_track_settings_are_one_line_at_their_line(tmp_path, oriented, extra, words):
    prj = _project(tmp_path, oriented, extra)
    line = prj.read_text().splitlines().index(extra) + 1
    with pytest.raises(InputError) as exc:
        read_project(prj)
    text = str(exc.value)
    assert f"track.prj:{line}:" in text and words in text and "\n" not in text


def test_a_video_of_an_unknown_station_and_missing_files_are_refused(tmp_path, oriented):
    prj = _project(tmp_path, oriented, videos=("S1", "S9"))
    with pytest.raises(InputError, match="S9"):
        read_project(prj)
    prj = _project(tmp_path, oriented)
    (tmp_path / "video" / "S2.avi").unlink()
    with pytest.raises(InputError, match="S2.avi not found"):
        read_project(prj)
    prj = _project(tmp_path, oriented, more='[observations]\npoints = "x.csv"\n')
    with pytest.raises(InputError, match="observations"):
        read_project(prj)


def _csv(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_seeds_are_checked_record_by_record(tmp_path):
    kw = dict(stations=["S1", "S2"], markers=["P1", "P2"], n_frames={"S1": 10, "S2": 10})
    ok = read_seeds(_csv(tmp_path, "s.csv", "station,frame,marker,x,y\nS1,3,P1,1.5,2\n"
                                            "S2,4,P1,3,4\n"), **kw)
    assert ok.frame.tolist() == [3, 4] and ok.x.tolist() == [1.5, 3.0]
    for body, words in [("S3,3,P1,1,2", "S3"), ("S1,3,P7,1,2", "P7"), ("S1,10,P1,1,2", "0..9"),
                        ("S1,2.5,P1,1,2", "frame"), ("S1,3,P1,1,2\nS1,5,P1,3,3", "second")]:
        with pytest.raises(InputError) as exc:
            read_seeds(_csv(tmp_path, "b.csv", "station,frame,marker,x,y\n" + body), **kw)
        assert words in str(exc.value) and "b.csv:" in str(exc.value)


def test_exposures_must_be_frames_of_every_video_after_its_offset(tmp_path):
    f = _csv(tmp_path, "f.csv", "exposure,frame\n001,2\n002,3\n003,4\n")
    e = read_exposures(f, n_frames={"S1": 6, "S2": 6}, offsets={"S2": 1})
    assert e.ids == ["001", "002", "003"]
    np.testing.assert_array_equal(e.in_station(1), [1, 2, 3])
    with pytest.raises(InputError, match="003.*S2"):
        read_exposures(f, n_frames={"S1": 6, "S2": 4}, offsets={})
    with pytest.raises(InputError, match="S2"):
        read_exposures(f, n_frames={"S1": 6, "S2": 6}, offsets={"S2": 3})
    for body, words in [("001,2\n001,3", "twice"), ("001,3\n002,2", "increase"),
                        ("001,2.5", "integer")]:
        with pytest.raises(InputError, match=words):
            read_exposures(_csv(tmp_path, "g.csv", "exposure,frame\n" + body),
                           n_frames={"S1": 9}, offsets={})
