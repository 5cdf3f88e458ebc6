"""The OpenSim storage files of ``photogram mocap`` (issue 20, item 6):
``angles.mot`` (the angles of metrics.csv) and ``camera_rotations.mot``
(pan, tilt, roll of pan-tilt cameras per frame), in OpenSim's layout, read
back with photogram's ``read_mot`` and, where installed, with OpenSim
itself (``pytest.importorskip``; benchmarks/mocap_outputs_clients.py runs
the full check)."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from photogram.geometry import opk_to_matrix
from photogram.io.mocap_results import MOT_ANGLES, camera_rotation_columns, pan_tilt_roll
from photogram.io.trajectories import mot_text, read_mot
from photogram.io.trc import read_trc
from photogram.mocap.files import write_angles_mot
from photogram.simulation.ski.simproject import write_simulated_project
from photogram.simulation.ski.simulate import simulate_session
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _camera(pan, tilt, roll):
    """World-to-camera R of a camera with the given yaw (pan), pitch (tilt,
    up positive) and roll (right side up positive), built independently of
    pan_tilt_roll: scipy's intrinsic Z-Y'-X'' body frame (forward, left,
    up), then photogram's camera axes (x right = -left, y up, z = -forward)."""
    body = Rotation.from_euler("ZYX", np.stack([pan, -tilt, -roll], -1),
                               degrees=True).as_matrix()
    fwd, left, up = body[..., :, 0], body[..., :, 1], body[..., :, 2]
    return np.stack([-left, up, -fwd], axis=-2)


def test_pan_tilt_roll_reproduces_known_rotations():
    rng = np.random.default_rng(4)
    n = 500
    truth = np.column_stack([rng.uniform(-179, 179, n), rng.uniform(-85, 85, n),
                             rng.uniform(-60, 60, n)])
    R = _camera(*truth.T)
    assert np.allclose(np.einsum("nij,nkj->nik", R, R), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)
    assert np.allclose(pan_tilt_roll(R), truth, atol=1e-9)
    # a level camera looking along +X, +Y, straight down the -X axis
    assert np.allclose(pan_tilt_roll(_camera(90.0, 0.0, 0.0)), [90, 0, 0], atol=1e-12)
    level_x = np.array([[0.0, -1, 0], [0, 0, 1], [-1, 0, 0]])     # right -Y, up Z, view +X
    assert np.allclose(pan_tilt_roll(level_x), [0, 0, 0], atol=1e-12)
    # a camera 10 deg below the horizon: tilt -10, whatever the pan
    assert np.allclose(pan_tilt_roll(_camera(-120.0, -10.0, 0.0)), [-120, -10, 0])


def test_a_pan_of_30_degrees_about_the_up_axis_reads_as_pan_30():
    # cameras as the photogrammetric angles give them (omega-phi-kappa, world to camera)
    rng = np.random.default_rng(1)
    opk = np.radians(np.column_stack([rng.uniform(60, 120, 50), rng.uniform(-40, 40, 50),
                                      rng.uniform(-180, 180, 50)]))
    R = opk_to_matrix(opk)
    turned = R @ Rotation.from_euler("z", 30, degrees=True).as_matrix().T   # camera turned about Z
    a, b = pan_tilt_roll(R), pan_tilt_roll(turned)
    assert np.allclose((b[:, 0] - a[:, 0] + 180) % 360 - 180, 30.0, atol=1e-9)
    assert np.allclose(b[:, 1:], a[:, 1:], atol=1e-9)
    # a 30 deg tilt-up about the camera's own horizontal axis adds 30 to the tilt
    level = _camera(np.full(5, 40.0), np.zeros(5), np.zeros(5))
    up30 = Rotation.from_euler("x", -30, degrees=True).as_matrix() @ level
    assert np.allclose(pan_tilt_roll(up30), [40, 30, 0], atol=1e-9)


