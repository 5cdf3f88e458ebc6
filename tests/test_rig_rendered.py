"""Multi-camera calibration on rendered images of a ChArUco board waved
through the volume (issue 20, item 1): photogram.simulation.board_rig
renders the views (supersampled, exact inverse distortion, blur, noise,
JPEG, motion blur; known truth), photogram.io.targets.detect finds the
corners, photogram.rig calibrates. The goal of the issue: camera centres
within 5 mm and angles within 0.05 deg at 2-6 m; here in the floor frame
(the board laid on the floor, pose 0: the datum, no alignment), and every
error within the calibration's own sigmas. A harsher set (noise 4, JPEG
60, 1/100 s motion blur, occluding bar; cameras at 1.5-2.5 m) is held to
its sigmas only."""

import numpy as np
import pytest

from photogram.io.targets import parse_target
from photogram.rig import calibrate_rig
from photogram.simulation import board_rig as br

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

TARGET = parse_target(br.TARGET_SPEC)


def _set(settings, n_cameras, n_poses, seed):
    cameras = br.rig_cameras(n_cameras, seed=seed, distance=br.USABLE_DISTANCE)
    poses = br.board_poses(n_poses, seed=seed, cameras=cameras, target=TARGET,
                           partly_outside=settings.partly_outside)
    return cameras, poses, br.detect_rendered(cameras, poses, TARGET, settings)


def _errors(cameras, poses, res):
    R0, t0 = br.floor_frame(poses)          # X_world = R0 X_floor + t0
    out = []
    for c in cameras:
        rc = res.cameras[c.name]
        C_true = R0.T @ (c.centre - t0)
        R_true = c.R @ R0
        dC = rc.centre - C_true
        cosang = (np.trace(rc.R @ R_true.T) - 1) / 2
        ang = np.degrees(np.arccos(np.clip(cosang, -1, 1)))
        s_rot = np.sqrt(sum(rc.sigmas[k] ** 2 for k in ("rx", "ry", "rz")))
        out.append((np.linalg.norm(dC), rc.centre_sigma, ang, s_rot))
    return np.array(out)


@pytest.fixture(scope="module")
def normal():
    return _set(br.normal_settings(seed=0), 4, 30, 0)


def test_rendered_rig_meets_the_goal_in_the_floor_frame(normal):
    cameras, poses, dets = normal
    assert any(0 in d for d in dets.values())
    res = calibrate_rig(dets, {c.name: c.image_size for c in cameras}, TARGET, floor_frame=0,
                        fix_k3=False)
    e = _errors(cameras, poses, res)
    print("centre mm", np.round(1000 * e[:, 0], 2), "sigma", np.round(1000 * e[:, 1], 2),
          "angle deg", np.round(e[:, 2], 3), "sigma", np.round(e[:, 3], 3),
          "corners left out", res.summary["rejected_corners"])
    assert np.all(e[:, 0] < 0.005)                     # 5 mm at 2-4 m
    assert np.all(e[:, 0] < 4 * e[:, 1]) and np.all(e[:, 2] < 4 * e[:, 3])
    # angles: the goal's 0.05 deg is met by the 6-camera, 50-pose set of
    # benchmarks/board_rig.py (median 0.040); this smaller set (4 cameras,
    # 30 poses, the floor pose in fewer cameras) holds 0.1
    assert np.median(e[:, 2]) < 0.1
    for c in cameras:                                  # focal length within 0.2 %
        assert abs(res.cameras[c.name].K[0, 0] / c.K[0, 0] - 1) < 2e-3


def test_rendered_rig_harsh_within_its_sigmas():
    """The harsh degradations with the cameras at 1.5-2.5 m. At the usable
    distance (2-4 m) they leave some camera with fewer than 3 detected views
    in every draw tried (seeds 1-4, 40 poses; the board's 6 cm markers are
    3 px per bit there), so this test never reached its assertions before;
    closer cameras keep the degradations and let the set calibrate (seed 1
    here; seed 3, not used here, gave 0.5-1.7 sigmas too). 30 poses (40
    until issue 23, for test time): the errors are held to the set's own
    sigmas, whatever its size; with 30 poses (the one count tried) each
    camera has 8-11 detected views, the centres are 5-8.5 mm off at
    0.5-1.2 of their sigmas (40 poses: 4-15 mm, 0.5-1.4 sigmas)."""
    settings = br.harsh_settings(seed=1)
    cameras = br.rig_cameras(4, seed=1, distance=(1.5, 2.5))
    poses = br.board_poses(30, seed=1, cameras=cameras, target=TARGET,
                           partly_outside=settings.partly_outside)
    dets = br.detect_rendered(cameras, poses, TARGET, settings)
    sizes = {c.name: c.image_size for c in cameras}
    assert all(len(d) >= 3 for d in dets.values()), {c: len(d) for c, d in dets.items()}
    assert any(0 in d for d in dets.values())          # the floor pose is detected
    res = calibrate_rig(dets, sizes, TARGET, floor_frame=0, fix_k3=False)
    e = _errors(cameras, poses, res)
    print("harsh centre mm", np.round(1000 * e[:, 0], 2), "sigma", np.round(1000 * e[:, 1], 2),
          "angle deg", np.round(e[:, 2], 3), "sigma", np.round(e[:, 3], 3))
    assert np.all(e[:, 0] < 4.5 * e[:, 1]) and np.all(e[:, 2] < 4.5 * e[:, 3])
    assert np.all(e[:, 0] < 0.02)


def test_a_camera_with_two_usable_views_is_named(normal):
    """A camera that sees the board in fewer than 3 frames stops the
    calibration with one line naming it (the normal set with all but two
    of cam02's views left out)."""
    from photogram.errors import InputError
    cameras, _, dets = normal
    two = {c: (dict(list(d.items())[:2]) if c == "cam02" else d) for c, d in dets.items()}
    with pytest.raises(InputError, match=r"camera cam02: the board is seen in 2 frame\(s\)"):
        calibrate_rig(two, {c.name: c.image_size for c in cameras}, TARGET, fix_k3=False)
