"""Conversions between the brown (backward) and opencv (forward) models."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import (brown_to_opencv, camera_model, fit_distortion,
                                format_grid, opencv_to_brown)

SIZE = (640, 480)
BROWN = np.array([1420.0, 321.5, 238.2, 2.3e-7, -3.0e-13, 6.0e-19, 6.0e-6, -4.0e-6, 4.0e-4, 0.0])
OPENCV = np.array([1420.0, 1425.0, 322.0, 238.0, -0.25, 0.3, 1.0e-3, -8.0e-4, -0.5])


def rays(n=200, seed=2):
    return np.random.default_rng(seed).uniform([-0.22, -0.17], [0.22, 0.17], (n, 2))


def test_pinhole_part_converts_exactly():
    b = BROWN.copy()
    b[3:8] = 0.0                              # keep c, x0, y0 and the aspect B1
    o = brown_to_opencv(b)
    assert np.allclose(o[:4], [1420 / 1.0004, 1420, 321.5, 238.2])
    t = rays()
    xy_b = camera_model("brown").ray_to_image(t, b)
    xy_o = camera_model("opencv").ray_to_image(t, o)
    assert np.allclose(xy_b, xy_o, atol=1e-9)
    assert np.allclose(opencv_to_brown(o), b, rtol=1e-14, atol=1e-12)


def test_lossy_conversion_is_refused_unless_asked():
    with pytest.raises(InputError, match="K1"):
        brown_to_opencv(BROWN)
    with pytest.raises(InputError, match="k1"):
        opencv_to_brown(OPENCV)
    assert np.all(brown_to_opencv(BROWN, strict=False)[4:] == 0)
    shear = np.zeros(10)
    shear[:3] = 1420, 320, 240
    shear[9] = 1e-4
    with pytest.raises(InputError, match="B2"):
        brown_to_opencv(shear)


@pytest.mark.parametrize("source,params,target,limit", [
    ("brown", BROWN, "opencv", 0.1),
    ("opencv", OPENCV, "brown", 0.1),
])
def test_fit_distortion_between_forms(source, params, target, limit):
    fitted, rms = fit_distortion(source, params, target, SIZE)
    assert rms < limit
    # the reported misfit is the image-space one
    grid = format_grid(SIZE)
    t = camera_model(source).image_to_ray(grid, params)
    misfit = camera_model(target).ray_to_image(t, fitted) - grid
    assert np.isclose(rms, np.sqrt(np.mean(np.sum(misfit ** 2, 1))))
    # and the distortion is large, so the fit did something
    _, rms0 = fit_distortion(source, params, target, SIZE, free=())
    assert rms0 > 20 * rms


def test_first_order_coefficients():
    """k1 ~ -K1 c^2, p1 ~ P2 c, p2 ~ -P1 c (docs/camera-models.md)."""
    b = np.zeros(10)
    b[:3] = 1420, 320, 240
    b[3], b[6], b[7] = 2e-8, 1e-7, -2e-7        # mild: first order dominates
    o, rms = fit_distortion("brown", b, "opencv", SIZE)
    c = 1420.0
    assert np.isclose(o[4], -b[3] * c ** 2, rtol=0.05)
    assert np.isclose(o[6], b[7] * c, rtol=0.05)
    assert np.isclose(o[7], -b[6] * c, rtol=0.05)
    assert rms < 1e-3


@pytest.mark.parametrize("model,params", [("opencv", OPENCV), ("brown", BROWN)])
def test_fit_to_same_model_recovers_parameters(model, params):
    start = params.copy()
    free = {"opencv": ("k1", "k2", "p1", "p2", "k3"),
            "brown": ("K1", "K2", "K3", "P1", "P2")}[model]
    idx = [camera_model(model).index(n) for n in free]
    start[idx] = 0.0
    fitted, rms = fit_distortion(model, params, model, SIZE, target_params=start)
    assert rms < 1e-9
    assert np.allclose(fitted, params, rtol=1e-6, atol=0)
