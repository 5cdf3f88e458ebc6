"""Rendered multi-camera ChArUco sets (photogram.simulation.board_rig,
issue 20 item 1): the renderer against its own truth.

* the texture <-> board mapping agrees with ``Target.object_points()``
  (corners detected in the texture itself);
* the interpolated sample rays equal the exact inverse distortion;
* corners detected by ``photogram.io.targets.detect`` in a rendered view lie
  within 0.1 px RMS of ``cv2.projectPoints`` of the truth (normal), 0.3 px
  (harsh, motion blur on);
* the floor pose lies on Z = 0, printed face up; renders are seeded;
* most poses of a 6-camera set are detected in >= 2 cameras;
* the written set reads back (cameras.toml, board_poses.csv).
"""

from __future__ import annotations

import tomllib

import numpy as np
import pandas as pd
import pytest

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

cv2 = pytest.importorskip("cv2")

from photogram.io.targets import detect, parse_target          # noqa: E402
from photogram.simulation import board_rig as br                # noqa: E402
from photogram.simulation.board_rig import geometry, render      # noqa: E402

TARGET = parse_target(br.TARGET_SPEC)
DIST = br.USABLE_DISTANCE


@pytest.fixture(scope="module")
def cameras():
    return br.rig_cameras(6, seed=0, distance=DIST)


def near_pose(cam, tilt_deg, moving=False):
    """The board 2 m in front of ``cam``, tilted about the camera's y axis."""
    centre = cam.centre + 2.0 * cam.R[2] + 0.3 * cam.R[0]
    R, t = geometry._facing(centre, -cam.R[2], 0.3, cam.R[1], np.radians(tilt_deg), TARGET)
    v, w = (np.array([0.5, 0.3, 0.0]), np.array([0.0, 0.5, 0.8])) if moving else \
        (np.zeros(3), np.zeros(3))
    return R, t, v, w


def rms(det, xy):
    e = det[1] - xy[det[0]]
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


def test_texture_mapping_matches_object_points():
    levels, texel, margin = render._texture(TARGET, 0.02)
    obj = TARGET.object_points()[:, :2]
    for L in (2, 3):
        img = np.clip(np.rint(levels[L] * 255), 0, 255).astype(np.uint8)
        ids, xy = detect(img, TARGET)
        assert len(ids) >= 20
        pred = (obj[ids] + margin) / (texel * 2 ** L) - 0.5
        assert np.abs(xy - pred).max() < 0.01


def test_interpolated_rays_equal_the_exact_inverse(cameras):
    cam = cameras[0]                     # k1 = -0.17: the strongest distortion of the rig
    s, (x0, y0, x1, y1) = 3, (0, 0, 40, 30)   # the image corner: most curvature
    rays = render._sample_rays(cam, s, x0, y0, x1, y1)
    u = (np.arange(x0 * s, x1 * s) + 0.5) / s - 0.5
    v = (np.arange(y0 * s, y1 * s) + 0.5) / s - 0.5
    uu, vv = np.meshgrid(u, v)
    exact = geometry._undistort(cam, np.column_stack([uu.ravel(), vv.ravel()]))
    err_px = np.abs(rays.reshape(-1, 2) - exact) * cam.K[0, 0]
    assert err_px.max() < 1e-3
    # and the exact inverse reprojects onto the sample positions
    xyz = np.column_stack([exact, np.ones(len(exact))])
    back = cv2.projectPoints(xyz, np.zeros(3), np.zeros(3), cam.K, cam.dist)[0].reshape(-1, 2)
    assert np.abs(back - np.column_stack([uu.ravel(), vv.ravel()])).max() < 1e-6


@pytest.mark.parametrize("tilt", [0, 40])
def test_detected_corners_match_truth_normal(cameras, tilt):
    for i in (0, 2):
        cam = cameras[i]
        pose = near_pose(cam, tilt)
        img = br.render_view(cam, pose, TARGET, br.normal_settings(), key=(i, 0))
        det = detect(img, TARGET)
        xy, vis = br.true_corners(cam, pose, TARGET)
        assert det is not None and len(det[0]) == 24 and vis.all()
        assert rms(det, xy) < 0.1


def test_detected_corners_match_truth_harsh(cameras):
    """Harsh: noise 4, JPEG 60, blur 1 px, motion blur over 1/100 s at 0.6
    m/s and 0.9 rad/s (the truth is the mid-exposure pose)."""
    errors = []
    for i in (0, 2):
        cam = cameras[i]
        pose = near_pose(cam, 25, moving=True)
        settings = br.harsh_settings()
        img = br.render_view(cam, pose, TARGET, settings, key=(i, 1))
        det = detect(img, TARGET)
        xy, vis = br.true_corners(cam, pose, TARGET, settings, key=(i, 1))
        assert det is not None and len(det[0]) >= 8
        errors.append(rms(det, xy))
    assert max(errors) < 0.3, errors


