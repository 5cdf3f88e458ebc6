"""Multi-camera rig calibration from a board (photogram.rig, issue 20):
the board-point residual block's Jacobians against finite differences, and
the whole calibration against the truth on board corners projected by
OpenCV itself (cv2.projectPoints) with noise."""

import cv2
import numpy as np
import pytest

from photogram.adjust.board_blocks import BoardPointBlock
from photogram.adjust.state import Layout, State
from photogram.errors import InputError
from photogram.geometry import camera_model, rodrigues_to_matrix
from photogram.geometry.camera import FLIP_YZ
from photogram.io.targets import parse_target
from photogram.rig import calibrate_rig
from photogram.rig.initial import chordal_mean

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

TARGET = parse_target("chessboard:8x6:0.08")


def _look_at(C, target=np.zeros(3), up=np.array([0.0, 0.0, 1.0])):
    """OpenCV world-to-camera R, t of a camera at C looking at target."""
    z = target - C
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    return R, -R @ C


def _rig(n_cameras=4, seed=0):
    rng = np.random.default_rng(seed)
    cams = {}
    for i in range(n_cameras):
        a = 2 * np.pi * i / n_cameras + rng.uniform(-0.3, 0.3)
        d = rng.uniform(2.5, 5.5)
        C = np.array([d * np.cos(a), d * np.sin(a), rng.uniform(1.0, 2.5)])
        R, t = _look_at(C, np.array([0.0, 0.0, 0.8]))
        K = np.array([[rng.uniform(900, 1300), 0, 640 + rng.uniform(-20, 20)],
                      [0, 0, 360 + rng.uniform(-20, 20)], [0, 0, 1.0]])
        K[1, 1] = K[0, 0] * rng.uniform(0.998, 1.002)
        dist = np.array([rng.uniform(-0.2, 0.05), rng.uniform(-0.05, 0.1),
                         rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3), 0.0])
        cams[f"cam{i + 1:02d}"] = (K, dist, R, t)
    return cams


def _poses(n, seed=0):
    """Board-to-world poses: one on the floor (frame 0: board x = world X,
    board y = -Y, board z = -Z, face up), the rest waved through the volume."""
    rng = np.random.default_rng(seed + 1)
    out = {0: (FLIP_YZ.copy(), np.array([-0.3, 0.2, 0.0]))}
    for f in range(1, n):
        # face a random horizontal direction, tilted
        yaw = rng.uniform(0, 2 * np.pi)
        R0 = rodrigues_to_matrix(np.array([np.pi / 2, 0, 0]))     # board upright
        R = rodrigues_to_matrix(np.array([0, 0, yaw])) @ R0 @ \
            rodrigues_to_matrix(rng.normal(0, 0.35, 3))
        t = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.3, 1.8)])
        out[f] = (R, t)
    return out


def _fisheye_rig(n_cameras=4, seed=0):
    """Wide cameras (fx about 420 px on 1280 x 720: 113 degrees across)
    with Kannala-Brandt k1..k4."""
    cams = _rig(n_cameras, seed)
    rng = np.random.default_rng(seed + 5)
    out = {}
    for c, (K, dist, R, t) in cams.items():
        K = K.copy()
        K[0, 0] = rng.uniform(400, 440)
        K[1, 1] = K[0, 0] * 1.001
        D = np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.02, 0.02), 0.0, 0.0])
        out[c] = (K, D, R, t)
    return out


def _detections(cams, poses, noise=0.1, seed=2, fisheye=False):
    rng = np.random.default_rng(seed)
    P = TARGET.object_points()
    dets, sizes = {}, {}
    for c, (K, dist, R, t) in cams.items():
        dets[c], sizes[c] = {}, (1280, 720)
        for f, (Rb, tb) in poses.items():
            Xw = P @ Rb.T + tb
            Xc = Xw @ R.T + t
            n_board = Rb[:, 2]                    # board z in the world
            C = -R.T @ t
            # the board's front (-z side) must face the camera
            if np.any(Xc[:, 2] < 0.3) or (C - tb) @ (-n_board) <= 0:
                continue
            if fisheye:
                xy, _ = cv2.fisheye.projectPoints(Xw[:, None, :], cv2.Rodrigues(R)[0], t, K,
                                                  dist)
            else:
                xy, _ = cv2.projectPoints(Xw, cv2.Rodrigues(R)[0], t, K, dist)
            xy = xy.reshape(-1, 2)
            inside = (xy[:, 0] > 5) & (xy[:, 0] < 1275) & (xy[:, 1] > 5) & (xy[:, 1] < 715)
            if inside.sum() < 20:
                continue
            ids = np.flatnonzero(inside)
            dets[c][f] = (ids, xy[ids] + rng.normal(0, noise, (len(ids), 2)))
    return dets, sizes


