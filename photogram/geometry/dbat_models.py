"""DBAT's lens distortion models other than model 3 (which is ``brown``).

DBAT (niclasborlin/dbat, ``code/bundle/cameramodel/brown_euler_cam4.m``)
selects the image residual by its lens distortion model number
(docs/camera-models.md, section 4.5):

* model 3, ``res_euler_brown_1.m``: affinity, then the Brown correction:
  photogram's ``brown``;
* models 1 (the legacy ``multilensdist`` path) and 2
  (``res_euler_brown_0.m``): the Brown correction without affinity:
  ``brown`` with B1 = B2 = 0 held fixed (no class here);
* model 4, ``res_euler_brown_2.m``: the Brown correction, then the
  affinity: :class:`BrownAffineAfterModel` (``brown_affine_after``);
* model 5, ``res_euler_brown_3.m``: the aspect scales the measured x
  *before* the principal point is subtracted, the skew acts after the
  correction: :class:`BrownAspectFirstModel` (``brown_aspect_first``);
* model -1 (forward, "computer vision"): the Brown polynomial of the ideal
  point is *subtracted* from it to give the measured point:
  :class:`BrownForwardModel` (``brown_forward``).

All work in the y-up frame of DBAT (``w = (x - x0, -(y - y0))``) and take
DBAT's *reported* values (cc, px, py, K1-K3, P1-P2, as, sk; the report
flips the signs of py, K and P of DBAT's internal vector,
``bundle_result_file.m``) unchanged when the image unit is mm.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.geometry.brown import BrownModel, radial_not_monotonic
from photogram.geometry.camera import newton_invert, register_model
from photogram.geometry.forward_model import ForwardModel

__all__ = ["brown_polynomial", "BrownAffineAfterModel", "BrownAspectFirstModel",
           "BrownForwardModel", "aspect_first_to_brown", "brown_to_aspect_first"]


def brown_polynomial(u, v, K1, K2, K3, P1, P2):
    """Brown (1971) radial and decentring terms of (u, v), y up.

    ``r2 = u^2 + v^2``, ``k = K1 r2 + K2 r2^2 + K3 r2^3``,
    ``U = u + u k + P1 (r2 + 2 u^2) + 2 P2 u v``,
    ``V = v + v k + P2 (r2 + 2 v^2) + 2 P1 u v`` (DBAT's ``brown_dist.m``
    with the reported K and P).

    Returns
    -------
    U, V : (n,)
    jac : tuple (a, b, c, d)
        ``d(U, V)/d(u, v) = [[a, b], [c, d]]``.
    dK : list of three (gu, gv)
        ``d(U, V)/d K_i = (u r2^i, v r2^i)``.
    dP : list of two (gu, gv)
        ``d(U, V)/d P1 = (r2 + 2u^2, 2uv)``, ``d/d P2 = (2uv, r2 + 2v^2)``.
    """
    r2 = u * u + v * v
    k = r2 * (K1 + r2 * (K2 + r2 * K3))
    U = u + u * k + P1 * (r2 + 2 * u * u) + 2 * P2 * u * v
    V = v + v * k + P2 * (r2 + 2 * v * v) + 2 * P1 * u * v
    kp = K1 + r2 * (2.0 * K2 + 3.0 * r2 * K3)          # dk/d(r2)
    a = 1 + k + 2 * u * u * kp + 6 * P1 * u + 2 * P2 * v
    b = 2 * u * v * kp + 2 * P1 * v + 2 * P2 * u
    c = 2 * u * v * kp + 2 * P2 * u + 2 * P1 * v
    d = 1 + k + 2 * v * v * kp + 6 * P2 * v + 2 * P1 * u
    dK = [(u * r2, v * r2), (u * r2 ** 2, v * r2 ** 2), (u * r2 ** 3, v * r2 ** 3)]
    dP = [(r2 + 2 * u * u, 2 * u * v), (2 * u * v, r2 + 2 * v * v)]
    return U, V, (a, b, c, d), dK, dP


def _radial_monotonic(u, v, io, samples=33):
    """Reject spurious roots of the inversion (as ``BrownModel``): the
    radial correction ``r (1 + k(r^2))`` of the distortion input (u, v) must
    increase from the centre out to it."""
    bad = radial_not_monotonic(u * u + v * v, io, samples)
    if bad:
        raise GeometryError(
            f"{bad} of {len(u)} points project where the distortion "
            "correction is not invertible (radial correction not monotonic)",
            hint="the points are far outside the image format for these "
                 "distortion parameters")


def _io_partials(n, n_params, cols):
    """(n, 2, p) array with the columns ``{col: (gx, gy)}``."""
    dio = np.zeros((n, 2, n_params))
    for col, (gx, gy) in cols.items():
        dio[:, 0, col], dio[:, 1, col] = gx, gy
    return dio


@register_model
class BrownAffineAfterModel(BrownModel):
    """DBAT lens model 4 (``res_euler_brown_2.m``): Brown correction, then
    affinity and shear.

    With ``w = (u, v) = (x - x0, -(y - y0))`` (y up) and
    ``(U', V') = brown_polynomial(w)``, the corrected point is
    ``(U, V) = [[1 + B1, B2], [0, 1]] (U', V')``; collinearity as
    ``brown``: ``(U, -V) = (-c Xc_x / Xc_z, c Xc_y / Xc_z)``. The radial
    distance is that of the uncorrected, un-scaled w (in ``brown`` it is
    taken after the affinity). Parameters and units as ``brown``.
    """

    name = "brown_affine_after"

    def _core(self, xbar, ybar, io, partials=True):
        """Corrected (U, -V) of (xbar, ybar), its partials by (xbar, ybar)
        (n,2,2) and by io (n,2,p); see ``BrownModel._core``."""
        B1, B2 = io[:, 8], io[:, 9]
        u, v = xbar, -ybar
        Up, Vp, (a, b, c, d), dK, dP = brown_polynomial(u, v, *(io[:, i] for i in range(3, 8)))
        s = 1.0 + B1
        C = np.stack([s * Up + B2 * Vp, -Vp], -1)
        if not partials:
            return C, None, None
        dxy = np.empty((len(u), 2, 2))
        dxy[:, 0, 0] = s * a + B2 * c
        dxy[:, 0, 1] = -(s * b + B2 * d)
        dxy[:, 1, 0] = -c
        dxy[:, 1, 1] = d
        if partials == "xy":
            return C, dxy, None
        cols = {3 + i: (s * gu + B2 * gv, -gv) for i, (gu, gv) in enumerate(dK + dP)}
        cols[8] = (Up, 0.0)
        cols[9] = (Vp, 0.0)
        return C, dxy, _io_partials(len(u), self.n_params, cols)

    @staticmethod
    def _check_monotonic(zbar, io, samples=33):
        """The inversion's root check on the distortion input w."""
        _radial_monotonic(zbar[:, 0], -zbar[:, 1], io, samples)


