"""Skeletons, mappings between them, de Leva's segments."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.mocap.body.anthropometry import DE_LEVA_MALE, centre_of_mass
from photogram.mocap.body.skeleton import (BODY14, BODY25B, COCO17, MEDIAPIPE33, SKELETONS, SKI24,
                                           get_skeleton, map_joints)
from photogram.mocap.sources.mediapipe import landmarks_to_joints


def test_ski24_has_the_papers_joints_and_connected_limbs():
    assert SKI24.n_joints == 24
    assert SKI24.joints[:2] == ("head", "neck")
    assert set(BODY14) <= set(SKI24.joints) and len(BODY14) == 14
    for s in "rl":
        for j in ("shoulder", "elbow", "hand", "pole", "hip", "knee", "ankle", "ski_tip",
                  "toes", "heel", "ski_tail"):
            assert f"{s}_{j}" in SKI24.joints
    # every joint is on a limb and the limb graph is connected
    L = SKI24.limb_indices()
    seen, todo = {0}, [0]
    while todo:
        j = todo.pop()
        for a, b in L:
            for x, y in ((a, b), (b, a)):
                if x == j and y not in seen:
                    seen.add(y)
                    todo.append(y)
    assert seen == set(range(24))


@pytest.mark.parametrize("name", list(SKELETONS))
def test_swap_permutation_is_an_involution_and_limbs_are_valid(name):
    sk = SKELETONS[name]
    perm = sk.swap_permutation()
    assert np.array_equal(perm[perm], np.arange(sk.n_joints))
    assert sk.limb_indices().shape[1] == 2


def test_unknown_skeleton_lists_the_known_ones():
    with pytest.raises(InputError, match="known skeletons: ski24"):
        get_skeleton("body99")


def test_body25b_maps_onto_ski24_and_leaves_skis_unobserved():
    det = np.zeros((2, 25, 3))
    det[..., 0] = np.arange(25)
    det[..., 1] = 100 + np.arange(25)
    det[..., 2] = 0.9
    det[1, BODY25B.index("RKnee"), 2] = 0.0
    out = map_joints(det, BODY25B, SKI24)
    assert out.shape == (2, 24, 3)
    assert out[0, SKI24.index("head"), 0] == BODY25B.index("Head")
    assert out[0, SKI24.index("r_hand"), 0] == BODY25B.index("RWrist")
    assert out[0, SKI24.index("l_toes"), 0] == BODY25B.index("LBigToe")
    assert np.isnan(out[0, SKI24.index("r_ski_tip"), 0]) and out[0, SKI24.index("r_pole"), 2] == 0
    assert out[1, SKI24.index("r_knee"), 2] == 0 and np.isnan(out[1, SKI24.index("r_knee"), 0])


def test_coco_neck_is_the_mean_of_the_shoulders_with_the_lower_confidence():
    det = np.zeros((17, 3))
    det[COCO17.index("left_shoulder")] = (10, 20, 0.8)
    det[COCO17.index("right_shoulder")] = (30, 40, 0.6)
    out = map_joints(det, COCO17, SKI24)
    assert np.allclose(out[SKI24.index("neck")], (20, 30, 0.6))


class _Landmark:
    def __init__(self, x, y, v):
        self.x, self.y, self.visibility = x, y, v


class _Landmarks:
    def __init__(self, pts):
        self.landmark = [_Landmark(*p) for p in pts]


def test_mediapipe_landmarks_map_to_pixels_and_onto_ski24():
    pts = [(k / 40.0, 0.5 + k / 100.0, 0.5 + k / 100.0) for k in range(33)]
    j = landmarks_to_joints(_Landmarks(pts), width=400, height=200)
    assert j.shape == (33, 3)
    k = MEDIAPIPE33.index("left_wrist")
    assert np.allclose(j[k], (k * 10.0, 100 + 2 * k, 0.5 + k / 100))
    ski = map_joints(j, MEDIAPIPE33, SKI24)
    assert np.allclose(ski[SKI24.index("l_hand")], j[k])
    ears = j[[MEDIAPIPE33.index("right_ear"), MEDIAPIPE33.index("left_ear")]]
    assert np.allclose(ski[SKI24.index("head"), :2], ears[:, :2].mean(0))
    assert np.allclose(ski[SKI24.index("r_toes")], j[MEDIAPIPE33.index("right_foot_index")])
    assert landmarks_to_joints(None, 10, 10)[:, 2].sum() == 0


def test_mediapipe_detector_without_the_package_is_a_one_line_input_error():
    try:
        import mediapipe  # noqa: F401
        pytest.skip("mediapipe is installed")
    except ImportError:
        pass
    from photogram.mocap.sources.mediapipe import MediapipeDetector
    with pytest.raises(InputError) as exc:
        MediapipeDetector()
    assert "photogram[mediapipe]" in exc.value.one_line() and "\n" not in exc.value.one_line()


def test_de_leva_masses_add_up_and_com_of_a_standing_pose():
    total = DE_LEVA_MALE["head"][0] + DE_LEVA_MALE["trunk"][0] + 2 * sum(
        DE_LEVA_MALE[s][0] for s in ("upper_arm", "forearm", "hand", "thigh", "shank", "foot"))
    assert total == pytest.approx(1.0, abs=1e-9)
    J = {"head": [0, 0, 1.8], "neck": [0, 0, 1.55]}
    for s, y in (("r_", -1), ("l_", 1)):
        J.update({s + "shoulder": [0, 0.19 * y, 1.45], s + "elbow": [0, 0.2 * y, 1.15],
                  s + "hand": [0, 0.2 * y, 0.9], s + "hip": [0, 0.09 * y, 0.95],
                  s + "knee": [0, 0.09 * y, 0.5], s + "ankle": [0, 0.09 * y, 0.08],
                  s + "heel": [-0.05, 0.09 * y, 0.0], s + "toes": [0.2, 0.09 * y, 0.0]})
    com = centre_of_mass({k: np.array(v, float) for k, v in J.items()})
    assert com[1] == pytest.approx(0.0, abs=1e-12)
    assert 0.95 < com[2] < 1.1           # about 55-60 % of the height