def _truth_in_floor_frame(cams, poses):
    """The cameras with the world = floor board (frame 0) made Z-up, as
    calibrate_rig defines it: X' = F (Rb0^T (X - tb0))."""
    Rb0, tb0 = poses[0]
    A = FLIP_YZ @ Rb0.T
    out = {}
    for c, (K, dist, R, t) in cams.items():
        # X = A^T X' + tb0 -> x_cam = R A^T X' + (R tb0 + t)
        out[c] = (R @ A.T, R @ tb0 + t)
    return out


def test_board_block_jacobians_match_finite_differences():
    rng = np.random.default_rng(3)
    model = camera_model("opencv")
    n_c, n_b, N = 2, 3, 12
    R = np.stack([rodrigues_to_matrix(rng.normal(0, 0.5, 3)) for _ in range(n_c + n_b)])
    X0 = rng.normal(0, 1, (n_c + n_b, 3))
    X0[:n_c] += np.array([0, 0, 8.0])
    R[:n_c] = np.stack([FLIP_YZ @ _look_at(x)[0] for x in X0[:n_c]])
    io = [np.array([1000.0, 1001, 640, 360, -0.1, 0.05, 1e-3, -1e-3, 0.01]) for _ in range(n_c)]
    layout = Layout([9] * n_c, n_c + n_b, 0, np.zeros(0, bool),
                    {"camera": [np.ones(9, bool)] * n_c, "station": np.ones((n_c + n_b, 6), bool),
                     "point": np.zeros((0, 3), bool)})
    cam = rng.integers(0, n_c, N)
    pose = n_c + rng.integers(0, n_b, N)
    p = rng.uniform(-0.3, 0.3, (N, 3))
    block = BoardPointBlock(model, np.arange(n_c), cam, cam, pose, p,
                            rng.normal(600, 50, (N, 2)), np.ones(N), layout)
    state = State(np.zeros((0, 3)), R, X0, io)
    e, J = block.evaluate(state)
    h = 1e-6
    # the engine's own update (R = expm([d]x) R0, X0 + d, io + d) column by column
    for slot, cols in enumerate(block.slot_cols):
        for k in range(cols.shape[1]):
            num = np.zeros((N, 2))
            for sgn in (1, -1):
                dx = np.zeros(layout.n_columns)
                for n in range(N):
                    dx[cols[n, k]] = sgn * h * (1e3 if slot == 2 and k < 4 else 1.0)
                en, _ = block.evaluate(state.updated(layout, dx), jacobians=False)
                num += sgn * en
            scale = h * (1e3 if slot == 2 and k < 4 else 1.0)
            num /= 2 * scale
            # rows touching the same column twice: the numerical derivative
            # of each row is still its own (one column per row at a time)
            np.testing.assert_allclose(J[slot][:, :, k], num, rtol=1e-5, atol=1e-6 * np.abs(
                J[slot]).max())