def test_motion_blur_smears_the_board(cameras):
    """Noise and JPEG off: the moving board's edges are softer (Laplacian
    variance), a board at rest renders the same with or without sub-frames."""
    from dataclasses import replace
    cam = cameras[1]
    quiet = replace(br.harsh_settings(), noise=0.0, jpeg_quality=0, occlusion=0.0)
    still = br.render_view(cam, near_pose(cam, 10), TARGET, quiet)
    R, t, _, _ = near_pose(cam, 10)
    fast = (R, t, 1.5 * cam.R[0], np.zeros(3))      # 1.5 m/s sideways: 8 px in 1/100 s
    moving = br.render_view(cam, fast, TARGET, quiet)
    single = br.render_view(cam, near_pose(cam, 10), TARGET, replace(quiet, subframes=1))
    xy, _ = br.true_corners(cam, near_pose(cam, 10), TARGET)
    (x0, y0), (x1, y1) = xy.min(0).astype(int), xy.max(0).astype(int)
    lap = [cv2.Laplacian(im[y0:y1, x0:x1].astype(float), cv2.CV_64F).var()
           for im in (still, moving)]
    assert lap[1] < 0.8 * lap[0]
    assert np.abs(still.astype(int) - single).max() <= 1


def test_floor_pose_on_the_floor_face_up(cameras):
    poses = br.board_poses(4, seed=0, cameras=cameras, target=TARGET)
    R, t = poses.R[0], poses.t[0]
    X = TARGET.object_points() @ R.T + t
    assert np.abs(X[:, 2]).max() < 1e-12
    assert np.allclose(R[:, 2], [0, 0, -1])          # board z into the print: down
    # photogram.rig's floor frame: the board's axes made Z-up (x, -y, -z)
    Rf, tf = br.floor_frame(poses)
    assert np.allclose(Rf[:, 2], [0, 0, 1]) and np.allclose(Rf[:, 0], R[:, 0])
    assert np.allclose(tf, t)
    seen = [br.true_corners(c, poses[0], TARGET)[1].all() for c in cameras]
    assert sum(seen) >= 2


def test_cameras_and_poses_as_specified():
    cams = br.rig_cameras(5, seed=3)
    for c in cams:
        assert np.allclose(c.R @ c.R.T, np.eye(3)) and np.linalg.det(c.R) > 0
        d = np.linalg.norm(c.centre - br.VOLUME_CENTRE)
        assert 2.0 <= d <= 6.0 and 1.0 <= c.centre[2] <= 3.0
        assert 900 <= c.K[0, 0] <= 1400 and -0.2 <= c.dist[0] <= 0.1
        # looks at the volume: its centre projects into the image
        x = c.R @ br.VOLUME_CENTRE + c.t
        u = c.K @ (x / x[2])
        assert x[2] > 0 and 0 < u[0] < 1280 and 0 < u[1] < 720
    poses = br.board_poses(30, seed=3, cameras=cams, target=TARGET)
    assert np.allclose(np.einsum("kij,kil->kjl", poses.R, poses.R), np.eye(3))
    centres = poses.t + np.einsum("kij,j->ki", poses.R, geometry._board_centre(TARGET))
    assert np.all(np.abs(centres[1:, :2]) <= 1.5) and np.all(centres[1:, 2] > 0.2)
    # spread through the volume, both halves of x and y
    assert np.ptp(centres[1:, 0]) > 1.5 and np.ptp(centres[1:, 1]) > 1.5


def test_seeded_renders_are_reproducible(cameras):
    cam = cameras[0]
    pose = near_pose(cam, 20, moving=True)
    a = br.render_view(cam, pose, TARGET, br.normal_settings(), key=(0, 5))
    b = br.render_view(cam, pose, TARGET, br.normal_settings(), key=(0, 5))
    c = br.render_view(cam, pose, TARGET, br.normal_settings(seed=9), key=(0, 5))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    p1 = br.board_poses(6, seed=4, cameras=cameras, target=TARGET)
    p2 = br.board_poses(6, seed=4, cameras=cameras, target=TARGET)
    assert np.array_equal(p1.R, p2.R) and np.array_equal(p1.t, p2.t)


def test_most_poses_seen_by_two_cameras(cameras):
    n = 6
    poses = br.board_poses(n, seed=0, cameras=cameras, target=TARGET)
    # detect_rendered: the detections of render_rig's views (tested below)
    dets = br.detect_rendered(cameras, poses, TARGET, br.normal_settings())
    seen = np.zeros(n, int)
    for cam in cameras:
        for k, det in dets[cam.name].items():
            seen[k] += 1
            xy, _ = br.true_corners(cam, poses[k], TARGET)
            # no misread board (oblique views: single corners 1-3 px off,
            # cornerSubPix pulled by the marker borders; docs)
            err = np.linalg.norm(det[1] - xy[det[0]], axis=1)
            assert np.median(err) < 0.3 and err.max() < 5
    assert np.mean(seen >= 2) >= 0.6, seen


