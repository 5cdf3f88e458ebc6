"""The OpenCV ("forward", computer-vision) camera model.

Identical to ``cv2.projectPoints`` with the camera matrix
``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` and distortion coefficients
``(k1, k2, p1, p2, k3)`` when the OpenCV extrinsics are
``R_cv = diag(1,-1,-1) R``, ``t_cv = -R_cv X0`` (docs/camera-models.md,
"The opencv model"):

1. normalised coordinates (y down) -- the OpenCV ``x' = X/Z``, ``y' = Y/Z``
   in its own camera frame, which equal the ideal projection with c = 1:
   ``x' = -Xc_x / Xc_z``, ``y' = Xc_y / Xc_z`` (ski-jump paper, appendix A,
   eq. (A1) with c = 1);
2. distortion (Brown-Conrady, forward):
   ``r2 = x'^2 + y'^2``, ``k = 1 + k1 r2 + k2 r2^2 + k3 r2^3``,
   ``x'' = x' k + 2 p1 x' y' + p2 (r2 + 2 x'^2)``,
   ``y'' = y' k + p1 (r2 + 2 y'^2) + 2 p2 x' y'``;
3. pixels: ``x = fx x'' + cx``, ``y = fy y'' + cy``.

The residual is ``r = xy_obs - project(...)``.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.camera import register_model
from photogram.geometry.forward_model import ForwardModel


@register_model
class OpenCVModel(ForwardModel):
    """Forward Brown-Conrady model of OpenCV.

    ``parameter_names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2",
    "k3")``; fx, fy, cx, cy in the image unit (px), k and p dimensionless.
    """

    name = "opencv"
    parameter_names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    parameter_dims = (1, 1, 1, 1, 0, 0, 0, 0, 0)

    # ------------------------------------------------------------------
    def distortion(self, xn, yn, io):
        """Distortion displacement ``d = (x'', y'') - (x', y')`` of normalised
        coordinates (step 2).

        Returns
        -------
        d : (n, 2)
        partials : dict
            ``"xy"`` dd/d(x', y') (n,2,2), ``"io"`` dd/d io (n,2,p) (zero for
            fx, fy, cx, cy).
        """
        xn = np.atleast_1d(np.asarray(xn, dtype=float))
        yn = np.atleast_1d(np.asarray(yn, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xn), self.n_params))
        k1, k2, p1, p2, k3 = (io[:, i] for i in range(4, 9))
        r2 = xn * xn + yn * yn
        k = r2 * (k1 + r2 * (k2 + r2 * k3))
        kp = k1 + r2 * (2 * k2 + 3 * r2 * k3)
        dx = xn * k + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
        dy = yn * k + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
        n = len(xn)
        dxy = np.empty((n, 2, 2))
        dxy[:, 0, 0] = k + 2 * xn * xn * kp + 2 * p1 * yn + 6 * p2 * xn
        dxy[:, 0, 1] = 2 * xn * yn * kp + 2 * p1 * xn + 2 * p2 * yn
        dxy[:, 1, 0] = 2 * xn * yn * kp + 2 * p1 * xn + 2 * p2 * yn
        dxy[:, 1, 1] = k + 2 * yn * yn * kp + 6 * p1 * yn + 2 * p2 * xn
        dio = np.zeros((n, 2, self.n_params))
        dio[:, 0, 4], dio[:, 1, 4] = xn * r2, yn * r2
        dio[:, 0, 5], dio[:, 1, 5] = xn * r2 ** 2, yn * r2 ** 2
        dio[:, 0, 8], dio[:, 1, 8] = xn * r2 ** 3, yn * r2 ** 3
        dio[:, 0, 6], dio[:, 1, 6] = 2 * xn * yn, r2 + 2 * yn * yn
        dio[:, 0, 7], dio[:, 1, 7] = r2 + 2 * xn * xn, 2 * xn * yn
        return np.stack([dx, dy], -1), {"xy": dxy, "io": dio}

    def _forward(self, t, io):
        """Pixels of normalised coordinates t (steps 2-3) with d/dt (n,2,2)
        and d/d io (n,2,p)."""
        d, part = self.distortion(t[:, 0], t[:, 1], io)
        td = t + d
        f = io[:, 0:2]
        xy = f * td + io[:, 2:4]
        dt = (part["xy"] + np.eye(2)) * f[:, :, None]
        dio = part["io"] * f[:, :, None]
        dio[:, 0, 0] = td[:, 0]
        dio[:, 1, 1] = td[:, 1]
        dio[:, 0, 2] = 1.0
        dio[:, 1, 3] = 1.0
        return xy, dt, dio