def test_camera_rotation_columns_unwrap_the_pan():
    pan = np.linspace(170, 200, 31)                 # crosses +180 deg
    R = _camera(pan, np.full(31, 5.0), np.zeros(31))[:, None]
    cols = camera_rotation_columns(np.arange(31) / 50, ["C1"], R)
    assert list(cols) == ["time", "C1_pan", "C1_tilt", "C1_roll"]
    assert np.allclose(cols["C1_pan"], pan, atol=1e-9)          # continuous, no jump to -180
    assert np.allclose(cols["C1_tilt"], 5.0) and np.allclose(cols["C1_roll"], 0.0)


def _header(path):
    """OpenSim's header keys of a .mot file (lines ``key=value`` before endheader)."""
    head = read_mot(path)["_header"]
    return head, dict(ln.split("=", 1) for ln in head if "=" in ln)


def _check_opensim_layout(path):
    """OpenSim's storage layout, checked line by line; returns the rows."""
    lines = Path(path).read_text(encoding="utf-8").split("\n")
    assert lines[-1] == "" and "\r" not in Path(path).read_text(encoding="utf-8")
    lines = lines[:-1]
    end = lines.index("endheader")
    head, keys = _header(path)
    assert head[0] == Path(path).name
    assert head[1:5] == ["version=1", f"nRows={len(lines) - end - 2}",
                         f"nColumns={len(lines[end + 1].split(chr(9)))}", "inDegrees=yes"]
    assert keys["version"] == "1" and keys["inDegrees"] == "yes"
    names = lines[end + 1].split("\t")
    assert names[0] == "time" and len(set(names)) == len(names)
    rows = [ln.split("\t") for ln in lines[end + 2:]]
    assert len(rows) == int(keys["nRows"])
    assert all(len(r) == int(keys["nColumns"]) for r in rows)      # tabs only, full rows
    assert all(" " not in v and v for r in rows for v in r)
    return names, rows


def test_mot_text_layout_and_nan_gaps(tmp_path):
    t = np.arange(5) / 50
    metrics = {"knee_flexion_r": np.array([10.5, np.nan, 12.0, 13.25, 14.0]),
               "lean": np.array([1.0, 2.0, 3.0, 4.0, np.nan]), "speed": np.ones(5),
               "outside": np.array(["r"] * 5)}
    path = write_angles_mot(tmp_path / "angles.mot", t, metrics)
    names, rows = _check_opensim_layout(path)
    assert names == ["time", "knee_flexion_r", "lean"]               # angles only, in order
    assert rows[1][1] == "NaN" and rows[4][2] == "NaN"
    back = read_mot(path)
    assert np.array_equal(back["time"], t)
    for k in ("knee_flexion_r", "lean"):
        assert np.array_equal(back[k], metrics[k], equal_nan=True)
    with pytest.raises(ValueError, match="time"):
        mot_text("x.mot", {"a": [1.0]})
    with pytest.raises(ValueError, match="length"):
        mot_text("x.mot", {"time": [0.0, 1.0], "a": [1.0]})


@pytest.fixture(scope="module")
def ptz_results(tmp_path_factory):
    """A short simulated pan-tilt-zoom session (rotations known per frame)
    run through ``photogram mocap``."""
    folder = tmp_path_factory.mktemp("ski-outputs")
    sim = simulate_session(seed=11, n_runs=1, frames_per_run=40)
    write_simulated_project(sim, folder, name="ski")
    assert main(["mocap", "--no-report", "--no-figures", str(folder / "ski.prj"), "-q"]) == 0
    return folder, folder / "results", sim


def test_mocap_writes_angles_mot_equal_to_metrics(ptz_results):
    _, out, _ = ptz_results
    names, rows = _check_opensim_layout(out / "angles.mot")
    metrics = pd.read_csv(out / "metrics.csv", comment="#")
    assert names == ["time"] + [c for c in MOT_ANGLES if c in metrics.columns]
    assert len(names) == 1 + len(MOT_ANGLES)
    back = read_mot(out / "angles.mot")
    for c in names:
        assert np.array_equal(back[c], metrics[c].to_numpy(float), equal_nan=True), c
    written = json.loads((out / "summary.json").read_text())
    assert written["command"] == "mocap"


