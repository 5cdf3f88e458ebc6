"""The photogrammetric ("backward", correction) Brown model.

This is DBAT's lens distortion model 3 (``res_euler_brown_1.m``: K1-K3,
P1-P2, aspect and skew), which is also PhotoModeler's and, up to the affine
terms, Australis'. Measured coordinates are *corrected* to ideal ones; the
collinearity condition holds for the corrected coordinates
(docs/camera-models.md, "The brown model"):

1. relative to the principal point, y down:
   ``xbar = x - x0``, ``ybar = y - y0``
2. affinity and shear, in the y-up photogrammetric frame (u, v):
   ``u = (1 + B1) xbar - B2 ybar``, ``v = -ybar``
   (in y-up terms ``u = (1 + B1) xbar + B2 ybar_up``: DBAT's
   ``[1+as, sk; 0, 1]``)
3. Brown (1971) radial and decentring correction of (u, v):
   ``r2 = u^2 + v^2``, ``k = K1 r2 + K2 r2^2 + K3 r2^3``,
   ``U = u + u k + P1 (r2 + 2 u^2) + 2 P2 u v``,
   ``V = v + v k + P2 (r2 + 2 v^2) + 2 P1 u v``
4. collinearity (ski-jump paper, appendix A, eq. (A1), y down):
   ``(U, -V) = (-c Xc_x / Xc_z, c Xc_y / Xc_z)``.

The parameters are DBAT's reported values (cc, px, py, K1..K3, P1, P2, as,
sk) unchanged when the image unit is mm and the pixel size is DBAT's
nominal one; see :func:`photogram.geometry.rescale_parameters` for px.
The residual is ``r = (U, -V) - ideal``; DBAT's v is ``(-r_x, r_y)``.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError
from photogram.geometry.camera import (CameraModel, ideal_projection, newton_invert,
                                       pose_jacobians, register_model,
                                       rotation_observations, solve2)


def radial_not_monotonic(r2, io, samples=33) -> int:
    """How many rows have a radial slope ``1 + 3 K1 s + 5 K2 s^2 + 7 K3 s^3``
    (K = ``io[:, 3:6]``) that is not positive at one of ``samples`` points
    evenly spaced on [0, r2].

    Rows where ``3 |K1| r2 + 5 |K2| r2^2 + 7 |K3| r2^3 < 1/2`` have a slope
    above 1/2 on all of [0, r2] (far above rounding) and are not sampled:
    with realistic distortion that is every row, and the count is the one
    of sampling them all.
    """
    r2 = np.asarray(r2, dtype=float)
    K = np.abs(io[:, 3:6])
    with np.errstate(invalid="ignore", over="ignore"):   # such rows are sampled below
        bound = r2 * (3 * K[:, 0] + r2 * (5 * K[:, 1] + 7 * r2 * K[:, 2]))
    rows = np.flatnonzero(~(bound < 0.5))          # NaN rows are sampled too
    if not len(rows):
        return 0
    s = r2[rows, None] * np.linspace(0.0, 1.0, samples)
    K1, K2, K3 = io[rows, 3:4], io[rows, 4:5], io[rows, 5:6]
    slope = 1 + s * (3 * K1 + s * (5 * K2 + 7 * s * K3))
    return int(np.count_nonzero(np.any(slope <= 0, axis=1)))


@register_model
class BrownModel(CameraModel):
    """Backward (correction) Brown model with affinity and shear.

    ``parameter_names = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2",
    "B1", "B2")``; all lengths in the image unit (px or mm).
    """

    name = "brown"
    parameter_names = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2")
    parameter_dims = (1, 1, 1, -2, -4, -6, -1, -1, 0, 0)

    def default_parameters(self, principal_distance, image_size):
        """c = principal_distance, principal point at the format centre
        ``image_size / 2``, no distortion. Same unit as image_size."""
        w, h = image_size
        p = np.zeros(self.n_params)
        p[:3] = principal_distance, w / 2.0, h / 2.0
        return p

    # ------------------------------------------------------------------
    # correction (closed form)
    # ------------------------------------------------------------------
    def _core(self, xbar, ybar, io, partials=True):
        """Corrected coordinates C = (U, -V) of (xbar, ybar) (steps 2-3)
        with dC/d(xbar, ybar) (n,2,2) and dC/d io (n,2,p) (c, x0, y0 zero);
        with ``partials=False`` only C (and None, None), with ``"xy"`` C and
        dC/d(xbar, ybar) (and None)."""
        n = len(xbar)
        K1, K2, K3, P1, P2, B1, B2 = (io[:, i] for i in range(3, 10))
        u = (1.0 + B1) * xbar - B2 * ybar
        v = -ybar
        r2 = u * u + v * v
        k = r2 * (K1 + r2 * (K2 + r2 * K3))
        U = u + u * k + P1 * (r2 + 2 * u * u) + 2 * P2 * u * v
        V = v + v * k + P2 * (r2 + 2 * v * v) + 2 * P1 * u * v
        if not partials:
            return np.stack([U, -V], -1), None, None
        kp = K1 + r2 * (2.0 * K2 + 3.0 * r2 * K3)          # dk/d(r2)
        # d(U, V)/d(u, v)
        a = 1 + k + 2 * u * u * kp + 6 * P1 * u + 2 * P2 * v
        b = 2 * u * v * kp + 2 * P1 * v + 2 * P2 * u
        c = 2 * u * v * kp + 2 * P2 * u + 2 * P1 * v
        d = 1 + k + 2 * v * v * kp + 6 * P2 * v + 2 * P1 * u
        # d(U,-V)/d(u,v) = [[a, b], [-c, -d]] times d(u,v)/d(xbar,ybar) =
        # [[1 + B1, -B2], [0, -1]], written out
        dxy = np.empty((n, 2, 2))
        dxy[:, 0, 0] = a * (1.0 + B1)
        dxy[:, 0, 1] = a * -B2 - b
        dxy[:, 1, 0] = -c * (1.0 + B1)
        dxy[:, 1, 1] = -c * -B2 + d
        if partials == "xy":
            return np.stack([U, -V], -1), dxy, None
        dio = np.zeros((n, 2, self.n_params))
        for col, (gu, gv) in zip((3, 4, 5), ((u * r2, v * r2), (u * r2 ** 2, v * r2 ** 2),
                                             (u * r2 ** 3, v * r2 ** 3))):
            dio[:, 0, col], dio[:, 1, col] = gu, -gv
        dio[:, 0, 6], dio[:, 1, 6] = r2 + 2 * u * u, -2 * u * v
        dio[:, 0, 7], dio[:, 1, 7] = 2 * u * v, -(r2 + 2 * v * v)
        dio[:, 0, 8], dio[:, 1, 8] = a * xbar, -c * xbar
        dio[:, 0, 9], dio[:, 1, 9] = a * -ybar, -c * -ybar
        return np.stack([U, -V], -1), dxy, dio

    def _correct_full(self, xy, io):
        xy = np.asarray(xy, dtype=float)
        C, dxy, dio = self._core(xy[:, 0] - io[:, 1], xy[:, 1] - io[:, 2], io)
        dio[:, :, 1] = -dxy[:, :, 0]
        dio[:, :, 2] = -dxy[:, :, 1]
        return C, dxy, dio

    def correct(self, xy_obs, io, jacobians=False):
        """Undistort measured coordinates (closed form, steps 1-3).

        Returns the corrected coordinates relative to the principal point,
        y down, which satisfy ``(-c Xc_x/Xc_z, c Xc_y/Xc_z)``; with
        ``jacobians=True`` also ``{"xy": (n,2,2), "io": (n,2,p)}``, with
        ``jacobians="xy"`` only ``{"xy": (n,2,2)}``.
        """
        xy_obs = np.atleast_2d(np.asarray(xy_obs, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xy_obs), self.n_params))
        if jacobians == "xy":
            C, dxy, _ = self._core(xy_obs[:, 0] - io[:, 1], xy_obs[:, 1] - io[:, 2], io,
                                   partials="xy")
            return C, {"xy": dxy}
        if not jacobians:               # the same C, without the (n, 2, p) partials
            return self._core(xy_obs[:, 0] - io[:, 1], xy_obs[:, 1] - io[:, 2], io,
                              partials=False)[0]
        C, dxy, dio = self._correct_full(xy_obs, io)
        return (C, {"xy": dxy, "io": dio}) if jacobians else C

    def distortion(self, xbar, ybar, io):
        """Correction terms ``d = C - (xbar, ybar)`` (affinity, shear, radial,
        decentring; y down) of coordinates relative to the principal point.

        Returns
        -------
        d : (n, 2)
        partials : dict
            ``"xy"`` d d / d(xbar, ybar) (n,2,2); ``"io"`` (n,2,p) (zero for
            c, x0, y0, which do not enter).
        """
        xbar = np.atleast_1d(np.asarray(xbar, dtype=float))
        ybar = np.atleast_1d(np.asarray(ybar, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xbar), self.n_params))
        C, dxy, dio = self._core(xbar, ybar, io)
        return C - np.stack([xbar, ybar], -1), {"xy": dxy - np.eye(2), "io": dio}

    # ------------------------------------------------------------------
    # residuals (DBAT's formulation) and forward projection (inverse)
    # ------------------------------------------------------------------
    def residuals(self, xy_obs, X, angles, X0, io, jacobians=True):
        """Residual ``r = correct(xy_obs) - ideal`` (n, 2), image axes.

        This is DBAT's ``res_euler_brown_1`` residual v with ``r = (-v_x,
        v_y)`` (same sum of squares). With ``jacobians=True`` returns
        ``(r, jac)`` with the keys of the module docstring of camera.py.
        """
        X, angles, X0, io, Xc, R, d = self._prepare(X, angles, X0, io)
        return self._residuals(xy_obs, X, angles, io, Xc, R, d, jacobians)

    def residuals_rotation(self, xy_obs, X, R, X0, io, jacobians=True, correction=None,
                           stations=True):
        """:meth:`residuals` with world-to-camera matrices R (n,3,3) instead
        of angles; the Jacobian dict has no ``"angles"``. ``correction``:
        the :meth:`correction_terms` of ``(xy_obs, io)`` if already known
        (they depend on the observations and the interior orientation only:
        the engine keeps them while both stay the same). ``stations=False``:
        no Jacobians by X0 and the rotation (None; the stations are fixed)."""
        X, R, X0, io, Xc, d = rotation_observations(X, R, X0, io, self.n_params)
        return self._residuals(xy_obs, X, None, io, Xc, R, d, jacobians, correction, stations)

    def correction_terms(self, xy_obs, io, io_jacobian=True):
        """``(C, dC/dio)`` of measured coordinates (n, 2) and per-row io
        (``dC/dio`` None without ``io_jacobian``: the residuals then have no
        ``"io"`` Jacobian, for a fixed interior orientation)."""
        xy_obs = np.asarray(xy_obs, dtype=float)
        if not io_jacobian:
            C, _, _ = self._core(xy_obs[:, 0] - io[:, 1], xy_obs[:, 1] - io[:, 2], io,
                                 partials=False)
            return C, None
        C, _, dC_dio = self._correct_full(xy_obs, io)
        return C, dC_dio

    def _residuals(self, xy_obs, X, angles, io, Xc, R, d, jacobians, correction=None,
                   stations=True):
        xy_obs = np.asarray(xy_obs, dtype=float).reshape(len(X), 2)
        if not jacobians:
            if correction is not None:
                return correction[0] - ideal_projection(Xc, io[:, 0])
            C, _, _ = self._core(xy_obs[:, 0] - io[:, 1], xy_obs[:, 1] - io[:, 2], io,
                                 partials=False)
            return C - ideal_projection(Xc, io[:, 0])
        if correction is not None:
            C, dC_dio = correction[0], correction[1]
            dC_dio = None if dC_dio is None else dC_dio.copy()
        else:
            C, _, dC_dio = self._correct_full(xy_obs, io)
        ideal, J_xc, J_c = ideal_projection(Xc, io[:, 0], jacobians=True)
        jac = pose_jacobians(-J_xc, R, d, angles, Xc, stations=stations)
        if dC_dio is not None:
            dC_dio[:, :, 0] -= J_c
        jac["io"] = dC_dio
        return C - ideal, jac

    def project(self, X, angles, X0, io, jacobians=False):
        """Forward projection into measured coordinates by inverting the
        correction with Newton's method (relative tolerance 1e-12).

        Jacobians by the implicit function theorem: with ``C(xy) = ideal``,
        ``dxy/dtheta = (dC/dxy)^-1 (d ideal/dtheta - dC/dtheta)``.

        Raises
        ------
        GeometryError
            If the inversion does not converge for some point.
        """
        X, angles, X0, io, Xc, R, d = self._prepare(X, angles, X0, io)
        ideal, J_xc, J_c = ideal_projection(Xc, io[:, 0], jacobians=True)
        xy = self._invert(ideal, io)
        if not jacobians:
            return xy
        _, dC_dxy, dC_dio = self._correct_full(xy, io)
        jac = pose_jacobians(solve2(dC_dxy, J_xc), R, d, angles, Xc)
        rhs = -dC_dio
        rhs[:, :, 0] += J_c
        jac["io"] = solve2(dC_dxy, rhs)
        return xy, jac

    def _invert(self, ideal, io):
        """Measured xy whose correction equals ``ideal`` (Newton)."""
        pp = io[:, 1:3]

        def fun(z):
            C, dxy, _ = self._core(z[:, 0], z[:, 1], io)
            return C, dxy

        scale = np.maximum(np.abs(io[:, 0]), np.abs(ideal).max(axis=1))
        zbar = newton_invert(fun, ideal, ideal, scale)
        self._check_monotonic(zbar, io)
        return zbar + pp

    @staticmethod
    def _check_monotonic(zbar, io, samples=33):
        """Reject spurious roots: the radial correction ``r (1 + k(r^2))``
        must increase from the centre out to the solution, i.e.
        ``1 + 3 K1 s + 5 K2 s^2 + 7 K3 s^3 > 0`` on [0, r^2]."""
        u = (1.0 + io[:, 8]) * zbar[:, 0] - io[:, 9] * zbar[:, 1]
        bad = radial_not_monotonic(u * u + zbar[:, 1] ** 2, io, samples)
        if bad:
            raise GeometryError(
                f"{bad} of {len(zbar)} points project where the distortion "
                "correction is not invertible (radial correction not monotonic)",
                hint="the points are far outside the image format for these "
                     "distortion parameters")

    # ------------------------------------------------------------------
    # rays (used by the conversions)
    # ------------------------------------------------------------------
    def image_to_ray(self, xy, io):
        """Normalised ideal coordinates ``correct(xy) / c`` (n,2), y down."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xy), self.n_params))
        return self.correct(xy, io) / io[:, :1]

    def ray_to_image(self, t, io):
        """Measured coordinates of normalised ideal coordinates t (n,2)."""
        t = np.atleast_2d(np.asarray(t, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(t), self.n_params))
        return self._invert(io[:, :1] * t, io)
