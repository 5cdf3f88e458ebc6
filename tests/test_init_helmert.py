"""Seven-parameter 3D similarity (Helmert) transformation."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from photogram.errors import GeometryError
from photogram.geometry.rotations import (matrix_to_rodrigues, opk_to_matrix,
                                          rodrigues_to_matrix)
from photogram.init.helmert import apply_helmert, helmert, helmert_outliers


def truth(seed, n=12):
    rng = np.random.default_rng(seed)
    src = rng.uniform(-3, 3, (n, 3)) + np.array([0.0, 0.0, -4.0])
    angles = rng.uniform(-1.2, 1.2, 3)
    R = opk_to_matrix(angles)
    s = rng.uniform(0.2, 5.0)
    t = rng.normal(size=3) * 100
    return src, s, R, t, angles


@pytest.mark.parametrize("seed", range(5))
def test_noise_free_recovers_truth(seed):
    src, s, R, t, angles = truth(seed)
    dst = s * src @ R.T + t
    res = helmert(src, dst)
    assert abs(res.scale - s) < 1e-10 * s
    assert np.abs(res.R - R).max() < 1e-10
    assert np.abs(res.t - t).max() < 1e-10 * np.abs(t).max()
    assert np.abs(res.angles - angles).max() < 1e-10
    assert np.abs(res.residuals).max() < 1e-9
    assert res.dof == 3 * len(src) - 7
    assert np.allclose(apply_helmert(res, src), dst, atol=1e-9)
    assert np.allclose(res.inverse().apply(dst), src, atol=1e-9)


def test_weighted_noise_free_and_minimum_points():
    src, s, R, t, _ = truth(9, n=3)
    dst = s * src @ R.T + t
    for w in (None, np.array([1.0, 4.0, 0.5]), np.array([[1, 2, 3], [4, 5, 6], [1, 1, 9.0]])):
        res = helmert(src, dst, weights=w)
        assert abs(res.scale - s) < 1e-10 * s
        assert np.abs(res.R - R).max() < 1e-10
        assert np.abs(res.t - t).max() < 1e-10 * np.abs(t).max()
        assert res.dof == 2


def test_noisy_fit_within_own_accuracy():
    sigma = 0.002
    src, s, R, t, _ = truth(3, n=25)
    rng = np.random.default_rng(42)
    dst = s * src @ R.T + t + rng.normal(scale=sigma, size=src.shape)
    res = helmert(src, dst, weights=np.full(len(src), 1 / sigma ** 2))
    # sigma0 of unit weight ~ 1 (chi-square, 68 degrees of freedom)
    assert 0.7 < res.sigma0 < 1.3
    assert abs(np.sqrt((res.residuals ** 2).sum() / res.dof) - sigma) < 0.3 * sigma
    std = np.sqrt(np.diag(res.covariance))
    # rotation error as the small left rotation dR with R_est = exp([dR]x) R_true
    dR = matrix_to_rodrigues(res.R @ R.T)
    err = np.r_[res.scale - s, dR, res.t - t]
    assert np.all(np.abs(err) < 4 * std), err / std
    assert np.abs(res.redundancy.sum() - res.dof) < 1e-9
    assert np.abs(res.standardized).max() < 4


def test_anisotropic_weights_match_general_least_squares():
    src, s, R, t, _ = truth(5, n=10)
    rng = np.random.default_rng(1)
    sig = rng.uniform(0.001, 0.02, (10, 3))
    dst = s * src @ R.T + t + rng.normal(size=src.shape) * sig
    res = helmert(src, dst, weights=1 / sig ** 2)

    def fun(p):
        Rp = rodrigues_to_matrix(p[1:4]) @ R
        return ((p[0] * src @ Rp.T + p[4:] - dst) / sig).ravel()

    ref = least_squares(fun, np.r_[s, 0, 0, 0, t], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    Rref = rodrigues_to_matrix(ref.x[1:4]) @ R
    assert abs(res.scale - ref.x[0]) < 1e-9
    assert np.abs(res.R - Rref).max() < 1e-9
    assert np.abs(res.t - ref.x[4:]).max() < 1e-7
    # the isotropic closed form alone would differ
    iso = helmert(src, dst, weights=(1 / sig ** 2).mean(axis=1))
    assert np.abs(iso.t - res.t).max() > 1e-6


def test_gross_error_in_reference_coordinates_is_found():
    sigma = 0.001
    src, s, R, t, _ = truth(8, n=12)
    rng = np.random.default_rng(3)
    dst = s * src @ R.T + t + rng.normal(scale=sigma, size=src.shape)
    dst[7, 1] += 0.03                                 # 30 sigma blunder
    res = helmert(src, dst)
    bad = helmert_outliers(res, k=3)
    assert bad.tolist()[:1] == [7]
    assert np.argmax(np.abs(res.standardized).max(axis=1)) == 7
    # with the a-priori sigma of unit weight (weights 1/sigma^2) as well
    resw = helmert(src, dst, weights=np.full(12, 1 / sigma ** 2))
    assert 7 in helmert_outliers(resw, k=3, sigma0=1.0)
    # removing the blunder leaves a clean fit (this noise draw has one
    # genuine 3.3-sigma value, so test at 4)
    keep = np.arange(12) != 7
    clean = helmert(src[keep], dst[keep])
    assert len(helmert_outliers(clean, k=4)) == 0
    assert 0.5 * sigma < clean.sigma0 < 1.5 * sigma


def test_degenerate_input_raises():
    src, s, R, t, _ = truth(1, n=6)
    dst = s * src @ R.T + t
    with pytest.raises(GeometryError, match="at least 3 points"):
        helmert(src[:2], dst[:2])
    line = np.outer(np.linspace(0, 1, 6), [1.0, 2.0, 3.0]) + 5.0
    with pytest.raises(GeometryError, match="non-collinear.*lie on a line"):
        helmert(line, s * line @ R.T + t)
    with pytest.raises(GeometryError, match="non-zero weight"):
        helmert(src, dst, weights=np.r_[1.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(GeometryError, match="shape"):
        helmert(src, dst[:5])
    with pytest.raises(GeometryError, match="weights"):
        helmert(src, dst, weights=np.ones(4))
