"""The ``opencv_full`` model (OpenCV's rational, thin-prism and tilted-sensor
distortion): equal to cv2.projectPoints, analytic Jacobians at tau = 0, the
inverse, and the ``opencv`` model as its special case."""

import cv2
import numpy as np
import pytest

from photogram.geometry import (camera_model, matrix_to_rodrigues, opencv_pose,
                                opk_to_matrix)
from photogram.geometry.opencv_full_model import tilt_matrix

P = np.array([1420.0, 1425.0, 322.0, 238.0, -0.25, 0.3, 1.0e-3, -8.0e-4, -0.5,
              0.1, -0.05, 0.2, 2.0e-3, -1.0e-3, 1.5e-3, 5.0e-4, 0.02, -0.015])


def scene(n=60, seed=3, spread=0.22):
    rng = np.random.default_rng(seed)
    angles = np.array([0.1, -0.2, 0.3])
    X0 = np.array([1.0, 2.0, 3.0])
    depth = rng.uniform(4, 9, n)
    Xc = np.stack([rng.uniform(-spread, spread, n) * depth,
                   rng.uniform(-0.75 * spread, 0.75 * spread, n) * depth, -depth], -1)
    X = Xc @ opk_to_matrix(angles) + X0
    return X, angles, X0


def cv2_pixels(X, angles, X0, p, n_coef):
    R_cv, t_cv = opencv_pose(opk_to_matrix(angles), X0)
    K = np.array([[p[0], 0, p[2]], [0, p[1], p[3]], [0, 0, 1.0]])
    xy, _ = cv2.projectPoints(X.reshape(-1, 1, 3), matrix_to_rodrigues(R_cv), t_cv, K,
                              p[4:4 + n_coef])
    return xy.reshape(-1, 2)


@pytest.mark.parametrize("n_coef", [4, 5, 8, 12, 14])
def test_equals_cv2_project_points(n_coef):
    """With 4, 5, 8, 12 and 14 coefficients (the rest zero) the model is
    cv2.projectPoints to 1e-9 px (measured: ~5e-13 px)."""
    X, angles, X0 = scene()
    p = P.copy()
    p[4 + n_coef:] = 0.0
    xy = camera_model("opencv_full").project(X, angles, X0, p)
    ref = cv2_pixels(X, angles, X0, p, n_coef)
    assert np.abs(xy - ref).max() < 1e-9


def test_opencv_is_the_special_case():
    """k4..tauY = 0: the ``opencv`` model's pixels, bit for bit up to rounding."""
    X, angles, X0 = scene()
    p = P.copy()
    p[9:] = 0.0
    a = camera_model("opencv_full").project(X, angles, X0, p)
    b = camera_model("opencv").project(X, angles, X0, p[:9])
    assert np.abs(a - b).max() < 1e-10


def test_tilt_matrix_is_identity_at_zero_and_its_derivative():
    H, dHx, dHy = tilt_matrix(np.zeros(2), np.zeros(2))
    assert np.array_equal(H, np.broadcast_to(np.eye(3), (2, 3, 3)))
    h = 1e-6
    for k, dH in enumerate((dHx, dHy)):
        tau = np.array([[0.03, -0.02]])
        plus, minus = tau.copy(), tau.copy()
        plus[0, k] += h
        minus[0, k] -= h
        fd = (tilt_matrix(*plus.T)[0] - tilt_matrix(*minus.T)[0]) / (2 * h)
        ana = tilt_matrix(*tau.T)[1 + k]
        assert np.abs(fd - ana).max() < 1e-8
        assert np.abs(dH).max() > 0.5          # not zero at tau = 0


@pytest.mark.parametrize("zero", ["tilt", "prism-and-tilt", "none"])
def test_io_jacobian_at_zero_terms(zero):
    """d xy / d io against central differences (1e-6 relative) also where
    the thin-prism and tilt terms are 0 (their derivatives are not)."""
    m = camera_model("opencv_full")
    X, angles, X0 = scene(n=40)
    p = P.copy()
    if zero != "none":
        p[16:] = 0.0
    if zero == "prism-and-tilt":
        p[12:] = 0.0
    _, jac = m.project(X, angles, X0, p, jacobians=True)
    typical = np.r_[[1420.0] * 4, [1.0] * 14]
    for col in range(m.n_params):
        h = 1e-5 * typical[col]
        a, b = p.copy(), p.copy()
        a[col] += h
        b[col] -= h
        fd = (m.project(X, angles, X0, a) - m.project(X, angles, X0, b)) / (2 * h)
        scale = np.abs(fd).max()
        err = np.abs(jac["io"][:, :, col] - fd) / np.maximum(np.abs(fd), scale)
        assert err.max() < 1e-6, (m.parameter_names[col], err.max())


def test_image_to_ray_inverts_and_matches_cv2_undistort():
    m = camera_model("opencv_full")
    rng = np.random.default_rng(4)
    t = rng.uniform([-0.2, -0.15], [0.2, 0.15], (200, 2))
    xy = m.ray_to_image(t, P)
    back = m.image_to_ray(xy, P)
    assert np.abs(back - t).max() < 1e-12
    K = np.array([[P[0], 0, P[2]], [0, P[1], P[3]], [0, 0, 1.0]])
    ref = cv2.undistortPoints(xy.reshape(-1, 1, 2), K, P[4:],
                              criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
                                        200, 1e-15)).reshape(-1, 2)
    assert np.abs(ref - t).max() < 1e-6        # OpenCV's fixed-point iteration


def test_registered_with_the_schema():
    from photogram.project.camera_schema import parameter_dims, parameter_names
    m = camera_model("opencv_full")
    assert parameter_names("opencv_full") == m.parameter_names
    assert parameter_dims("opencv_full") == m.parameter_dims
    assert m.parameter_names[9:] == ("k4", "k5", "k6", "s1", "s2", "s3", "s4", "tauX", "tauY")


def test_refit_between_opencv_and_opencv_full_is_exact():
    """An ``opencv`` camera refitted as ``opencv_full`` (k1..k6, p1, p2 free,
    started at 0) and an ``opencv_full`` camera with k4..tauY = 0 refitted
    as ``opencv`` project a finer grid than the fit's to 1e-9 px (measured:
    ~1e-13 px)."""
    from photogram.geometry import fit_distortion, format_grid
    p = P[:9]
    size = (640, 480)
    grid = format_grid(size, (31, 23))
    rays = camera_model("opencv").image_to_ray(grid, p)
    free = ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]
    q, rms = fit_distortion("opencv", p, "opencv_full", size,
                            target_params=np.r_[p[:4], np.zeros(14)], free=free)
    assert rms < 1e-9
    assert np.abs(camera_model("opencv_full").ray_to_image(rays, q) - grid).max() < 1e-9
    back, rms = fit_distortion("opencv_full", np.r_[p, np.zeros(9)], "opencv", size,
                               target_params=np.r_[p[:4], np.zeros(5)])
    assert rms < 1e-9
    assert np.abs(camera_model("opencv").ray_to_image(rays, back) - grid).max() < 1e-9
