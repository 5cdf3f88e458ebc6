"""Camera rotations of pan-tilt cameras as Euler-angle trajectories, and the
rotation prior E_rot of eq. (14).

Parametrisation (section 4.5 of the paper; the details are our choice). In a
window of T frames the world-to-camera rotation of camera c is

    R_c(t) = R_ref,c E(gamma_c(t)),   E(g) = Rx(g_0) Ry(g_1) Rz(g_2),
    gamma_c,a(t) = sum_k g_c,a,k B_Gamma[t, k]          (N_Gamma = 11)

with ``R_ref`` a fixed rotation per camera and window (the start's rotation
at the window's middle frame) and ``Rx, Ry, Rz`` rotations about the world
axes (applied to world coordinates before ``R_ref``): a small-angle-free
parametrisation whose only singularity, ``g_1 = +-90 deg``, is far from any
pan-tilt motion within a window. ``B_Gamma`` is the orthonormal DCT basis
of :mod:`photogram.mocap.reconstruction.dct` (or the identity: rotations free per frame).

Chained reference (with measured differences): ``R_ref`` may be given per
frame, ``R_ref(t) = Q(t) Q(m)^T R_ref(m)`` with ``Q`` the chain of the
measured differences (``Q(t+1) = dR(t) Q(t)``) and m the window's middle
frame. Then ``R(t) = R_ref(t) E(gamma(t))`` follows the measured camera
motion exactly at ``gamma = const`` (E_rot = 0), and the DCT of ``gamma``
only carries the slow correction of the chain's drift: 11 DCT terms cannot
represent a pan of 0.46 deg per frame (residual up to 0.27 deg at the
window ends, 0.06 deg in the middle), the chain can.

Rotation prior (eq. (14), our reading): the measured rotation differences
``dR_c(t)`` (from background homographies, :mod:`photogram.mocap.motion.homography`;
``R_c(t+1) = dR_c(t) R_c(t)``) should equal those of the trajectory:

    E_rot = lambda_rot sum_{c,t} |r_c(t)|^2,
    r = vee(M - M^T) / 2 * 180/pi,   M = dR^T R(t+1) R(t)^T

``vee(M - M^T)/2`` is ``sin(angle) * axis`` of the discrepancy rotation M:
its rotation vector to third order. Residuals are in **degrees** (our
assumption, see docs/mocap.md: with lambda_rot = 10000 a discrepancy of
0.076 deg per frame weighs as much as the reprojection error of a detection
at the simulator's noise level).
"""

from __future__ import annotations

import numpy as np

__all__ = ["euler_matrices", "euler_from_matrices", "generators", "rotation_residuals",
           "DEG"]

DEG = 180.0 / np.pi


def _elementary(g):
    """Rx, Ry, Rz and their derivatives for angles g (..., 3): arrays
    (..., 3, 3)."""
    c, s = np.cos(g), np.sin(g)
    z, o = np.zeros_like(g[..., 0]), np.ones_like(g[..., 0])

    def m(rows):
        return np.stack([np.stack(r, -1) for r in rows], -2)

    c0, s0, c1, s1, c2, s2 = c[..., 0], s[..., 0], c[..., 1], s[..., 1], c[..., 2], s[..., 2]
    Rx = m([[o, z, z], [z, c0, -s0], [z, s0, c0]])
    Ry = m([[c1, z, s1], [z, o, z], [-s1, z, c1]])
    Rz = m([[c2, -s2, z], [s2, c2, z], [z, z, o]])
    dRx = m([[z, z, z], [z, -s0, -c0], [z, c0, -s0]])
    dRy = m([[-s1, z, c1], [z, z, z], [-c1, z, -s1]])
    dRz = m([[-s2, -c2, z], [c2, -s2, z], [z, z, z]])
    return (Rx, Ry, Rz), (dRx, dRy, dRz)


def euler_matrices(g, derivatives: bool = False):
    """``E(g) = Rx(g0) Ry(g1) Rz(g2)`` for angles g (..., 3) in radians;
    with ``derivatives`` also ``dE/dg_a`` as an array (3, ..., 3, 3)."""
    g = np.asarray(g, dtype=float)
    (Rx, Ry, Rz), (dRx, dRy, dRz) = _elementary(g)
    E = Rx @ Ry @ Rz
    if not derivatives:
        return E
    return E, np.stack([dRx @ Ry @ Rz, Rx @ dRy @ Rz, Rx @ Ry @ dRz])


def euler_from_matrices(E) -> np.ndarray:
    """Angles g (..., 3) with ``euler_matrices(g) = E`` (|g_1| < 90 deg)."""
    E = np.asarray(E, dtype=float)
    g1 = np.arcsin(np.clip(E[..., 0, 2], -1.0, 1.0))
    g0 = np.arctan2(-E[..., 1, 2], E[..., 2, 2])
    g2 = np.arctan2(-E[..., 0, 1], E[..., 0, 0])
    return np.stack([g0, g1, g2], -1)


def generators(R_ref, E, dE):
    """``G_a = R_ref dE_a E^T R_ref^T`` (3, ..., 3, 3): the derivative of the
    camera coordinates ``Xc = R_ref E (X - X0)`` with respect to ``g_a`` is
    ``G_a Xc`` (skew-symmetric: an angular velocity in the camera frame)."""
    RT = np.swapaxes(R_ref, -1, -2)
    ET = np.swapaxes(E, -1, -2)
    return R_ref @ dE @ ET @ RT


def _vee_anti(M):
    """vee((M - M^T)/2) for M (..., 3, 3) -> (..., 3)."""
    return 0.5 * np.stack([M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0],
                           M[..., 1, 0] - M[..., 0, 1]], -1)


def rotation_residuals(R_ref, E, dE, dR_meas, jacobian: bool = True):
    """Residuals of E_rot (module doc) between consecutive frames.

    Parameters
    ----------
    R_ref : (..., 3, 3) or (..., T, 3, 3)
        Reference rotation (broadcast over the frames), or one per frame
        (the chained rotation differences: module doc).
    E, dE : (..., T, 3, 3), (3, ..., T, 3, 3)
        ``euler_matrices(g, derivatives=True)`` of the frames.
    dR_meas : (..., T-1, 3, 3)
        Measured ``dR(t)`` with ``R(t+1) = dR(t) R(t)``.

    Returns
    -------
    r : (..., T-1, 3)
        In degrees.
    J0, J1 : (..., T-1, 3, 3)
        ``dr/dg(t)`` and ``dr/dg(t+1)`` (columns: the three angles), per
        radian; only with ``jacobian``.
    """
    Rr = np.asarray(R_ref)
    if Rr.ndim == np.ndim(E):                              # a reference per frame
        Rr0, Rr1 = Rr[..., :-1, :, :], Rr[..., 1:, :, :]
    else:
        Rr0 = Rr1 = Rr[..., None, :, :]
    RrT = np.swapaxes(Rr0, -1, -2)
    A = np.swapaxes(dR_meas, -1, -2) @ Rr1                 # dR^T R_ref(t+1)
    E0T = np.swapaxes(E[..., :-1, :, :], -1, -2)
    E1 = E[..., 1:, :, :]
    r = DEG * _vee_anti(A @ E1 @ E0T @ RrT)
    if not jacobian:
        return r
    J1 = np.stack([_vee_anti(A @ dE[a][..., 1:, :, :] @ E0T @ RrT) for a in range(3)], -1)
    J0 = np.stack([_vee_anti(A @ E1 @ np.swapaxes(dE[a][..., :-1, :, :], -1, -2) @ RrT)
                   for a in range(3)], -1)
    return r, DEG * J0, DEG * J1
