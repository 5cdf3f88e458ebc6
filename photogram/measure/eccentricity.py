"""Eccentricity of a circle's projected centre.

The image of a circle under a central projection is an ellipse whose
centre is not the image of the circle's centre (Ahn, Warnecke & Kotowski
1999, "Systematic geometric image measurement errors of circular object
targets", Photogrammetric Record 16(93); Luhmann et al. sec. 3.6.1.2).
For a circle of radius ``R`` about ``(X0, Y0)`` in a plane mapped to the
image by the homography ``H`` the circle's conic is
``C = [[1, 0, -X0], [0, 1, -Y0], [-X0, -Y0, X0^2 + Y0^2 - R^2]]``, its image
``C' = H^-T C H^-1``, and the centre of ``C'`` is the pole of the line at
infinity, ``e ~ C'^-1 (0, 0, 1)^T = H C^-1 H^T (0, 0, 1)^T``. With
``C^-1 = [[I - m m^T / R^2, -m / R^2], [-m^T / R^2, -1 / R^2]]`` (m = (X0, Y0))
and ``h = H^T (0, 0, 1)^T`` (the third row of H, the vanishing line's
pull-back) this is ``e ~ H (R^2 h' - (m . h' + h3) (m, 1))`` with h' = h[:2] (up to
sign and scale), written out in :func:`ellipse_centres`. The
eccentricity is ``e - H (m, 1)``: subtracting it from a measured ellipse
centre gives the image of the circle's centre.

The same pole in object space, for the adjustment (which predicts ellipse
centres from the orientation instead of correcting the measurements with a
homography), is :func:`photogram.geometry.circle.ellipse_centre_point`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ellipse_centres", "eccentricity", "eccentricity_jacobian"]


def _dehom(p):
    return p[..., :2] / p[..., 2:3]


def ellipse_centres(H: np.ndarray, XY: np.ndarray, radius) -> np.ndarray:
    """Image centres of the ellipses of circles (centres XY, radii) under H.

    Derivation: ``C^-1 h`` with ``h = (h1, h2, h3)`` the third row of H is,
    up to the factor ``-1/R^2``, ``(m (m.h' + h3) - R^2 h', m.h' + h3)``,
    i.e. the homogeneous sheet point ``q = (m - R^2 h' / s, 1)`` with
    ``s = m.h' + h3``; the ellipse centre is ``H q``.
    """
    XY = np.atleast_2d(np.asarray(XY, float))
    R2 = np.broadcast_to(np.asarray(radius, float) ** 2, (len(XY),))
    h = H[2]
    s = XY @ h[:2] + h[2]
    q = XY - R2[:, None] * h[None, :2] / s[:, None]
    return _dehom(np.column_stack([q, np.ones(len(q))]) @ H.T)


def eccentricity(H: np.ndarray, XY: np.ndarray, radius) -> np.ndarray:
    """Ellipse centre minus the image of the circle's centre (n, 2), px."""
    XY = np.atleast_2d(np.asarray(XY, float))
    centre = _dehom(np.column_stack([XY, np.ones(len(XY))]) @ H.T)
    return ellipse_centres(H, XY, radius) - centre


def eccentricity_jacobian(H: np.ndarray, XY: np.ndarray, radius) -> np.ndarray:
    """Analytic derivative of :func:`eccentricity` with respect to the nine
    entries of H (row-major), shape (n, 2, 9).

    With ``p = H q`` (homogeneous) and ``x = p[:2] / p[2]`` the derivative of
    x by H_ij is ``(delta_i<2 e_i - x [i==2]) q_j / p3`` plus the chain
    through q, which depends on the third row of H only:
    ``dq/dh' = -R^2 (I s - h' m^T) / s^2`` and ``dq/dh3 = R^2 h' / s^2``.
    """
    XY = np.atleast_2d(np.asarray(XY, float))
    n = len(XY)
    R2 = np.broadcast_to(np.asarray(radius, float) ** 2, (n,))
    h = H[2]
    s = XY @ h[:2] + h[2]
    q = np.column_stack([XY - R2[:, None] * h[None, :2] / s[:, None], np.ones(n)])
    m = np.column_stack([XY, np.ones(n)])

    def dproj(v):
        p = v @ H.T
        x = p[:, :2] / p[:, 2:3]
        J = np.zeros((n, 2, 9))
        for i in range(2):
            J[:, i, 3 * i:3 * i + 3] = v / p[:, 2:3]
        J[:, :, 6:9] = -x[:, :, None] * v[:, None, :] / p[:, 2, None, None]
        # d x / d v (for the chain through q)
        dv = (H[:2][None, :, :] - x[:, :, None] * H[2][None, None, :]) / p[:, 2, None, None]
        return J, dv

    Jq, dxdq = dproj(q)
    Jm, _ = dproj(m)
    # dq / dH (only the third row of H, entries 6, 7, 8)
    dq = np.zeros((n, 3, 9))
    eye = np.eye(2)
    dq[:, :2, 6:8] = -R2[:, None, None] * (eye[None] * s[:, None, None]
                                           - h[None, :2, None] * XY[:, None, :]) \
        / s[:, None, None] ** 2
    dq[:, :2, 8] = R2[:, None] * h[None, :2] / s[:, None] ** 2
    return Jq + np.einsum("nij,njk->nik", dxdq, dq) - Jm
