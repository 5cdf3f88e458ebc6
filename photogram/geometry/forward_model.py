"""Forward (computer-vision) camera models: pixels = f(normalised ray).

A forward model maps the normalised coordinates of a ray (the ideal
projection with c = 1: ``x' = -Xc_x / Xc_z``, ``y' = Xc_y / Xc_z``, OpenCV's
``X/Z``, ``Y/Z``) to pixels by its own ``_forward(t, io) -> (xy, d xy/dt,
d xy/d io)``. Projection, residuals ``r = xy_obs - project(...)``, the
rotation-matrix path of the engine and the ray <-> image maps follow from
it, written once here for the ``opencv`` and ``opencv_fisheye`` models.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.camera import (CameraModel, ideal_projection, newton_invert,
                                       pose_jacobians, rotation_observations)

__all__ = ["ForwardModel"]


class ForwardModel(CameraModel):
    """Base of the models that define ``_forward(t, io)``."""

    def _forward(self, t, io):  # pragma: no cover - interface
        raise NotImplementedError

    def default_parameters(self, principal_distance, image_size):
        """fx = fy = principal_distance, (cx, cy) = image_size / 2, no
        distortion (the layout fx fy cx cy ... of the OpenCV models; a model
        with another layout overrides this)."""
        w, h = image_size
        p = np.zeros(self.n_params)
        p[:4] = principal_distance, principal_distance, w / 2.0, h / 2.0
        return p

    def project(self, X, angles, X0, io, jacobians=False):
        """Image coordinates (n, 2) [, Jacobian dict]."""
        X, angles, X0, io, Xc, R, d = self._prepare(X, angles, X0, io)
        t, J_xc, _ = ideal_projection(Xc, 1.0, jacobians=True)
        xy, dt, dio = self._forward(t, io)
        if not jacobians:
            return xy
        jac = pose_jacobians(dt @ J_xc, R, d, angles, Xc)
        jac["io"] = dio
        return xy, jac

    def residuals(self, xy_obs, X, angles, X0, io, jacobians=True):
        """Residual ``r = xy_obs - project(...)`` (n, 2) and, with
        ``jacobians=True``, its Jacobian dict (the negated projection one)."""
        n = np.atleast_2d(np.asarray(X)).shape[0]
        xy_obs = np.asarray(xy_obs, dtype=float).reshape(n, 2)
        if not jacobians:
            return xy_obs - self.project(X, angles, X0, io)
        xy, jac = self.project(X, angles, X0, io, jacobians=True)
        return xy_obs - xy, {key: -value for key, value in jac.items()}

    def residuals_rotation(self, xy_obs, X, R, X0, io, jacobians=True):
        """:meth:`residuals` with world-to-camera matrices R (n,3,3) instead
        of angles; the Jacobian dict has no ``"angles"``."""
        X, R, X0, io, Xc, d = rotation_observations(X, R, X0, io, self.n_params)
        xy_obs = np.asarray(xy_obs, dtype=float).reshape(len(X), 2)
        t, J_xc, _ = ideal_projection(Xc, 1.0, jacobians=True)
        xy, dt, dio = self._forward(t, io)
        if not jacobians:
            return xy_obs - xy
        jac = pose_jacobians(-(dt @ J_xc), R, d, None, Xc)
        jac["io"] = -dio
        return xy_obs - xy, jac

    def ray_to_image(self, t, io):
        """Pixels of normalised coordinates t (n,2) (closed form)."""
        t = np.atleast_2d(np.asarray(t, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(t), self.n_params))
        return self._forward(t, io)[0]

    def image_to_ray(self, xy, io):
        """Normalised coordinates of pixels (Newton's method on
        ``_forward``, converged to 1e-12: as ``cv2.undistortPoints`` or
        ``cv2.fisheye.undistortPoints``, but exact)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xy), self.n_params))
        start = (xy - io[:, 2:4]) / io[:, 0:2]

        def fun(t):
            value, dt, _ = self._forward(t, io)
            return value, dt

        return newton_invert(fun, xy, start, np.maximum(1.0, np.abs(start).max(axis=1)))
