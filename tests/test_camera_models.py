"""Camera models: analytic Jacobians, round trips, OpenCV agreement."""

import functools

import cv2
import numpy as np
import pytest

from photogram.errors import GeometryError, InputError
from photogram.geometry import (CAMERA_MODELS, camera_model, ideal_projection,
                                matrix_to_opk, opencv_pose, opk_to_matrix,
                                photogrammetric_pose, rescale_parameters, small_rotation)

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

RNG = np.random.default_rng(7)
N = 50
SIZE = (640, 480)

# A realistic camera: c = 1420 px on 640 x 480 with noticeable distortion
# (about 10-20 px at the corners).
PARAMS = {
    "brown": np.array([1420.0, 321.5, 238.2, 2.3e-7, -3.0e-13, 6.0e-19,
                       6.0e-6, -4.0e-6, 4.0e-4, -3.0e-4]),
    "opencv": np.array([1420.0, 1425.0, 322.0, 238.0, -0.25, 0.3, 1.0e-3, -8.0e-4, -0.5]),
    # Kannala-Brandt: theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8)
    "opencv_fisheye": np.array([1420.0, 1425.0, 322.0, 238.0, 0.05, -0.3, 0.8, -1.2]),
    # OpenCV's full set: rational k4..k6, thin prism s1..s4, tilt tauX tauY (rad)
    "opencv_full": np.array([1420.0, 1425.0, 322.0, 238.0, -0.25, 0.3, 1.0e-3, -8.0e-4, -0.5,
                             0.1, -0.05, 0.2, 2.0e-3, -1.0e-3, 1.5e-3, 5.0e-4, 0.02, -0.015]),
    # BAL (Snavely): f, k1, k2 of normalised radii; origin at the image centre
    "bal": np.array([1420.0, -0.25, 0.3]),
    # AICON / Australis forward form: balanced radial (r0 = 250 px),
    # decentring, affinity and shear; 1-7 px at the corners
    "aicon": np.array([1420.0, 321.5, 238.2, -1.5e-7, 3.0e-13, -5.0e-19,
                       5.0e-6, -4.0e-6, 3.0e-4, -2.0e-4, 250.0]),
    # DBAT's lens models 4, 5 and -1 (photogram.geometry.dbat_models)
    "brown_affine_after": np.array([1420.0, 321.5, 238.2, 2.3e-7, -3.0e-13, 6.0e-19,
                                    6.0e-6, -4.0e-6, 4.0e-4, -3.0e-4]),
    "brown_aspect_first": np.array([1420.0, 321.5, 238.2, 2.3e-7, -3.0e-13, 6.0e-19,
                                    6.0e-6, -4.0e-6, 4.0e-4, -3.0e-4]),
    "brown_forward": np.array([1420.0, 321.5, 238.2, 2.3e-7, -3.0e-13, 6.0e-19,
                               6.0e-6, -4.0e-6]),
}
# Characteristic magnitudes: a change of 1e-4 of these moves points by a
# few hundredths of a pixel (r ~ 400 px at the corners).
TYPICAL = {
    "brown": np.array([1420, 1420, 1420, 400.0 ** -2, 400.0 ** -4, 400.0 ** -6,
                       1 / 400, 1 / 400, 1, 1]),
    "opencv": np.array([1420, 1420, 1420, 1420, 1, 1, 1, 1, 1]),
    "opencv_fisheye": np.array([1420, 1420, 1420, 1420, 1, 1, 1, 1]),
    "opencv_full": np.array([1420, 1420, 1420, 1420] + [1] * 14),
    "bal": np.array([1420, 1, 1]),
    "aicon": np.array([1420, 1420, 1420, 400.0 ** -2, 400.0 ** -4, 400.0 ** -6,
                       1 / 400, 1 / 400, 1, 1, 400]),
    "brown_affine_after": np.array([1420, 1420, 1420, 400.0 ** -2, 400.0 ** -4, 400.0 ** -6,
                                    1 / 400, 1 / 400, 1, 1]),
    "brown_aspect_first": np.array([1420, 1420, 1420, 400.0 ** -2, 400.0 ** -4, 400.0 ** -6,
                                    1 / 400, 1 / 400, 1, 1]),
    "brown_forward": np.array([1420, 1420, 1420, 400.0 ** -2, 400.0 ** -4, 400.0 ** -6,
                               1 / 400, 1 / 400]),
}
STEP = {"angles": 1e-4, "rotation": 1e-4, "X0": 1e-3, "X": 1e-3}


