"""OpenCV's full distortion model: rational, thin prism and tilted sensor
(``cv2.projectPoints`` with the 14-coefficient distortion vector; COLMAP's
FULL_OPENCV is its first 12 with s = tau = 0).

Identical to ``cv2.projectPoints`` with the camera matrix
``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` and the distortion vector
``(k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tauX, tauY)`` under the
extrinsics convention of the ``opencv`` model (``R_cv = diag(1,-1,-1) R``,
``t_cv = -R_cv X0``; docs/camera-models.md, section 5.4). OpenCV's
``calib3d`` documentation ("Detailed Description") and
``modules/calib3d/src/calibration.cpp`` (``cvProjectPoints2Internal``):

1. normalised coordinates ``x' = X/Z``, ``y' = Y/Z`` in OpenCV's camera
   frame (the ideal projection with c = 1, as the ``opencv`` model);
2. ``r2 = x'^2 + y'^2``,
   ``g = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)``,
   ``x0 = x' g + 2 p1 x' y' + p2 (r2 + 2 x'^2) + s1 r2 + s2 r2^2``,
   ``y0 = y' g + p1 (r2 + 2 y'^2) + 2 p2 x' y' + s3 r2 + s4 r2^2``;
3. tilted sensor: ``v = H(tauX, tauY) (x0, y0, 1)``,
   ``(x'', y'') = (v_0 / v_2, v_1 / v_2)`` with
   ``H = [[M22, 0, -M02], [0, M22, -M12], [0, 0, 1]] M``,
   ``M = R_y(tauY) R_x(tauX)``,
   ``R_x(t) = [[1, 0, 0], [0, cos t, sin t], [0, -sin t, cos t]]``,
   ``R_y(t) = [[cos t, 0, -sin t], [0, 1, 0], [sin t, 0, cos t]]``
   (OpenCV's ``computeTiltProjectionMatrix``); ``H = I`` at tau = 0;
4. pixels ``x = fx x'' + cx``, ``y = fy y'' + cy``.

All Jacobians are analytic (tests: central differences, and
``cv2.projectPoints`` to 1e-9 px).
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.camera import register_model
from photogram.geometry.forward_model import ForwardModel

__all__ = ["OpenCVFullModel", "tilt_matrix"]


def _rot_x(t):
    """``R_x(t)`` (n,3,3) and its derivative."""
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    R = np.stack([np.stack([o, z, z], -1), np.stack([z, c, s], -1),
                  np.stack([z, -s, c], -1)], -2)
    dR = np.stack([np.stack([z, z, z], -1), np.stack([z, -s, c], -1),
                   np.stack([z, -c, -s], -1)], -2)
    return R, dR


def _rot_y(t):
    """``R_y(t)`` (n,3,3) and its derivative."""
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    R = np.stack([np.stack([c, z, -s], -1), np.stack([z, o, z], -1),
                  np.stack([s, z, c], -1)], -2)
    dR = np.stack([np.stack([-s, z, -c], -1), np.stack([z, z, z], -1),
                   np.stack([c, z, -s], -1)], -2)
    return R, dR


def _projz(M):
    """``[[M22, 0, -M02], [0, M22, -M12], [0, 0, 0]]`` of M (n,3,3): the
    part of OpenCV's ``matProjZ`` that is linear in M (its (2, 2) is 1)."""
    P = np.zeros_like(M)
    P[:, 0, 0] = P[:, 1, 1] = M[:, 2, 2]
    P[:, 0, 2] = -M[:, 0, 2]
    P[:, 1, 2] = -M[:, 1, 2]
    return P


def tilt_matrix(tau_x, tau_y):
    """OpenCV's tilted-sensor matrix ``H`` (n,3,3) and ``dH/dtauX``,
    ``dH/dtauY`` (``computeTiltProjectionMatrix`` of calib3d's
    ``distortion_model.hpp``: ``H = projZ(M) M``, ``M = R_y(tauY) R_x(tauX)``)."""
    tau_x = np.atleast_1d(np.asarray(tau_x, float))
    tau_y = np.atleast_1d(np.asarray(tau_y, float))
    Rx, dRx = _rot_x(tau_x)
    Ry, dRy = _rot_y(tau_y)
    M = Ry @ Rx
    P = _projz(M)
    P[:, 2, 2] = 1.0
    out = [P @ M]
    for dM in (Ry @ dRx, dRy @ Rx):
        out.append(_projz(dM) @ M + P @ dM)
    return tuple(out)


