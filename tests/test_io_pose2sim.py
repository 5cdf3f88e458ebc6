"""Pose2Sim / anipose calibration files: import, export, round trip, and the
projection of the Pose2Sim demo's own 3D points against cv2.projectPoints
with the original file."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model
from photogram.io.exchange import save_calibration
from photogram.io.export_source import load_source, views_of
from photogram.io.formats import export_results, import_project
from photogram.io.pose2sim import format_pose2sim, pose2sim_project, read_pose2sim
from photogram.io.trc import read_trc
from photogram_cli.main import main

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DEMO = SHARED / "pose2sim-demo"
CALIB = DEMO / "Calib_qualisys.toml"
TRC = DEMO / "pose2sim-triangulation-Balancing_for_IK.trc"


def need_demo():
    if not CALIB.is_file():
        pytest.skip(f"Pose2Sim demo data not found at {DEMO}")


def demo_points(step: int = 10) -> np.ndarray:
    """Pose2Sim's triangulated points (Z-up world of the calibration)."""
    trc = read_trc(TRC, rotate_to_z_up=True)          # Y-up file: (X, Y, Z) = (Z, X, Y)_trc
    xyz = np.concatenate([m[::step] for m in trc.markers.values()])
    return xyz[np.all(np.isfinite(xyz), axis=1)]


def original_pixels(X):
    """cv2.projectPoints with the numbers of the original file, read by tomllib."""
    import tomllib
    doc = tomllib.loads(CALIB.read_text())
    out = {}
    for key, cam in doc.items():
        if key == "metadata":
            continue
        xy, _ = cv2.projectPoints(X.reshape(-1, 1, 3), np.array(cam["rotation"], float),
                                  np.array(cam["translation"], float),
                                  np.array(cam["matrix"], float),
                                  np.array(cam["distortions"], float))
        out[cam["name"]] = xy.reshape(-1, 2)
    return out


def test_round_trip_gives_back_the_numbers(tmp_path):
    need_demo()
    prj = import_project("pose2sim", CALIB, tmp_path / "imp")
    out = export_results("pose2sim", prj.parent, tmp_path / "back.toml")[0]
    a, b = read_pose2sim(CALIB), read_pose2sim(out)
    assert [v.name for v in a] == [v.name for v in b] == ["cam_01", "cam_02", "cam_03", "cam_04"]
    for u, v in zip(a, b):
        assert np.array_equal(u.K, v.K) and np.array_equal(u.dist, v.dist)   # exact
        assert u.image_size == v.image_size == (1088, 1920)
        assert np.allclose(u.extra["rotation"], v.extra["rotation"], rtol=1e-9, atol=1e-15)
        assert np.allclose(u.t_cv, v.t_cv, rtol=1e-9, atol=1e-15)


def test_projection_equals_cv2_with_the_original_file(tmp_path):
    """Pose2Sim's own 3D points (Y-up TRC turned back to the calibration's
    Z-up world) project to the same pixels through photogram's imported
    project, and through its export, as through the original file."""
    need_demo()
    X = demo_points()
    assert len(X) > 100
    ref = original_pixels(X)
    prj = import_project("pose2sim", CALIB, tmp_path / "imp")
    project = load_source(prj.parent).project
    model = camera_model("opencv")
    worst_ours = worst_export = 0.0
    for i, name in enumerate(project.stations.names):
        io = project.cameras[project.stations.camera[i]].values()
        xy = model.project(X, project.stations.angles[i], project.stations.position[i], io)
        worst_ours = max(worst_ours, np.abs(xy - ref[name]).max())
    exported = export_results("pose2sim", prj.parent, tmp_path / "back.toml")[0]
    for v in read_pose2sim(exported):
        worst_export = max(worst_export, np.abs(v.project(X) - ref[v.name]).max())
    # the points are inside the 1088 x 1920 images
    assert all((r[:, 0] > -50).all() and (r[:, 0] < 1150).all() for r in ref.values())
    assert worst_ours < 1e-6 and worst_export < 1e-6
    print(f"Pose2Sim demo, {len(X)} points x 4 cameras: max |photogram - cv2| = {worst_ours:.2e} "
          f"px (imported project), {worst_export:.2e} px (exported file)")