@functools.lru_cache(maxsize=None)
def _geometry(n, seed):
    """The stations and points of :func:`scene` (the same for every model:
    drawn before the interior parameters) and the generator's state after
    them; computed once per (n, seed), read-only."""
    rng = np.random.default_rng(seed)
    angles = np.stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-0.6, 0.6, n),
                       rng.uniform(-np.pi, np.pi, n)], -1)
    X0 = rng.uniform(-20, 20, (n, 3))
    depth = rng.uniform(5, 15, n)
    px = rng.uniform(20, 620, n) - 320
    py = rng.uniform(20, 460, n) - 240
    Xc = np.stack([px / 1420 * depth, -py / 1420 * depth, -depth], -1)
    X = np.einsum("nji,nj->ni", opk_to_matrix(angles), Xc) + X0
    for a in (X, angles, X0):
        a.setflags(write=False)
    return X, angles, X0, rng.bit_generator.state


def scene(model, n=N, seed=1):
    """n observations, each with its own station and slightly different
    interior parameters, of points visible in the 640 x 480 image."""
    X, angles, X0, state = _geometry(n, seed)
    rng = np.random.default_rng()
    rng.bit_generator.state = state
    io = PARAMS[model] * (1 + 0.01 * rng.normal(size=(n, len(PARAMS[model]))))
    return X, angles, X0, io


def evaluate(model, kind, X, angles, X0, io, xy_obs):
    m = camera_model(model)
    if kind == "project":
        return m.project(X, angles, X0, io, jacobians=True)
    return m.residuals(xy_obs, X, angles, X0, io, jacobians=True)


def value(model, kind, X, angles, X0, io, xy_obs):
    m = camera_model(model)
    if kind == "project":
        return m.project(X, angles, X0, io)
    return m.residuals(xy_obs, X, angles, X0, io, jacobians=False)


def perturbed(group, col, h, X, angles, X0, io, model):
    """Inputs with column ``col`` of ``group`` moved by h (all observations)."""
    X, angles, X0, io = X.copy(), angles.copy(), X0.copy(), io.copy()
    if group == "io":
        io[:, col] += h
    elif group == "angles":
        angles[:, col] += h
    elif group == "X0":
        X0[:, col] += h
    elif group == "X":
        X[:, col] += h
    else:   # incremental rotation: R = small_rotation(delta) R0
        delta = np.zeros(3)
        delta[col] = h
        angles = matrix_to_opk(small_rotation(delta) @ opk_to_matrix(angles))
    return X, angles, X0, io


def cases():
    for model in sorted(CAMERA_MODELS):
        for kind in ("project", "residuals"):
            for i, name in enumerate(camera_model(model).parameter_names):
                yield pytest.param(model, kind, "io", i, id=f"{model}-{kind}-io-{name}")
            for group in ("angles", "X0", "X", "rotation"):
                for i in range(3):
                    yield pytest.param(model, kind, group, i, id=f"{model}-{kind}-{group}-{i}")


@pytest.mark.parametrize("model,kind,group,col", list(cases()))
def test_jacobian_matches_central_differences(model, kind, group, col):
    X, angles, X0, io = scene(model)
    xy_obs = camera_model(model).project(X, angles, X0, io) + RNG.normal(0, 0.5, (N, 2))
    _, jac = evaluate(model, kind, X, angles, X0, io, xy_obs)
    h = 1e-4 * TYPICAL[model][col] if group == "io" else STEP[group]
    plus = value(model, kind, *perturbed(group, col, h, X, angles, X0, io, model), xy_obs)
    minus = value(model, kind, *perturbed(group, col, -h, X, angles, X0, io, model), xy_obs)
    fd = (plus - minus) / (2 * h)
    J = jac[group][:, :, col]
    scale = np.max(np.abs(fd))
    assert scale > 0
    err = np.abs(J - fd) / np.maximum(np.abs(J), scale)
    assert err.max() < 1e-6, f"max relative error {err.max():.2e}"


