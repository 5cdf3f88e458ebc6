"""The two-bar model of the skis of one image (eqs. (1), (2) of
:mod:`photogram.track.ski_edges`) and its analytic Jacobian, both bars in
one array pass: the parameter layout, the per-pixel terms, the model, the
Jacobian and the residuals the solver asks for."""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr

# parameters: per ski (4 each) the angle (rad, from the reference
# direction), the shift along the reference normal (px, at the reference
# point) and the ends a, b (px along); shared by both skis (same skis at
# about the same distance) the width (px), the grey and the blur (px)
_PER_SKI = 4
_W, _G, _BLUR = 8, 9, 10


# |z| beyond which ndtr(z) is 0 or 1 to double precision (ndtr(-8.3) = 5e-17,
# exp(-8.3^2 / 2) = 1e-15); scipy's ndtr is slowest there (its erfc branch)
_Z_SATURATED = 8.3
_INV_SQRT_2PI = 1.0 / np.sqrt(2.0 * np.pi)


class _PairTerms:
    """Eqs. (1), (2) for both bars in one pass at a parameter vector
    ``theta``, with what the Jacobian (:func:`_pair_jacobian`) reuses.

    One (8, 3) @ (3, n) product gives the standardised edge distances ``Z``
    (per bar ``(d + w/2)/s, (d - w/2)/s, (t - a)/s, (t - b)/s``), one
    ``ndtr`` call their normal CDFs; ``A`` (2, n), ``B`` (2, n) the across
    and along factors of eq. (1) of both bars, ``C = A B`` their coverages
    and ``union = C_1 + C_2 - C_1 C_2`` the bracket of eq. (2). ``X3`` is
    (3, n): the pixel centres x, y and ones. ``dd_dc``, ``dt_dc`` (2,) the
    derivatives of ``d_k``, ``t_k`` by the shift (``-n0 . n_k``,
    ``-n0 . u_k``)."""

    __slots__ = ("theta", "Z", "live", "z_live", "A", "B", "C", "union", "dd_dc", "dt_dc",
                 "a")

    def __init__(self, theta, X3, ref, u0):
        theta = np.array(theta, dtype=float)
        p = theta.tolist()
        w, s = p[_W], p[_BLUR]
        u0x, u0y = float(u0[0]), float(u0[1])
        rx, ry = float(ref[0]), float(ref[1])
        M = []
        dd_dc, dt_dc = [], []
        for k in (0, 1):
            ang, c, a, b = p[_PER_SKI * k:_PER_SKI * (k + 1)]
            ca, sa = math.cos(ang), math.sin(ang)
            ux, uy = u0x * ca - u0y * sa, u0x * sa + u0y * ca     # u = R(ang) u0
            px, py = rx - c * u0y, ry + c * u0x                    # p = ref + c n0
            pn, pu = ux * py - uy * px, ux * px + uy * py          # p . n, p . u
            M += [(-uy, ux, w / 2 - pn), (-uy, ux, -w / 2 - pn),
                  (ux, uy, -a - pu), (ux, uy, -b - pu)]
            dd_dc.append(-(u0x * ux + u0y * uy))
            dt_dc.append(u0y * ux - u0x * uy)
        self.theta = theta
        self.Z = Z = (np.array(M) * (1.0 / s)) @ X3
        # Phi(Z) is 0 or 1 to double precision beyond |Z| = 8.3 (most of the
        # along-the-bar arguments); ndtr only for the others ("live")
        z = Z.ravel()
        self.live = np.flatnonzero(np.abs(z) < _Z_SATURATED)
        self.z_live = z[self.live]
        P = (z > 0).astype(float)
        P[self.live] = ndtr(self.z_live)
        P = P.reshape(2, 2, 2, -1)
        AB = P[:, :, 0] - P[:, :, 1]
        self.A, self.B = AB[:, 0], AB[:, 1]
        self.C = self.A * self.B
        self.union = self.C[0] + self.C[1] - self.C[0] * self.C[1]
        self.dd_dc = np.array(dd_dc)[:, None]
        self.dt_dc = np.array(dt_dc)[:, None]
        self.a = np.array([[p[2]], [p[6]]])


