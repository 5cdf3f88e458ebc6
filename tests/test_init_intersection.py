"""Spatial intersection (ski-jump paper, appendix C.1): exactness on
noise-free data, honest precision estimates with noise, degenerate rays."""

import numpy as np
import pytest

from photogram.errors import GeometryError
from photogram.init.intersection import (intersect, intersect_points, max_intersection_angles,
                                         project_ideal, ray_directions)
from photogram.simulation.network import look_at as simulated_look_at

C = 1420.0                      # px, 640 x 480 images
TARGET = np.array([0.25, 0.25, 0.15])


def look_at(X0, target=TARGET, up=(0.0, 0.0, 1.0)):
    """World-to-camera rotation of one camera at X0 looking at target."""
    return simulated_look_at(X0, target, up)[0]


def three_cameras():
    X0 = np.array([[-1.5, -2.5, 1.5], [0.3, -3.2, 2.0], [2.2, -1.8, 1.2]])
    return np.array([look_at(x) for x in X0]), X0


def ring(n=6, radius=3.0, height=1.0):
    az = np.linspace(0, 2 * np.pi, n, endpoint=False)
    X0 = TARGET + np.c_[radius * np.cos(az), radius * np.sin(az), np.full(n, height)]
    return np.array([look_at(x) for x in X0]), X0


def frame_points(rng, n):
    return rng.uniform([0, 0, 0], [0.5, 0.5, 0.3], (n, 3))


def all_rays(P, R, X0, c=C):
    """Every point seen by every camera: (point index, station index)."""
    n, k = len(P), len(R)
    pi = np.repeat(np.arange(n), k)
    si = np.tile(np.arange(k), n)
    xy = project_ideal(P[pi], R[si], X0[si], c)
    return pi, si, xy


@pytest.mark.parametrize("setup", [three_cameras, ring])
def test_noise_free_truth(setup):
    rng = np.random.default_rng(3)
    R, X0 = setup()
    P = frame_points(rng, 40)
    pi, si, xy = all_rays(P, R, X0)
    assert np.abs(xy).max() < 240                     # inside a 640 x 480 image
    res = intersect_points(pi, xy, R[si], X0[si], np.full(len(pi), C))
    assert np.array_equal(res.point_index, np.arange(40))
    assert np.abs(res.X - P).max() < 1e-8 * np.abs(X0).max()
    assert res.valid.all() and res.converged.all()
    assert np.nanmax(np.abs(res.residuals)) < 1e-8
    assert np.all(res.sigma0 < 1e-8)
    assert np.all(res.behind == 0)
    assert np.all(res.n_rays == len(R))
    assert np.all(np.degrees(res.max_angle) > 20)


def test_single_point_function_matches_vectorized():
    rng = np.random.default_rng(4)
    R, X0 = ring()
    P = frame_points(rng, 5)
    pi, si, xy = all_rays(P, R, X0)
    xy = xy + rng.normal(0, 0.3, xy.shape)
    many = intersect_points(pi, xy, R[si], X0[si], np.full(len(pi), C), sigma_image=0.3)
    for k in range(5):
        rows = pi == k
        one = intersect(xy[rows], R[si[rows]], X0[si[rows]], np.full(rows.sum(), C),
                        sigma_image=0.3)
        assert np.allclose(one.X, many.X[k], rtol=0, atol=1e-12)
        assert np.allclose(one.covariance, many.covariance[k], rtol=1e-10)
        assert one.residuals.shape == (6, 2)
        assert one.max_angle == pytest.approx(many.max_angle[k])


def test_principal_point_and_unsorted_ids():
    rng = np.random.default_rng(5)
    R, X0 = three_cameras()
    P = frame_points(rng, 10)
    pi, si, xy = all_rays(P, R, X0)
    pp = np.array([321.5, 238.0])
    perm = rng.permutation(len(pi))
    ids = 100 + 7 * pi                                  # arbitrary, non-contiguous ids
    res = intersect_points(ids[perm], xy[perm] + pp, R[si[perm]], X0[si[perm]],
                           np.full(len(pi), C), x0y0=pp)
    assert np.array_equal(res.point_index, 100 + 7 * np.arange(10))
    assert np.abs(res.X - P).max() < 1e-9
    assert res.residuals.shape == (len(pi), 2)


def test_varying_number_of_rays():
    """Points with 2 to 6 rays in one call equal the single-point results."""
    rng = np.random.default_rng(6)
    R, X0 = ring()
    P = frame_points(rng, 30)
    pi, si, xy = all_rays(P, R, X0)
    keep = si < (2 + pi % 5)                           # point k seen by 2 + k % 5 cameras
    pi, si, xy = pi[keep], si[keep], xy[keep] + rng.normal(0, 0.3, (keep.sum(), 2))
    res = intersect_points(pi, xy, R[si], X0[si], np.full(len(pi), C))
    assert np.array_equal(res.n_rays, 2 + np.arange(30) % 5)
    for k in (0, 1, 4, 7):
        rows = pi == k
        one = intersect(xy[rows], R[si[rows]], X0[si[rows]], np.full(rows.sum(), C))
        assert np.allclose(one.X, res.X[k], atol=1e-12)


