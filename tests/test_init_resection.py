"""Space resection: closed-form candidates, choice, and least-squares
refinement with the full (distorted) camera model."""

import numpy as np
import pytest

from photogram.errors import GeometryError
from photogram.geometry import camera_model, matrix_to_opk, matrix_to_rodrigues, opk_to_matrix
from photogram.init.resection import (project_ideal, refine_resection, resect,
                                      resection_direct)

C, X0P, Y0P, W, H = 1420.0, 323.5, 238.2, 640, 480


def synthetic(seed, n=10, angles=None):
    """Camera (c = 1420 px, 640x480) and n points 2-5 m in front of it."""
    rng = np.random.default_rng(seed)
    if angles is None:
        angles = rng.uniform(-np.pi, np.pi, 3) * np.array([1.0, 0.45, 1.0])
    R = opk_to_matrix(np.asarray(angles, dtype=float))
    X0 = rng.normal(size=3) * 3
    xy = np.c_[rng.uniform(0, W, n), rng.uniform(0, H, n)]
    d = rng.uniform(2, 5, n)
    Xc = np.c_[(xy[:, 0] - X0P) * d / C, -(xy[:, 1] - Y0P) * d / C, -d]
    X = X0 + Xc @ R
    return X, xy, R, X0, np.asarray(angles, dtype=float)


def planar(seed, n=8):
    """Points on the plane Z = 0 seen obliquely from 3-5 m."""
    rng = np.random.default_rng(seed)
    X = np.c_[rng.uniform(-1.5, 1.5, n), rng.uniform(-1.0, 1.0, n), np.zeros(n)]
    angles = np.r_[rng.uniform(-0.5, 0.5, 2), rng.uniform(-np.pi, np.pi)]
    R = opk_to_matrix(angles)
    X0 = -R.T @ np.array([0.0, 0.0, -rng.uniform(3, 5)]) + np.r_[rng.normal(size=2) * 0.2, 0]
    return X, project_ideal(X, R, X0, C, X0P, Y0P), R, X0


def pose_error(R, X0, Rt, X0t):
    return max(np.abs(R - Rt).max(), np.abs(X0 - X0t).max() / max(1.0, np.abs(X0t).max()))


# ------------------------------------------------------------- closed form --

