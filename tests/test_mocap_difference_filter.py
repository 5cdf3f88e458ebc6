"""The filter of measured rotation differences (issue 22, estimated
rotations): pairs with few inliers are left out, and a fast pan keeps its
total turn through the filter (the chain of differences sums them)."""

import numpy as np

from photogram.geometry.rotations import matrix_to_rodrigues, rodrigues_to_matrix
from photogram.mocap.motion.homography import HomographySettings, RotationDifferences
from photogram.mocap.motion.rotation_series import confident_pairs, filter_rotation_differences


def _pan(n=120, seed=0):
    """A slow pan with a whip pan of ~55 deg over 12 pairs (the operator
    catching up after losing the athlete), 0.03 deg noise per pair."""
    rng = np.random.default_rng(seed)
    rate = np.full(n, 0.15)
    t = np.arange(n)
    rate += 8.0 * np.exp(-0.5 * ((t - 60) / 3.0) ** 2)         # deg per pair
    r_true = np.zeros((n, 3))
    r_true[:, 2] = np.radians(rate)
    r = r_true + rng.normal(0, np.radians(0.03), (n, 3))
    return r_true, r


def _chain_angle(r):
    return np.degrees(np.sum(r[:, 2]))


def test_fast_pan_keeps_its_total_turn():
    r_true, r = _pan()
    dR = rodrigues_to_matrix(r)
    st = HomographySettings()
    out = matrix_to_rodrigues(filter_rotation_differences(dR, np.ones(len(r), bool),
                                                          st.median, st.sigma))
    total = _chain_angle(r_true)
    assert abs(_chain_angle(out) - total) < 0.3                # the default: median 3
    old = matrix_to_rodrigues(filter_rotation_differences(dR, np.ones(len(r), bool), 7, 3.0))
    assert abs(_chain_angle(old) - total) > 1.0                # the paper's median 7 clips


def test_pairs_with_few_inliers_are_left_out():
    r_true, r = _pan(seed=1)
    n = len(r)
    rng = np.random.default_rng(2)
    wrong = np.array([20, 21, 45, 46, 90, 91])              # in pairs: median 3 keeps them
    r[wrong, 0] += np.radians(2.0)                           # wrong homographies
    inliers = rng.integers(150, 380, n)
    inliers[wrong] = rng.integers(15, 40, len(wrong))
    rd = RotationDifferences(rodrigues_to_matrix(r), inliers, np.full(n, 400),
                             np.ones(n, bool), 0.0, n + 1)
    ok = confident_pairs(rd, HomographySettings().min_inlier_fraction)
    assert not ok[wrong].any() and ok.sum() == n - len(wrong)
    assert np.array_equal(confident_pairs(rd, 0.0), rd.ok)
    st = HomographySettings()
    kept = matrix_to_rodrigues(filter_rotation_differences(rd.dR, ok, st.median, st.sigma))
    blind = matrix_to_rodrigues(filter_rotation_differences(rd.dR, rd.ok, st.median, st.sigma))
    drift_kept = abs(np.degrees(np.sum(kept[:, 0] - r_true[:, 0])))
    drift_blind = abs(np.degrees(np.sum(blind[:, 0] - r_true[:, 0])))
    assert drift_kept < 0.3 and drift_blind > 3.0, (drift_kept, drift_blind)
