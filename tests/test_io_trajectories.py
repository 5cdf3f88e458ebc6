"""Trajectory exports (TRC, C3D, OpenSim .mot, CSV) from an intersect
results folder: units, axes, gaps, residual and camera masks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.io.formats import export_results
from photogram.io.trajectories import load_trajectories, read_c3d, read_mot
from photogram.io.trc import read_trc

PRJ = """[project]
name = "t"
length_unit = "dm"
angle_unit = "gon"

[cameras.K]
model = "opencv"
fx = 1000.0
fy = 1000.0
image_size = [640, 480]

[stations]
file = "st.csv"

[observations]
points = "obs.csv"
"""
OBS = """exposure,station,point,x,y
001,S1,P1,10,10
001,S2,P1,11,11
002,S2,P1,12,12
002,S3,P1,13,13
001,S1,P2,20,20
001,S3,P2,21,21
002,S1,P2,22,22
002,S2,P2,23,23
002,S3,P2,24,24
003,S1,P2,25,25
003,S2,P2,26,26
"""
# P1 is not reconstructed at exposure 003: a gap
POINTS = """exposure,time,point,X,Y,Z,sX,sY,sZ
001,0,P1,440.5,-4.25,-221.5,1.5,2.0,1.25
001,0,P2,433.75,-4.5,-224.0,1.0,1.0,1.0
002,0.03333333333,P1,446.5,-4.0,-222.75,1.5,2.5,1.5
002,0.03333333333,P2,439.25,-4.25,-225.0,1.0,1.25,1.0
003,0.06666666667,P2,445.0,-4.0,-226.0,1.0,1.0,1.5
"""
EXPOSURES = """exposure,frame,time,alpha,beta,gamma,Z0,v,sigma_alpha,sigma_beta,sigma_gamma,\
sigma_Z0,sigma_v,O_x,O_y,O_z
0,0,0,16.5,23.5,189.0,-226.0,208.0,0.5,0.75,1.0,1.5,60.0,425.0,-5.5,-226.0
1,1,0.03333333333,15.25,24.5,190.5,-229.5,209.0,0.5,0.75,1.0,1.5,30.0,431.0,-4.75,-229.5
2,2,0.06666666667,14.0,25.0,191.0,-232.0,210.0,0.5,0.75,1.0,1.5,30.0,437.0,-4.0,-232.0
"""


@pytest.fixture()
def results(tmp_path) -> Path:
    (tmp_path / "t.prj").write_text(PRJ)
    (tmp_path / "st.csv").write_text("station,camera\nS1,K\nS2,K\nS3,K\n")
    (tmp_path / "obs.csv").write_text(OBS)
    folder = tmp_path / "results"
    folder.mkdir()
    (folder / "points3d.csv").write_text(POINTS)
    (folder / "exposures.csv").write_text(EXPOSURES)
    (folder / "summary.json").write_text(json.dumps({"project": {
        "name": "t", "path": str(tmp_path / "t.prj"), "length_unit": "dm",
        "angle_unit": "gon"}}))
    return folder


def test_load_converts_to_metres_and_keeps_gaps(results):
    t = load_trajectories(results)
    assert list(t.markers) == ["P1", "P2", "O"] and t.rate == 30.0
    assert np.allclose(t.markers["P1"][0], [44.05, -0.425, -22.15])
    assert np.all(np.isnan(t.markers["P1"][2]))
    assert t.cameras["P1"].tolist() == [0b011, 0b110, 0] and t.cameras["P2"].tolist() == [
        0b101, 0b111, 0b011]


def test_trc_metres_y_up_gaps_nan(results, tmp_path):
    out = export_results("trc", results, tmp_path / "jump.trc")[0]
    back = read_trc(out, rotate_to_z_up=True)
    t = load_trajectories(results)
    for m in t.markers:
        assert np.allclose(back.markers[m], t.markers[m], rtol=1e-15, equal_nan=True)
    raw = read_trc(out)                                    # Y up: (X, Y, Z)_trc = (Y, Z, X)
    assert np.allclose(raw.markers["P2"][0], [-0.45, -22.4, 43.375])
    last = out.read_text().splitlines()[-1].split("\t")
    assert last[2:5] == ["NaN", "NaN", "NaN"]              # the gap of P1: NaN, not 0
    assert back.units == "m"


def test_c3d_mm_residual_and_camera_mask(results, tmp_path):
    out = export_results("c3d", results, tmp_path / "jump.c3d")[0]
    c = read_c3d(out)
    t = load_trajectories(results)
    assert c["labels"] == ["P1", "P2", "O"] and c["units"] == "mm" and c["rate"] == 30.0
    xyz = np.stack([t.markers[m] for m in c["labels"]], axis=1) * 1000
    assert np.allclose(c["xyz"], xyz, rtol=1e-7, equal_nan=True)     # float32 storage
    assert np.isnan(c["xyz"][2, 0]).all() and c["residual"][2, 0] == -1
    # residual: sqrt(mean(s^2)) of P1 at 001 = 171.3 mm, quantised to the 1 mm scale
    assert abs(c["residual"][0, 0] - np.sqrt(np.mean(np.array([150, 200, 125.0]) ** 2))) <= 1
    assert c["cameras"][:, 0].tolist()[:2] == [3, 6] and c["cameras"][:, 1].tolist() == [5, 7, 3]


def test_mot_degrees_and_csv(results, tmp_path):
    out = export_results("mot", results, tmp_path / "jump.mot")[0]
    m = read_mot(out)
    assert "inDegrees=yes" in m["_header"]
    assert np.allclose(m["alpha"], [16.5 * 0.9, 15.25 * 0.9, 14.0 * 0.9])
    assert np.allclose(m["sigma_gamma"], 0.9) and np.allclose(m["Z0"], [-22.6, -22.95, -23.2])
    csv = export_results("csv", results, tmp_path / "jump.csv")[0].read_text().splitlines()
    assert csv[0].startswith("exposure,time,P1_X,P1_Y,P1_Z,P1_sX")     # no comment line
    assert csv[-1].split(",")[2:8] == [""] * 6                       # the gap
    with pytest.raises(InputError, match="file exists"):
        export_results("csv", results, tmp_path / "jump.csv")


def test_missing_and_malformed(results, tmp_path):
    with pytest.raises(InputError, match="no points3d.csv"):
        load_trajectories(tmp_path)
    p = results / "points3d.csv"
    p.write_text(POINTS.replace("446.5", "44x.5"))
    with pytest.raises(InputError) as err:
        load_trajectories(results)
    assert err.value.file == str(p) and err.value.line == 4
    (results / "exposures.csv").unlink()
    p.write_text(POINTS)
    with pytest.raises(InputError, match="exposures.csv"):
        export_results("mot", results, tmp_path / "x.mot")
