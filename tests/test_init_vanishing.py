"""Vanishing points and the principal distance from them (eqs. (B1)-(B2))."""

import numpy as np
import pytest

from photogram.errors import GeometryError
from photogram.geometry.rotations import opk_to_matrix
from photogram.init.vanishing import (calibrate_from_vanishing_points, lines_from_points,
                                      principal_distance_from_vanishing_points,
                                      vanishing_point)

C, X0P, Y0P = 1420.0, 323.5, 238.2


def camera(seed):
    """A camera whose optical axis is at roughly 55 deg to each of three
    orthogonal object directions (three-point perspective)."""
    rng = np.random.default_rng(seed)
    axes = opk_to_matrix(rng.uniform(-np.pi, np.pi, 3))       # rows: object directions
    view = axes.sum(axis=0) / np.sqrt(3) + rng.normal(scale=0.05, size=3)
    view /= np.linalg.norm(view)
    z = -view                                                 # camera looks along -z
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    X0 = rng.normal(size=3)
    return R, X0, axes, rng


def project(X, R, X0):
    Xc = (X - X0) @ R.T
    return np.stack([X0P - C * Xc[:, 0] / Xc[:, 2], Y0P + C * Xc[:, 1] / Xc[:, 2]], -1)


def true_vp(direction, R):
    d = R @ direction
    return np.array([X0P - C * d[0] / d[2], Y0P + C * d[1] / d[2]])


def segments(direction, R, X0, rng, m=8, length=0.8):
    """m image segments of object lines along `direction`, 2-5 m in front."""
    depth = rng.uniform(2, 5, m)
    lateral = rng.uniform(-0.3, 0.3, (m, 2)) * depth[:, None]
    Xc = np.c_[lateral, -depth]
    A = X0 + Xc @ R
    B = A + length * direction
    return np.stack([project(A, R, X0), project(B, R, X0)], axis=1)


@pytest.mark.parametrize("seed", range(6))
def test_noise_free_vanishing_points_and_principal_distance(seed):
    R, X0, axes, rng = camera(seed)
    vps = []
    for k in range(3):
        segs = segments(axes[k], R, X0, rng)
        v = vanishing_point(segs)
        vt = true_vp(axes[k], R)
        assert np.abs(v - vt).max() < 1e-8 * np.abs(vt).max()
        # two lines: exact intersection; homogeneous input: same point
        assert np.allclose(vanishing_point(segs[:2]), vt, rtol=1e-8, atol=0)
        assert np.allclose(vanishing_point(lines_from_points(segs)), vt, rtol=1e-8, atol=0)
        vps.append(v)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        c = principal_distance_from_vanishing_points(vps[i], vps[j], X0P, Y0P)
        assert abs(c - C) < 1e-8 * C
    cal = calibrate_from_vanishing_points(*vps)
    assert abs(cal["c"] - C) < 1e-8 * C
    assert abs(cal["x0"] - X0P) < 1e-8 * C and abs(cal["y0"] - Y0P) < 1e-8 * C
    # broadcasting over several pairs
    cs = principal_distance_from_vanishing_points(np.stack(vps[:2]), np.stack(vps[1:]), X0P, Y0P)
    assert cs.shape == (2,) and np.allclose(cs, C, rtol=1e-8)


def test_noisy_vanishing_points_within_own_accuracy():
    sigma = 0.3
    R, X0, axes, rng = camera(3)
    noise = np.random.default_rng(11)
    vps, covs = [], []
    for k in range(2):
        segs = segments(axes[k], R, X0, rng, m=12, length=1.5)
        segs = segs + noise.normal(scale=sigma, size=segs.shape)
        v, cov = vanishing_point(segs, return_covariance=True)
        vt = true_vp(axes[k], R)
        assert np.all(np.abs(v - vt) < 4 * np.sqrt(np.diag(cov)))
        # a-priori sigma gives a covariance of the same size
        _, cov_p = vanishing_point(segs, return_covariance=True, sigma=sigma)
        assert 0.4 < np.sqrt(np.trace(cov) / np.trace(cov_p)) < 1.6
        vps.append(v)
        covs.append(cov)
    c = principal_distance_from_vanishing_points(vps[0], vps[1], X0P, Y0P)
    p = np.array([X0P, Y0P])
    g1, g2 = -(vps[1] - p) / (2 * c), -(vps[0] - p) / (2 * c)    # dc/dv1, dc/dv2
    sc = np.sqrt(g1 @ covs[0] @ g1 + g2 @ covs[1] @ g2)
    assert abs(c - C) < 4 * sc
    assert sc < 0.05 * C


def test_parallel_and_coincident_lines_raise():
    par = np.array([[[0.0, 0.0], [100.0, 50.0]], [[0.0, 10.0], [100.0, 60.0]],
                    [[5.0, -30.0], [205.0, 70.0]]])
    with pytest.raises(GeometryError, match="parallel in the image"):
        vanishing_point(par[:2])
    with pytest.raises(GeometryError, match="parallel in the image"):
        vanishing_point(par)
    with pytest.raises(GeometryError, match="parallel in the image"):
        vanishing_point(lines_from_points(par))
    with pytest.raises(GeometryError, match="coincide"):
        vanishing_point(np.array([par[0], par[0] * 2]))
    with pytest.raises(GeometryError, match="coincide"):
        vanishing_point(np.array([par[0], par[0] * 2, par[0] * 3]))
    with pytest.raises(GeometryError, match="at least 2 lines"):
        vanishing_point(par[:1])
    with pytest.raises(GeometryError, match="two equal points"):
        vanishing_point(np.array([par[0], [[1.0, 1.0], [1.0, 1.0]]]))
    with pytest.raises(GeometryError, match="shape"):
        vanishing_point(np.zeros((3, 4)))


def test_non_orthogonal_directions_raise():
    R, X0, axes, rng = camera(1)
    v1 = true_vp(axes[0], R)
    # same direction twice: (v - p).(v - p) > 0, no real c
    with pytest.raises(GeometryError, match="cannot be orthogonal"):
        principal_distance_from_vanishing_points(v1, v1, X0P, Y0P)
    # vanishing points on the same side of the principal point
    with pytest.raises(GeometryError, match="not negative"):
        principal_distance_from_vanishing_points([1000.0, 300.0], [900.0, 100.0], X0P, Y0P)
    with pytest.raises(GeometryError, match="collinear"):
        calibrate_from_vanishing_points([0.0, 0.0], [100.0, 100.0], [300.0, 300.0])