def test_chordal_mean_of_noisy_rotations():
    rng = np.random.default_rng(4)
    R0 = rodrigues_to_matrix(np.array([0.3, -0.2, 1.0]))
    Rs = [rodrigues_to_matrix(rng.normal(0, 0.01, 3)) @ R0 for _ in range(200)]
    M = chordal_mean(Rs)
    ang = np.degrees(np.arccos((np.trace(M.T @ R0) - 1) / 2))
    assert ang < 0.1
    assert np.allclose(M @ M.T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("noise,seed", [(0.1, 0), (0.5, 1)])
def test_rig_recovers_the_truth_within_its_sigmas(noise, seed):
    cams = _rig(4, seed)
    poses = _poses(40, seed)
    dets, sizes = _detections(cams, poses, noise, seed + 7)
    assert all(0 in d for d in dets.values()), "the floor pose must be seen by every camera"
    res = calibrate_rig(dets, sizes, TARGET, floor_frame=0, sigma_image=noise)
    truth = _truth_in_floor_frame(cams, poses)
    assert res.sigma0 == pytest.approx(1.0, abs=0.15)
    z_centre, z_f, z_rot = [], [], []
    for c, (K, dist, R, t) in cams.items():
        rc = res.cameras[c]
        Rt, tt = truth[c]
        C_true = -Rt.T @ tt
        dC = rc.centre - C_true
        z_centre += list(dC / [rc.sigmas["X0"], rc.sigmas["Y0"], rc.sigmas["Z0"]])
        z_f.append((rc.K[0, 0] - K[0, 0]) / rc.sigmas["fx"])
        assert np.linalg.norm(dC) < 5e-3 * (noise / 0.1)          # 5 mm at 0.1 px
        # the world's axes come from one board pose (the datum): the
        # absolute angles share its error, within their sigmas
        rv = FLIP_YZ @ cv2.Rodrigues(rc.R @ Rt.T)[0].ravel()
        z_rot += list(np.degrees(rv) / [rc.sigmas["rx"], rc.sigmas["ry"], rc.sigmas["rz"]])
        assert rc.rms_px == pytest.approx(noise * np.sqrt(2), rel=0.2)
    # the cameras' relative orientations do not depend on the datum
    names = list(cams)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            rel = res.cameras[a].R @ res.cameras[b].R.T
            rel_true = truth[a][0] @ truth[b][0].T
            ang = np.degrees(np.arccos(np.clip((np.trace(rel.T @ rel_true) - 1) / 2, -1, 1)))
            # (cameras on opposite sides never see the board's face together:
            # their relative orientation is chained through the others)
            assert ang < 0.2 * (noise / 0.1)
    # honest sigmas: the errors over the sigmas are about standard normal
    z = np.asarray(z_centre + z_f + z_rot)
    assert np.sqrt(np.mean(z ** 2)) < 2.0
    assert np.abs(z).max() < 4.5
    assert res.weakest == max(names, key=lambda c: res.cameras[c].centre_sigma)


def test_a_camera_that_never_sees_the_board_is_named():
    cams = _rig(3, 0)
    dets, sizes = _detections(cams, _poses(20, 0))
    dets["cam03"] = {}
    with pytest.raises(InputError, match="cam03"):
        calibrate_rig(dets, sizes, TARGET, floor_frame=0)


def test_cameras_that_share_no_frame_are_named():
    cams = _rig(3, 0)
    dets, sizes = _detections(cams, _poses(30, 0))
    # cam03 keeps only frames that no other camera sees
    others = set(dets["cam01"]) | set(dets["cam02"])
    dets["cam03"] = {f + 1000: v for f, v in dets["cam03"].items() if f not in others} or \
        {f + 1000: v for f, v in dets["cam03"].items()}
    with pytest.raises(InputError, match="cam03"):
        calibrate_rig(dets, sizes, TARGET, floor_frame=0)


def test_fisheye_rig_recovers_the_truth():
    """OpenCV's fisheye model (opencv_fisheye) through the same adjustment:
    corners projected by cv2.fisheye.projectPoints, 0.1 px noise."""
    cams = _fisheye_rig(4, 3)
    poses = _poses(40, 3)
    dets, sizes = _detections(cams, poses, 0.1, 11, fisheye=True)
    res = calibrate_rig(dets, sizes, TARGET, model="opencv_fisheye", floor_frame=0,
                        sigma_image=0.1)
    truth = _truth_in_floor_frame(cams, poses)
    assert res.sigma0 == pytest.approx(1.0, abs=0.15)
    z = []
    for c, (K, D, R, t) in cams.items():
        rc = res.cameras[c]
        assert rc.model == "opencv_fisheye" and rc.dist.shape == (4,)
        C_true = -truth[c][0].T @ truth[c][1]
        dC = rc.centre - C_true
        assert np.linalg.norm(dC) < 0.01
        z += list(dC / [rc.sigmas["X0"], rc.sigmas["Y0"], rc.sigmas["Z0"]])
        z += [(rc.K[0, 0] - K[0, 0]) / rc.sigmas["fx"], (rc.dist[0] - D[0]) / rc.sigmas["k1"]]
    z = np.asarray(z)
    assert np.sqrt(np.mean(z ** 2)) < 2.0 and np.abs(z).max() < 4.5


def test_scene_points_of_known_coordinates_fix_the_world():
    """Pose2Sim's scene extrinsics: 8 points of known coordinates (its
    demo's layout, a 2 x 0.6 m pattern on the floor, two 5 cm up) marked in
    every camera with 0.5 px noise; no floor board: the cameras come out
    in the scene's world directly."""
    from photogram.rig import SceneControl
    cams = _rig(4, 0)
    poses = _poses(40, 0)
    dets, sizes = _detections(cams, poses, 0.1, 7)
    coords = np.array([[-1.0, 0.3, 0.0], [-1.0, 0.0, 0.0], [-1.0, 0.0, 0.05], [-1.0, -0.3, 0.0],
                       [1.0, 0.3, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.05], [1.0, -0.3, 0.0]])
    rng = np.random.default_rng(5)
    obs = {}
    for c, (K, dist, R, t) in cams.items():
        xy, _ = cv2.projectPoints(coords, cv2.Rodrigues(R)[0], t, K, dist)
        obs[c] = {f"S{k}": xy[k, 0] + rng.normal(0, 0.5, 2) for k in range(len(coords))}
    scene = SceneControl({f"S{k}": (coords[k], 0.0) for k in range(len(coords))}, obs,
                         sigma_image=0.5)
    res = calibrate_rig(dets, sizes, TARGET, scene=scene, sigma_image=0.1)
    assert res.floor_frame is None and res.summary["scene_rms_px"] < 1.0
    for c, (K, dist, R, t) in cams.items():
        rc = res.cameras[c]
        dC = rc.centre - (-R.T @ t)
        # 8 points marked at 0.5 px fix the world to 1-8 mm (sigmas)
        assert np.linalg.norm(dC) < 0.03
        assert np.all(np.abs(dC) < 4.5 * np.array([rc.sigmas["X0"], rc.sigmas["Y0"],
                                                   rc.sigmas["Z0"]]))
        # the world's axes from 8 points 0.6 m across marked at 0.5 px: a
        # few tenths of a degree, within the propagated sigmas
        rv = np.degrees(FLIP_YZ @ cv2.Rodrigues(rc.R @ R.T)[0].ravel())
        assert np.linalg.norm(rv) < 0.5
        assert np.all(np.abs(rv) < 4.5 * np.array([rc.sigmas["rx"], rc.sigmas["ry"],
                                                   rc.sigmas["rz"]]))
    with pytest.raises(InputError, match="not both"):
        calibrate_rig(dets, sizes, TARGET, scene=scene, floor_frame=0)
    few = SceneControl(scene.points, {c: {k: v for k, v in o.items() if k in ("S0", "S1")}
                                      for c, o in obs.items()})
    with pytest.raises(InputError, match="3 or more"):
        calibrate_rig(dets, sizes, TARGET, scene=few)
    stray = SceneControl(scene.points, {"cam09": obs["cam01"]})
    with pytest.raises(InputError, match="cam09"):
        calibrate_rig(dets, sizes, TARGET, scene=stray)


def test_a_misnumbered_board_view_is_left_out():
    """One camera's detection in one frame with its corners numbered the
    other way round (a chessboard seen upside down): left out by its RMS,
    named in the summary, and the rig as without it."""
    cams = _rig(4, 0)
    poses = _poses(40, 0)
    dets, sizes = _detections(cams, poses, 0.1, 7)
    clean = calibrate_rig(dets, sizes, TARGET, floor_frame=0, sigma_image=0.1)
    f = next(f for f in sorted(dets["cam02"]) if f != 0 and len(dets["cam02"][f][0]) == 48
             and sum(f in d for d in dets.values()) >= 3)
    ids, xy = dets["cam02"][f]
    dets["cam02"][f] = (47 - ids, xy)                  # 180 degrees
    res = calibrate_rig(dets, sizes, TARGET, floor_frame=0, sigma_image=0.1)
    assert list(res.summary["rejected_views"]) == [f"cam02 {f}"]
    for c in cams:
        assert np.linalg.norm(res.cameras[c].centre - clean.cameras[c].centre) < 1e-3
    assert res.sigma0 == pytest.approx(clean.sigma0, rel=0.05)


def test_a_view_with_corners_along_one_row_does_not_stop_the_start():
    """cv2.calibrateCamera stops with an assertion (initIntrinsicParams2D)
    when one view's corners lie on one row of the board (seen on a rendered
    harsh set); that view is left out of the start, the rest calibrates."""
    from photogram.rig.initial import camera_intrinsics, planar_view_ok
    P = TARGET.object_points()
    K = np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]])
    rng = np.random.default_rng(0)
    frames = {}
    for f in range(8):
        xy, _ = cv2.projectPoints(P, rng.normal(0, 0.3, 3), np.array([-0.2, -0.15, 1.5 + f / 25]),
                                  K, np.zeros(5))
        frames[f] = (np.arange(len(P)), xy.reshape(-1, 2) + rng.normal(0, 0.1, (len(P), 2)))
    row = np.flatnonzero(np.isclose(P[:, 1], P[0, 1]))
    frames[9] = (row, frames[3][1][row])
    assert not planar_view_ok(P[row], frames[9][1]) and planar_view_ok(P, frames[3][1])
    with pytest.raises(cv2.error):
        cv2.calibrateCamera([P[frames[f][0]].astype(np.float32) for f in frames],
                            [frames[f][1].astype(np.float32).reshape(-1, 1, 2) for f in frames],
                            (1280, 720), None, None)
    K_est, _, poses, rms = camera_intrinsics(frames, P, (1280, 720), name="c")
    assert 9 not in poses and len(poses) == 8
    assert abs(K_est[0, 0] / 1000 - 1) < 0.01 and rms < 0.3