@register_model
class BrownAspectFirstModel(BrownModel):
    """DBAT lens model 5 (``res_euler_brown_3.m``): aspect before the
    principal point, Brown correction, then shear.

    ``w = (u, v) = ((1 + B1) x - x0, -(y - y0))`` (DBAT's ``aniscale2b``
    then ``xlat2``), ``(U', V') = brown_polynomial(w)``, corrected point
    ``(U, V) = [[1, B2], [0, 1]] (U', V')`` (``skew.m``); collinearity as
    ``brown``. With B2 = 0 this is ``brown`` with ``x0_brown = x0 / (1 +
    B1)``: the same fit, x0 scaled (DBAT's px of model 5 is that of model 3
    times ``1 + as``). Parameters and units as ``brown``.

    ``_core`` takes ``xbar = x - x0`` like ``brown``'s, so that ``u = (1 +
    B1) xbar + B1 x0`` and its io partials are at fixed xbar (x0 column:
    ``B1 dC/du``).
    """

    name = "brown_aspect_first"

    def _core(self, xbar, ybar, io, partials=True):
        """Corrected (U, -V) of (xbar, ybar) = (x - x0, y - y0), its
        partials by (xbar, ybar) and by io at fixed (xbar, ybar)."""
        x0, B1, B2 = io[:, 1], io[:, 8], io[:, 9]
        s = 1.0 + B1
        u, v = s * xbar + B1 * x0, -ybar
        Up, Vp, (a, b, c, d), dK, dP = brown_polynomial(u, v, *(io[:, i] for i in range(3, 8)))
        C = np.stack([Up + B2 * Vp, -Vp], -1)
        if not partials:
            return C, None, None
        du = (a + B2 * c, -c)             # dC/du
        dv = (b + B2 * d, -d)             # dC/dv
        dxy = np.empty((len(u), 2, 2))
        dxy[:, 0, 0], dxy[:, 1, 0] = s * du[0], s * du[1]
        dxy[:, 0, 1], dxy[:, 1, 1] = -dv[0], -dv[1]
        if partials == "xy":
            return C, dxy, None
        cols = {3 + i: (gu + B2 * gv, -gv) for i, (gu, gv) in enumerate(dK + dP)}
        x = xbar + x0
        cols[1] = (B1 * du[0], B1 * du[1])
        cols[8] = (x * du[0], x * du[1])
        cols[9] = (Vp, 0.0)
        return C, dxy, _io_partials(len(u), self.n_params, cols)

    def _correct_full(self, xy, io):
        """Corrected coordinates of measured xy with the partials by xy and
        by io at fixed xy (x0 enters through xbar and directly)."""
        xy = np.asarray(xy, dtype=float)
        C, dxy, dio = self._core(xy[:, 0] - io[:, 1], xy[:, 1] - io[:, 2], io)
        dio[:, :, 1] -= dxy[:, :, 0]      # B1 dC/du - (1 + B1) dC/du = -dC/du
        dio[:, :, 2] = -dxy[:, :, 1]
        return C, dxy, dio

    @staticmethod
    def _check_monotonic(zbar, io, samples=33):
        """The inversion's root check on the distortion input w5."""
        u = (1.0 + io[:, 8]) * zbar[:, 0] + io[:, 8] * io[:, 1]
        _radial_monotonic(u, -zbar[:, 1], io, samples)