@pytest.mark.parametrize("seed", range(40))
def test_p3p_candidates_contain_truth(seed):
    X, xy, R, X0, _ = synthetic(seed, n=3)
    cands = resection_direct(X, xy, C, X0P, Y0P)
    assert 1 <= len(cands) <= 4
    assert min(pose_error(Rc, Xc, R, X0) for Rc, Xc in cands) < 1e-8
    for Rc, X0c in cands:                      # every candidate: proper rotation, points in front
        assert np.allclose(Rc @ Rc.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(Rc) > 0
        assert np.all(((X - X0c) @ Rc.T)[:, 2] < 0)


@pytest.mark.parametrize("seed", range(20))
def test_resect_non_planar_recovers_truth(seed):
    X, xy, R, X0, angles = synthetic(seed, n=8)
    est = resect(X, xy, C, X0P, Y0P)
    assert pose_error(est.R, est.X0, R, X0) < 1e-8
    assert np.abs(est.angles - angles).max() < 1e-8
    assert est.rms < 1e-8


@pytest.mark.parametrize("seed", range(10))
def test_resect_planar_recovers_truth(seed):
    X, xy, R, X0 = planar(seed)
    est = resect(X, xy, C, X0P, Y0P)
    assert pose_error(est.R, est.X0, R, X0) < 1e-8
    cands = resection_direct(X, xy, C, X0P, Y0P)
    # the homography candidate (last) is exact too
    assert pose_error(*cands[-1], R, X0) < 1e-8


def test_resect_with_noise_is_close():
    X, xy, R, X0, _ = synthetic(3, n=20)
    rng = np.random.default_rng(0)
    est = resect(X, xy + rng.normal(scale=0.3, size=xy.shape), C, X0P, Y0P)
    assert est.rms < 3.0
    assert np.abs(matrix_to_rodrigues(est.R @ R.T)).max() < 5e-3
    assert np.abs(est.X0 - X0).max() < 0.05


def test_degenerate_input_raises():
    X, xy, R, X0, _ = synthetic(1, n=6)
    with pytest.raises(GeometryError, match="at least 3 points"):
        resection_direct(X[:2], xy[:2], C)
    with pytest.raises(GeometryError, match="at least 3 points"):
        resect(X[:2], xy[:2], C)
    line = X0 + np.outer(np.linspace(2, 4, 5), R.T @ np.array([0.3, 0.1, -1.0]))
    xl = project_ideal(line + np.array([0.0, 0.5, 0.0]), R, X0, C, X0P, Y0P)
    with pytest.raises(GeometryError, match="non-collinear.*lie on a line"):
        resect(line + np.array([0.0, 0.5, 0.0]), xl, C, X0P, Y0P)
    # object points not collinear, image points collinear: camera in their plane
    with pytest.raises(GeometryError, match="image points are collinear"):
        resection_direct(X[:4], np.c_[np.arange(4.0), 2 * np.arange(4.0)], C)
    with pytest.raises(GeometryError, match="NaN"):
        resect(np.where(np.eye(6, 3) > 0, np.nan, X), xy, C)


def test_three_points_ambiguous_or_unique():
    for seed in range(30):
        X, xy, R, X0, _ = synthetic(seed, n=3)
        n_cands = len(resection_direct(X, xy, C, X0P, Y0P))
        if n_cands > 1:
            with pytest.raises(GeometryError, match="ambiguous"):
                resect(X, xy, C, X0P, Y0P)
            break
    else:
        pytest.fail("no ambiguous 3-point configuration found")


# --------------------------------------------------------------- refinement --

# Brown model in px: about 4 px distortion at the format corners,
# decentring, affinity and shear
IO = np.array([C, X0P, Y0P, -6e-8, 4e-14, -2e-20, 1.5e-6, -8e-7, 2e-4, -1e-4])


def model():
    return camera_model("brown")


def distorted(seed, n=20, angles=None):
    X, _, R, X0, angles = synthetic(seed, n=n, angles=angles)
    m = model()
    xy = m.project(X, angles, X0, IO)
    return m, X, xy, R, X0, angles


@pytest.mark.parametrize("seed", range(4))
def test_refine_noise_free_distorted_recovers_pose(seed):
    m, X, xy, R, X0, angles = distorted(seed)
    # the distortion is real: the uncorrected image misplaces points by pixels
    assert np.abs(xy - project_ideal(X, R, X0, C, X0P, Y0P)).max() > 1.0
    # approximation: closed form on the uncorrected coordinates
    approx = resect(X, xy, C, X0P, Y0P)
    assert pose_error(approx.R, approx.X0, R, X0) > 1e-5
    res = refine_resection(X, xy, m, IO, approx.angles, approx.X0)
    assert res.converged
    assert np.abs(res.angles - angles).max() < 1e-8
    assert pose_error(res.R, res.X0, R, X0) < 1e-8
    assert np.abs(res.residuals).max() < 1e-8
    assert res.iterations <= 10
    # with the distortion removed first, the closed form is exact
    ideal = m.correct(xy, IO)
    exact = resect(X, ideal, C)
    assert pose_error(exact.R, exact.X0, R, X0) < 1e-8


def test_refine_with_noise_within_own_covariance():
    sigma = 0.3
    m, X, xy, R, X0, angles = distorted(12, n=30)
    rng = np.random.default_rng(7)
    obs = xy + rng.normal(scale=sigma, size=xy.shape)
    approx = resect(X, m.correct(obs, IO), C)
    res = refine_resection(X, obs, m, IO, approx.angles, approx.X0, sigma=sigma)
    assert res.converged
    assert 0.7 < res.sigma0 < 1.3                         # 54 degrees of freedom
    err = np.r_[res.angles - angles, res.X0 - X0]
    assert np.all(np.abs(err) < 4 * res.std), err / res.std
    assert res.covariance.shape == (6, 6)
    assert np.allclose(res.covariance, res.covariance.T)
    # unweighted: same pose, sigma0 in pixels
    res1 = refine_resection(X, obs, m, IO, approx.angles, approx.X0)
    assert np.allclose(res1.X0, res.X0, atol=1e-9)
    assert abs(res1.sigma0 - sigma * res.sigma0) < 1e-9


def test_refine_through_gimbal_lock():
    # phi = 90 deg: omega and kappa are not separable, the incremental
    # rotation update still converges
    m, X, xy, R, X0, _ = distorted(5, angles=[0.3, np.pi / 2, -0.4])
    start = opk_to_matrix([0.35, np.pi / 2 - 0.05, -0.3])
    res = refine_resection(X, xy, m, IO, matrix_to_opk(start), X0 + 0.1)
    assert res.converged
    assert pose_error(res.R, res.X0, R, X0) < 1e-8


def test_refine_chirality_and_degenerate():
    m, X, xy, R, X0, angles = distorted(2, n=8)
    flipped = matrix_to_opk(np.diag([-1.0, 1.0, -1.0]) @ R)   # looks the other way
    with pytest.raises(GeometryError, match="behind the camera"):
        refine_resection(X, xy, m, IO, flipped, X0)
    with pytest.raises(GeometryError, match="at least 3 points"):
        refine_resection(X[:2], xy[:2], m, IO, angles, X0)
    with pytest.raises(GeometryError, match="sigma"):
        refine_resection(X, xy, m, IO, angles, X0, sigma=np.ones(3))
