"""Image line fit (ski-jump paper, appendix C.2 step A, eq. (C11))."""

import numpy as np
import pytest

from photogram.errors import GeometryError, InputError
from photogram.lines import (
    ViewCamera, fit_image_line, fit_view_line, line_angle, line_distance, normalize_line)
from photogram.simulation.designs import true_cameras

ANGLES = np.radians([0.0, 1e-7, 17.0, 45.0, 60.0, 89.9999, 90.0, 123.0, 180.0, 271.0])


def _points(theta, n=15, centre=(320.0, 240.0), length=70.0):
    t = np.array([np.cos(theta), np.sin(theta)])
    s = np.linspace(-length / 2, length / 2, n)
    return np.asarray(centre) + s[:, None] * t, t


def _tls(xy):
    """Orthogonal regression in closed form (principal axis)."""
    c = xy.mean(0)
    _, v = np.linalg.eigh((xy - c).T @ (xy - c))
    n = v[:, 0]
    return n, n @ c


@pytest.mark.parametrize("theta", ANGLES)
def test_noise_free_fit_is_exact_in_every_direction(theta):
    xy, t = _points(theta)
    line = fit_image_line(xy, 0.33)
    assert np.abs(line.residuals).max() < 1e-10
    assert abs(abs(line.direction @ t) - 1) < 1e-12
    assert line.direction @ (xy[-1] - xy[0]) > 0          # oriented first -> last point
    assert np.abs(line.distance(xy)).max() < 1e-10
    l = line.homogeneous
    assert np.abs(np.column_stack([xy, np.ones(len(xy))]) @ l).max() < 1e-10
    assert line.length == pytest.approx(70.0, abs=1e-9)
    np.testing.assert_allclose(line.end_points, xy[[0, -1]], atol=1e-9)
    # the paper's well-conditioned form: |a| <= 1 in the form used
    a = line.slope_intercept(transposed=line.transposed)[0]
    assert abs(a) <= 1 + 1e-9


@pytest.mark.parametrize("theta", ANGLES)
def test_iteration_converges_to_orthogonal_regression(theta):
    rng = np.random.default_rng(7)
    xy, _ = _points(theta)
    xy = xy + rng.normal(0, 0.5, xy.shape)
    line = fit_image_line(xy, 0.5)
    n, d = _tls(xy)
    s = np.sign(n @ line.normal)
    np.testing.assert_allclose(line.normal, s * n, atol=1e-12)
    assert line.d == pytest.approx(s * d, abs=1e-9)
    assert line.iterations < 10


def test_slope_intercept_form_and_covariance():
    rng = np.random.default_rng(1)
    xy, _ = _points(np.radians(20.0))
    xy = xy + rng.normal(0, 0.3, xy.shape)
    line = fit_image_line(xy, 0.3)
    a, b, cov = line.slope_intercept()
    assert np.allclose(xy[:, 1] - (a * xy[:, 0] + b), line.residuals * np.hypot(a, 1), atol=1e-9)
    # covariance of (a, b) = J cov(theta, d) J^T with a numerical Jacobian
    th, d = line.theta, line.d
    h = 1e-7

    def ab(th, d):
        n = np.array([np.cos(th), np.sin(th)])
        return np.array([-n[0] / n[1], d / n[1]])
    J = np.column_stack([(ab(th + h, d) - ab(th - h, d)) / (2 * h),
                         (ab(th, d + h) - ab(th, d - h)) / (2 * h)])
    np.testing.assert_allclose(cov, J @ line.covariance @ J.T, rtol=1e-6)
    with pytest.raises(GeometryError, match="slope form"):
        fit_image_line(_points(np.pi / 2)[0]).slope_intercept()
    a2, b2, _ = fit_image_line(_points(np.pi / 2)[0]).slope_intercept(transposed=True)
    assert abs(a2) < 1e-12 and b2 == pytest.approx(320.0)


