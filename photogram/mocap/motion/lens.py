"""Radial lens model of the simulated cameras: exact inversion and scaling.

The simulator's cameras use the OpenCV model (fx, fy, cx, cy, k1, k2, p1,
p2, k3) with radial distortion only (p1 = p2 = 0). Distorted normalised
coordinates ``d = (p - c) / f`` have the radius ``r_d``; the undistorted
radius solves ``r_u (1 + k1 r_u^2 + k2 r_u^4 + k3 r_u^6) = r_d``
(:func:`undistort_radius`, Newton's method, exact to 1e-15). Images of
another size ``(W, H)`` than the full resolution keep OpenCV's pixel-centre
convention ``x_small = s (x_full + 0.5) - 0.5`` (:func:`scaled_parameters`).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError

__all__ = ["undistort_radius", "scaled_parameters", "pixel_rays", "distort", "check_radial"]


def undistort_radius(r_d, k1: float, k2: float = 0.0, k3: float = 0.0) -> np.ndarray:
    """Undistorted radius ``r_u`` with ``r_u (1 + k1 r_u^2 + k2 r_u^4 + k3 r_u^6) = r_d``.

    Newton's method from ``r_u = r_d``, vectorised, until the residual is
    below 1e-15 (at most 30 steps); exact for the radial OpenCV model.

    Raises
    ------
    InputError
        If the model is not invertible at some radius (derivative <= 0).
    """
    r_d = np.asarray(r_d, dtype=float)
    r = r_d.copy()
    for _ in range(30):
        r2 = r * r
        poly = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dpoly = 1.0 + r2 * (3 * k1 + r2 * (5 * k2 + 7 * r2 * k3))
        if np.any(dpoly <= 0):
            raise InputError("the lens distortion is not invertible inside the image",
                             hint=f"k1={k1}, k2={k2}, k3={k3}")
        res = r * poly - r_d
        r = r - res / dpoly
        if np.max(np.abs(res), initial=0.0) < 1e-15:
            break
    return r


def scaled_parameters(io, full_size, size) -> np.ndarray:
    """OpenCV parameters (..., 9) of full-resolution images at ``size``.

    ``fx_s = s_x fx``, ``cx_s = s_x (cx + 0.5) - 0.5`` (same for y); the
    distortion coefficients are unchanged.
    """
    io = np.array(io, dtype=float)
    sx, sy = size[0] / float(full_size[0]), size[1] / float(full_size[1])
    io[..., 0] *= sx
    io[..., 1] *= sy
    io[..., 2] = sx * (io[..., 2] + 0.5) - 0.5
    io[..., 3] = sy * (io[..., 3] + 0.5) - 0.5
    return io



def check_radial(model: str, io) -> None:
    """InputError unless ``model`` is opencv with p1 = p2 = 0."""
    if model != "opencv":
        raise InputError(f"rendering supports the opencv camera model, not {model!r}")
    if io[6] != 0 or io[7] != 0:
        raise InputError("rendering supports radial distortion only (p1 = p2 = 0)",
                         hint=f"p1={io[6]}, p2={io[7]}")


def pixel_rays(io_row, xy) -> np.ndarray:
    """Normalised (ideal) coordinates (n, 2) of pixels xy (n, 2) of an
    OpenCV camera with radial distortion, exactly (float64)."""
    io = np.asarray(io_row, float)
    check_radial("opencv", io)
    xy = np.atleast_2d(np.asarray(xy, float))
    d = (xy - io[2:4]) / io[0:2]
    rd = np.hypot(d[:, 0], d[:, 1])
    ru = undistort_radius(rd, io[4], io[5], io[8])
    g = np.where(rd > 0, ru / np.where(rd > 0, rd, 1.0), 1.0)
    return d * g[:, None]


def distort(t, io):
    """Pixels (n, 2) of normalised coordinates t (n, 2) (radial model)."""
    r2 = np.sum(t * t, axis=-1, keepdims=True)
    k = 1.0 + r2 * (io[4] + r2 * (io[5] + r2 * io[8]))
    return t * k * io[0:2] + io[2:4]