def test_a_board_pose_seen_only_in_views_left_out_of_the_start():
    """A frame whose only view lies along one board row (left out of the
    start: planar_view_ok) has no start pose; the adjustment goes on
    without it instead of stopping (a KeyError on the rendered harsh set),
    and the rig is the one without that frame."""
    cams = _rig(4, 0)
    poses = _poses(40, 0)
    dets, sizes = _detections(cams, poses, 0.1, 7)
    f = next(f for f in sorted(dets["cam02"]) if f != 0 and len(dets["cam02"][f][0]) == 48)
    for d in dets.values():
        d.pop(f, None)
    clean = calibrate_rig(dets, sizes, TARGET, floor_frame=0, sigma_image=0.1)
    P = TARGET.object_points()
    row = np.flatnonzero(np.isclose(P[:, 1], P[0, 1]))
    xy, _ = cv2.projectPoints(P[row] @ poses[f][0].T + poses[f][1],
                              cv2.Rodrigues(cams["cam02"][2])[0], cams["cam02"][3],
                              cams["cam02"][0], cams["cam02"][1])
    dets["cam02"][f] = (row, xy.reshape(-1, 2))
    res = calibrate_rig(dets, sizes, TARGET, floor_frame=0, sigma_image=0.1)
    assert f not in res.board_poses
    for c in cams:
        assert np.linalg.norm(res.cameras[c].centre - clean.cameras[c].centre) < 1e-9


