"""OpenCV FileStorage and COLMAP text models: import, export, round trips,
conventions (OpenCV pose, COLMAP's half-pixel origin), malformed files."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model, matrix_to_quaternion, rodrigues_to_matrix
from photogram.io.colmap import colmap_project, read_colmap
from photogram.io.exchange import View
from photogram.io.export_source import load_source
from photogram.io.formats import export_results, import_project
from photogram.io.opencv_fs import format_opencv, read_opencv, write_opencv
from photogram_cli.main import main

K = np.array([[1502.25, 0.0, 961.125], [0.0, 1498.5, 538.75], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.034, 2.5e-4, -1.5e-4, -0.004])


def view(name="cam", rvec=(0.3, -0.2, 0.1), tvec=(0.2, -0.1, 4.0)):
    return View(name=name, camera=name, K=K.copy(), dist=DIST.copy(),
                R_cv=rodrigues_to_matrix(np.array(rvec)), t_cv=np.array(tvec, float),
                image_size=(1920, 1080))


# --------------------------------------------------------------------------
# OpenCV FileStorage


@pytest.mark.parametrize("ext", [".yml", ".xml", ".json"])
def test_opencv_round_trip_is_exact(tmp_path, ext):
    path = tmp_path / f"cam{ext}"
    write_opencv(path, [view()])
    prj = import_project("opencv", path, tmp_path / "imp")
    out = export_results("opencv", prj.parent, tmp_path / f"back{ext}")[0]
    a, b = read_opencv(path)[0], read_opencv(out)[0]
    assert np.array_equal(a.K, b.K) and np.array_equal(a.dist, b.dist)
    assert np.allclose(a.R_cv, b.R_cv, rtol=0, atol=1e-15)
    assert np.allclose(a.t_cv, b.t_cv, rtol=1e-12, atol=1e-15)
    assert b.image_size == (1920, 1080) and b.name == "cam"


def test_opencv_pose_convention(tmp_path):
    """photogram's imported station projects like cv2.projectPoints with R, T."""
    path = tmp_path / "cam.yml"
    write_opencv(path, [view()])
    p = load_source(import_project("opencv", path, tmp_path / "imp").parent).project
    X = np.random.default_rng(1).uniform(-1, 1, (50, 3))
    ref, _ = cv2.projectPoints(X.reshape(-1, 1, 3), np.array([0.3, -0.2, 0.1]),
                               np.array([0.2, -0.1, 4.0]), K, DIST)
    xy = camera_model("opencv").project(X, p.stations.angles[0], p.stations.position[0],
                                        p.cameras["cam"].values())
    assert np.abs(xy - ref.reshape(-1, 2)).max() < 1e-9