def _pair_jacobian(T, bg):
    """Analytic Jacobian (11, n), transposed, of the model eq. (2)
    ``(bg - G) union`` at the terms ``T`` (:class:`_PairTerms`).

    With ``u = R(angle) u0``, ``n = perp(u)``, ``p = ref + c n0``, the
    distances ``d = (x - p) . n`` and ``t = (x - p) . u`` of eq. (1) have
    ``dd/dangle = -t``, ``dt/dangle = d``, ``dd/dc = -n0 . n``,
    ``dt/dc = -n0 . u``; the coverage is ``A(d) B(t)`` with
    ``A = Phi(z_1) - Phi(z_2)``, ``B = Phi(z_a) - Phi(z_b)`` (Phi the normal
    CDF, phi its density), so ``dA/dd = (phi(z_1) - phi(z_2)) / s``,
    ``dA/dw = (phi(z_1) + phi(z_2)) / 2s``, ``dB/da = -phi(z_a) / s``,
    ``dB/db = phi(z_b) / s`` and ``dC/ds = -(z_1 phi(z_1) - z_2 phi(z_2)) B / s
    - A (z_a phi(z_a) - z_b phi(z_b)) / s``; eq. (2) has
    ``d/dC_1 = (bg - G)(1 - C_2)`` (and 1, 2 swapped) and
    ``d/dG = -union``."""
    th, Z, A, B = T.theta, T.Z, T.A, T.B
    s = th[_BLUR]
    n = Z.shape[1]
    E = np.zeros(Z.size)                           # sqrt(2 pi) phi(Z), 0 if saturated
    E[T.live] = np.exp(T.z_live * T.z_live * -0.5)
    E = E.reshape(2, 2, 2, n)
    EZ = E * Z.reshape(2, 2, 2, n)
    Ed = E[:, :, 0] - E[:, :, 1]
    g = (bg - th[_G]) * (_INV_SQRT_2PI / s) * (1.0 - T.C[::-1])   # d model / d C_k, / s
    gA, gB = g * A, g * B
    dd = gB * Ed[:, 0]                             # d model / d d_k
    dt = gA * Ed[:, 1]                             # d model / d t_k
    Zs = Z.reshape(2, 4, n)
    d = (Zs[:, 0] + Zs[:, 1]) * (0.5 * s)
    t = Zs[:, 2] * s + T.a
    JT = np.empty((11, n))
    Jb = JT[:8].reshape(2, 4, n)
    Jb[:, 0] = dt * d - dd * t                     # angle
    Jb[:, 1] = dd * T.dd_dc + dt * T.dt_dc         # shift c
    Jb[:, 2] = -gA * E[:, 1, 0]                    # a
    Jb[:, 3] = gA * E[:, 1, 1]                     # b
    JT[_W] = (0.5 * gB * (E[:, 0, 0] + E[:, 0, 1])).sum(0)
    JT[_G] = -T.union
    EZd = EZ[:, :, 0] - EZ[:, :, 1]
    JT[_BLUR] = -(gB * EZd[:, 0] + gA * EZd[:, 1]).sum(0)
    return JT


def _xy1(x, y):
    """Pixel centres as the (3, n) rows x, y, 1 of :class:`_PairTerms`."""
    return np.stack([np.ravel(x), np.ravel(y), np.ones(np.size(x))])


def _model(theta, x, y, bg, ref, u0):
    """Eq. (2) at pixel centres (x, y) with background ``bg``: ``B - I``."""
    T = _PairTerms(theta, _xy1(x, y), ref, u0)
    return ((np.ravel(bg) - theta[_G]) * T.union).reshape(np.shape(x))


def _model_jacobian(theta, x, y, bg, ref, u0):
    """d model / d theta (n, 11) of :func:`_model`, analytic."""
    T = _PairTerms(theta, _xy1(x, y), ref, u0)
    return _pair_jacobian(T, np.ravel(bg)).T


class _PairResiduals:
    """Residuals eq. (2) minus data ``v`` of one set of used pixels, and
    their Jacobian from the terms of the last residual evaluation (the
    solver asks for the Jacobian at the point just accepted)."""

    def __init__(self, x, y, bg, v, ref, u0):
        self.X3, self.bg, self.v, self.ref, self.u0 = _xy1(x, y), bg, v, ref, u0
        self.last = None

    def fun(self, th):
        self.last = T = _PairTerms(th, self.X3, self.ref, self.u0)
        return (self.bg - th[_G]) * T.union - self.v

    def jac(self, th):
        T = self.last
        if T is None or not np.array_equal(T.theta, th):
            T = _PairTerms(th, self.X3, self.ref, self.u0)
        return _pair_jacobian(T, self.bg).T