def test_mocap_camera_rotations_follow_the_cameras(ptz_results):
    folder, out, sim = ptz_results
    names, rows = _check_opensim_layout(out / "camera_rotations.mot")
    cams = list(sim.cameras.names)
    assert names == ["time"] + [f"{c}_{a}" for c in cams for a in ("pan", "tilt", "roll")]
    back = read_mot(out / "camera_rotations.mot")
    metrics = pd.read_csv(out / "metrics.csv", comment="#")
    assert np.array_equal(back["time"], metrics["time"].to_numpy(float))
    # equal to the convention applied to the project's camera_frames.csv (deg, world to camera)
    frames = pd.read_csv(folder / "camera_frames.csv", comment="#")
    for c in cams:
        rows_c = frames[frames["camera"] == c].sort_values("frame")
        R = opk_to_matrix(np.radians(rows_c[["omega", "phi", "kappa"]].to_numpy(float)))
        a = pan_tilt_roll(R)
        for k, what in enumerate(("pan", "tilt", "roll")):
            got = back[f"{c}_{what}"]
            diff = (got - a[:, k] + 180) % 360 - 180
            assert np.max(np.abs(diff)) < 2e-7, (c, what)
    # independent of the formula: the cameras follow the athlete, so pan and tilt are the
    # heading and elevation of the line camera -> centre of mass within half the field of view
    joints = pd.read_csv(folder / "truth" / "joints3d.csv", comment="#")
    xyz = np.stack([joints[[f"{j}_{a}" for a in "XYZ"]].to_numpy(float)
                    for j in ("l_hip", "r_hip", "neck")], 1).mean(1)
    for c, name in enumerate(cams):
        d = xyz - sim.cameras.X0[c]
        heading = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
        elevation = np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))
        fov = np.degrees(np.arctan(960.0 / frames[frames["camera"] == name]["fx"].min()))
        dpan = (back[f"{name}_pan"] - heading + 180) % 360 - 180
        assert np.max(np.abs(dpan)) < fov, name
        assert np.max(np.abs(back[f"{name}_tilt"] - elevation)) < fov, name


def test_opensim_reads_the_outputs(ptz_results):
    opensim = pytest.importorskip("opensim")
    opensim.Logger.removeFileSink()                   # no opensim.log in the working folder
    _, out, _ = ptz_results
    metrics = pd.read_csv(out / "metrics.csv", comment="#")
    table = opensim.TimeSeriesTable(str(out / "angles.mot"))
    assert table.getTableMetaDataAsString("inDegrees") == "yes"
    assert np.array_equal(np.asarray(table.getIndependentColumn()),
                          metrics["time"].to_numpy(float))
    for name in table.getColumnLabels():
        assert np.array_equal(table.getDependentColumn(name).to_numpy(),
                              metrics[name].to_numpy(float)), name
    storage = opensim.Storage(str(out / "angles.mot"))    # no gaps here: Storage reads all
    assert storage.getSize() == len(metrics) and storage.isInDegrees()
    rot = read_mot(out / "camera_rotations.mot")
    table = opensim.TimeSeriesTable(str(out / "camera_rotations.mot"))
    assert table.getNumColumns() == len(rot) - 2
    for name in table.getColumnLabels():
        assert np.array_equal(table.getDependentColumn(name).to_numpy(), rot[name]), name
    markers = opensim.TimeSeriesTableVec3(str(out / "joints3d.trc"))
    ours = read_trc(out / "joints3d.trc")
    joints = pd.read_csv(out / "joints3d.csv", comment="#")
    assert markers.getTableMetaDataAsString("Units") == "m"
    assert list(markers.getColumnLabels()) == list(ours.markers)
    assert np.array_equal(np.asarray(markers.getIndependentColumn()), ours.times)
    for k, name in enumerate(markers.getColumnLabels()):
        col = markers.getDependentColumnAtIndex(k)
        xyz = np.array([[col[i][0], col[i][1], col[i][2]] for i in range(col.size())])
        assert np.array_equal(xyz, ours.markers[name]), name         # every digit
        ref = joints[[f"{name}_Y", f"{name}_Z", f"{name}_X"]].to_numpy(float)   # Y up
        assert np.max(np.abs(xyz - ref)) <= 5e-6 + 1e-12, name     # joints3d.csv: 5 decimals