@pytest.mark.parametrize("model", sorted(CAMERA_MODELS))
def test_jacobian_shapes(model):
    X, angles, X0, io = scene(model, n=7)
    m = camera_model(model)
    xy, jac = m.project(X, angles, X0, io, jacobians=True)
    r, jac_r = m.residuals(xy, X, angles, X0, io)
    p = len(m.parameter_names)
    for j in (jac, jac_r):
        assert set(j) == {"io", "angles", "X0", "X", "rotation"}
        assert j["io"].shape == (7, 2, p)
        for key in ("angles", "X0", "X", "rotation"):
            assert j[key].shape == (7, 2, 3)
    assert np.allclose(r, 0, atol=1e-9)


# ---------------------------------------------------------------- registry
def test_registry():
    assert set(CAMERA_MODELS) == {"aicon", "bal", "brown", "opencv", "opencv_fisheye",
                                  "opencv_full",
                                  "brown_affine_after", "brown_aspect_first", "brown_forward"}
    assert camera_model("brown").parameter_names == (
        "c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2")
    assert camera_model("opencv").parameter_names == (
        "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    assert camera_model("bal").parameter_names == ("f", "k1", "k2")
    assert camera_model("opencv_fisheye").parameter_names == (
        "fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")
    assert camera_model("aicon").parameter_names == (
        "c", "xh", "yh", "A1", "A2", "A3", "B1", "B2", "C1", "C2", "r0")
    with pytest.raises(InputError, match="aicon.*bal.*brown.*opencv"):
        camera_model("fisheye")


def test_default_parameters():
    b = camera_model("brown").default_parameters(1420.0, SIZE)
    assert np.allclose(b, [1420, 320, 240, 0, 0, 0, 0, 0, 0, 0])
    o = camera_model("opencv").default_parameters(1420.0, SIZE)
    assert np.allclose(o, [1420, 1420, 320, 240, 0, 0, 0, 0, 0])


# ---------------------------------------------------------------- conventions
def test_ideal_projection_signs():
    """Camera looks along -z; image x right, y down."""
    Xc = np.array([[1.0, 0.0, -10.0], [0.0, 1.0, -10.0]])
    xy = ideal_projection(Xc, 1000.0)
    assert np.allclose(xy, [[100.0, 0.0], [0.0, -100.0]])


def test_kappa_90_turns_image():
    """Nadir camera 10 m above the origin. kappa = 0: world +x is image right,
    world +y image up. kappa = +90 deg: camera x = world +y, camera y = world
    -x, so world +x appears below the centre and world +y right of it."""
    b = camera_model("brown")
    io = b.default_parameters(1000.0, SIZE)
    X = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    xy0 = b.project(X, [0, 0, 0], [0, 0, 10.0], io)
    assert np.allclose(xy0, [[420.0, 240.0], [320.0, 140.0]])
    xy = b.project(X, [0, 0, np.pi / 2], [0, 0, 10.0], io)
    assert np.allclose(xy, [[320.0, 340.0], [420.0, 240.0]])


# ---------------------------------------------------------------- brown
def test_brown_project_then_correct_is_ideal():
    X, angles, X0, io = scene("brown", n=500, seed=3)
    b = camera_model("brown")
    xy = b.project(X, angles, X0, io)
    R = opk_to_matrix(angles)
    Xc = np.einsum("nij,nj->ni", R, X - X0)
    ideal = ideal_projection(Xc, io[:, 0])
    corrected = b.correct(xy, io)
    assert np.max(np.abs(corrected - ideal)) <= 1e-10 * np.max(np.abs(ideal))
    assert np.max(np.abs(b.residuals(xy, X, angles, X0, io, jacobians=False))) < 1e-9
    # the distortion is noticeable
    assert np.max(np.abs(xy - io[:, 1:3] - ideal)) > 5.0


def test_brown_distortion_is_correction_minus_input():
    b = camera_model("brown")
    io = PARAMS["brown"]
    xy = RNG.uniform(0, 1, (40, 2)) * SIZE
    xbar, ybar = xy[:, 0] - io[1], xy[:, 1] - io[2]
    d, part = b.distortion(xbar, ybar, io)
    assert np.allclose(d, b.correct(xy, io) - np.stack([xbar, ybar], -1), atol=1e-12)
    h = 1e-3
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        fd = (b.distortion(xbar + e[0], ybar + e[1], io)[0]
              - b.distortion(xbar - e[0], ybar - e[1], io)[0]) / (2 * h)
        assert np.allclose(part["xy"][:, :, k], fd, atol=1e-9)


def test_brown_correct_jacobian_wrt_xy():
    b = camera_model("brown")
    io = PARAMS["brown"]
    xy = RNG.uniform(0, 1, (40, 2)) * SIZE
    _, jac = b.correct(xy, io, jacobians=True)
    for k in range(2):
        e = np.zeros(2)
        e[k] = 1e-3
        fd = (b.correct(xy + e, io) - b.correct(xy - e, io)) / 2e-3
        assert np.allclose(jac["xy"][:, :, k], fd, atol=1e-9)


def test_brown_inversion_failure_is_geometry_error():
    b = camera_model("brown")
    io = PARAMS["brown"].copy()
    io[3] = -5e-6         # strong barrel: no inverse far outside the format
    X = np.array([[0.1, 0.0, -1.0], [5.0, 0.0, -1.0]])   # 80 deg off axis
    with pytest.raises(GeometryError, match="1 of 2"):
        b.project(X, [0, 0, 0], [0, 0, 0], io)           # spurious far root
    io[4:6] = 0.0
    with pytest.raises(GeometryError):
        b.project(X, [0, 0, 0], [0, 0, 0], io)           # no root at all


def test_brown_units_mm_and_px_are_equivalent():
    b = camera_model("brown")
    X, angles, X0, io = scene("brown", n=30)
    xy = b.project(X, angles, X0, io) + RNG.normal(0, 0.3, (30, 2))
    size = 0.0031911                                     # mm per px
    io_mm = rescale_parameters("brown", io, size)
    r_px = b.residuals(xy, X, angles, X0, io, jacobians=False)
    r_mm = b.residuals(xy * size, X, angles, X0, io_mm, jacobians=False)
    assert np.allclose(r_mm / size, r_px, rtol=1e-9, atol=1e-9)
    assert np.allclose(rescale_parameters(b, io_mm, 1 / size), io)


# ---------------------------------------------------------------- opencv
def test_opencv_equals_cv2_project_points():
    o = camera_model("opencv")
    p = PARAMS["opencv"]
    K = np.array([[p[0], 0, p[2]], [0, p[1], p[3]], [0, 0, 1]])
    X, angles, X0, _ = scene("opencv", n=40, seed=5)
    for station in range(3):             # a few stations, each seeing all points
        a, c = angles[station], X0[station]
        Xs = (np.einsum("ji,nj->ni", opk_to_matrix(a), X - X0) + c)   # re-centre
        R_cv, t_cv = opencv_pose(opk_to_matrix(a), c)
        rvec, _ = cv2.Rodrigues(R_cv)
        ref, _ = cv2.projectPoints(Xs, rvec, t_cv, K, p[4:])
        ours = o.project(Xs, a, c, p)
        assert np.allclose(ours, ref[:, 0, :], atol=1e-9)


def test_opencv_fisheye_equals_cv2_fisheye_project_points():
    """cv2.fisheye.projectPoints, also far off the axis (a wide lens: the
    points of the scene seen with fx = 300 reach 60 degrees), and the
    inverse (image_to_ray) against cv2.fisheye.undistortPoints."""
    o = camera_model("opencv_fisheye")
    X, angles, X0, _ = scene("opencv_fisheye", n=40, seed=5)
    for f in (1420.0, 300.0):
        p = PARAMS["opencv_fisheye"].copy()
        p[:2] = f, f * 1.003
        K = np.array([[p[0], 0, p[2]], [0, p[1], p[3]], [0, 0, 1]])
        for station in range(3):
            a, c = angles[station], X0[station]
            Xs = (np.einsum("ji,nj->ni", opk_to_matrix(a), X - X0) + c)
            R_cv, t_cv = opencv_pose(opk_to_matrix(a), c)
            ref, _ = cv2.fisheye.projectPoints(Xs[:, None, :], cv2.Rodrigues(R_cv)[0], t_cv,
                                               K, p[4:])
            xy = o.project(Xs, a, c, p)
            np.testing.assert_allclose(xy, ref[:, 0, :], rtol=0, atol=1e-7)
        t = o.image_to_ray(xy, p)
        und = cv2.fisheye.undistortPoints(xy[:, None, :], K, p[4:],
                                          criteria=(cv2.TERM_CRITERIA_COUNT
                                                    | cv2.TERM_CRITERIA_EPS, 100, 1e-14))
        np.testing.assert_allclose(t, und[:, 0, :], atol=1e-6)
        np.testing.assert_allclose(o.ray_to_image(t, p), xy, atol=1e-8)


def test_opencv_fisheye_on_the_axis_has_its_limits():
    """At r = 0 the model is the pinhole (s = 1) and its Jacobian finite."""
    o = camera_model("opencv_fisheye")
    p = PARAMS["opencv_fisheye"]
    t = np.array([[0.0, 0.0], [1e-12, -1e-12], [1e-3, 2e-3]])
    xy, dt, dio = o._forward(t, np.broadcast_to(p, (3, 8)))
    assert np.allclose(xy[0], p[2:4]) and np.all(np.isfinite(dt)) and np.all(np.isfinite(dio))
    np.testing.assert_allclose(dt[0], np.diag(p[:2]), rtol=1e-12)
    np.testing.assert_allclose(dt[1], np.diag(p[:2]), rtol=1e-9)


def test_frame_conversion_reproduces_pixels():
    """Brown with no distortion, c = fx = fy, equals cv2 with R_cv, t_cv."""
    b = camera_model("brown")
    X, angles, X0, _ = scene("brown", n=40, seed=9)
    a, c = angles[0], X0[0]
    Xs = np.einsum("ji,nj->ni", opk_to_matrix(a), X - X0) + c
    io = b.default_parameters(1420.0, SIZE)
    io[1:3] = 321.5, 238.2
    R_cv, t_cv = opencv_pose(opk_to_matrix(a), c)
    K = np.array([[1420.0, 0, 321.5], [0, 1420.0, 238.2], [0, 0, 1]])
    ref, _ = cv2.projectPoints(Xs, cv2.Rodrigues(R_cv)[0], t_cv, K, None)
    assert np.allclose(b.project(Xs, a, c, io), ref[:, 0, :], atol=1e-9)
    # and back
    R, X0b = photogrammetric_pose(R_cv, t_cv)
    assert np.allclose(R, opk_to_matrix(a), atol=1e-14)
    assert np.allclose(X0b, c, atol=1e-12)


def test_opencv_image_to_ray_inverts_projection():
    o = camera_model("opencv")
    p = PARAMS["opencv"]
    t = RNG.uniform(-0.2, 0.2, (100, 2))
    xy = o.ray_to_image(t, p)
    assert np.allclose(o.image_to_ray(xy, p), t, atol=1e-12)
    ref = cv2.undistortPoints(xy[:, None, :], np.array(
        [[p[0], 0, p[2]], [0, p[1], p[3]], [0, 0, 1]]), p[4:],
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14))
    assert np.allclose(ref[:, 0, :], t, atol=1e-6)


