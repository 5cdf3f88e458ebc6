"""Rotation parameterisations, vectorised over leading dimensions.

Every function takes arrays of shape ``(..., 3)`` (angles, rotation vectors),
``(..., 4)`` (quaternions) or ``(..., 3, 3)`` (matrices) and works on all of
them at once. Angles are radians.

Conventions (see docs/camera-models.md, "Rotations"):

* The matrix ``R`` is the **world-to-camera** rotation: ``Xc = R (X - X0)``.
* Omega-phi-kappa is the photogrammetric sequence of Wolf / Kraus,
  ``R = M_kappa M_phi M_omega`` with ``M_omega = R_x(omega)^T`` etc., so that
  ``r11 = cos(phi) cos(kappa)``, ``r31 = sin(phi)``. This is exactly DBAT's
  ``eulerrotmat(ang, 123, false)'`` (the transposed x-y-z moving-axis
  product), so angles reported by DBAT can be used as they are.
* Rotation vectors (Rodrigues) and quaternions (w, x, y, z; Hamilton, active)
  describe the same matrix ``R``: ``R = expm([r]x)``, as ``cv2.Rodrigues``.
* Derivative arrays have the parameter as the **last** axis:
  ``dR[..., i, j, k] = d R[i, j] / d p[k]``.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError

ANGLE_FACTORS = {"rad": 1.0, "deg": np.pi / 180.0, "gon": np.pi / 200.0}

# Below this rotation angle the closed forms are replaced by Taylor series.
_SMALL_ANGLE = 1e-2
# Below this value of cos(phi) the omega-phi-kappa decomposition is locked.
_GIMBAL_EPS = 1e-12


# --------------------------------------------------------------------------
# units
# --------------------------------------------------------------------------
def _factor(unit: str) -> float:
    try:
        return ANGLE_FACTORS[unit]
    except (KeyError, TypeError):
        raise InputError(f"unknown angle unit {unit!r}",
                         hint="use one of " + ", ".join(ANGLE_FACTORS)) from None


def to_radians(values, unit: str) -> np.ndarray:
    """Convert angles from ``unit`` ("rad", "deg" or "gon") to radians.

    Raises
    ------
    InputError
        For an unknown unit.
    """
    return np.asarray(values, dtype=float) * _factor(unit)


def from_radians(values, unit: str) -> np.ndarray:
    """Convert angles in radians to ``unit`` ("rad", "deg" or "gon")."""
    return np.asarray(values, dtype=float) / _factor(unit)


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def skew(v) -> np.ndarray:
    """Cross-product matrix ``[v]x`` of ``v`` (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    k = np.zeros(v.shape[:-1] + (3, 3))
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    k[..., 0, 1], k[..., 0, 2] = -w, y
    k[..., 1, 0], k[..., 1, 2] = w, -x
    k[..., 2, 0], k[..., 2, 1] = -y, x
    return k


def _elementary(angles):
    """Wolf's elementary matrices M_omega, M_phi, M_kappa and derivatives
    (each (..., 3, 3), filled in place: the same values as stacking the
    entries, without 36 nested ``np.stack`` calls over all observations)."""
    a = np.asarray(angles, dtype=float)
    c, s = np.cos(a), np.sin(a)
    shape = a.shape[:-1] + (3, 3)
    co, so = c[..., 0], s[..., 0]
    cp, sp = c[..., 1], s[..., 1]
    ck, sk = c[..., 2], s[..., 2]

    def mat(entries):
        """A (..., 3, 3) array of zeros with ``{(i, j): value}`` set."""
        m = np.zeros(shape)
        for (i, j), v in entries.items():
            m[..., i, j] = v
        return m

    m_o = mat({(0, 0): 1.0, (1, 1): co, (1, 2): so, (2, 1): -so, (2, 2): co})
    d_o = mat({(1, 1): -so, (1, 2): co, (2, 1): -co, (2, 2): -so})
    m_p = mat({(0, 0): cp, (0, 2): -sp, (1, 1): 1.0, (2, 0): sp, (2, 2): cp})
    d_p = mat({(0, 0): -sp, (0, 2): -cp, (2, 0): cp, (2, 2): -sp})
    m_k = mat({(0, 0): ck, (0, 1): sk, (1, 0): -sk, (1, 1): ck, (2, 2): 1.0})
    d_k = mat({(0, 0): -sk, (0, 1): ck, (1, 0): -ck, (1, 1): -sk})
    return (m_o, m_p, m_k), (d_o, d_p, d_k)


# --------------------------------------------------------------------------
# omega-phi-kappa
# --------------------------------------------------------------------------
def opk_to_matrix(angles) -> np.ndarray:
    """World-to-camera matrix from omega-phi-kappa angles.

    ``R = M_kappa M_phi M_omega`` (Wolf & Dewitt, Elements of Photogrammetry,
    eq. C-33; Kraus, Photogrammetry vol. 1, eq. 2.1-7), identical to DBAT's
    ``eulerrotmat(ang,123,false)'``::

        r11 =  cos(phi) cos(kappa)
        r12 =  cos(omega) sin(kappa) + sin(omega) sin(phi) cos(kappa)
        r13 =  sin(omega) sin(kappa) - cos(omega) sin(phi) cos(kappa)
        r21 = -cos(phi) sin(kappa)
        r22 =  cos(omega) cos(kappa) - sin(omega) sin(phi) sin(kappa)
        r23 =  sin(omega) cos(kappa) + cos(omega) sin(phi) sin(kappa)
        r31 =  sin(phi)
        r32 = -sin(omega) cos(phi)
        r33 =  cos(omega) cos(phi)

    Parameters
    ----------
    angles : array_like, (..., 3)
        omega, phi, kappa in radians.

    Returns
    -------
    R : ndarray, (..., 3, 3)
    """
    (m_o, m_p, m_k), _ = _elementary(angles)
    return m_k @ m_p @ m_o


def opk_derivatives(angles) -> np.ndarray:
    """Partial derivatives of :func:`opk_to_matrix`.

    Returns
    -------
    dR : ndarray, (..., 3, 3, 3)
        ``dR[..., i, j, k] = d r_ij / d angle_k`` with angle order
        (omega, phi, kappa).
    """
    (m_o, m_p, m_k), (d_o, d_p, d_k) = _elementary(angles)
    return np.stack([m_k @ m_p @ d_o, m_k @ d_p @ m_o, d_k @ m_p @ m_o], -1)


def matrix_to_opk(R) -> np.ndarray:
    """Omega-phi-kappa angles of a world-to-camera matrix (inverse of
    :func:`opk_to_matrix`).

    ``phi = atan2(r31, hypot(r11, r21))`` lies in [-pi/2, pi/2];
    ``omega = atan2(-r32, r33)``, ``kappa = atan2(-r21, r11)``. At gimbal
    lock (``cos(phi)`` below 1e-12, phi = +-90 deg) only omega +- kappa is
    defined: omega is set to 0 and ``kappa = atan2(r12, r22)``. Never NaN.

    Parameters
    ----------
    R : array_like, (..., 3, 3)

    Returns
    -------
    angles : ndarray, (..., 3)
    """
    R = np.asarray(R, dtype=float)
    cphi = np.hypot(R[..., 0, 0], R[..., 1, 0])
    phi = np.arctan2(R[..., 2, 0], cphi)
    locked = cphi < _GIMBAL_EPS
    omega = np.where(locked, 0.0, np.arctan2(-R[..., 2, 1], R[..., 2, 2]))
    kappa = np.where(locked, np.arctan2(R[..., 0, 1], R[..., 1, 1]),
                     np.arctan2(-R[..., 1, 0], R[..., 0, 0]))
    return np.stack([omega, phi, kappa], -1)


# --------------------------------------------------------------------------
# Rodrigues (rotation vector)
# --------------------------------------------------------------------------
def _rodrigues_ab(theta):
    """A = sin t / t and B = (1 - cos t) / t^2, stable at t = 0 (Taylor
    series below 1e-2); also the masked angle, its square, sin and cos."""
    small = theta < _SMALL_ANGLE
    if small.all():            # a solver's increments: only the series (same values)
        t2 = theta * theta
        return (1 - t2 / 6 + t2 * t2 / 120 - t2 ** 3 / 5040,
                0.5 - t2 / 24 + t2 * t2 / 720 - t2 ** 3 / 40320, small, None, t2, None, None)
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    s, c = np.sin(t), np.cos(t)
    a = np.where(small, 1 - t2 / 6 + t2 * t2 / 120 - t2 ** 3 / 5040, s / t)
    b = np.where(small, 0.5 - t2 / 24 + t2 * t2 / 720 - t2 ** 3 / 40320,
                 (1 - c) / t ** 2)
    return a, b, small, t, t2, s, c


def _rodrigues_coefficients(theta):
    """A = sin t / t, B = (1 - cos t) / t^2 and their derivatives divided by
    t, A'/t and B'/t, stable at t = 0 (Taylor series below 1e-2)."""
    a, b, small, t, t2, s, c = _rodrigues_ab(np.asarray(theta, dtype=float))
    if t is None:
        t = np.ones_like(t2)
        s, c = np.sin(t), np.cos(t)
    da = np.where(small, -1 / 3 + t2 / 30 - t2 * t2 / 840 + t2 ** 3 / 45360,
                  (t * c - s) / t ** 3)
    db = np.where(small, -1 / 12 + t2 / 180 - t2 * t2 / 6720 + t2 ** 3 / 453600,
                  (t * s - 2 * (1 - c)) / t ** 4)
    return a, b, da, db


def rodrigues_to_matrix(rvec) -> np.ndarray:
    """Rotation matrix of a rotation vector, ``R = expm([r]x)``.

    Rodrigues' formula ``R = I + A [r]x + B [r]x^2`` with
    ``A = sin(t)/t``, ``B = (1 - cos(t))/t^2``, ``t = |r|``; series near 0.
    Same convention as ``cv2.Rodrigues``.

    Parameters
    ----------
    rvec : array_like, (..., 3)

    Returns
    -------
    R : ndarray, (..., 3, 3)
    """
    r = np.asarray(rvec, dtype=float)
    a, b = _rodrigues_ab(np.sqrt((r * r).sum(-1)))[:2]
    k = skew(r)
    return (np.eye(3) + a[..., None, None] * k
            + b[..., None, None] * (k @ k))


def small_rotation(delta) -> np.ndarray:
    """Incremental rotation ``expm([delta]x)`` (..., 3) -> (..., 3, 3).

    A solver updates ``R = small_rotation(delta) @ R0`` and so never meets
    the omega-phi-kappa gimbal lock; d(R X)/d delta at 0 is ``-[R X]x``.
    """
    return rodrigues_to_matrix(delta)


def rodrigues_derivatives(rvec) -> np.ndarray:
    """Partial derivatives of :func:`rodrigues_to_matrix`, stable at 0.

    ``dR/dr_k = (A'/t) r_k [r]x + A [e_k]x + (B'/t) r_k [r]x^2
    + B ([e_k]x [r]x + [r]x [e_k]x)``; at ``r = 0`` this is ``[e_k]x``.

    Returns
    -------
    dR : ndarray, (..., 3, 3, 3)
        ``dR[..., i, j, k] = d R[i, j] / d r_k``.
    """
    r = np.asarray(rvec, dtype=float)
    a, b, da, db = _rodrigues_coefficients(np.linalg.norm(r, axis=-1))
    k = skew(r)
    k2 = k @ k
    e = skew(np.eye(3))                       # (3, 3, 3): [e_k]x
    out = []
    for i in range(3):                        # 3 fixed axes, not observations
        ek = e[i]
        term = (da * r[..., i])[..., None, None] * k \
            + a[..., None, None] * ek \
            + (db * r[..., i])[..., None, None] * k2 \
            + b[..., None, None] * (ek @ k + k @ ek)
        out.append(term)
    return np.stack(out, -1)


def matrix_to_rodrigues(R) -> np.ndarray:
    """Rotation vector of a rotation matrix (inverse of
    :func:`rodrigues_to_matrix`), angle in [0, pi].

    Computed through the sign-canonical quaternion (Shepperd's method), which
    is stable near 0 and near pi: ``r = 2 atan2(|v|, w) v / |v|``.
    """
    q = matrix_to_quaternion(R)
    w, v = q[..., 0], q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    tiny = s < 1e-8
    factor = np.where(tiny, 2.0 / np.where(tiny, w, 1.0),
                      2.0 * np.arctan2(s, w) / np.where(tiny, 1.0, s))
    return factor[..., None] * v


# --------------------------------------------------------------------------
# quaternions
# --------------------------------------------------------------------------
def quaternion_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z) (normalised first).

    Hamilton convention, active rotation: the matrix returned rotates by
    ``2 acos(w)`` about (x, y, z), as ``rodrigues_to_matrix`` does for the
    same axis and angle.
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = (q[..., i] for i in range(4))
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def matrix_to_quaternion(R) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix, ``w >= 0``.

    Shepperd (1978) / Markley: the largest of ``1 + trace``, ``1 + 2 r_ii -
    trace`` is used as pivot, so the result is accurate for every rotation.
    When ``w == 0`` (a half turn) the first non-zero of x, y, z is made
    positive.
    """
    R = np.asarray(R, dtype=float)
    r11, r22, r33 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = r11 + r22 + r33
    d32, d13, d21 = R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], \
        R[..., 1, 0] - R[..., 0, 1]
    s12, s13, s23 = R[..., 0, 1] + R[..., 1, 0], R[..., 0, 2] + R[..., 2, 0], \
        R[..., 1, 2] + R[..., 2, 1]
    piv = np.stack([1 + tr, 1 + 2 * r11 - tr, 1 + 2 * r22 - tr, 1 + 2 * r33 - tr], -1)
    choice = np.argmax(piv, axis=-1)
    cands = np.stack([
        np.stack([piv[..., 0], d32, d13, d21], -1),
        np.stack([d32, piv[..., 1], s12, s13], -1),
        np.stack([d13, s12, piv[..., 2], s23], -1),
        np.stack([d21, s13, s23, piv[..., 3]], -1),
    ], -2)                                          # (..., 4 candidates, 4)
    q = np.take_along_axis(cands, choice[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return _canonical_sign(q)


def _canonical_sign(q):
    """Flip q so that its first non-zero component (w, x, y, z order) is > 0."""
    nz = np.abs(q) > 1e-15
    first = np.argmax(nz, axis=-1)
    lead = np.take_along_axis(q, first[..., None], axis=-1)
    return np.where(lead < 0, -q, q)


def angle_increment_map(R):
    """``(angles, E)`` with ``d(opk) = E delta`` for ``R = expm([delta]x) R0``:
    how omega-phi-kappa change under the engine's incremental rotation.

    From ``[delta]x R = sum_j dR/da_j da_j``: the columns of ``E^-1`` are
    ``vee(dR/da_j R^T)``.
    """
    angles = matrix_to_opk(R)
    dR = opk_derivatives(angles)                       # (n, 3, 3, 3): [..., j]
    M = np.einsum("nikj,nlk->njil", dR, R)             # (n, j, 3, 3) dR_j R^T
    Einv = np.stack([M[:, :, 2, 1], M[:, :, 0, 2], M[:, :, 1, 0]], axis=1)  # (n, 3, j)
    return angles, np.linalg.inv(Einv)


def opk_inverse_jacobian(angles) -> np.ndarray:
    """Jacobian of the angles of the inverse rotation with respect to the
    angles: ``d b / d a`` for ``R(b) = R(a)^T`` (world-to-camera <->
    camera-to-world), (..., 3) -> (..., 3, 3); NaN rows stay NaN.

    With ``R = expm([delta]x) R0`` the inverse is
    ``R^T = expm([-R0^T delta]x) R0^T``, so with the increment maps
    ``d(opk) = E delta`` of :func:`angle_increment_map`::

        d b = -E(R0^T) R0^T E(R0)^-1 d a

    Analytic (tested against finite differences); singular at phi = +-90 deg
    of either direction (gimbal lock), where the result is not finite.
    A covariance ``C`` of the angles ``a`` becomes ``J C J^T`` for ``b``.
    """
    a = np.asarray(angles, dtype=float)
    shape = a.shape
    a = a.reshape(-1, 3)
    out = np.full((len(a), 3, 3), np.nan)
    ok = np.all(np.isfinite(a), axis=1)
    if np.any(ok):
        R = opk_to_matrix(a[ok])
        Rt = np.swapaxes(R, -1, -2)
        _, E = angle_increment_map(R)
        _, Et = angle_increment_map(Rt)
        with np.errstate(all="ignore"):
            out[ok] = -Et @ Rt @ np.linalg.inv(E)
    return out.reshape(shape[:-1] + (3, 3))
