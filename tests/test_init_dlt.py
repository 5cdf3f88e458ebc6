"""Direct linear transformation and projection-matrix decomposition."""

import numpy as np
import pytest

from photogram.errors import GeometryError
from photogram.geometry.rotations import opk_to_matrix
from photogram.init.dlt import (FLIP, compose_projection, decompose_projection, dlt,
                                dlt_project, dlt_residuals)

C, X0P, Y0P, W, H = 1420.0, 323.5, 238.2, 640, 480


def synthetic(seed, n=12, offset=(0.0, 0.0, 0.0)):
    """Camera (c = 1420 px, 640x480) and n points 2-5 m in front of it."""
    rng = np.random.default_rng(seed)
    angles = rng.uniform(-np.pi, np.pi, 3) * np.array([1.0, 0.45, 1.0])
    R = opk_to_matrix(angles)
    X0 = rng.normal(size=3) * 3 + np.asarray(offset)
    xy = np.c_[rng.uniform(0, W, n), rng.uniform(0, H, n)]
    d = rng.uniform(2, 5, n)
    Xc = np.c_[(xy[:, 0] - X0P) * d / C, -(xy[:, 1] - Y0P) * d / C, -d]
    X = X0 + Xc @ R                      # X = X0 + R^T Xc
    return X, xy, R, X0, angles


def rel(a, b):
    return np.abs(np.asarray(a) - np.asarray(b)).max() / max(1.0, np.abs(b).max())


@pytest.mark.parametrize("seed", range(5))
def test_noise_free_recovers_projection_and_camera(seed):
    X, xy, R, X0, angles = synthetic(seed)
    P = dlt(X, xy)
    Ptrue = compose_projection(C, X0P, Y0P, R, X0)
    Ptrue = Ptrue / np.linalg.norm(Ptrue[2, :3])
    assert rel(P, Ptrue) < 1e-8
    assert np.abs(dlt_residuals(P, X, xy)).max() < 1e-8 * C
    d = decompose_projection(P)
    for key, true in (("c", C), ("cx", C), ("cy", C), ("x0", X0P), ("y0", Y0P)):
        assert abs(d[key] - true) < 1e-8 * C, key
    assert abs(d["skew"]) < 1e-8 * C
    assert abs(d["aspect"] - 1) < 1e-8
    assert np.abs(d["R"] - R).max() < 1e-8
    assert rel(d["X0"], X0) < 1e-8
    assert np.abs(d["angles"] - angles).max() < 1e-8
    assert np.allclose(opk_to_matrix(d["angles"]), R, atol=1e-8)


def test_hartley_normalization_handles_large_coordinates():
    # map-like coordinates (km offsets) must not ruin the conditioning
    X, xy, R, X0, _ = synthetic(7, n=10, offset=(5e4, 2e5, 300.0))
    d = decompose_projection(dlt(X, xy))
    assert abs(d["c"] - C) < 1e-6 * C
    assert np.abs(d["R"] - R).max() < 1e-8
    assert np.abs(d["X0"] - X0).max() < 1e-6


def test_decomposition_sign_and_scale_invariant():
    X, xy, R, X0, _ = synthetic(3)
    P = dlt(X, xy)
    for factor in (-1.0, 3.7e-4, -250.0):
        d = decompose_projection(factor * P)
        assert abs(d["c"] - C) < 1e-8 * C
        assert np.abs(d["R"] - R).max() < 1e-8
        assert rel(d["X0"], X0) < 1e-8
    # points in front of the camera: Xc_z < 0 and the depth (P X)_3 > 0
    Xc = (X - X0) @ R.T
    assert np.all(Xc[:, 2] < 0)
    assert np.all(X @ P[2, :3] + P[2, 3] > 0)


def test_matches_opencv_decomposition():
    cv2 = pytest.importorskip("cv2")
    X, xy, R, X0, _ = synthetic(11, n=15)
    P = dlt(X, xy)
    K, Rcv, Ch = cv2.decomposeProjectionMatrix(P)[:3]
    d = decompose_projection(P)
    # OpenCV's camera frame is ours flipped: y down, looking along +z
    assert np.allclose(K / K[2, 2], d["K"], rtol=0, atol=1e-8 * C)
    assert np.allclose(Rcv, FLIP @ d["R"], atol=1e-9)
    assert np.allclose(Ch[:3, 0] / Ch[3, 0], d["X0"], atol=1e-9)
    assert np.allclose(FLIP @ Rcv, R, atol=1e-8)


def test_noisy_dlt_consistent_with_noise_level():
    sigma = 0.3
    X, xy, R, X0, _ = synthetic(21, n=60)
    rng = np.random.default_rng(5)
    obs = xy + rng.normal(scale=sigma, size=xy.shape)
    P = dlt(X, obs)
    v = dlt_residuals(P, X, obs)
    s0 = np.sqrt((v ** 2).sum() / (2 * len(X) - 11))
    # chi-square with 109 degrees of freedom: s0/sigma = 1 +- 0.07
    assert 0.75 * sigma < s0 < 1.25 * sigma
    # the fit reproduces the true image points about as well as the noise allows
    err = dlt_project(P, X) - xy
    assert np.sqrt((err ** 2).mean()) < sigma
    d = decompose_projection(P)
    assert abs(d["c"] - C) / C < 0.02
    assert np.abs(d["X0"] - X0).max() < 0.05


def test_coplanar_points_raise():
    X, xy, *_ = synthetic(2, n=10)
    Xp = X.copy()
    Xp[:, 2] = 1.5                                   # all in a plane
    with pytest.raises(GeometryError, match="non-coplanar") as exc:
        dlt(Xp, xy)
    assert "lie in a plane" in str(exc.value)
    assert "space resection with known interior orientation" in str(exc.value)
    # near-coplanar: tilted plane plus micrometre jitter
    rng = np.random.default_rng(0)
    uv = rng.uniform(-2, 2, (10, 2))
    Xn = np.c_[uv, 0.3 * uv[:, 0] - 0.2 * uv[:, 1] + rng.normal(scale=1e-6, size=10)]
    with pytest.raises(GeometryError, match="rms off-plane"):
        dlt(Xn, xy)


def test_too_few_points_and_bad_shapes_raise():
    X, xy, *_ = synthetic(4, n=6)
    dlt(X, xy)                                       # 6 points are enough
    with pytest.raises(GeometryError, match="at least 6"):
        dlt(X[:5], xy[:5])
    with pytest.raises(GeometryError, match=r"\(n, 3\)"):
        dlt(X[:, :2], xy)
    Xbad = X.copy()
    Xbad[0, 0] = np.nan
    with pytest.raises(GeometryError, match="NaN"):
        dlt(Xbad, xy)


def test_singular_projection_matrix_raises():
    P = np.zeros((3, 4))
    P[:, 3] = 1.0
    with pytest.raises(GeometryError, match="singular"):
        decompose_projection(P)