@pytest.mark.parametrize("setup", [three_cameras, ring])
def test_noise_within_claimed_accuracy(setup):
    """With 0.3 px noise the errors agree with the claimed sigmas."""
    rng = np.random.default_rng(7)
    R, X0 = setup()
    P = frame_points(rng, 300)
    pi, si, xy = all_rays(P, R, X0)
    xy = xy + rng.normal(0, 0.3, xy.shape)
    res = intersect_points(pi, xy, R[si], X0[si], np.full(len(pi), C), sigma_image=0.3)
    z = ((res.X - P) / res.sigma_xyz).ravel()
    assert np.mean(np.abs(z) < 4) >= 0.995
    assert 0.85 < np.sqrt(np.mean(z ** 2)) < 1.15
    # the a-posteriori sigma0 estimates the image noise
    assert np.mean(res.sigma0 ** 2) == pytest.approx(0.09, rel=0.15)
    # a-posteriori scaling: same matrix, scaled by each point's own sigma0
    post = intersect_points(pi, xy, R[si], X0[si], np.full(len(pi), C))
    ratio = post.covariance[:, 0, 0] / res.covariance[:, 0, 0]
    assert np.allclose(ratio, (post.sigma0 / 0.3) ** 2)
    # residuals: observed - computed
    xy_hat = project_ideal(res.X[pi], R[si], X0[si], C)
    assert np.allclose(res.residuals, xy - xy_hat, atol=1e-9)


def test_max_intersection_angles_brute_force():
    rng = np.random.default_rng(8)
    d = rng.normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    g = rng.integers(0, 9, 40)
    got = max_intersection_angles(g, d, 10)
    for k in range(10):
        dk = d[g == k]
        want = max((np.arccos(np.clip(a @ b, -1, 1)) for i, a in enumerate(dk)
                    for b in dk[i + 1:]), default=0.0)
        assert got[k] == pytest.approx(want, abs=1e-12)


def test_ray_directions_point_at_the_object():
    rng = np.random.default_rng(9)
    R, X0 = three_cameras()
    P = frame_points(rng, 5)
    pi, si, xy = all_rays(P, R, X0)
    d = ray_directions(xy, R[si], np.full(len(pi), C))
    u = P[pi] - X0[si]
    assert np.allclose(d, u / np.linalg.norm(u, axis=1, keepdims=True), atol=1e-12)


# ------------------------------------------------------------- degenerate --

def test_single_ray_raises():
    R, X0 = three_cameras()
    xy = project_ideal(TARGET, R[0], X0[0], C)[None]
    with pytest.raises(GeometryError, match="1 ray, needs at least 2"):
        intersect(xy, R[:1], X0[:1], [C])
    with pytest.raises(GeometryError, match=r"point P7: only 1 ray"):
        intersect_points([0], xy, R[:1], X0[:1], [C], point_ids=["P7"])


def test_parallel_rays_raise_and_name_the_point():
    R = np.stack([np.eye(3)] * 2)
    X0 = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])        # 1 cm apart
    P = np.array([0.3, 0.2, -10.0])                            # 10 m away: 0.06 deg
    xy = project_ideal(np.stack([P, P]), R, X0, C)
    with pytest.raises(GeometryError, match=r"point 17: rays nearly parallel") as e:
        intersect_points([17, 17], xy, R, X0, [C, C])
    assert "min_angle_deg" in str(e.value)
    with pytest.raises(GeometryError, match="intersection: rays nearly parallel"):
        intersect(xy, R, X0, [C, C])
    # exactly parallel rays
    xy0 = np.zeros((2, 2))
    with pytest.raises(GeometryError, match="parallel"):
        intersect(xy0, R, X0, [C, C], point_id="A")
    # the threshold is a parameter
    ok = intersect(xy, R, X0, [C, C], min_angle_deg=0.01)
    assert np.allclose(ok.X, P, atol=1e-9)


def test_non_strict_marks_bad_points_and_keeps_good_ones():
    rng = np.random.default_rng(10)
    R, X0 = three_cameras()
    P = frame_points(rng, 4)
    pi, si, xy = all_rays(P, R, X0)
    keep = ~((pi == 2) & (si > 0))                       # point 2 keeps one ray
    res = intersect_points(pi[keep], xy[keep], R[si[keep]], X0[si[keep]],
                           np.full(keep.sum(), C), strict=False, point_ids=list("abcd"))
    assert list(res.valid) == [True, True, False, True]
    assert res.reason[2] == "point c: only 1 ray, needs 2"
    assert np.isnan(res.X[2]).all()
    assert np.abs(res.X[[0, 1, 3]] - P[[0, 1, 3]]).max() < 1e-9
    assert np.isnan(res.residuals[pi[keep] == 2]).all()


def test_point_behind_cameras_is_counted():
    R, X0 = three_cameras()
    Q = np.array([0.3, -8.0, 1.6])                  # behind all three cameras
    xy = project_ideal(np.stack([Q] * 3), R, X0, C)   # the images of its mirror rays
    res = intersect_points([0, 0, 0], xy, R, X0, [C] * 3, strict=False)
    assert np.allclose(res.X[0], Q, atol=1e-9)
    assert res.behind[0] == 3


def test_malformed_input():
    R, X0 = three_cameras()
    with pytest.raises(GeometryError, match=r"\(n, 2\)"):
        intersect_points([0, 0, 0], np.zeros((3, 3)), R, X0, [C] * 3)
    with pytest.raises(GeometryError, match="non-finite"):
        intersect_points([0, 0, 0], np.array([[0, 0], [np.nan, 0], [1, 1.0]]), R, X0, [C] * 3)
    with pytest.raises(GeometryError, match="one rotation"):
        intersect_points([0, 0, 0], np.zeros((3, 2)), R[:2], X0, [C] * 3)