def test_export_takes_the_frame_rate_of_the_mocap_run(tmp_path):
    """joints3d.csv rounds the times to 1e-6 s: at 60 fps the rate from the
    times is 59.9988; the export takes summary.json's fps (TRC DataRate,
    C3D POINT:RATE), and falls back to the times when they disagree."""
    from photogram.io.trajectories import load_trajectories, write_trc_export
    n = 30
    t = np.round(np.arange(n) / 60.0, 6)
    lines = ["# 3D joints (m, world axes, Z up) of photogram mocap", "frame,time,a_X,a_Y,a_Z"]
    lines += [f"{k},{float(t[k])!r},{k * 0.01!r},1.0,2.0" for k in range(n)]
    (tmp_path / "joints3d.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "summary.json").write_text(json.dumps({"command": "mocap", "fps": 60}))
    traj = load_trajectories(tmp_path)
    assert traj.rate == 60.0
    assert np.array_equal(traj.times, t)                       # the times stay the table's
    header = write_trc_export(tmp_path / "a.trc", traj).read_text().splitlines()[2]
    assert header.split("\t")[0] == "60"
    (tmp_path / "summary.json").write_text(json.dumps({"command": "mocap", "fps": 50}))
    assert load_trajectories(tmp_path).rate == pytest.approx(59.9988, abs=1e-4)


def test_estimated_rotations_are_written_as_pan_tilt_roll(tmp_path):
    """rotation = "estimate" (rotation differences taken exactly from the
    simulator's cameras): camera_rotations.mot is rotations.csv in the
    pan/tilt/roll convention, close to the true rotations."""
    from photogram.mocap.motion.homography import RotationDifferences
    from photogram.mocap.motion.rotation_series import write_rotation_differences
    from photogram.simulation.ski.simproject import write_estimate_project
    sim = simulate_session(seed=12, n_runs=1, frames_per_run=30)
    write_simulated_project(sim, tmp_path, name="ski")
    prj = write_estimate_project(sim, tmp_path, name="ski")
    R = sim.cameras.rotations(30)
    per = {}
    for c, name in enumerate(sim.cameras.names):
        dR = R[1:, c] @ np.swapaxes(R[:-1, c], -1, -2)        # R(t+1) = dR R(t)
        per[name] = RotationDifferences(dR, np.full(29, 500), np.full(29, 600),
                                        np.ones(29, bool), 0.0, 30)
    write_rotation_differences(tmp_path / "rotation_differences.csv", per)
    assert main(["mocap", "--no-report", "--no-figures", str(prj), "-q"]) == 0
    out = tmp_path / "results-estimate"
    mot = read_mot(out / "camera_rotations.mot")
    _check_opensim_layout(out / "camera_rotations.mot")
    rot = pd.read_csv(out / "rotations.csv", comment="#")
    truth = pan_tilt_roll(R)                                   # (F, C, 3)
    for c, name in enumerate(sim.cameras.names):
        rows = rot[rot["camera"] == name].sort_values("frame")
        a = pan_tilt_roll(opk_to_matrix(np.radians(rows[["omega", "phi", "kappa"]]
                                                   .to_numpy(float))))
        for k, what in enumerate(("pan", "tilt", "roll")):
            got = mot[f"{name}_{what}"]
            assert np.max(np.abs((got - a[:, k] + 180) % 360 - 180)) < 1e-6, (name, what)
            assert np.median(np.abs((got - truth[:, c, k] + 180) % 360 - 180)) < 1.0, \
                (name, what)                 # the estimate: 0.06-0.37 deg here
