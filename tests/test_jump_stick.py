"""Stick model: known-truth synthetic jumper, options and errors."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.jump import PARAMETERS, PlaneGround, ProfileGround, stick_model
from photogram.jump.synthetic import synthetic_jumper


@pytest.fixture(scope="module")
def jump():
    return synthetic_jumper(n=20, fps=30.0)


def model_of(s, **kw):
    return stick_model(s["P"], s["d1"], s["d2"], c1=s["c1"], c2=s["c2"], **kw)


def test_synthetic_flight_is_about_20_m_at_30_fps(jump):
    assert len(jump["times"]) == 20
    assert np.allclose(np.diff(jump["times"]), 1 / 30)
    assert 19.0 < np.linalg.norm(jump["O"][-1] - jump["O"][0]) < 21.0


def test_every_parameter_is_recovered_noise_free(jump):
    m = model_of(jump)
    for name in PARAMETERS:
        assert np.max(np.abs(m[name] - jump["truth"][name])) < 1e-8, name
    assert np.allclose(m.O, jump["O"], atol=1e-10)
    for got, want in ((m.X, "X"), (m.Y, "Y"), (m.Z, "Z"), (m.d1, "u1"), (m.d2, "u2")):
        assert np.allclose(got, jump[want], atol=1e-12)


def test_frame_is_right_handed_and_P1_has_no_Y(jump):
    m = model_of(jump)
    assert np.allclose(np.cross(m.X, m.Y), m.Z, atol=1e-12)
    assert np.allclose(np.einsum("ni,ni->n", m.P[:, 0] - m.O, m.Y), 0, atol=1e-12)
    assert np.all(np.einsum("ni,ni->n", m.P[:, 0] - m.O, m.Z) > 0)


def test_gamma_in_plane_is_pi_minus_alpha_minus_beta():
    s = synthetic_jumper(n=5)
    P = s["P"].copy()
    # remove the lateral hip offset: then the body is in the X'Z' plane
    y = s["Y"]
    off = np.einsum("ni,ni->n", P[:, 1] - s["O"], y)
    P[:, 1] -= off[:, None] * y
    m = stick_model(P, s["d1"], s["d2"])
    assert np.allclose(m["gamma"], np.pi - np.abs(m["alpha"] - m["beta"]), atol=1e-12)


def test_ski_segments(jump):
    m = model_of(jump)
    assert np.allclose(m.binding_points, jump["feet"], atol=1e-10)
    tail, tip = m.skis[:, :, 0], m.skis[:, :, 1]
    assert np.allclose(np.linalg.norm(tip - tail, axis=-1), 2.63, atol=1e-12)
    u = np.stack([jump["u1"], jump["u2"]], axis=1)
    assert np.allclose(tail, jump["feet"] - 0.43 * 2.63 * u, atol=1e-10)
    # without points on the ski lines, the lines pass through the bindings
    m2 = stick_model(jump["P"], jump["d1"], jump["d2"], binding_fraction=0.5)
    assert np.allclose(m2.binding_points, jump["P"][:, 2:4], atol=1e-12)
    assert np.allclose(0.5 * (m2.skis[:, :, 0] + m2.skis[:, :, 1]), jump["P"][:, 2:4])


def test_length_unit_converts_ski_length_and_scales_lengths():
    s = synthetic_jumper(n=8, length_unit="mm")
    m = stick_model(s["P"], s["d1"], s["d2"], length_unit="mm")
    assert m.ski_length == pytest.approx(2630.0)
    for name in PARAMETERS:
        assert np.allclose(m[name], s["truth"][name], rtol=1e-10, atol=1e-9), name
    tail, tip = m.skis[:, :, 0], m.skis[:, :, 1]
    assert np.allclose(np.linalg.norm(tip - tail, axis=-1), 2630.0)


def test_speed_with_missing_frames_and_points(jump):
    keep = np.r_[0:8, 9:20]                    # frame 8 is missing
    P = jump["P"][keep].copy()
    P[12, 2] = np.nan                          # P3 of frame 13 not measured
    m = stick_model(P, jump["d1"][keep], jump["d2"][keep], times=jump["times"][keep])
    v, truth = m["v"], jump["truth"]["v"][keep]
    frames = m.frames
    assert list(frames[:9]) == list(range(8)) + [9]
    nan_expected = {7, 8}                       # neighbours of the missing frame 8
    nan_expected |= {11, 13}                   # neighbours of the exposure without O
    # the exposure without O itself keeps the central difference of its neighbours
    for i in range(len(keep)):
        if i in nan_expected:
            assert np.isnan(v[i]), i
        else:
            assert v[i] == pytest.approx(truth[i], abs=1e-8), i
    assert np.isnan(m["alpha"][12]) and np.isfinite(m["alpha"][11])


def test_times_with_offset_and_single_exposure(jump):
    m = stick_model(jump["P"], jump["d1"], jump["d2"], times=jump["times"] + 12.345)
    assert np.allclose(m["v"], jump["truth"]["v"], atol=1e-8)
    one = stick_model(jump["P"][:1], jump["d1"][:1], jump["d2"][:1])
    assert np.isnan(one["v"][0]) and np.isfinite(one["alpha"][0])


def test_forward_orients_the_ski_directions(jump):
    d1 = -jump["d1"]
    d2 = jump["d2"].copy()
    d2[::2] *= -1
    with pytest.raises(InputError, match="against each other"):
        stick_model(jump["P"], d1, d2)
    for fwd in ("flight", [1.0, 0.0, 0.0]):
        m = stick_model(jump["P"], d1, d2, forward=fwd)
        assert np.allclose(m["phi"], jump["truth"]["phi"], atol=1e-12)


def test_ground_plane_and_profile(jump):
    slope = np.deg2rad(35.0)
    normal = (np.sin(slope), 0.0, np.cos(slope))
    point = (0.0, 0.0, 30.0)
    O = jump["O"]
    zplane = 30.0 - np.tan(slope) * O[:, 0]
    m = model_of(jump, ground=PlaneGround(point, normal))
    assert np.allclose(m["Z0"], O[:, 2] - zplane, atol=1e-10)
    m = model_of(jump, ground=PlaneGround(point, normal, vertical=False))
    assert np.allclose(m["Z0"], (O[:, 2] - zplane) * np.cos(slope), atol=1e-10)
    x = np.array([0.0, 20.0, 50.0])
    z = np.array([30.0, 20.0, 5.0])
    m = model_of(jump, ground=ProfileGround(x, z))
    assert np.allclose(m["Z0"], O[:, 2] - np.interp(O[:, 0], x, z), atol=1e-10)
    m = model_of(jump, ground=ProfileGround(np.array([0.0, 15.0]), np.array([30.0, 20.0])))
    assert np.all(np.isnan(m["Z0"][O[:, 0] > 15.0]))


def test_to_frame(jump):
    cov_points = np.broadcast_to(np.eye(3) * 1e-4, (20, 4, 3, 3))
    m = model_of(jump, cov_points=cov_points)
    f = m.to_frame("deg")
    assert len(f) == 20
    for name in PARAMETERS:
        assert name in f.columns and "sigma_" + name in f.columns
    assert np.allclose(f["alpha"], np.rad2deg(jump["truth"]["alpha"]))
    assert np.allclose(f["Z0"], jump["truth"]["Z0"])
    assert f.attrs["angle_unit"] == "deg" and f.attrs["length_unit"] == "m"
    assert "sigma_alpha" not in model_of(jump).to_frame().columns
    with pytest.raises(InputError):
        m.to_frame("grad")


@pytest.mark.parametrize("kw, match", [
    ({"fps": 0.0}, "fps"),
    ({"length_unit": "ft"}, "length unit"),
    ({"binding_fraction": 1.5}, "binding_fraction"),
    ({"times": np.arange(20) * 0.05}, "fps grid"),
    ({"times": np.zeros(20)}, "increasing"),
    ({"cov_points": np.eye(5)}, "covariance has shape"),
])
def test_errors(jump, kw, match):
    with pytest.raises(InputError, match=match):
        stick_model(jump["P"], jump["d1"], jump["d2"], **kw)


def test_shape_errors(jump):
    with pytest.raises(InputError, match="P has shape"):
        stick_model(jump["P"][:, :3], jump["d1"], jump["d2"])
    with pytest.raises(InputError, match="d2 has shape"):
        stick_model(jump["P"], jump["d1"], jump["d2"][:5])
