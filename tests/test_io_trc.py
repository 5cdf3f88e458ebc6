"""OpenSim .trc files: round trip with gaps, axes, and Pose2Sim's file."""

from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.io.trc import read_trc, write_trc, yup_to_zup, zup_to_yup

POSE2SIM = Path("/work/shared/data/pose2sim-demo/pose2sim-triangulation-Balancing_for_IK.trc")


def markers(n=12, seed=3):
    rng = np.random.default_rng(seed)
    out = {name: rng.normal(size=(n, 3)) * [5.0, 1.0, 2.0] + [0.0, 0.0, 40.0]
           for name in ("P1", "P2", "P3", "P4", "O")}
    out["P2"][3:6] = np.nan                         # a gap of three frames
    out["P4"][0, 1] = np.nan                        # a single missing coordinate
    out["O"][-1] = np.nan                           # missing at the end
    return out


def test_axes_are_a_proper_rotation_and_invert():
    M = zup_to_yup(np.eye(3))                       # rows: images of e_x, e_y, e_z
    assert np.isclose(np.linalg.det(M), 1.0)
    p = np.array([1.0, 2.0, 3.0])
    assert list(zup_to_yup(p)) == [2.0, 3.0, 1.0]   # (Y, Z, X): world Z up -> Y_trc
    assert list(yup_to_zup(zup_to_yup(p))) == [1.0, 2.0, 3.0]


def test_round_trip_with_gaps(tmp_path):
    t = 1.5 + np.arange(12) / 30.0
    mk = markers()
    path = write_trc(tmp_path / "jump.trc", t, mk, units="m")
    data = read_trc(path, rotate_to_z_up=True)
    assert list(data.markers) == list(mk)
    assert np.array_equal(data.times, t)
    assert list(data.frames) == list(range(1, 13))
    for name, xyz in mk.items():
        assert np.array_equal(np.isnan(data.markers[name]), np.isnan(xyz)), name
        assert np.array_equal(data.markers[name][~np.isnan(xyz)], xyz[~np.isnan(xyz)]), name
    raw = read_trc(path)                            # as in the file: Y up
    assert np.array_equal(raw.markers["P1"][:, 1], mk["P1"][:, 2], equal_nan=True)
    assert data.units == "m" and float(data.header["DataRate"]) == pytest.approx(30.0)
    assert data.header["NumFrames"] == "12" and data.header["NumMarkers"] == "5"


def test_file_layout(tmp_path):
    t = np.arange(4) / 30.0
    mk = {"P1": np.ones((4, 3)), "P2": np.full((4, 3), np.nan)}
    path = write_trc(tmp_path / "a.trc", t, mk, units="mm", rotate_to_y_up=False)
    lines = path.read_text().split("\n")
    assert lines[0] == "PathFileType\t4\t(X/Y/Z)\ta.trc"
    assert lines[1].split("\t") == ["DataRate", "CameraRate", "NumFrames", "NumMarkers",
                                    "Units", "OrigDataRate", "OrigDataStartFrame",
                                    "OrigNumFrames"]
    assert lines[2].split("\t") == ["30", "30", "4", "2", "mm", "30", "1", "4"]
    assert lines[3] == "Frame#\tTime\tP1\t\t\tP2\t\t"
    assert lines[4] == "\t\tX1\tY1\tZ1\tX2\tY2\tZ2"
    # the gap is NaN (OpenSim's TimeSeriesTableVec3 refuses an empty last
    # marker), never 0
    assert lines[5] == "1\t0.0\t1.0\t1.0\t1.0\tNaN\tNaN\tNaN"
    assert len(lines) == 5 + 4 + 1 and lines[-1] == ""


def test_write_errors(tmp_path):
    t = np.arange(3) / 30.0
    good = {"A": np.zeros((3, 3))}
    with pytest.raises(InputError):
        write_trc(tmp_path / "x.trc", t, {"A": np.zeros((2, 3))})
    with pytest.raises(InputError):
        write_trc(tmp_path / "x.trc", t, {"": np.zeros((3, 3))})   # a tab is escaped instead
    with pytest.raises(InputError):
        write_trc(tmp_path / "x.trc", t[::-1], good)
    with pytest.raises(InputError):
        write_trc(tmp_path / "x.trc", t, good, units="in")
    with pytest.raises(InputError):
        write_trc(tmp_path / "x.trc", t, {})
    assert not (tmp_path / "x.trc").exists()


def test_read_errors(tmp_path):
    p = tmp_path / "bad.trc"
    p.write_text("hello\n")
    with pytest.raises(InputError, match="not a TRC"):
        read_trc(p)
    with pytest.raises(InputError):
        read_trc(tmp_path / "missing.trc")
    write_trc(p, np.arange(3) / 30.0, {"A": np.zeros((3, 3))})
    text = p.read_text().replace("\t0.0\t0.0\t0.0\n", "\t0.0\tx\t0.0\n", 1)
    p.write_text(text)
    with pytest.raises(InputError, match="bad number") as exc:
        read_trc(p)
    assert exc.value.line == 6


@pytest.mark.skipif(not POSE2SIM.exists(), reason="Pose2Sim demo file not available")
def test_reads_pose2sim_reference_file():
    data = read_trc(POSE2SIM)
    assert len(data.markers) == 21 and data.header["NumMarkers"] == "21"
    assert len(data.times) == 100 == int(data.header["NumFrames"])
    assert data.units == "m" and data.data_rate == 60.0
    assert list(data.markers)[:3] == ["RHip", "RKnee", "RAnkle"]
    assert data.times[0] == pytest.approx(1 / 60)
    assert np.all(np.isfinite(np.stack(list(data.markers.values()))))
    # Y up in the file: the head is higher than the ankles in Y_trc ...
    head, ankle = data.markers["Head"], data.markers["RAnkle"]
    assert np.all(head[:, 1] - ankle[:, 1] > 1.0)
    # ... and in our Z after rotate_to_z_up
    z = read_trc(POSE2SIM, rotate_to_z_up=True)
    assert np.all(z.markers["Head"][:, 2] - z.markers["RAnkle"][:, 2] > 1.0)
    assert np.array_equal(z.markers["Head"], head[:, [2, 0, 1]])


@pytest.mark.skipif(not POSE2SIM.exists(), reason="Pose2Sim demo file not available")
def test_pose2sim_file_survives_our_round_trip(tmp_path):
    data = read_trc(POSE2SIM, rotate_to_z_up=True)
    out = write_trc(tmp_path / "copy.trc", data.times, data.markers, units=data.units,
                    data_rate=data.data_rate)
    back = read_trc(out)
    orig = read_trc(POSE2SIM)
    for name in orig.markers:
        assert np.array_equal(back.markers[name], orig.markers[name])
    assert list(back.frames) == list(orig.frames)
