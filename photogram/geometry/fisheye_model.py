"""OpenCV's fisheye camera model (Kannala-Brandt, ``cv2.fisheye``; COLMAP's
OPENCV_FISHEYE).

Identical to ``cv2.fisheye.projectPoints`` with ``K = [[fx, 0, cx], [0,
fy, cy], [0, 0, 1]]`` (no skew) and ``D = (k1, k2, k3, k4)`` under the same
extrinsics convention as the ``opencv`` model (``R_cv = diag(1,-1,-1) R``,
``t_cv = -R_cv X0``; docs/camera-models.md):

1. normalised coordinates ``a = X/Z``, ``b = Y/Z`` in OpenCV's camera
   frame (the ideal projection with c = 1, as the ``opencv`` model);
2. ``r = sqrt(a^2 + b^2)``, ``theta = atan(r)``,
   ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)``
   (Kannala & Brandt 2006, eq. (6); OpenCV's fisheye documentation);
3. ``x' = (theta_d / r) a``, ``y' = (theta_d / r) b``;
4. pixels ``x = fx x' + cx``, ``y = fy y' + cy``.

The Jacobians are analytic (tests against finite differences and against
``cv2.fisheye.projectPoints``): with ``s(r) = theta_d / r``,
``d(s t)/dt = s I + s'(r) t t^T / r`` and
``s'(r) = (theta_d'(theta) / (1 + r^2) - s) / r``; near the axis
(``r < 1e-8``) ``s = 1`` and ``s' t t^T / r = 0`` (the limits).
Points are at most 90 degrees off the axis (``Z > 0``), as in
``cv2.fisheye``.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.camera import register_model
from photogram.geometry.forward_model import ForwardModel

__all__ = ["OpenCVFisheyeModel"]

_EPS = 1e-8


@register_model
class OpenCVFisheyeModel(ForwardModel):
    """OpenCV's fisheye model.

    ``parameter_names = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")``;
    fx fy cx cy in the image unit (px), k dimensionless.
    """

    name = "opencv_fisheye"
    parameter_names = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")
    parameter_dims = (1, 1, 1, 1, 0, 0, 0, 0)

    def distortion(self, xn, yn, io):
        """Displacement ``(x', y') - (a, b)`` of normalised coordinates and
        its partials (``"xy"`` (n,2,2), ``"io"`` (n,2,p))."""
        t = np.stack([np.atleast_1d(xn), np.atleast_1d(yn)], -1).astype(float)
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(t), self.n_params))
        td, dt, dk = self._distort(t, io)
        dio = np.zeros((len(t), 2, self.n_params))
        dio[:, :, 4:8] = dk
        return td - t, {"xy": dt - np.eye(2), "io": dio}

    @staticmethod
    def _distort(t, io):
        """``(x', y')`` of normalised t (n,2), d/dt (n,2,2), d/dk (n,2,4)."""
        k = io[:, 4:8]
        r = np.hypot(t[:, 0], t[:, 1])
        th = np.arctan(r)
        th2 = th * th
        poly = 1 + th2 * (k[:, 0] + th2 * (k[:, 1] + th2 * (k[:, 2] + th2 * k[:, 3])))
        thd = th * poly
        dthd = 1 + th2 * (3 * k[:, 0] + th2 * (5 * k[:, 1] + th2 * (7 * k[:, 2]
                                                                     + th2 * 9 * k[:, 3])))
        small = r < _EPS
        rs = np.where(small, 1.0, r)
        s = np.where(small, 1.0, thd / rs)
        ds = np.where(small, 0.0, (dthd / (1 + r * r) - s) / rs)      # s'(r)
        td = s[:, None] * t
        u = np.where(small[:, None], 0.0, t / rs[:, None])             # t / r
        dt = s[:, None, None] * np.eye(2) + (ds[:, None, None] * t[:, :, None] * u[:, None, :])
        # d theta_d / d k_i = theta^(2i+3); d(s t)/dk_i = theta^(2i+3) / r t
        pw = np.stack([th ** 3, th ** 5, th ** 7, th ** 9], -1)
        fac = np.where(small[:, None], 0.0, pw / rs[:, None])
        dk = t[:, :, None] * fac[:, None, :]
        return td, dt, dk

    def _forward(self, t, io):
        """Pixels of normalised coordinates t (steps 2-4), d/dt (n,2,2) and
        d/d io (n,2,p)."""
        td, dtd, dk = self._distort(t, io)
        f = io[:, 0:2]
        xy = f * td + io[:, 2:4]
        dt = dtd * f[:, :, None]
        dio = np.zeros((len(t), 2, self.n_params))
        dio[:, 0, 0] = td[:, 0]
        dio[:, 1, 1] = td[:, 1]
        dio[:, 0, 2] = 1.0
        dio[:, 1, 3] = 1.0
        dio[:, :, 4:8] = dk * f[:, :, None]
        return xy, dt, dio