@register_model
class BrownForwardModel(ForwardModel):
    """DBAT lens model -1, "Forward (Computer Vision) model 1"
    (``brown_euler_cam4.m``, ``distModel == -1``: ``ptDist = xy + ld`` with
    ``ld = multilensdist(xy)``).

    With the ideal point ``(u, v) = (-c Xc_x / Xc_z, -c Xc_y / Xc_z)`` (y
    up, relative to the principal point) and ``(U', V') =
    brown_polynomial(u, v)`` (DBAT's reported K, P), the measured point is
    ``(u, v) - ((U', V') - (u, v))`` -- the correction polynomial of
    ``brown`` evaluated at the ideal point and subtracted (DBAT adds its
    internal distortion, whose K and P are the reported ones negated) --
    so ``x = x0 + 2u - U'``, ``y = y0 - (2v - V')``. No aspect or skew.
    The signs of K1..P2 are those of ``brown`` (equal to first order).

    ``parameter_names = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2")``.
    """

    name = "brown_forward"
    parameter_names = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2")
    parameter_dims = (1, 1, 1, -2, -4, -6, -1, -1)

    def default_parameters(self, principal_distance, image_size):
        """c = principal_distance, principal point at ``image_size / 2``,
        no distortion."""
        w, h = image_size
        p = np.zeros(self.n_params)
        p[:3] = principal_distance, w / 2.0, h / 2.0
        return p

    def distortion(self, xbar, ybar, io):
        """Displacement ``d = (x - x0, y - y0) - (xbar, ybar)`` (y down) of
        ideal coordinates (xbar, ybar) relative to the principal point.

        Returns
        -------
        d : (n, 2)
        partials : dict
            ``"xy"`` dd/d(xbar, ybar) (n,2,2), ``"io"`` (n,2,p) (zero for
            c, x0, y0).
        """
        xbar = np.atleast_1d(np.asarray(xbar, dtype=float))
        ybar = np.atleast_1d(np.asarray(ybar, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xbar), self.n_params))
        u, v = xbar, -ybar
        Up, Vp, (a, b, c, d), dK, dP = brown_polynomial(u, v, *(io[:, i] for i in range(3, 8)))
        disp = np.stack([u - Up, Vp - v], -1)          # (x, y) down minus (xbar, ybar)
        dxy = np.empty((len(u), 2, 2))
        dxy[:, 0, 0], dxy[:, 0, 1] = 1 - a, b
        dxy[:, 1, 0], dxy[:, 1, 1] = c, 1 - d
        cols = {3 + i: (-gu, gv) for i, (gu, gv) in enumerate(dK + dP)}
        return disp, {"xy": dxy, "io": _io_partials(len(u), self.n_params, cols)}

    def _forward(self, t, io):
        """Image coordinates of normalised ideal coordinates t (c = 1, y
        down) with d/dt (n,2,2) and d/d io (n,2,p)."""
        c = io[:, 0]
        ideal = c[:, None] * t
        disp, part = self.distortion(ideal[:, 0], ideal[:, 1], io)
        xy = io[:, 1:3] + ideal + disp
        dideal = part["xy"] + np.eye(2)                 # d xy / d ideal
        dt = dideal * c[:, None, None]
        dio = part["io"]
        dio[:, :, 0] = np.einsum("nij,nj->ni", dideal, t)
        dio[:, 0, 1] = 1.0
        dio[:, 1, 2] = 1.0
        return xy, dt, dio

    def image_to_ray(self, xy, io):
        """Normalised coordinates of image points (Newton's method on
        ``_forward``, converged to 1e-12 relative)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xy), self.n_params))
        start = (xy - io[:, 1:3]) / io[:, :1]

        def fun(t):
            value, dt, _ = self._forward(t, io)
            return value, dt

        return newton_invert(fun, xy, start, np.maximum(1.0, np.abs(start).max(axis=1)))


# --------------------------------------------------------------------------
# exact conversion model 5 <-> model 3 (no shear)
# --------------------------------------------------------------------------
def _rescale_x0(params, cov, source, factor_of):
    p = np.array(params, dtype=float)
    if p.shape != (10,):
        raise InputError(f"{source} parameters must be the 10 values c, x0, y0, K1, K2, K3, "
                         f"P1, P2, B1, B2, got shape {p.shape}")
    if p[9] != 0:
        raise InputError(f"{source} shear B2 = {p[9]:g} cannot be converted exactly",
                         hint="brown shears before the correction, brown_aspect_first "
                              "after it; refit the camera in the other model")
    f, df = factor_of(p[8])
    J = np.eye(10)
    J[1, 1], J[1, 8] = f, p[1] * df
    p[1] *= f
    if cov is None:
        return p
    return p, J @ np.asarray(cov, dtype=float) @ J.T


def aspect_first_to_brown(params, cov=None):
    """``brown_aspect_first`` (DBAT model 5) -> ``brown`` (model 3), exact
    for B2 = 0: ``x0_brown = x0 / (1 + B1)``, all else equal
    (``(1 + B1) x - x0 = (1 + B1)(x - x0_brown)``; docs/camera-models.md,
    section 4.5).

    Parameters
    ----------
    params : (10,) the model-5 parameters (any image unit).
    cov : (10, 10), optional
        Their covariance; propagated as ``J cov J^T``.

    Returns
    -------
    params : (10,), and the covariance if ``cov`` was given.

    Raises
    ------
    InputError
        If B2 is not zero (the shears act on different sides of the
        correction).
    """
    return _rescale_x0(params, cov, "brown_aspect_first",
                       lambda b1: (1.0 / (1.0 + b1), -1.0 / (1.0 + b1) ** 2))


def brown_to_aspect_first(params, cov=None):
    """``brown`` -> ``brown_aspect_first``, exact for B2 = 0:
    ``x0 = (1 + B1) x0_brown`` (the inverse of
    :func:`aspect_first_to_brown`)."""
    return _rescale_x0(params, cov, "brown", lambda b1: (1.0 + b1, 1.0))
