"""The camera model of Bundle Adjustment in the Large (BAL; Agarwal et al.
2010; Ceres' ``SnavelyReprojectionError``): a pinhole with its principal
point at the image centre and two radial terms, one (f, k1, k2) per camera.

In photogram's conventions (docs/camera-models.md; camera looks along -z,
image y down, origin at the image centre):

1. normalised coordinates ``t = (-Xc_x / Xc_z, Xc_y / Xc_z)`` (the ideal
   projection with c = 1);
2. ``r2 = |t|^2``, ``d = 1 + k1 r2 + k2 r2^2``;
3. ``xy = f d t``.

BAL itself writes ``p = -P / P_z`` with ``P = R X + t`` and y **up**: with
``R_bal = R``, ``t_bal = -R X0`` and ``(x, y)_bal = (x, -y)`` it is the same
projection (:mod:`photogram.bundle.bal` converts). The residual is
``r = xy_obs - xy`` (Ceres' is ``xy - xy_obs``; same cost).

Parameters: ``f`` (image unit), ``k1``, ``k2`` (dimensionless, the
normalised radius is).
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.camera import (CameraModel, ideal_projection, newton_invert,
                                       pose_jacobians, register_model,
                                       rotation_observations)


@register_model
class BALModel(CameraModel):
    """BAL / Snavely camera: ``xy = f (1 + k1 r2 + k2 r2^2) t``."""

    name = "bal"
    parameter_names = ("f", "k1", "k2")
    parameter_dims = (1, 0, 0)
    #: the engine's compiled twin of :func:`_bal_rows`
    #: (photogram.adjust._numba_kernels), passed to :meth:`residuals_indexed`
    row_kernel = "bal_rows"

    def default_parameters(self, principal_distance, image_size=None):
        """f = principal_distance, no distortion (the principal point is the
        origin of the image coordinates, not a parameter)."""
        return np.array([float(principal_distance), 0.0, 0.0])

    # ------------------------------------------------------------------
    def distortion(self, tx, ty, io):
        """Radial displacement ``(d - 1) t`` of normalised coordinates and
        its partials ``"xy"`` (n,2,2) and ``"io"`` (n,2,3) (f column zero)."""
        tx = np.atleast_1d(np.asarray(tx, dtype=float))
        ty = np.atleast_1d(np.asarray(ty, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(tx), self.n_params))
        t = np.stack([tx, ty], -1)
        r2 = tx * tx + ty * ty
        k1, k2 = io[:, 1], io[:, 2]
        dm1 = r2 * (k1 + k2 * r2)
        dp = k1 + 2 * k2 * r2                              # d(d)/d(r2)
        dxy = 2 * dp[:, None, None] * t[:, :, None] * t[:, None, :]
        dxy += dm1[:, None, None] * np.eye(2)
        dio = np.zeros((len(tx), 2, 3))
        dio[:, :, 1] = r2[:, None] * t
        dio[:, :, 2] = (r2 * r2)[:, None] * t
        return dm1[:, None] * t, {"xy": dxy, "io": dio}

    def _forward(self, t, io):
        """Image coordinates of normalised t (n,2) with d/dt (n,2,2) and
        d/d io (n,2,3)."""
        f, k1, k2 = io[:, 0], io[:, 1], io[:, 2]
        r2 = np.einsum("ni,ni->n", t, t)
        d = 1.0 + r2 * (k1 + k2 * r2)
        dp = k1 + 2.0 * k2 * r2
        xy = (f * d)[:, None] * t
        dt = (2.0 * f * dp)[:, None, None] * t[:, :, None] * t[:, None, :]
        dt[:, 0, 0] += f * d
        dt[:, 1, 1] += f * d
        dio = np.empty((len(t), 2, 3))
        dio[:, :, 0] = d[:, None] * t
        dio[:, :, 1] = (f * r2)[:, None] * t
        dio[:, :, 2] = (f * r2 * r2)[:, None] * t
        return xy, dt, dio

    def project(self, X, angles, X0, io, jacobians=False):
        """Image coordinates (n, 2) [, Jacobian dict]."""
        X, angles, X0, io, Xc, R, d = self._prepare(X, angles, X0, io)
        return self._project(Xc, R, d, angles, io, jacobians)

    def _project(self, Xc, R, d, angles, io, jacobians):
        t, J_xc, _ = ideal_projection(Xc, 1.0, jacobians=True)
        xy, dt, dio = self._forward(t, io)
        if not jacobians:
            return xy
        jac = pose_jacobians(dt @ J_xc, R, d, angles, Xc)
        jac["io"] = dio
        return xy, jac

    def residuals(self, xy_obs, X, angles, X0, io, jacobians=True):
        """Residual ``r = xy_obs - project(...)`` (n, 2) [, Jacobian dict]."""
        X, angles, X0, io, Xc, R, d = self._prepare(X, angles, X0, io)
        return self._residuals(xy_obs, Xc, R, d, angles, io, jacobians)

    def residuals_rotation(self, xy_obs, X, R, X0, io, jacobians=True):
        """:meth:`residuals` with world-to-camera matrices R (n,3,3)."""
        X, R, X0, io, Xc, d = rotation_observations(X, R, X0, io, self.n_params)
        return self._residuals(xy_obs, Xc, R, d, None, io, jacobians)

    def _residuals(self, xy_obs, Xc, R, d, angles, io, jacobians):
        xy_obs = np.asarray(xy_obs, dtype=float).reshape(len(Xc), 2)
        if not jacobians:
            return xy_obs - self._project(Xc, R, d, angles, io, False)
        xy, jac = self._project(Xc, R, d, angles, io, True)
        return xy_obs - xy, {key: -value for key, value in jac.items()}

    def residuals_indexed(self, xy_obs, points, R, X0, io, point, station, camera,
                          jacobians=True, kernel=None):
        """Residuals of observations given by indices into the state
        (``points[point]``, ``R[station]``, ``X0[station]``, ``io[camera]``):
        ``(r, [J_X, J_station (X0 and rotation increment, n x 2 x 6), J_io])``
        (``(r, None)`` without Jacobians). The engine's fast path:
        component-wise numpy, or ``kernel``, a compiled function with the
        signature of :func:`_bal_rows` that the engine passes for large
        problems (its numba ``bal_rows``, named by :attr:`row_kernel`; the
        camera model does not choose or know the solver's kernels); same
        values as :meth:`residuals_rotation`."""
        n = len(point)
        r = np.empty((n, 2))
        if jacobians:
            JX, JS, JI = np.empty((n, 2, 3)), np.empty((n, 2, 6)), np.empty((n, 2, 3))
        else:
            JX = JS = JI = np.empty((0, 2, 6))
        if kernel is not None:
            kernel(xy_obs, points, R, X0, io, point, station, camera,
                   r, JX, JS, JI, bool(jacobians))
        else:
            _bal_rows(xy_obs, points, R, X0, io, point, station, camera, r, JX, JS, JI, jacobians)
        return (r, [JX, JS, JI]) if jacobians else (r, None)

    # ------------------------------------------------------------------
    def ray_to_image(self, t, io):
        """Image coordinates of normalised coordinates t (n,2)."""
        t = np.atleast_2d(np.asarray(t, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(t), self.n_params))
        return self._forward(t, io)[0]

    def image_to_ray(self, xy, io):
        """Normalised coordinates of image points (Newton's method)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xy), self.n_params))
        start = xy / io[:, :1]

        def fun(t):
            value, dt, _ = self._forward(t, io)
            return value, dt

        return newton_invert(fun, xy, start, np.maximum(1.0, np.abs(start).max(axis=1)))


def _bal_rows(xy, points, R, X0, io, point, station, camera, r, JX, JS, JI, jac):
    """numpy version of the compiled ``bal_rows`` kernel: the same formulas
    on component arrays (numpy's matmul of 10^5 stacked 2x3 matrices is
    slower than a few element-wise products)."""
    d = points[point] - X0[station]
    Rs = R[station]
    x0, x1, x2 = np.einsum("nij,nj->in", Rs, d)
    iz = 1.0 / x2
    tx, ty = -x0 * iz, x1 * iz
    f, k1, k2 = io[camera].T
    r2 = tx * tx + ty * ty
    dd = 1.0 + r2 * (k1 + k2 * r2)
    fd = f * dd
    r[:, 0] = xy[:, 0] - fd * tx
    r[:, 1] = xy[:, 1] - fd * ty
    if not jac:
        return
    dp2 = 2.0 * (k1 + 2.0 * k2 * r2)
    m00 = f * (dd + dp2 * tx * tx)
    m01 = f * dp2 * tx * ty
    m11 = f * (dd + dp2 * ty * ty)
    # residual Jacobian wrt Xc, rows (j00 j01 j02), (j10 j11 j12)
    j00, j01, j02 = m00 * iz, -m01 * iz, (m00 * tx + m01 * ty) * iz
    j10, j11, j12 = m01 * iz, -m11 * iz, (m01 * tx + m11 * ty) * iz
    for i in range(3):
        a = j00 * Rs[:, 0, i] + j01 * Rs[:, 1, i] + j02 * Rs[:, 2, i]
        b = j10 * Rs[:, 0, i] + j11 * Rs[:, 1, i] + j12 * Rs[:, 2, i]
        JX[:, 0, i] = a
        JX[:, 1, i] = b
        JS[:, 0, i] = -a
        JS[:, 1, i] = -b
    # rotation increment: row i is Xc x J_i
    JS[:, 0, 3] = x1 * j02 - x2 * j01
    JS[:, 0, 4] = x2 * j00 - x0 * j02
    JS[:, 0, 5] = x0 * j01 - x1 * j00
    JS[:, 1, 3] = x1 * j12 - x2 * j11
    JS[:, 1, 4] = x2 * j10 - x0 * j12
    JS[:, 1, 5] = x0 * j11 - x1 * j10
    JI[:, 0, 0] = -dd * tx
    JI[:, 1, 0] = -dd * ty
    fr2 = f * r2
    JI[:, 0, 1] = -fr2 * tx
    JI[:, 1, 1] = -fr2 * ty
    JI[:, 0, 2] = -fr2 * r2 * tx
    JI[:, 1, 2] = -fr2 * r2 * ty