def test_views_that_would_cut_a_camera_off_are_kept():
    """removable_views leaves out the worst views first but keeps a view
    that is the last tie of a camera to the others, a camera's third view
    and the floor pose's last view."""
    from photogram.rig.calibrate import removable_views
    v = (np.zeros(0, int), np.zeros((0, 2)))
    dets = {"a": dict.fromkeys([0, 1, 2, 3], v), "b": dict.fromkeys([1, 2, 4, 5], v),
            "c": dict.fromkeys([3, 6, 7, 8], v)}
    # c is tied to the others by frame 3 only; b by frames 1 and 2
    bad = {("c", 3): 50.0, ("a", 1): 40.0, ("a", 2): 30.0, ("b", 4): 20.0, ("a", 0): 10.0}
    out = removable_views(dets, bad, keep_frame=0)
    assert ("c", 3) not in out            # c's only tie
    assert ("a", 1) in out and ("a", 2) not in out     # a-b keeps one shared frame
    assert ("b", 4) in out                # b keeps 3 views
    assert ("a", 0) not in out            # a would keep 2 views (and frame 0 is the floor)
    assert removable_views(dets, {("a", 0): 9.0}, keep_frame=0) == {}
    # alone, a keeps 3 views without frame 0: it goes unless it is the floor
    assert removable_views(dets, {("a", 0): 9.0}) == {("a", 0): 9.0}