def test_harsh_bar_and_border_views(cameras):
    settings = br.harsh_settings()
    poses = br.board_poses(21, seed=2, cameras=cameras, target=TARGET,
                           partly_outside=settings.partly_outside)
    hidden, cut = 0, 0
    for i, cam in enumerate(cameras):
        for k in range(len(poses)):
            xy, vis = br.true_corners(cam, poses[k], TARGET, settings, key=(i, k))
            plain = br.true_corners(cam, poses[k], TARGET)[1]
            hidden += int((plain & ~vis).any())
            front = (cam.R @ poses.R[k])[:, 2] @ (cam.R @ poses.t[k] + cam.t) > 0
            inside = (xy[:, 0] > 0) & (xy[:, 0] < 1280) & (xy[:, 1] > 0) & (xy[:, 1] < 720)
            cut += int(front and inside.any() and not inside.all())
    assert hidden >= 3 and cut >= 2


def test_write_rig_set(tmp_path, cameras):
    cams = cameras[:2]
    poses = br.board_poses(2, seed=0, cameras=cameras, target=TARGET)
    folder = br.write_rig_set(tmp_path / "set", cams, poses, TARGET, br.normal_settings())
    assert sorted(p.name for p in (folder / "cam01").iterdir()) == ["000000.png", "000001.png"]
    toml = tomllib.loads((folder / "truth" / "cameras.toml").read_text())
    for c in cams:
        assert np.allclose(toml[c.name]["matrix"], c.K, rtol=1e-15)
        assert np.allclose(toml[c.name]["rotation"], c.R, rtol=1e-15)
        assert np.allclose(toml[c.name]["translation"], c.t, rtol=1e-15)
        assert tuple(toml[c.name]["size"]) == c.image_size
    table = pd.read_csv(folder / "truth" / "board_poses.csv")
    R = table[[f"r{i}{j}" for i in range(3) for j in range(3)]].to_numpy().reshape(-1, 3, 3)
    assert np.allclose(R, poses.R, atol=1e-8)
    assert np.allclose(table[["tx", "ty", "tz"]].to_numpy(), poses.t, atol=1e-8)
    corners = pd.read_csv(folder / "truth" / "corners.csv")
    assert len(corners) == 2 * 2 * 24
    with pytest.raises(FileExistsError):
        br.write_rig_set(folder, cams, poses, TARGET, br.normal_settings())
    video = br.write_rig_set(tmp_path / "vid", cams, poses, TARGET, br.normal_settings(),
                             video=True)
    cap = cv2.VideoCapture(str(video / "cam01.avi"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 2
    cap.release()


def test_detect_rendered_equals_detecting_all_rendered_views(cameras):
    """The streaming detect_rendered (one view in memory) gives what
    detect_rig gives on render_rig's views, array for array."""
    poses = br.board_poses(2, seed=2, cameras=cameras[:2], target=TARGET)
    settings = br.normal_settings()     # seed 0: the backgrounds test_write_rig_set built
    a = br.detect_rendered(cameras[:2], poses, TARGET, settings)
    b = br.detect_rig(cameras[:2], br.render_rig(cameras[:2], poses, TARGET, settings), TARGET)
    assert a.keys() == b.keys() and any(len(v) for v in a.values())
    for name in a:
        assert a[name].keys() == b[name].keys()
        for k in a[name]:
            assert np.array_equal(a[name][k][0], b[name][k][0])
            assert np.array_equal(a[name][k][1], b[name][k][1])


def test_views_without_the_printed_face_are_not_rendered(cameras):
    """detect_rendered skips the views render.face_seen rejects: the
    board's back towards the camera (rendered: plain grey, nothing
    detected) or the board outside the image; a view of its face is kept."""
    cam = cameras[0]
    R, t, v, w = near_pose(cam, 20)
    back = (R @ np.diag([-1.0, 1.0, -1.0]), t, v, w)      # turned about its y axis
    away = (R, t + 5.0 * cam.R[0], v, w)                   # 5 m to the camera's right
    settings = br.normal_settings()
    assert render.face_seen(cam, (R, t, v, w), TARGET, settings)
    assert not render.face_seen(cam, back, TARGET, settings)
    assert not render.face_seen(cam, away, TARGET, settings)
    img = br.render_view(cam, back, TARGET, settings)
    board = np.abs(img.astype(float) - render._background(cam.name, cam.image_size, 0)) > 30
    assert board.sum() > 10000                             # the back is in the image
    assert detect(img, TARGET) is None
    poses = br.BoardPoses(*(np.array(a)[None] for a in back))
    assert br.detect_rendered([cam], poses, TARGET, settings) == {cam.name: {}}