def test_opencv_reads_common_layouts(tmp_path):
    # the calibration sample: camera_matrix, distortion_coefficients, extrinsic_parameters
    fs = cv2.FileStorage(str(tmp_path / "sample.yml"), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1920)
    fs.write("image_height", 1080)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", DIST.reshape(5, 1))
    fs.write("extrinsic_parameters", np.array([[0.1, 0.2, 0.3, 0.0, 0.1, 2.0],
                                               [0.0, -0.1, 0.0, 0.3, 0.0, 2.5]]))
    fs.release()
    views = read_opencv(tmp_path / "sample.yml")
    assert [v.name for v in views] == ["sample_1", "sample_2"]
    assert np.allclose(views[1].t_cv, [0.3, 0.0, 2.5])
    # stereoCalibrate: M1 D1 M2 D2 R T
    fs = cv2.FileStorage(str(tmp_path / "stereo.xml"), cv2.FILE_STORAGE_WRITE)
    for k in ("1", "2"):
        fs.write("M" + k, K)
        fs.write("D" + k, DIST.reshape(1, 5))
    fs.write("R", rodrigues_to_matrix(np.array([0.0, 0.2, 0.0])))
    fs.write("T", np.array([[-0.5], [0.0], [0.0]]))
    fs.release()
    a, b = read_opencv(tmp_path / "stereo.xml")
    assert np.array_equal(a.R_cv, np.eye(3)) and np.allclose(b.t_cv, [-0.5, 0, 0])
    # intrinsics only: the station has no orientation
    fs = cv2.FileStorage(str(tmp_path / "intr.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("K", K)
    fs.write("D", DIST[:4].reshape(1, 4))
    fs.release()
    prj = import_project("opencv", tmp_path / "intr.yaml", tmp_path / "intr")
    src = load_source(prj.parent)
    assert np.all(np.isnan(src.project.stations.angles))
    assert src.project.cameras["intr"].parameters["k3"].value == 0.0


def test_opencv_several_stations_go_to_a_folder(tmp_path):
    files = write_opencv(tmp_path / "out", [view("a"), view("b", tvec=(1, 0, 4))])
    assert [f.name for f in files] == ["a.yml", "b.yml"]
    with pytest.raises(InputError, match="file exists"):
        write_opencv(tmp_path / "out", [view("a"), view("b")])


def test_opencv_malformed_files(tmp_path):
    text = format_opencv(view(), ".yml")
    cut = tmp_path / "cut.yml"
    cut.write_text(text[:len(text) // 2])
    with pytest.raises(InputError) as err:
        read_opencv(cut)
    assert err.value.file == str(cut) and err.value.line is not None
    skew = tmp_path / "skew.yml"
    skew.write_text(text.replace("1502.25, 0.,", "1502.25, 3.,", 1))
    with pytest.raises(InputError, match="skew") as err:
        read_opencv(skew)
    assert err.value.line == text.splitlines().index("camera_matrix: !!opencv-matrix") + 1
    none = tmp_path / "none.yml"
    fs = cv2.FileStorage(str(none), cv2.FILE_STORAGE_WRITE)
    fs.write("something", 1)
    fs.release()
    with pytest.raises(InputError, match="no camera matrix"):
        read_opencv(none)


@pytest.mark.parametrize("extra", [[0.1, 0, 0.02], [0.1, 0, 0.02, 1e-3, 0, -2e-3, 5e-4],
                                   [0.1, 0, 0.02, 1e-3, 0, -2e-3, 5e-4, 0.01, -0.02]])
def test_opencv_rational_thin_prism_tilt_round_trip(tmp_path, extra):
    """8, 12 and 14 coefficients import as an ``opencv_full`` camera that
    projects as cv2.projectPoints (1e-9 px) and export back unchanged."""
    path = tmp_path / "full.yml"
    v = view()
    v.dist = np.r_[DIST, extra]
    write_opencv(path, [v])
    prj = import_project("opencv", path, tmp_path / "imp")
    p = load_source(prj.parent).project
    cam = p.cameras["cam"]
    assert cam.model == "opencv_full"
    X = np.random.default_rng(1).uniform(-1, 1, (50, 3))
    xy = camera_model("opencv_full").project(X, p.stations.angles[0], p.stations.position[0],
                                             cam.values())
    assert np.abs(xy - v.project(X)).max() < 1e-9
    out = export_results("opencv", prj.parent, tmp_path / "back.yml")[0]
    back = read_opencv(out)[0]
    assert np.array_equal(back.dist, v.dist) and np.array_equal(back.K, v.K)
    with pytest.raises(InputError, match="Pose2Sim"):
        export_results("pose2sim", prj.parent, tmp_path / "p.toml")


# --------------------------------------------------------------------------
# COLMAP


def synthetic_colmap(folder: Path, model="OPENCV"):
    """A COLMAP text model of 4 images of 30 points, 2D points made with
    cv2.projectPoints in OpenCV's frame and written with COLMAP's +0.5."""
    rng = np.random.default_rng(7)
    X = rng.uniform([-1, -1, 0], [1, 1, 1], (30, 3))
    folder.mkdir()
    if model == "OPENCV":
        params = [K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5, *DIST[:4]]
        dist = np.r_[DIST[:4], 0.0]
    else:
        params = [1500.0, K[0, 2] + 0.5, K[1, 2] + 0.5, -0.05]
        dist = np.array([-0.05, 0, 0, 0, 0])
    Kc = K.copy() if model == "OPENCV" else np.array([[1500.0, 0, K[0, 2]], [0, 1500.0, K[1, 2]],
                                                      [0, 0, 1]])
    (folder / "cameras.txt").write_text(
        "# Camera list\n# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
        f"7 {model} 1920 1080 " + " ".join(repr(float(p)) for p in params) + "\n")
    lines, tracks = ["# Image list"], {i: [] for i in range(len(X))}
    for k in range(4):
        rvec = np.array([0.1 * k, 0.2 - 0.1 * k, 0.05])
        t = np.array([0.1 * k, -0.2, 5.0])
        q = matrix_to_quaternion(rodrigues_to_matrix(rvec))
        xy, _ = cv2.projectPoints(X.reshape(-1, 1, 3), rvec, t, Kc, dist)
        xy = xy.reshape(-1, 2) + 0.5
        lines.append(" ".join([str(10 + k)] + [repr(float(c)) for c in (*q, *t)] +
                              ["7", f"img_{k}.jpg"]))
        pts = []
        for i in range(len(X)):
            if (i + k) % 7 == 0:
                continue                          # not every point in every image
            tracks[i].append((10 + k, len(pts) // 3))
            pts += [repr(float(xy[i, 0])), repr(float(xy[i, 1])), str(100 + i)]
        pts += ["5.5", "6.5", "-1"]              # a feature without a 3D point
        lines.append(" ".join(pts))
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    rows = ["# 3D point list"]
    for i in range(len(X)):
        rows.append(" ".join([str(100 + i)] + [repr(float(c)) for c in X[i]] +
                             ["10", "20", "30", "0.5"] +
                             [f"{a} {b}" for a, b in tracks[i]]))
    (folder / "points3D.txt").write_text("\n".join(rows) + "\n")
    return X


@pytest.mark.parametrize("model", ["OPENCV", "SIMPLE_RADIAL"])
def test_colmap_import_conventions(tmp_path, model):
    """The imported project reproduces COLMAP's 2D points (shifted by -0.5 px
    to OpenCV's frame) with photogram's camera model to 1e-9 px."""
    synthetic_colmap(tmp_path / "sparse", model)
    p = colmap_project(tmp_path / "sparse")
    assert len(p.stations) == 4 and len(p.points) == 30
    assert p.stations.names == ["img_0.jpg", "img_1.jpg", "img_2.jpg", "img_3.jpg"]
    ip = p.image_points
    cam = p.cameras["7"]
    r = camera_model("opencv").residuals(ip.xy, p.points.xyz[ip.point],
                                         p.stations.angles[ip.station],
                                         p.stations.position[ip.station], cam.values(),
                                         jacobians=False)
    assert np.abs(r).max() < 1e-9
    assert np.isclose(cam.parameters["cx"].value, K[0, 2])


def test_colmap_round_trip(tmp_path):
    synthetic_colmap(tmp_path / "sparse")
    prj = import_project("colmap", tmp_path / "sparse", tmp_path / "imp")
    export_results("colmap", prj, tmp_path / "back")
    a, b = read_colmap(tmp_path / "sparse"), read_colmap(tmp_path / "back")
    assert [v.name for v in a.views] == [v.name for v in b.views]
    for u, v in zip(a.views, b.views):
        assert np.allclose(u.K, v.K, rtol=1e-12) and np.allclose(u.dist, v.dist, rtol=1e-12)
        assert np.allclose(u.R_cv, v.R_cv, atol=1e-14)
        assert np.allclose(u.t_cv, v.t_cv, rtol=1e-9, atol=1e-14)
    assert a.point_ids == b.point_ids
    assert np.allclose(a.xyz, b.xyz, rtol=1e-12)
    ka = sorted(zip(a.obs_image, a.obs_point, map(tuple, a.obs_xy)))
    kb = sorted(zip(b.obs_image, b.obs_point, map(tuple, b.obs_xy)))
    assert [k[:2] for k in ka] == [k[:2] for k in kb]
    assert np.allclose([k[2] for k in ka], [k[2] for k in kb], rtol=1e-12, atol=1e-12)
    cams = (tmp_path / "back" / "cameras.txt").read_text()
    assert "7 OPENCV 1920 1080" in cams
    with pytest.raises(InputError, match="file exists"):
        export_results("colmap", prj, tmp_path / "back")


def test_colmap_from_results_folder(lab_results, tmp_path):
    """A results folder (one brown camera, fitted) exports as COLMAP;
    re-imported, its stations agree with the results; ERROR is the mean
    image residual (0.5 px)."""
    files = export_results("colmap", lab_results, tmp_path / "c")
    assert [f.name for f in files] == ["cameras.txt", "images.txt", "points3D.txt"]
    back = colmap_project(tmp_path / "c")
    src = load_source(lab_results)
    assert back.stations.names == src.project.stations.names
    assert np.allclose(back.stations.position, src.project.stations.position, atol=1e-9)
    assert "FULL_OPENCV" in (tmp_path / "c" / "cameras.txt").read_text()
    assert np.allclose(read_colmap(tmp_path / "c").error, 0.5)


BAD_COLMAP = [
    ("cameras.txt", lambda t: t.replace("OPENCV 1920 1080", "FOV 1920 1080"), 3, "not supported"),
    ("cameras.txt", lambda t: t.rsplit(" ", 1)[0] + "\n", 3, "expected 8"),
    ("images.txt", lambda t: t[:t.rfind(" ")] + "\n", 9, "triples"),
    ("images.txt", lambda t: t.replace(" 7 img_2.jpg", " 8 img_2.jpg"), 6, "CAMERA_ID 8"),
    ("points3D.txt", lambda t: t.replace(" 0.5 ", " x ", 1), 2, "not a number"),
]


@pytest.mark.parametrize("name,edit,line,words", BAD_COLMAP)
def test_colmap_malformed(tmp_path, name, edit, line, words):
    synthetic_colmap(tmp_path / "sparse")
    f = tmp_path / "sparse" / name
    f.write_text(edit(f.read_text()))
    with pytest.raises(InputError) as err:
        read_colmap(tmp_path / "sparse")
    assert err.value.file == str(f) and err.value.line == line and words in str(err.value)


def test_cli_import_export_exit_codes(tmp_path, capsys):
    synthetic_colmap(tmp_path / "sparse")
    assert main(["import", "colmap", str(tmp_path / "sparse"), "--to", str(tmp_path / "p")]) == 0
    assert main(["check", "-q", str(tmp_path / "p")]) == 0
    assert main(["export", "ply", str(tmp_path / "p"), "--to", str(tmp_path / "p.ply")]) == 0
    capsys.readouterr()
    assert main(["export", "ply", str(tmp_path / "p"), "--to", str(tmp_path / "p.ply")]) == 2
    assert "file exists" in capsys.readouterr().err
    assert main(["export", "ply", str(tmp_path / "p"), "--to", str(tmp_path / "p.ply"),
                 "--force", "-q"]) == 0
    assert main(["import", "colmapp", "x", "--to", "y"]) == 2
    assert "did you mean 'colmap'" in capsys.readouterr().err
    assert main(["import", "colmap", str(tmp_path / "sparse")]) == 2
    assert "missing --to" in capsys.readouterr().err
    assert main(["export"]) == 2


# --------------------------------------------------------------------------
# from a results folder: PLY with sigmas, OpenCV views of brown cameras


@pytest.fixture(scope="module")
def lab_results(tmp_path_factory):
    """A results folder as the commands write it (write_results), of the
    synthetic COLMAP network with a second, brown camera (c 1500 px, barrel
    distortion of ~6 px at the corners, decentring) for two stations."""
    from photogram.project import write_results
    from photogram.project.model import Camera, Parameter
    base = tmp_path_factory.mktemp("res")
    synthetic_colmap(base / "sparse")
    p = colmap_project(base / "sparse")
    values = {"c": 1500.0, "x0": 961.0, "y0": 539.0, "K1": 2.0e-8, "K2": -3.0e-15, "K3": 0.0,
              "P1": 1.0e-7, "P2": -5.0e-8, "B1": 0.0, "B2": 0.0}
    p.cameras["B"] = Camera("B", "brown", {k: Parameter(v, free=True) for k, v in
                                          values.items()}, image_size=(1920, 1080))
    p.stations.camera[2:] = ["B", "B"]
    n, m = len(p.stations), len(p.points)
    ip = p.image_points
    res = {"station": ip.station, "point": ip.point, "x": ip.xy[:, 0], "y": ip.xy[:, 1],
           "vx": np.full(len(ip), 0.3), "vy": np.full(len(ip), 0.4)}
    sig = 0.001 * (1 + np.arange(3 * m).reshape(m, 3) % 3)
    return write_results(base / "results", p, {"status": "converged", "sigma0": 1.0},
                         station_sigma=np.full((n, 6), 1e-3), point_sigma=sig, residuals=res)


def test_ply_round_trip_with_sigmas(lab_results, tmp_path):
    from photogram.io.ply import read_ply
    src = load_source(lab_results)
    out = export_results("ply", lab_results, tmp_path / "points.ply")[0]
    text = out.read_text()
    assert "property double sigma_x" in text
    ids = [i for i, k in zip(src.project.points.ids,
                             np.all(np.isfinite(src.project.points.xyz), axis=1)) if k]
    assert f"comment point 0 is {ids[0]}" in text or "property int id" in text
    ply = read_ply(out)
    keep = np.all(np.isfinite(src.project.points.xyz), axis=1)
    assert np.array_equal(np.column_stack([ply["x"], ply["y"], ply["z"]]),
                          src.project.points.xyz[keep])                 # exact (repr)
    assert np.array_equal(np.column_stack([ply["sigma_x"], ply["sigma_y"], ply["sigma_z"]]),
                          src.point_sigma[keep], equal_nan=True)
    tie = keep & (src.project.points.kind == "tie")
    assert tie.any() and np.all(src.point_sigma[tie] > 0)


def test_brown_cameras_export_with_their_fit(lab_results, tmp_path):
    """Brown cameras are fitted to OpenCV's model on export; the exported
    views project the points within a few times the fit's misfit of
    photogram's own projection."""
    src = load_source(lab_results)
    p = src.project
    views = {v.name: v for v in
             __import__("photogram.io.pose2sim", fromlist=["read_pose2sim"]).read_pose2sim(
                 export_results("pose2sim", lab_results, tmp_path / "lab.toml")[0])}
    X = p.points.xyz[np.all(np.isfinite(p.points.xyz), axis=1)]
    worst = 0.0
    for i, name in enumerate(p.stations.names):
        cam = p.cameras[p.stations.camera[i]]
        xy = camera_model(cam.model).project(X, p.stations.angles[i], p.stations.position[i],
                                             cam.values())
        worst = max(worst, np.abs(views[name].project(X) - xy).max())
    from photogram.io.exchange import opencv_intrinsics
    misfit = max(opencv_intrinsics(c)[2] for c in p.cameras.values())
    assert 0 < misfit < 0.05 and worst < 3 * misfit
    print(f"brown -> opencv fit: {misfit:.4f} px RMS over the format, "
          f"{worst:.4f} px max on the points")
    files = export_results("opencv", lab_results, tmp_path / "ocv")
    assert len(files) == len(p.stations)