def test_covariance_agrees_with_scatter_of_fits():
    """(theta, d) of a line far from the origin (correlated): the propagated
    covariance explains the scatter (chi-square mean 2), and sigma0 ~ 1."""
    rng = np.random.default_rng(11)
    xy0, _ = _points(np.radians(35.0), n=12)
    ref = fit_image_line(xy0, 0.33)
    chi2, s0 = [], []
    for _ in range(400):
        line = fit_image_line(xy0 + rng.normal(0, 0.33, xy0.shape), 0.33)
        e = np.array([line.theta - ref.theta, line.d - ref.d])
        chi2.append(e @ np.linalg.solve(line.covariance, e))
        s0.append(line.sigma0 ** 2)
        # the homogeneous covariance is the same information
        assert np.linalg.matrix_rank(line.cov_homogeneous, tol=1e-12) == 2
    assert 2 - 0.35 < np.mean(chi2) < 2 + 0.35
    assert 1 - 0.15 < np.mean(s0) < 1 + 0.15
    assert abs(ref.covariance[0, 1]) > 0.5 * np.sqrt(ref.covariance[0, 0] * ref.covariance[1, 1])


def test_weights_per_point():
    xy, _ = _points(0.3)
    xy[3] += [0.0, 5.0]                           # an outlier with a large sigma
    sig = np.full(len(xy), 0.3)
    sig[3] = 1e6
    line = fit_image_line(xy, sig)
    assert np.abs(np.delete(line.residuals, 3)).max() < 1e-9


def test_homogeneous_helpers():
    l = normalize_line([3.0, 4.0, -10.0])
    assert np.allclose(l, [0.6, 0.8, -2.0])
    assert line_distance([3.0, 4.0, -10.0], [[2.0, 1.0]])[0] == pytest.approx(0.0)
    assert line_angle([1, 0, 0], [1, 1, 5]) == pytest.approx(np.pi / 4)
    assert line_angle([1, 0, 0], [-1, 0, 5]) == pytest.approx(0.0)
    with pytest.raises(GeometryError):
        normalize_line([0.0, 0.0, 1.0])


def test_degenerate_and_bad_input():
    with pytest.raises(GeometryError, match="1 point"):
        fit_image_line([[1.0, 2.0]], label="L1", station="S1")
    with pytest.raises(GeometryError, match="coincide"):
        fit_image_line([[1.0, 2.0]] * 4)
    rng = np.random.default_rng(0)
    with pytest.raises(GeometryError, match="do not lie along a line"):
        fit_image_line(rng.normal(0, 1, (30, 2)))
    with pytest.raises(InputError):
        fit_image_line(np.zeros((4, 3)))
    with pytest.raises(InputError):
        fit_image_line(_points(0.1)[0], sigma=0.0)
    with pytest.raises(InputError):
        fit_image_line([[0.0, np.nan], [1.0, 1.0]])


def test_view_line_corrects_distortion_first():
    """Points of a straight object line are curved in the measured image;
    after the correction they are exactly straight (ideal frame)."""
    io = true_cameras()["K1"].copy()
    io[3] = -2e-7                                  # strong radial correction
    R = np.diag([1.0, -1.0, -1.0])                 # looking down along -Z... any pose
    cam = ViewCamera(R, [0.0, 0.0, 10.0], io, "brown", "S9")
    X = np.column_stack([np.linspace(-1.5, 1.5, 20), np.full(20, 1.2), np.zeros(20)])
    xy = cam.project(X)
    raw = fit_image_line(xy)
    assert np.abs(raw.residuals).max() > 0.5      # curved in measured coordinates
    line = fit_view_line(xy, cam, 0.33, label="L1")
    assert line.frame == "ideal" and line.station == "S9" and line.label == "L1"
    assert np.abs(line.residuals).max() < 1e-9
    np.testing.assert_allclose(cam.ideal(cam.measured(line.end_points)), line.end_points,
                               atol=1e-9)


def test_view_line_opencv_model_jacobian():
    io = np.array([1400.0, 1410.0, 320.0, 240.0, -0.2, 0.05, 1e-3, -2e-3, 0.0])
    cam = ViewCamera(np.eye(3), np.zeros(3), io, "opencv", "C")
    xy = np.array([[100.0, 50.0], [400.0, 300.0], [600.0, 420.0]])
    xi, J = cam.ideal(xy, jacobians=True)
    h = 1e-5
    num = np.stack([(cam.ideal(xy + h * e) - cam.ideal(xy - h * e)) / (2 * h)
                    for e in np.eye(2)], -1)
    np.testing.assert_allclose(J, num, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(cam.measured(xi), xy, atol=1e-8)
