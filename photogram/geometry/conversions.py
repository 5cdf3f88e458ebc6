"""Conversions between the brown (backward) and opencv (forward) models.

The pinhole part converts exactly (docs/camera-models.md, "Conversions"):
with no distortion and no shear, brown's correction
``((1 + B1)(x - x0), y - y0) = c t`` and OpenCV's ``(x, y) = (fx t_x + cx,
fy t_y + cy)`` describe the same camera when ``fx = c / (1 + B1)``,
``fy = c``, ``cx = x0``, ``cy = y0``.

The distortion does not: a polynomial *correction* of measured coordinates
and a polynomial *distortion* of ideal ones are not inverses of each other
for any finite set of coefficients, and brown's shear B2 has no OpenCV
counterpart. :func:`fit_distortion` gives the least-squares best fit over the
image format and reports the misfit (also for the ``aicon`` model, whose
exact conversions are in :mod:`photogram.geometry.aicon_conversions`).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError
from photogram.geometry import aicon_conversions
from photogram.geometry.camera import camera_model

DISTORTION_PARAMETERS = {"brown": ("K1", "K2", "K3", "P1", "P2", "B2"),
                         "opencv": ("k1", "k2", "p1", "p2", "k3"),
                         "aicon": ("A1", "A2", "A3", "B1", "B2", "C2")}
DEFAULT_FIT = {"brown": ("K1", "K2", "K3", "P1", "P2"),
               "opencv": ("k1", "k2", "p1", "p2", "k3"),
               "aicon": ("A1", "A2", "A3", "B1", "B2")}


def _lost(model, params, strict, target):
    m = camera_model(model)
    names = [n for n in DISTORTION_PARAMETERS[model] if params[m.index(n)] != 0]
    if names and strict:
        raise InputError(f"{model} parameters {', '.join(names)} cannot be converted "
                         f"exactly to the {target} model",
                         hint="use fit_distortion() for a least-squares conversion, "
                              "or strict=False to drop them")


def brown_to_opencv(params, strict=True) -> np.ndarray:
    """Exact pinhole conversion brown -> opencv.

    ``fx = c / (1 + B1)``, ``fy = c``, ``cx = x0``, ``cy = y0``; k, p = 0.
    The brown parameters must be in pixels.

    Raises
    ------
    InputError
        With ``strict=True`` if K1-K3, P1, P2 or B2 is non-zero (they would
        be lost; see :func:`fit_distortion`).
    """
    p = np.asarray(params, dtype=float)
    _lost("brown", p, strict, "opencv")
    c, x0, y0, b1 = p[0], p[1], p[2], p[8]
    return np.array([c / (1.0 + b1), c, x0, y0, 0, 0, 0, 0, 0], dtype=float)


def opencv_to_brown(params, strict=True) -> np.ndarray:
    """Exact pinhole conversion opencv -> brown.

    ``c = fy``, ``B1 = fy / fx - 1``, ``x0 = cx``, ``y0 = cy``; the rest 0.

    Raises
    ------
    InputError
        With ``strict=True`` if k1, k2, k3, p1 or p2 is non-zero.
    """
    p = np.asarray(params, dtype=float)
    _lost("opencv", p, strict, "brown")
    fx, fy, cx, cy = p[:4]
    out = np.zeros(10)
    out[:3] = fy, cx, cy
    out[8] = fy / fx - 1.0
    return out


def _pinhole_part(source, params, target):
    """The exact part of the conversion (the rest dropped): the start of
    :func:`fit_distortion`."""
    if source == target:
        return np.array(params, dtype=float)
    convert = {("brown", "opencv"): brown_to_opencv, ("opencv", "brown"): opencv_to_brown,
               ("aicon", "opencv"): aicon_conversions.aicon_to_opencv,
               ("opencv", "aicon"): aicon_conversions.opencv_to_aicon,
               ("aicon", "brown"): aicon_conversions.aicon_to_brown,
               ("brown", "aicon"): aicon_conversions.brown_to_aicon}
    if (source, target) not in convert:
        raise InputError(f"no conversion from the {source} to the {target} model",
                         hint="pass target_params (start values) to fit_distortion")
    return convert[source, target](params, strict=False)


def format_grid(image_size, shape=(25, 19)):
    """Measured points on a regular grid covering the image format
    ``[0, w] x [0, h]`` (n, 2)."""
    w, h = image_size
    gx, gy = np.meshgrid(np.linspace(0.0, w, shape[0]), np.linspace(0.0, h, shape[1]))
    return np.stack([gx.ravel(), gy.ravel()], -1)


def fit_distortion(source, source_params, target, image_size, target_params=None,
                   free=None, grid=(25, 19)):
    """Least-squares conversion of a camera between models.

    Measured points on a grid over the image format are turned into rays
    with the source model; the target parameters named in ``free`` are
    fitted so that the target model reproduces the grid from the rays, by
    minimising the target's own residual (``residuals``). All image
    quantities in pixels (rescale brown first, see
    :func:`photogram.geometry.rescale_parameters`).

    Parameters
    ----------
    source, target : str
        Model names ("brown", "opencv", "aicon").
    source_params : array_like
    image_size : (w, h)
    target_params : array_like, optional
        Start values and values of the parameters not fitted; default the
        exact pinhole conversion of the source.
    free : sequence of str, optional
        Target parameters to fit; default the radial and decentring terms.
    grid : (nx, ny)

    Returns
    -------
    params : ndarray
        Target parameters.
    rms : float
        RMS over the grid of the image-space distance between the source's
        and the fitted target's projection of the same rays (image unit).
    """
    src, tgt = camera_model(source), camera_model(target)
    m = format_grid(image_size, grid)
    p_src = np.asarray(source_params, dtype=float)
    rays = src.image_to_ray(m, p_src)
    X = tgt.rays_to_points(rays)
    p0 = (_pinhole_part(source, p_src, target) if target_params is None
          else np.array(target_params, dtype=float))
    idx = [tgt.index(name) for name in (DEFAULT_FIT[target] if free is None else free)]

    def full(x):
        p = p0.copy()
        p[idx] = x
        return p

    def fun(x):
        return tgt.residuals(m, X, np.zeros(3), np.zeros(3), full(x), jacobians=False).ravel()

    def jac(x):
        _, J = tgt.residuals(m, X, np.zeros(3), np.zeros(3), full(x))
        return J["io"][:, :, idx].reshape(-1, len(idx))

    if idx:
        from scipy.optimize import least_squares     # 0.3 s to import: only here
        sol = least_squares(fun, p0[idx], jac=jac, method="lm", x_scale="jac",
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
        p = full(sol.x)
    else:
        p = p0
    misfit = tgt.ray_to_image(rays, p) - m
    return p, float(np.sqrt(np.mean(np.sum(misfit ** 2, axis=1))))