# ---------------------------------------------------------------- vectorisation
@pytest.mark.parametrize("model", sorted(CAMERA_MODELS))
def test_hundred_thousand_observations_in_one_call(model):
    n = 100_000
    X, angles, X0, io = scene(model, n=n, seed=11)
    m = camera_model(model)
    xy, jac = m.project(X, angles, X0, io, jacobians=True)
    assert xy.shape == (n, 2) and np.all(np.isfinite(xy))
    r, jac_r = m.residuals(xy, X, angles, X0, io)
    assert np.max(np.abs(r)) < 1e-8
    assert jac_r["io"].shape == (n, 2, len(m.parameter_names))


@pytest.mark.parametrize("model", sorted(CAMERA_MODELS))
def test_single_station_broadcasts(model):
    X, angles, X0, io = scene(model, n=20)
    m = camera_model(model)
    one = m.project(X, angles[0], X0[0], io[0])
    many = m.project(X, np.tile(angles[0], (20, 1)), np.tile(X0[0], (20, 1)),
                     np.tile(io[0], (20, 1)))
    assert np.array_equal(one, many)
    with pytest.raises(InputError):
        m.project(X, angles[:3], X0, io)


# ---------------------------------------------------------------- rotation-matrix path
def rotation_cases():
    for model in sorted(CAMERA_MODELS):
        for i, name in enumerate(camera_model(model).parameter_names):
            yield pytest.param(model, "io", i, id=f"{model}-io-{name}")
        for group in ("X0", "X", "rotation"):
            for i in range(3):
                yield pytest.param(model, group, i, id=f"{model}-{group}-{i}")