def test_imported_folder_is_usable_by_projects(tmp_path):
    need_demo()
    prj = import_project("pose2sim", CALIB, tmp_path / "imp")
    folder = prj.parent
    assert sorted(p.name for p in folder.iterdir()) == [
        "Calib_qualisys.prj", "cameras.toml", "image_points.csv", "points.csv", "stations.csv"]
    assert 'from = "cameras.toml"' in prj.read_text()
    # until measurements are added the .prj says what is missing, with exit code 2
    assert main(["check", "-q", str(prj)]) == 2
    # never replaces: a second import into the same folder is refused
    with pytest.raises(InputError, match="already holds a project"):
        import_project("pose2sim", CALIB, folder)


def test_views_of_results_and_metres_axes():
    need_demo()
    p = pose2sim_project(CALIB)
    assert p.units.length == "m" and set(p.cameras) == {"cam_01", "cam_02", "cam_03", "cam_04"}
    # X0 = -R_cv^T t: camera 1 of the Qualisys calibration is ~3 m from the origin
    assert 2.0 < np.linalg.norm(p.stations.position[0]) < 5.0
    v = views_of(p)[0]
    assert np.allclose(v.t_cv, [0.3211048899999996, 0.9563320600000009, 2.8907130499999996],
                       rtol=1e-12)


BAD = [
    ("matrix = [ [ 1681.244873046875, 0.0, 532.97369384375], [ 0.0, 1681.075439453125, "
     "948.137390140625], [ 0.0, 0.0, 1.0]]", "matrix = [ [ 1, 2], [3, 4]]", "matrix", 4),
    ("fisheye = false", 'fisheye = "no"', "fisheye", 8),
    ("rotation = [ 1.6882754799999993, 1.0483220499999997, -0.41955852000000016]",
     'rotation = [ 1.0, "x", 2.0]', "rotation", 6),
]


@pytest.mark.parametrize("old,new,word,line", BAD)
def test_malformed_file_names_file_and_line(tmp_path, old, new, word, line):
    need_demo()
    text = CALIB.read_text()
    assert old in text
    bad = tmp_path / "Calib_bad.toml"
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(InputError) as err:
        read_pose2sim(bad)
    assert err.value.file == str(bad) and err.value.line == line and word in str(err.value)


def test_truncated_file_and_cli_exit_code(tmp_path, capsys):
    need_demo()
    bad = tmp_path / "Calib_cut.toml"
    bad.write_text(CALIB.read_text()[:300])
    with pytest.raises(InputError) as err:
        read_pose2sim(bad)
    assert err.value.file == str(bad) and err.value.line is not None
    assert main(["import", "pose2sim", str(bad), "--to", str(tmp_path / "x")]) == 2
    msg = capsys.readouterr().err.strip()
    assert msg.startswith(f"{bad}:") and len(msg.splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_format_writes_exact_floats():
    from photogram.io.exchange import View
    v = View(name="c1", camera="c1", K=np.array([[1000.1, 0, 500.25], [0, 1000.3, 300.5],
                                                 [0, 0, 1]]),
             dist=np.array([0.1, -0.01, 1e-4, 2e-4, 0.0]), R_cv=np.eye(3),
             t_cv=np.array([0.1, 0.2, 3.0]), image_size=(1000, 600))
    text = format_pose2sim([v])
    assert "distortions = [ 0.1, -0.01, 0.0001, 0.0002]" in text
    assert "[metadata]" in text


def test_calibration_folder_needs_oriented_stations(tmp_path):
    need_demo()
    p = pose2sim_project(CALIB)
    p.stations.angles[1] = np.nan
    save_calibration(p, tmp_path / "c")
    with pytest.raises(InputError, match="station cam_02 has no orientation"):
        export_results("pose2sim", tmp_path / "c", tmp_path / "o.toml")
