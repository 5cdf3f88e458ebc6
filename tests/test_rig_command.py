"""`photogram calibrate` on a board project (issue 20): image folders of a
ChArUco board drawn by homography into pinhole cameras (a small end-to-end
set; the rendered videos with distortion and blur are
photogram.simulation.board_rig's), the results folder, and bad input as
one line with exit code 2."""

import json

import cv2
import numpy as np
import pandas as pd
import pytest

from photogram.io.pose2sim import read_pose2sim
from photogram.io.targets import parse_target
from photogram.geometry import rodrigues_to_matrix
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

SPEC = "charuco:7x5:0.08:0.06:DICT_5X5_100"
SIZE = (800, 600)


def _look_at(C, target):
    z = target - C
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    return R, -R @ C


def _texture(target, px_per_m=1000):
    board = target.board()
    w = int(round(target.cols * target.size * px_per_m))
    h = int(round(target.rows * target.size * px_per_m))
    img = board.generateImage((w, h), marginSize=0, borderBits=1)
    return img, px_per_m


def _write_set(folder, n_cameras=3, n_poses=24, seed=0):
    """Image folders cam01.. of a board drawn by homography (pinhole, no
    distortion), pose 0 on the floor; returns the truth."""
    rng = np.random.default_rng(seed)
    target = parse_target(SPEC)
    tex, ppm = _texture(target)
    cams = {}
    for i in range(n_cameras):
        a = -0.6 + 1.2 * i / max(n_cameras - 1, 1)          # all in front: the board's face
        C = np.array([2.2 * np.sin(a), -2.2 * np.cos(a), 1.6])
        R, t = _look_at(C, np.array([0.0, 0.0, 0.4]))
        K = np.array([[700.0 + 40 * i, 0, 400], [0, 700.0 + 40 * i, 300], [0, 0, 1]])
        cams[f"cam{i + 1:02d}"] = (K, R, t)
    poses = [(np.diag([1.0, -1.0, -1.0]), np.array([-0.28, 0.2, 0.0]))]     # floor, face up
    for _ in range(n_poses - 1):
        # upright, facing -Y (the cameras), tilted a little
        R0 = rodrigues_to_matrix(np.array([-np.pi / 2, 0.0, 0.0]))
        Rb = R0 @ rodrigues_to_matrix(rng.normal(0, 0.45, 3))
        tb = np.array([rng.uniform(-0.5, 0.2), rng.uniform(-0.3, 0.3), rng.uniform(0.3, 0.9)])
        poses.append((Rb, tb))
    # texture pixel (u, v) -> board point (u / ppm, v / ppm, 0): OpenCV's
    # board frame (x along the first row, y down the columns, z into it)
    S = np.array([[1 / ppm, 0, 0.5 / ppm], [0, 1 / ppm, 0.5 / ppm], [0, 0, 1]])
    for name, (K, R, t) in cams.items():
        (folder / name).mkdir(parents=True)
        for k, (Rb, tb) in enumerate(poses):
            M = R @ Rb                                   # board -> camera
            H = K @ np.column_stack([M[:, 0], M[:, 1], R @ tb + t]) @ S
            img = cv2.warpPerspective(tex, H, SIZE, flags=cv2.INTER_AREA,
                                      borderValue=150)
            img = cv2.GaussianBlur(img, (0, 0), 0.6)
            noise = rng.normal(0, 2.0, img.shape)
            img = np.clip(img + noise, 0, 255).astype(np.uint8)
            # stored as BMP (the same pixels; zlib's inflate was most of
            # imread, and an uncompressed PNG still took 4.7 ms to write
            # and 1.1 ms to read at 800 x 600, a BMP 0.4 and 0.2 ms)
            cv2.imwrite(str(folder / name / f"{k:04d}.bmp"), img)
    return cams, poses


def _prj(folder, extra=""):
    p = folder / "rig.prj"
    p.write_text(f'[project]\nname = "rig"\n\n[board]\ntarget = "{SPEC}"\n'
                 f'cameras = {{ cam01 = "cam01", cam02 = "cam02", cam03 = "cam03" }}\n'
                 f'floor = "0000"\n{extra}\n[output]\nfolder = "results"\n')
    return p


