"""Rotation parameterisations: round trips, known matrices, derivatives."""

import cv2
import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import rotations as rot

RNG = np.random.default_rng(20240601)


def random_angles(n=200):
    a = RNG.uniform(-np.pi, np.pi, (n, 3))
    a[:, 1] = RNG.uniform(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3, n)
    return a


def random_rotations(n=200):
    return rot.opk_to_matrix(random_angles(n))


def central_difference(fun, x, h=1e-6):
    """d fun / d x[..., k] as the last axis, by central differences."""
    cols = []
    for k in range(x.shape[-1]):
        e = np.zeros_like(x)
        e[..., k] = h
        cols.append((fun(x + e) - fun(x - e)) / (2 * h))
    return np.stack(cols, -1)


# ---------------------------------------------------------------- units
@pytest.mark.parametrize("unit,full_turn", [("rad", 2 * np.pi), ("deg", 360.0), ("gon", 400.0)])
def test_unit_round_trip(unit, full_turn):
    a = random_angles()
    assert np.allclose(rot.to_radians(rot.from_radians(a, unit), unit), a, atol=1e-14)
    assert np.isclose(rot.to_radians(full_turn, unit), 2 * np.pi)


def test_unknown_unit_raises_input_error():
    with pytest.raises(InputError, match="grad"):
        rot.to_radians(1.0, "grad")
    with pytest.raises(InputError):
        rot.from_radians(1.0, "mil")


# ---------------------------------------------------------------- opk
def test_opk_matrix_elements_are_wolf_kraus():
    o, p, k = 0.3, -0.4, 1.1
    R = rot.opk_to_matrix([o, p, k])
    co, so, cp, sp, ck, sk = np.cos(o), np.sin(o), np.cos(p), np.sin(p), np.cos(k), np.sin(k)
    expected = np.array([
        [cp * ck, co * sk + so * sp * ck, so * sk - co * sp * ck],
        [-cp * sk, co * ck - so * sp * sk, so * ck + co * sp * sk],
        [sp, -so * cp, co * cp]])
    assert np.allclose(R, expected, atol=1e-15)


