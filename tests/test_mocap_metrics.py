"""Metrics of appendix C on poses with known answers."""

import numpy as np
import pytest

from photogram.mocap.body.skeleton import BODY25B, SKI24
from photogram.mocap.evaluation.metrics import (accuracy_3d, biomechanics, bone_lengths,
                                                centre_of_mass, fore_aft, knee_flexion, lean_angle,
                                                mpjpe_2d, pck, speed, ski_joints)


def _pose(knee_r=0.0, lean=0.0):
    """A skier standing on skis along +X at the origin, right knee bent by
    ``knee_r`` deg (shank forward), the whole body tilted by ``lean`` deg
    about X (towards +Y)."""
    J = {"head": [0, 0, 1.8], "neck": [0, 0, 1.55]}
    for s, y in (("r_", -0.1), ("l_", 0.1)):
        J.update({s + "shoulder": [0, 2 * y, 1.45], s + "elbow": [0, 2 * y, 1.15],
                  s + "hand": [0.2, 2 * y, 0.95], s + "pole": [-0.5, 2 * y, 0.2],
                  s + "hip": [0, y, 0.95], s + "knee": [0, y, 0.5], s + "ankle": [0, y, 0.1],
                  s + "heel": [-0.15, y, 0.05], s + "toes": [0.15, y, 0.05],
                  s + "ski_tip": [1.0, y, 0.0], s + "ski_tail": [-0.9, y, 0.0]})
    J = {k: np.array(v, float) for k, v in J.items()}
    a = np.radians(knee_r)
    J["r_ankle"] = J["r_knee"] + 0.4 * np.array([np.sin(a), 0, -np.cos(a)])
    t = np.radians(lean)
    Rx = np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    return np.stack([Rx @ J[n] for n in SKI24.joints])


def test_knee_flexion_is_zero_straight_and_the_bend_angle():
    X = np.stack([_pose(0.0), _pose(90.0), _pose(35.0)])
    J = ski_joints(X, SKI24)
    assert np.allclose(knee_flexion(J, "r"), [0.0, 90.0, 35.0], atol=1e-9)
    assert np.allclose(knee_flexion(J, "l"), 0.0, atol=1e-9)


def test_speed_of_a_uniform_motion_is_exact_also_at_the_ends():
    t = np.arange(40) / 50.0
    com = np.stack([17.0 * t, 0.5 * t, -3.0 * t], -1)
    v, s = speed(com, 50.0)
    assert np.allclose(s, np.linalg.norm([17.0, 0.5, -3.0]))
    v2, s2 = speed(np.concatenate([com, com + 100]), 50.0, breaks=[40])
    assert np.allclose(s2, s[0])


def test_lean_angle_sign_and_magnitude():
    X = np.stack([_pose(lean=30.0), _pose(lean=-20.0)])
    J = ski_joints(X, SKI24)
    com = centre_of_mass(J)
    vel = np.tile([15.0, 0.0, 0.0], (2, 1))
    lean = lean_angle(J, com, vel)
    # tilting about +X moves the body towards -Y (to the right of travel +X) for +30
    assert lean[0] == pytest.approx(-30.0, abs=1.0)
    assert lean[1] == pytest.approx(20.0, abs=1.0)


def test_fore_aft_on_the_extended_leg():
    X = _pose(knee_r=40.0)[None]
    J = ski_joints(X, SKI24)
    com = centre_of_mass(J)
    ang, dist, side = fore_aft(J, com)
    assert side[0] == "l"                           # the straight leg is the outside leg
    d = com[0] - J["l_ankle"][0]
    assert dist[0] == pytest.approx(d[0])            # the ski runs along +X
    assert ang[0] == pytest.approx(np.degrees(np.arctan2(d[0], np.hypot(d[1], d[2]))))
    assert fore_aft(J, com, "flexed")[2][0] == "r"


def test_accuracy_metrics_invariances():
    rng = np.random.default_rng(0)
    T = np.stack([_pose(k) for k in (0, 20, 40)]) + rng.normal(0, 0.01, (3, 24, 3))
    assert accuracy_3d(T, T, SKI24)["mpjpe"] == 0
    moved = accuracy_3d(T + [1.0, 2.0, 3.0], T, SKI24)
    assert moved["mpjpe"] == pytest.approx(np.sqrt(14))
    assert moved["mpjpe_hip"] == pytest.approx(0, abs=1e-12)
    hips = 0.5 * (T[:, SKI24.index("r_hip")] + T[:, SKI24.index("l_hip")])[:, None]
    scaled = accuracy_3d(hips + 1.1 * (T - hips), T, SKI24)
    assert scaled["mpjpe_normalized"] == pytest.approx(0, abs=1e-12) and scaled["mpjpe_hip"] > 0
    assert set(scaled) >= {"mpjpe_body", "mpjpe_hip_body", "mpjpe_normalized_body"}


def test_pck_uses_the_head_neck_radius_and_2d_mpjpe_is_normalised_by_the_width():
    truth = np.zeros((1, 1, 24, 2))
    truth[0, 0, :, 0] = np.arange(24) * 10.0
    truth[0, 0, SKI24.index("head")] = (0.0, 0.0)
    truth[0, 0, SKI24.index("neck")] = (0.0, 20.0)          # radius 20 px
    pred = truth.copy()
    pred[0, 0, 5:, 1] += 25.0                                # 19 joints off by 25 px
    pred[0, 0, 2:5, 1] += 15.0
    assert pck(pred, truth, SKI24) == pytest.approx(5 / 24)
    m = mpjpe_2d(pred, truth, [1000.0])
    assert m["mpjpe_2d_normalized"] == pytest.approx(m["mpjpe_2d_px"] * 2 / 1000)


def test_bone_lengths_of_a_rigid_motion_have_zero_cv_and_generic_skeletons_map():
    X = np.stack([_pose(0) + [k, 0, 0] for k in range(5)])
    bl = bone_lengths(X, SKI24)
    assert max(v[2] for v in bl.values()) < 1e-12
    b25 = np.full((2, 25, 3), np.nan)
    b25[:, BODY25B.index("RKnee")] = [0, 0, 0.5]
    J = ski_joints(b25, BODY25B)
    assert np.allclose(J["r_knee"], [0, 0, 0.5]) and np.all(np.isnan(J["r_ski_tip"]))
    out = biomechanics(X, SKI24, 50.0)
    assert np.allclose(out["speed"], 50.0) and np.allclose(out["knee_flexion_r"], 0, atol=1e-6)