@pytest.fixture(scope="module")
def rig_set(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rig")
    truth = _write_set(folder)
    return folder, truth


def test_calibrate_board_project_writes_cameras_near_the_truth(rig_set, capsys):
    folder, (cams, poses) = rig_set
    assert main(["calibrate", "--no-report", str(_prj(folder))]) == 0
    out = folder / "results"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "converged"
    assert summary["floor_frame"] == "0000"
    table = pd.read_csv(out / "cameras.csv")
    assert set(table.camera) == set(cams)
    views = {v.name: v for v in read_pose2sim(out / "Calib.toml")}
    Rb0, tb0 = poses[0]
    A = np.diag([1.0, -1.0, -1.0]) @ Rb0.T               # = I: the floor board, face up
    for name, (K, R, t) in cams.items():
        v = views[name]
        C_true = A @ (-R.T @ t - tb0)
        C = -v.R_cv.T @ v.t_cv
        row = table[table.camera == name].iloc[0]
        sC = np.array([row.s_X0, row.s_Y0, row.s_Z0])
        # a small board (56 x 40 cm, about 200 px) at 2.2 m: centimetres,
        # within the propagated sigmas
        assert np.all(np.abs(C - C_true) < 4 * sC) and np.linalg.norm(C - C_true) < 0.05
        assert abs(row.fx - K[0, 0]) < 4 * row.s_fx
        assert row.rms_px < 0.5
    assert summary["weakest_camera"] in cams
    assert "results in" in capsys.readouterr().out


def test_no_floor_frame_takes_the_pose_seen_by_most_cameras(rig_set, tmp_path, capsys):
    folder, _ = rig_set
    text = _prj(folder).read_text().replace('floor = "0000"\n', "")
    p = folder / "rig2.prj"
    p.write_text(text)
    assert main(["calibrate", "--no-report", str(p), "--output", str(tmp_path / "out")]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["floor_given"] is False and s["floor_frame"]


@pytest.mark.parametrize("change,expect", [
    ('target = "charuco:7x5:0.08:0.09:DICT_5X5_100"', "target"),
    ('cameras = { cam01 = "cam01", cam09 = "nowhere" }', "nowhere"),
    ('cameras = { cam01 = "cam01" }', "at least 2 cameras"),
    ('floor = "9999"', "floor"),
    ("fix_k3 = 3", "fix_k3"),
    ("stepp = 0.2", "stepp"),
    ('model = "fisheye"', "opencv_fisheye"),
])
def test_bad_board_projects_get_one_line_and_exit_2(rig_set, tmp_path, capsys, change, expect):
    folder, _ = rig_set
    lines = _prj(folder).read_text().splitlines()
    key = change.split("=")[0].strip()
    lines = [ln for ln in lines if not ln.startswith(key + " ")]
    i = lines.index("[output]")
    lines.insert(i - 1, change)
    p = folder / f"bad_{key}.prj"
    p.write_text("\n".join(lines) + "\n")
    code = main(["calibrate", "--no-report", str(p), "--output", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and expect in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "o").exists()


def test_a_camera_that_never_sees_the_board_is_named(rig_set, tmp_path, capsys):
    folder, _ = rig_set
    blank = folder / "blank"
    blank.mkdir(exist_ok=True)
    for k in range(3):
        cv2.imwrite(str(blank / f"{k:04d}.png"), np.full((600, 800), 128, np.uint8))
    text = _prj(folder).read_text().replace('cam03 = "cam03"', 'cam03 = "blank"')
    p = folder / "blank.prj"
    p.write_text(text)
    code = main(["calibrate", "--no-report", str(p), "--output", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "cam03" in err[0] and "not found" in err[0]


def test_a_fisheye_rig_is_written_as_fisheye_in_calib_toml():
    from photogram.io.exchange import View
    from photogram.io.pose2sim import format_pose2sim
    v = View("c1", "c1", np.array([[400.0, 0, 640], [0, 400, 360], [0, 0, 1]]),
             np.array([0.01, -0.002, 0.0, 0.0]), np.eye(3), np.zeros(3), (1280, 720),
             extra={"fisheye": True})
    text = format_pose2sim([v])
    assert "fisheye = true" in text
    assert "distortions = [ 0.01, -0.002, 0.0, 0.0]" in text


def test_scene_points_give_the_world(rig_set, tmp_path, capsys):
    """[board] scene: 6 points of known coordinates on the floor and on a
    box, marked (projected, 0.3 px noise) in every camera: the cameras in
    that world, without a floor frame."""
    folder, (cams, poses) = rig_set
    rng = np.random.default_rng(9)
    pts = np.array([[-0.6, -0.4, 0.0], [0.6, -0.4, 0.0], [0.6, 0.5, 0.0], [-0.6, 0.5, 0.0],
                    [0.0, 0.0, 0.45], [0.3, 0.2, 0.45]])
    (folder / "scene.csv").write_text("point,X,Y,Z\n" + "".join(
        f"S{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(pts)))
    rows = ["camera,point,x,y"]
    for name, (K, R, t) in cams.items():
        xy = (pts @ R.T + t) @ K.T
        xy = xy[:, :2] / xy[:, 2:] + rng.normal(0, 0.3, (len(pts), 2))
        rows += [f"{name},S{k},{x:.3f},{y:.3f}" for k, (x, y) in enumerate(xy)]
    (folder / "marks.csv").write_text("\n".join(rows) + "\n")
    text = _prj(folder).read_text().replace(
        'floor = "0000"\n', 'scene = { points = "scene.csv", image_points = "marks.csv", '
                            'sigma_image = 0.3 }\n')
    p = folder / "scene.prj"
    p.write_text(text)
    assert main(["calibrate", "--no-report", str(p), "--output", str(tmp_path / "out")]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["world"] == "scene" and s["scene_rms_px"] < 1.0
    table = pd.read_csv(tmp_path / "out" / "cameras.csv")
    views = {v.name: v for v in read_pose2sim(tmp_path / "out" / "Calib.toml")}
    for name, (K, R, t) in cams.items():
        v = views[name]
        row = table[table.camera == name].iloc[0]
        dC = -v.R_cv.T @ v.t_cv - (-R.T @ t)
        assert np.all(np.abs(dC) < 4.5 * np.array([row.s_X0, row.s_Y0, row.s_Z0]))
        assert np.linalg.norm(dC) < 0.05
    bad = text.replace('marks.csv', 'scene.csv')
    p.write_text(bad)
    assert main(["calibrate", "--no-report", str(p), "--output", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "scene.csv" in err[0]


def _to_video(folder, name, fps):
    files = sorted((folder / name).glob("*.bmp"))
    first = cv2.imread(str(files[0]))
    path = folder / f"{name}_{int(fps)}.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps,
                        (first.shape[1], first.shape[0]))
    for f in files:
        w.write(cv2.imread(str(f)))
    w.release()
    return path


def test_videos_are_read_by_time_step_and_must_share_their_frame_rate(rig_set, tmp_path,
                                                                      capsys):
    folder, (cams, _) = rig_set
    for name in cams:
        _to_video(folder, name, 10.0)
    text = _prj(folder).read_text()
    for name in cams:
        text = text.replace(f'{name} = "{name}"', f'{name} = "{name}_10.avi"')
    text = text.replace('floor = "0000"', 'floor = "0"\nstep = 0.2')
    p = folder / "video.prj"
    p.write_text(text)
    assert main(["calibrate", "--no-report", str(p), "--output", str(tmp_path / "v")]) == 0
    s = json.loads((tmp_path / "v" / "summary.json").read_text())
    # 24 frames at 10 fps, one every 0.2 s: frames 0, 2, ..., 22
    assert all(c["frames_read"] == 12 for c in s["cameras"].values())
    assert s["floor_frame"] == "0"
    _to_video(folder, "cam03", 25.0)
    p.write_text(text.replace('cam03 = "cam03_10.avi"', 'cam03 = "cam03_25.avi"'))
    code = main(["calibrate", "--no-report", str(p), "--output", str(tmp_path / "v2")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "cam03" in err[0] and "25" in err[0]
