"""Conversions of the ``aicon`` model: to and from ``brown`` and ``opencv``
where they are exact, and the change of the balancing radius r0.

All follow from writing each model as a function of the normalised ray
``t`` (the ideal projection with c = 1, y down; docs/camera-models.md,
section 5.3). The aicon model is then, with ``rho2 = |t|^2`` and
``s0 = A1 r0^2 + A2 r0^4 + A3 r0^6``::

    x - xh = c (1 + C1 - s0) t_x - c C2 t_y + sum_i A_i c^(2i+1) rho2^i t_x
             + c^2 (B1 (rho2 + 2 t_x^2) - 2 B2 t_x t_y)
    y - yh = c (1 - s0) t_y + sum_i A_i c^(2i+1) rho2^i t_y
             + c^2 (-B2 (rho2 + 2 t_y^2) + 2 B1 t_x t_y)

Two parameter sets give the same camera exactly when these polynomials in
t have the same coefficients. Hence:

* **r0**: ``F = c (1 - s0)``, ``a_i = A_i c^(2i+1)``, ``b_j = B_j c^2``,
  ``g_k = C_k c`` (and xh, yh) are the invariants; a new r0 gives a new
  ``c'`` from ``c' - sum_i a_i r0'^(2i) / c'^(2i) = F`` (Newton) and
  ``A_i' = a_i / c'^(2i+1)``, ``B_j' = b_j / c'^2``, ``C_k' = g_k / c'``:
  :func:`change_r0`, exact for every parameter set;
* **opencv** (forward, y down): ``fx = c (1 + C1 - s0)``, ``fy = c (1 -
  s0)``, ``k_i = A_i c^(2i+1) / fy``, ``p1 = -B2 c^2 / fy``, ``p2 = B1 c^2 /
  fy``; exact unless ``C2 != 0`` (OpenCV has no shear) or ``C1 != 0``
  together with distortion (OpenCV's fx scales its distortion in x, AICON's
  C1 does not);
* **brown** (backward): only the pinhole part and the affinity are exact
  (a polynomial correction of measured coordinates is not a polynomial
  distortion of ideal ones): ``C1 = -B1 / (1 + B1)``, ``C2 = -B2 / (1 +
  B1)``, c, principal point unchanged; exact unless A1-A3, B1, B2 (aicon)
  or K1-K3, P1, P2 (brown) are non-zero.

The refused conversions raise :class:`InputError` naming the parameters;
``strict=False`` drops them instead (a start for
:func:`photogram.geometry.fit_distortion`).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError
from photogram.geometry.camera import camera_model

__all__ = ["aicon_invariants", "change_r0", "aicon_to_opencv", "opencv_to_aicon",
           "aicon_to_brown", "brown_to_aicon"]

_C, _XH, _YH, _A, _B, _CC, _R0 = 0, 1, 2, slice(3, 6), slice(6, 8), slice(8, 10), 10
OPENCV_KNOWN = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")


def _vector(params, model):
    p = np.array(params, dtype=float)
    n = camera_model(model).n_params
    if p.shape != (n,):
        raise InputError(f"{model} parameters must be {n} values, got shape {p.shape}",
                         hint="in the order " + ", ".join(camera_model(model).parameter_names))
    return p


def _refuse(names, source, target, why):
    if names:
        raise InputError(f"{source} parameter(s) {', '.join(names)} cannot be converted "
                         f"exactly to the {target} model ({why})",
                         hint="use fit_distortion() for a least-squares conversion and "
                              "look at its misfit, or strict=False to drop them")


def _nonzero(p, model, names):
    m = camera_model(model)
    return [n for n in names if p[m.index(n)] != 0]


# --------------------------------------------------------------------------
# r0
# --------------------------------------------------------------------------
def aicon_invariants(params, jacobian=False):
    """The quantities that fix the aicon camera independently of r0.

    ``(F, xh, yh, a1, a2, a3, b1, b2, g1, g2)`` with ``F = c (1 - s0)``,
    ``s0 = sum_i A_i r0^(2i)``, ``a_i = A_i c^(2i+1)``, ``b_j = B_j c^2``,
    ``g_k = C_k c`` (module docstring). With ``jacobian=True`` also their
    (10, 10) Jacobian with respect to the first ten parameters (r0 held).
    """
    p = _vector(params, "aicon")
    c, A, B, C, R = p[_C], p[_A], p[_B], p[_CC], p[_R0] ** 2
    powers = np.array([1.0, 2.0, 3.0])
    s0 = float(np.sum(A * R ** powers))
    inv = np.concatenate([[c * (1.0 - s0), p[_XH], p[_YH]], A * c ** (2 * powers + 1),
                          B * c ** 2, C * c])
    if not jacobian:
        return inv
    J = np.zeros((10, 10))
    J[0, 0] = 1.0 - s0
    J[0, 3:6] = -c * R ** powers
    J[1, 1] = J[2, 2] = 1.0
    for i, k in enumerate(powers):
        J[3 + i, 0] = (2 * k + 1) * A[i] * c ** (2 * k)
        J[3 + i, 3 + i] = c ** (2 * k + 1)
    J[6:8, 0] = 2.0 * B * c
    J[6, 6] = J[7, 7] = c ** 2
    J[8:10, 0] = C
    J[8, 8] = J[9, 9] = c
    return inv, J


def _solve_c(inv, r0, start, tol=1e-15, max_iter=60):
    """c' of ``c' - sum_i a_i r0^(2i) / c'^(2i) = F`` by Newton's method."""
    F, a = inv[0], inv[3:6]
    k = np.array([1.0, 2.0, 3.0])
    w = a * (r0 * r0) ** k
    c = float(start)
    for _ in range(max_iter):
        h = c - np.sum(w * c ** (-2 * k)) - F
        dh = 1.0 + np.sum(2 * k * w * c ** (-2 * k - 1))
        step = h / dh
        c -= step
        if not np.isfinite(c) or c <= 0:
            break
        if abs(step) <= tol * abs(c):
            return c
    raise InputError(f"no aicon parameters with r0 = {r0:g} describe this camera "
                     "(the principal distance equation has no positive solution near c)",
                     hint="choose a balancing radius inside the image format")


def change_r0(params, r0, covariance=None):
    """The same aicon camera with the balancing radius ``r0``.

    The projection of every ray is unchanged (exactly: same polynomial in
    t); c and A1-A3, B1, B2, C1, C2 change (module docstring), xh, yh do
    not. ``r0 = 0`` gives the unbalanced form.

    Parameters
    ----------
    params : (11,) aicon parameters.
    r0 : float
        New balancing radius (image unit, >= 0).
    covariance : (11, 11) or (10, 10), optional
        Covariance of the parameters; r0 is a constant (its row and column,
        if given, are ignored and zero in the result).

    Returns
    -------
    params : (11,)
    covariance : (same shape as given), only if ``covariance`` is given:
        ``J Q J^T`` with ``J = (dI/dp at the new parameters)^-1 (dI/dp at
        the old)``, I the invariants (implicit function theorem).
    jacobian : (10, 10), only if ``covariance`` is given.
    """
    p = _vector(params, "aicon")
    r0 = float(r0)
    if not np.isfinite(r0) or r0 < 0:
        raise InputError(f"balancing radius r0 must be >= 0, got {r0:g}")
    inv, J_old = aicon_invariants(p, jacobian=True)
    c = _solve_c(inv, r0, p[_C])
    k = np.array([1.0, 2.0, 3.0])
    out = np.concatenate([[c, p[_XH], p[_YH]], inv[3:6] / c ** (2 * k + 1),
                          inv[6:8] / c ** 2, inv[8:10] / c, [r0]])
    if covariance is None:
        return out
    _, J_new = aicon_invariants(out, jacobian=True)
    J = np.linalg.solve(J_new, J_old)
    Q = np.asarray(covariance, dtype=float)
    if Q.shape not in ((10, 10), (11, 11)):
        raise InputError(f"aicon covariance must be (10,10) or (11,11), got {Q.shape}")
    Q_new = np.zeros_like(Q)
    Q_new[:10, :10] = J @ Q[:10, :10] @ J.T
    return out, Q_new, J


# --------------------------------------------------------------------------
# opencv
# --------------------------------------------------------------------------
def aicon_to_opencv(params, strict=True) -> np.ndarray:
    """Exact conversion aicon -> opencv (module docstring).

    ``fx = c (1 + C1 - s0)``, ``fy = c (1 - s0)``, ``cx = xh``, ``cy =
    yh``, ``k_i = A_i c^(2i+1) / fy``, ``p1 = -B2 c^2 / fy``, ``p2 = B1 c^2
    / fy``. Both in the same image unit (px for OpenCV).

    Raises
    ------
    InputError
        With ``strict=True``: C2 non-zero, or C1 non-zero together with a
        non-zero A1-A3, B1, B2.
    """
    p = _vector(params, "aicon")
    if strict:
        _refuse(_nonzero(p, "aicon", ("C2",)), "aicon", "opencv", "OpenCV has no shear")
        distortion = _nonzero(p, "aicon", ("A1", "A2", "A3", "B1", "B2"))
        if p[8] != 0 and distortion:
            _refuse(["C1"] + distortion, "aicon", "opencv",
                    "AICON's affinity C1 does not scale the distortion, OpenCV's fx does")
    inv = aicon_invariants(p)
    F, a, b, g = inv[0], inv[3:6], inv[6:8], inv[8:10]
    o = camera_model("opencv")
    out = np.zeros(o.n_params)
    values = {"fx": F + g[0], "fy": F, "cx": p[_XH], "cy": p[_YH], "k1": a[0] / F,
              "k2": a[1] / F, "k3": a[2] / F, "p1": -b[1] / F, "p2": b[0] / F}
    for name, value in values.items():
        out[o.index(name)] = value
    return out


def opencv_to_aicon(params, r0=0.0, strict=True) -> np.ndarray:
    """Exact conversion opencv -> aicon with balancing radius ``r0``.

    At r0 = 0: ``c = fy``, ``xh = cx``, ``yh = cy``, ``C1 = (fx - fy) / fy``,
    ``A_i = k_i / fy^(2i)``, ``B1 = p2 / fy``, ``B2 = -p1 / fy``; then
    :func:`change_r0`.

    Raises
    ------
    InputError
        With ``strict=True``: a non-zero k or p while ``fx != fy``, or a
        non-zero OpenCV parameter that the aicon model does not have.
    """
    p = _vector(params, "opencv")
    o = camera_model("opencv")
    get = {name: p[o.index(name)] for name in OPENCV_KNOWN}
    if strict:
        extra = [n for n in o.parameter_names if n not in OPENCV_KNOWN and p[o.index(n)] != 0]
        _refuse(extra, "opencv", "aicon", "no such term in the aicon model")
        if get["fx"] != get["fy"]:
            _refuse(_nonzero(p, "opencv", ("k1", "k2", "k3", "p1", "p2")), "opencv", "aicon",
                    "with fx != fy OpenCV scales its distortion differently in x and y")
    c = get["fy"]
    out = np.array([c, get["cx"], get["cy"], get["k1"] / c ** 2, get["k2"] / c ** 4,
                    get["k3"] / c ** 6, get["p2"] / c, -get["p1"] / c,
                    (get["fx"] - c) / c, 0.0, 0.0])
    return out if r0 == 0 else change_r0(out, r0)


# --------------------------------------------------------------------------
# brown
# --------------------------------------------------------------------------
def aicon_to_brown(params, strict=True) -> np.ndarray:
    """Exact conversion aicon -> brown of the pinhole part and the affinity.

    ``c``, ``x0 = xh``, ``y0 = yh`` unchanged, ``B1 = -C1 / (1 + C1)``,
    ``B2 = -C2 / (1 + C1)`` (brown's B1, B2 are its affinity and shear),
    K, P = 0.

    Raises
    ------
    InputError
        With ``strict=True`` if A1-A3, B1 or B2 is non-zero.
    """
    p = _vector(params, "aicon")
    if strict:
        _refuse(_nonzero(p, "aicon", ("A1", "A2", "A3", "B1", "B2")), "aicon", "brown",
                "a polynomial distortion of ideal coordinates is no polynomial "
                "correction of measured ones")
    C1, C2 = p[8], p[9]
    b = camera_model("brown")
    out = np.zeros(b.n_params)
    for name, value in (("c", p[_C]), ("x0", p[_XH]), ("y0", p[_YH]),
                        ("B1", -C1 / (1.0 + C1)), ("B2", -C2 / (1.0 + C1))):
        out[b.index(name)] = value
    return out


def brown_to_aicon(params, r0=0.0, strict=True) -> np.ndarray:
    """Exact conversion brown -> aicon of the pinhole part and the affinity.

    ``c``, ``xh = x0``, ``yh = y0``, ``C1 = -B1 / (1 + B1)``,
    ``C2 = -B2 / (1 + B1)``, A, B = 0 (r0 is then irrelevant; it is set to
    ``r0``).

    Raises
    ------
    InputError
        With ``strict=True`` if K1-K3, P1 or P2 is non-zero.
    """
    p = _vector(params, "brown")
    if strict:
        _refuse(_nonzero(p, "brown", ("K1", "K2", "K3", "P1", "P2")), "brown", "aicon",
                "a polynomial correction of measured coordinates is no polynomial "
                "distortion of ideal ones")
    b = camera_model("brown")
    B1, B2 = p[b.index("B1")], p[b.index("B2")]
    return np.array([p[b.index("c")], p[b.index("x0")], p[b.index("y0")], 0, 0, 0, 0, 0,
                     -B1 / (1.0 + B1), -B2 / (1.0 + B1), float(r0)])