def test_opk_equals_dbat_eulerrotmat_transposed():
    """DBAT: world-to-camera = eulerrotmat(ang,123,false)' = (R1 R2 R3)'."""
    def r1(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def r2(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def r3(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    for a in random_angles(20):
        assert np.allclose(rot.opk_to_matrix(a), (r1(a[0]) @ r2(a[1]) @ r3(a[2])).T, atol=1e-14)


def test_known_matrices():
    assert np.allclose(rot.opk_to_matrix([0, 0, 0]), np.eye(3))
    # kappa = 90 deg: camera x axis = world -y... R maps world x to camera -y
    Rk = rot.opk_to_matrix([0, 0, np.pi / 2])
    assert np.allclose(Rk, [[0, 1, 0], [-1, 0, 0], [0, 0, 1]], atol=1e-15)
    Ro = rot.opk_to_matrix([np.pi / 2, 0, 0])
    assert np.allclose(Ro, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-15)
    Rp = rot.opk_to_matrix([0, np.pi / 2, 0])
    assert np.allclose(Rp, [[0, 0, -1], [0, 1, 0], [1, 0, 0]], atol=1e-15)


def test_orthonormal_and_proper():
    R = random_rotations()
    assert np.allclose(R @ np.swapaxes(R, -1, -2), np.eye(3), atol=1e-14)
    assert np.allclose(np.linalg.det(R), 1.0, atol=1e-14)


def test_opk_round_trip_all_units():
    a = random_angles()
    assert np.allclose(rot.matrix_to_opk(rot.opk_to_matrix(a)), a, atol=1e-12)
    for unit in ("deg", "gon"):
        a_u = rot.from_radians(a, unit)
        back = rot.from_radians(rot.matrix_to_opk(rot.opk_to_matrix(rot.to_radians(a_u, unit))), unit)
        assert np.allclose(back, a_u, atol=1e-9)


def test_vectorised_leading_dims():
    a = random_angles(24).reshape(2, 3, 4, 3)
    R = rot.opk_to_matrix(a)
    assert R.shape == (2, 3, 4, 3, 3)
    assert rot.opk_derivatives(a).shape == (2, 3, 4, 3, 3, 3)
    assert np.allclose(rot.matrix_to_opk(R), a, atol=1e-12)


@pytest.mark.parametrize("phi", [np.pi / 2, -np.pi / 2])
def test_gimbal_lock_no_nan(phi):
    a = np.array([[0.3, phi, -0.7], [0.0, phi, 0.0], [-1.2, phi, 2.5]])
    R = rot.opk_to_matrix(a)
    back = rot.matrix_to_opk(R)
    assert np.all(np.isfinite(back))
    assert np.allclose(back[:, 0], 0.0)
    assert np.allclose(back[:, 1], phi)
    assert np.allclose(rot.opk_to_matrix(back), R, atol=1e-12)


def test_near_gimbal_lock_reproduces_matrix():
    a = np.array([[0.3, np.pi / 2 - 1e-9, -0.7], [0.2, -np.pi / 2 + 1e-13, 0.1]])
    R = rot.opk_to_matrix(a)
    assert np.allclose(rot.opk_to_matrix(rot.matrix_to_opk(R)), R, atol=1e-8)


def test_opk_derivatives_match_finite_differences():
    a = random_angles(50)
    fd = central_difference(rot.opk_to_matrix, a)
    assert np.allclose(rot.opk_derivatives(a), fd, atol=1e-9)


# ---------------------------------------------------------------- Rodrigues
def test_rodrigues_round_trip_and_cv2():
    R = random_rotations()
    r = rot.matrix_to_rodrigues(R)
    assert np.all(np.linalg.norm(r, axis=1) <= np.pi + 1e-12)
    assert np.allclose(rot.rodrigues_to_matrix(r), R, atol=1e-13)
    for Ri, ri in zip(R[:5], r[:5]):
        cv_r, _ = cv2.Rodrigues(Ri)
        assert np.allclose(cv_r.ravel(), ri, atol=1e-10)
        assert np.allclose(cv2.Rodrigues(ri)[0], Ri, atol=1e-12)


@pytest.mark.parametrize("theta", [0.0, 1e-15, 1e-9, 1e-5, 1e-3, 0.5, np.pi - 1e-7, np.pi])
def test_rodrigues_stable_near_zero_and_pi(theta):
    axes = RNG.normal(size=(20, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    r = axes * theta
    R = rot.rodrigues_to_matrix(r)
    assert np.allclose(R @ np.swapaxes(R, -1, -2), np.eye(3), atol=1e-14)
    back = rot.matrix_to_rodrigues(R)
    assert np.all(np.isfinite(back))
    assert np.allclose(rot.rodrigues_to_matrix(back), R, atol=1e-12)
    if theta < 3.0:
        assert np.allclose(back, r, atol=1e-12)
    else:   # at pi, r and -r are the same rotation
        assert np.allclose(np.abs(np.sum(back * axes, axis=1)), theta, atol=1e-6)


@pytest.mark.parametrize("scale", [0.0, 1e-8, 1e-3, 0.02, 1.0, 3.0])
def test_rodrigues_derivatives(scale):
    r = RNG.normal(size=(30, 3))
    r = r / np.linalg.norm(r, axis=1, keepdims=True) * scale
    fd = central_difference(rot.rodrigues_to_matrix, r)
    assert np.allclose(rot.rodrigues_derivatives(r), fd, atol=1e-9)
    if scale == 0.0:
        assert np.allclose(rot.rodrigues_derivatives(r)[0], np.moveaxis(rot.skew(np.eye(3)), 0, -1))


def test_small_rotation_is_expm():
    from scipy.linalg import expm
    d = RNG.normal(size=3) * 0.3
    assert np.allclose(rot.small_rotation(d), expm(rot.skew(d)), atol=1e-14)
    assert np.allclose(rot.small_rotation(np.zeros(3)), np.eye(3))


# ---------------------------------------------------------------- quaternions
def test_quaternion_round_trip_unit_and_sign():
    R = random_rotations()
    q = rot.matrix_to_quaternion(R)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.all(q[:, 0] >= 0)
    assert np.allclose(rot.quaternion_to_matrix(q), R, atol=1e-13)
    assert np.allclose(rot.quaternion_to_matrix(-3.0 * q), R, atol=1e-13)   # normalised, sign free


def test_quaternion_agrees_with_rodrigues():
    r = RNG.normal(size=(50, 3))
    theta = np.linalg.norm(r, axis=1)
    q = np.concatenate([np.cos(theta / 2)[:, None],
                        np.sin(theta / 2)[:, None] * r / theta[:, None]], 1)
    assert np.allclose(rot.quaternion_to_matrix(q), rot.rodrigues_to_matrix(r), atol=1e-13)


def test_quaternion_half_turns_canonical():
    R = rot.rodrigues_to_matrix(np.array([[np.pi, 0, 0], [0, -np.pi, 0], [0, 0, np.pi]]))
    q = rot.matrix_to_quaternion(R)
    assert np.allclose(q, [[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], atol=1e-12)
    assert np.allclose(rot.quaternion_to_matrix(q), R, atol=1e-13)


def test_rodrigues_series_shortcut_is_the_general_formula():
    """rodrigues_to_matrix takes the series alone when every angle is below
    1e-2 (a solver's increments): the same numbers as when the same vectors
    come with a large one (np.where over both branches)."""
    from photogram.geometry.rotations import rodrigues_to_matrix
    rng = np.random.default_rng(8)
    small = rng.normal(0, 1e-3, (20, 3))
    mixed = np.vstack([small, [[0.3, -0.2, 1.0]]])
    np.testing.assert_array_equal(rodrigues_to_matrix(small), rodrigues_to_matrix(mixed)[:20])
    R = rodrigues_to_matrix(small)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-15)
