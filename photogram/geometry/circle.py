"""Where the centre of the imaged ellipse of a circular target lies.

The image of a circle under a central projection is an ellipse whose
centre is not the image of the circle's centre (Ahn, Warnecke & Kotowski
1999, "Systematic geometric image measurement errors of circular object
targets", Photogrammetric Record 16(93); Luhmann et al., Close-Range
Photogrammetry, sec. 3.6.1.2). Projective maps keep pole and polar: the
ellipse centre (the pole of the image's line at infinity with respect to
the image conic) is the image of the pole, with respect to the circle, of
the line of the target plane that maps to infinity. That line is where the
target plane meets the plane through the projection centre ``X0`` parallel
to the image plane, ``{P : k . (P - X0) = 0}`` with ``k = R^T e3`` the
camera's z axis in the object frame (``R`` world-to-camera,
docs/camera-models.md). For a circle of radius ``r`` about ``X`` with unit
normal ``n`` the pole is the object point

    X_e = X + delta,   delta = -r^2 P k / s,   P = I - n n^T,   s = k . (X - X0)   (1)

(in plane coordinates about ``X``: the pole of the line ``g . a + s = 0``,
``g = P k``, is ``a = -r^2 g / s``, the formula of
``photogram.measure.eccentricity.ellipse_centres`` with ``m = 0``). The
imaged ellipse centre is then the *projection of X_e*: exact for a pinhole
camera with any affine image terms (principal distance, principal point,
affinity, shear), and to first order with lens distortion (the distortion
is locally affine over the target and affine maps keep conic centres).
``delta`` does not depend on the interior orientation at all.

Derivatives of (1), all analytic (checked against central differences in
tests/test_adjust_eccentric.py):

* ``d delta / d X  =  r^2 g k^T / s^2``
* ``d delta / d X0 = -r^2 g k^T / s^2``
* ``d delta / d k  = -r^2 (P / s - g (X - X0)^T / s^2)``, and with
  ``R = small_rotation(theta) R0`` (the solver's rotation increment)
  ``d k / d theta = R^T [e3]x``.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.rotations import skew

__all__ = ["ellipse_centre_offset", "ellipse_centre_point"]


def ellipse_centre_offset(X, normal, radius, R, X0, jacobians=False):
    """Object-space offset ``delta`` of eq. (1) (module docstring).

    Parameters
    ----------
    X : (n, 3) circle centres
    normal : (n, 3) or (3,) plane normals (any length, either sign)
    radius : (n,) or scalar circle radii (object units; 0 = a point)
    R : (n, 3, 3) world-to-camera rotations
    X0 : (n, 3) projection centres
    jacobians : bool

    Returns
    -------
    delta : (n, 3)
    jac : dict, with ``jacobians=True``: ``"X"``, ``"X0"``, ``"rotation"``
        (n, 3, 3), the last with respect to ``theta`` in
        ``R = small_rotation(theta) @ R``.
    """
    X = np.atleast_2d(np.asarray(X, float))
    n = len(X)
    nv = np.broadcast_to(np.asarray(normal, float), (n, 3))
    nv = nv / np.linalg.norm(nv, axis=1, keepdims=True)
    r2 = np.broadcast_to(np.asarray(radius, float) ** 2, (n,))
    R = np.broadcast_to(np.asarray(R, float), (n, 3, 3))
    d = X - np.broadcast_to(np.asarray(X0, float), (n, 3))
    k = R[:, 2, :]                                   # camera z axis, object frame
    P = np.eye(3)[None] - nv[:, :, None] * nv[:, None, :]
    g = np.einsum("nij,nj->ni", P, k)
    s = np.einsum("ni,ni->n", k, d)
    delta = -r2[:, None] * g / s[:, None]
    if not jacobians:
        return delta
    dX = (r2 / s ** 2)[:, None, None] * g[:, :, None] * k[:, None, :]
    dk = -(r2 / s)[:, None, None] * P + (r2 / s ** 2)[:, None, None] * g[:, :, None] * d[:, None, :]
    dk_dtheta = np.einsum("nji,jk->nik", R, skew(np.array([0.0, 0.0, 1.0])))
    return delta, {"X": dX, "X0": -dX, "rotation": dk @ dk_dtheta}


def ellipse_centre_point(X, normal, radius, R, X0, jacobians=False):
    """``X_e = X + delta`` (eq. (1)): the object point whose projection is
    the centre of the imaged ellipse; Jacobians as
    :func:`ellipse_centre_offset` with the identity added for ``"X"``."""
    out = ellipse_centre_offset(X, normal, radius, R, X0, jacobians)
    if not jacobians:
        return np.atleast_2d(np.asarray(X, float)) + out
    delta, jac = out
    jac["X"] = jac["X"] + np.eye(3)[None]
    return np.atleast_2d(np.asarray(X, float)) + delta, jac