@pytest.mark.parametrize("model,group,col", list(rotation_cases()))
def test_rotation_path_jacobian_matches_central_differences(model, group, col):
    """``residuals_rotation`` (the engine's R-based path): its Jacobians
    against central differences, and its values equal ``residuals``."""
    X, angles, X0, io = scene(model)
    m = camera_model(model)
    R = opk_to_matrix(angles)
    xy_obs = m.project(X, angles, X0, io) + RNG.normal(0, 0.5, (N, 2))
    r, jac = m.residuals_rotation(xy_obs, X, R, X0, io)
    assert set(jac) == {"io", "X0", "X", "rotation"}
    r_angles, jac_angles = m.residuals(xy_obs, X, angles, X0, io)
    np.testing.assert_allclose(r, r_angles, rtol=0, atol=1e-9)
    np.testing.assert_allclose(jac[group], jac_angles[group], rtol=1e-9,
                               atol=1e-12 * np.abs(jac_angles[group]).max())
    h = 1e-4 * TYPICAL[model][col] if group == "io" else STEP[group]

    def moved(s):
        Xp, X0p, iop, Rp = X.copy(), X0.copy(), io.copy(), R
        if group == "io":
            iop[:, col] += s
        elif group == "X0":
            X0p[:, col] += s
        elif group == "X":
            Xp[:, col] += s
        else:
            delta = np.zeros(3)
            delta[col] = s
            Rp = small_rotation(delta) @ R
        return m.residuals_rotation(xy_obs, Xp, Rp, X0p, iop, jacobians=False)

    fd = (moved(h) - moved(-h)) / (2 * h)
    J = jac[group][:, :, col]
    err = np.abs(J - fd) / np.maximum(np.abs(J), np.max(np.abs(fd)))
    assert err.max() < 1e-6, f"max relative error {err.max():.2e}"


def test_bal_model_is_snavely_projection():
    """The bal model equals BAL's formula p = -P/P_z, r = f (1 + k1 |p|^2 +
    k2 |p|^4) p with P = R X + t, t = -R X0, and y flipped (BAL is y up)."""
    X, angles, X0, io = scene("bal", n=40, seed=4)
    R = opk_to_matrix(angles)
    P = np.einsum("nij,nj->ni", R, X) - np.einsum("nij,nj->ni", R, X0)
    p = -P[:, :2] / P[:, 2:]
    r2 = np.sum(p * p, axis=1)
    bal = (io[:, 0] * (1 + io[:, 1] * r2 + io[:, 2] * r2 ** 2))[:, None] * p
    ours = camera_model("bal").project(X, angles, X0, io)
    np.testing.assert_allclose(ours, bal * [1.0, -1.0], rtol=1e-12, atol=1e-9)
    t = camera_model("bal").image_to_ray(ours, io)
    np.testing.assert_allclose(camera_model("bal").ray_to_image(t, io), ours, atol=1e-9)