@register_model
class OpenCVFullModel(ForwardModel):
    """OpenCV's forward model with every distortion term of
    ``cv2.projectPoints``.

    ``parameter_names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2",
    "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tauX", "tauY")`` in
    OpenCV's order; fx fy cx cy in the image unit (px), the others
    dimensionless (tauX, tauY in radians).
    """

    name = "opencv_full"
    parameter_names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6",
                       "s1", "s2", "s3", "s4", "tauX", "tauY")
    parameter_dims = (1, 1, 1, 1) + (0,) * 14

    # ------------------------------------------------------------------
    def _undistorted_to_sensor(self, t, io):
        """Step 2: ``(x0, y0)`` of normalised t (n,2), d/dt (n,2,2) and
        d/d(k1..s4) (n,2,14) in the columns of io 4..17 (tau columns 0)."""
        x, y = t[:, 0], t[:, 1]
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = (io[:, i] for i in range(4, 16))
        r2 = x * x + y * y
        r4 = r2 * r2
        r6 = r4 * r2
        num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
        g = num / den
        dnum = k1 + r2 * (2 * k2 + 3 * r2 * k3)
        dden = k4 + r2 * (2 * k5 + 3 * r2 * k6)
        dg = (dnum * den - num * dden) / (den * den)          # dg/dr2
        sx = s1 + 2 * s2 * r2                                 # d(s1 r2 + s2 r4)/dr2
        sy = s3 + 2 * s4 * r2
        x0 = x * g + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
        y0 = y * g + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
        n = len(x)
        dt = np.empty((n, 2, 2))
        dt[:, 0, 0] = g + 2 * x * x * dg + 2 * p1 * y + 6 * p2 * x + 2 * x * sx
        dt[:, 0, 1] = 2 * x * y * dg + 2 * p1 * x + 2 * p2 * y + 2 * y * sx
        dt[:, 1, 0] = 2 * x * y * dg + 2 * p1 * x + 2 * p2 * y + 2 * x * sy
        dt[:, 1, 1] = g + 2 * y * y * dg + 6 * p1 * y + 2 * p2 * x + 2 * y * sy
        dp = np.zeros((n, 2, self.n_params))
        for col, power in ((4, r2), (5, r4), (8, r6)):          # k1, k2, k3
            dp[:, 0, col], dp[:, 1, col] = x * power / den, y * power / den
        for col, power in ((9, r2), (10, r4), (11, r6)):        # k4, k5, k6
            f = -num * power / (den * den)
            dp[:, 0, col], dp[:, 1, col] = x * f, y * f
        dp[:, 0, 6], dp[:, 1, 6] = 2 * x * y, r2 + 2 * y * y   # p1
        dp[:, 0, 7], dp[:, 1, 7] = r2 + 2 * x * x, 2 * x * y   # p2
        dp[:, 0, 12], dp[:, 0, 13] = r2, r4                     # s1, s2
        dp[:, 1, 14], dp[:, 1, 15] = r2, r4                     # s3, s4
        return np.stack([x0, y0], -1), dt, dp

    def _distort(self, t, io):
        """Steps 2-3: ``(x'', y'')``, d/dt (n,2,2), d/d io (n,2,p) (zero in
        the columns fx fy cx cy)."""
        s, ds_dt, dp = self._undistorted_to_sensor(t, io)
        # always through H (= I at tau = 0, exactly): d/dtau is not zero there
        H, dHx, dHy = tilt_matrix(io[:, 16], io[:, 17])
        sh = np.concatenate([s, np.ones((len(s), 1))], 1)
        v = np.einsum("nij,nj->ni", H, sh)
        iw = 1.0 / v[:, 2]
        td = v[:, :2] * iw[:, None]
        # d(v0/v2, v1/v2)/dv = [[1/v2, 0, -v0/v2^2], [0, 1/v2, -v1/v2^2]]
        Jv = np.zeros((len(s), 2, 3))
        Jv[:, 0, 0] = Jv[:, 1, 1] = iw
        Jv[:, :, 2] = -td * iw[:, None]
        Js = Jv @ H[:, :, :2]                                   # d td / d (x0, y0)
        dt = Js @ ds_dt
        dio = Js @ dp
        dio[:, :, 16] = np.einsum("nij,nj->ni", Jv @ dHx, sh)
        dio[:, :, 17] = np.einsum("nij,nj->ni", Jv @ dHy, sh)
        return td, dt, dio

    def distortion(self, xn, yn, io):
        """Displacement ``(x'', y'') - (x', y')`` of normalised coordinates
        (steps 2-3) and its partials (``"xy"`` (n,2,2), ``"io"`` (n,2,p))."""
        t = np.stack([np.atleast_1d(xn), np.atleast_1d(yn)], -1).astype(float)
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(t), self.n_params))
        td, dt, dio = self._distort(t, io)
        return td - t, {"xy": dt - np.eye(2), "io": dio}

    def _forward(self, t, io):
        """Pixels of normalised coordinates t (steps 2-4), d/dt (n,2,2) and
        d/d io (n,2,p)."""
        td, dtd, dio = self._distort(t, io)
        f = io[:, 0:2]
        xy = f * td + io[:, 2:4]
        dt = dtd * f[:, :, None]
        dio = dio * f[:, :, None]
        dio[:, 0, 0] = td[:, 0]
        dio[:, 1, 1] = td[:, 1]
        dio[:, 0, 2] = 1.0
        dio[:, 1, 3] = 1.0
        return xy, dt, dio
