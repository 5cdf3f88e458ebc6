"""Covariance propagation for the stick model, and the speed of O.

Per exposure ``i`` the inputs are the 18 numbers ``x_i = (P1, P2, P3, P4, d1,
d2)`` with covariance ``C_i`` (18 x 18; points and directions uncorrelated
unless a full matrix is given). Every parameter except ``v`` depends on its
own exposure only, with the analytic Jacobian ``J_i`` (7 x 18) of
:func:`photogram.jump.definitions.parameters`, so

    Cov(theta_i) = J_i C_i J_i^T.

The speed ``v_i = |O_b - O_a| / (t_b - t_a)`` uses the neighbours ``a = i-1,
b = i+1`` (central difference) or, at the first and last exposure, the
exposure itself and its one neighbour. With ``g = e / (t_b - t_a)``, ``e`` the
unit vector of ``O_b - O_a``, and exposures independent:

    var(v_i) = g^T (C_O[a] + C_O[b]) g,      C_O[k] = J_O[k] C_k J_O[k]^T,

and at the ends (``b = i`` or ``a = i``) ``v_i`` is correlated with the other
parameters of exposure ``i``: ``Cov(v_i, theta_i) = ± g^T J_O[i] C_i J_i^T``.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError
from photogram.jump.definitions import N_INPUTS

__all__ = ["exposure_frames", "speed_pairs", "speed", "input_covariance",
           "propagate"]


def exposure_frames(times: np.ndarray, fps: float) -> np.ndarray:
    """Frame numbers (0 at the first exposure) of the exposure ``times``.

    Raises
    ------
    InputError
        Times not finite, not increasing or not on the ``1/fps`` grid.
    """
    times = np.asarray(times, dtype=float)
    if not np.all(np.isfinite(times)):
        raise InputError("exposure times must be finite", hint="drop or fill the NaN times")
    if np.any(np.diff(times) <= 0):
        raise InputError("exposure times must be strictly increasing")
    if times.size == 0:
        return np.zeros(0, dtype=int)
    f = (times - times[0]) * fps
    frames = np.rint(f).astype(int)
    off = np.abs(f - frames)
    if np.any(off > 0.25):
        k = int(np.argmax(off))
        raise InputError(f"exposure {k} at t = {times[k]:g} s is {off[k]:.2f} frames off the "
                         f"{fps:g} fps grid", hint="check fps= or the times")
    return frames


def speed_pairs(frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(a, b)`` of the two exposures the speed of each exposure is
    taken from; -1 where a needed neighbour exposure is missing.

    Inside the series: the previous and next frame (central difference); at
    the first / last exposure: itself and the next / previous frame.
    """
    n = len(frames)
    a = np.full(n, -1)
    b = np.full(n, -1)
    if n < 2:
        return a, b
    has_prev = np.zeros(n, dtype=bool)
    has_next = np.zeros(n, dtype=bool)
    has_prev[1:] = np.diff(frames) == 1
    has_next[:-1] = np.diff(frames) == 1
    idx = np.arange(n)
    inner = (idx > 0) & (idx < n - 1) & has_prev & has_next
    a[inner], b[inner] = idx[inner] - 1, idx[inner] + 1
    if has_next[0]:
        a[0], b[0] = 0, 1
    if has_prev[n - 1]:
        a[n - 1], b[n - 1] = n - 2, n - 1
    return a, b


def speed(O: np.ndarray, times: np.ndarray, a: np.ndarray, b: np.ndarray):
    """Speed of O from the exposure pairs of :func:`speed_pairs`.

    Returns
    -------
    v : ndarray (n,)
        Speed (length unit per second); NaN where a pair is missing.
    velocity : ndarray (n, 3)
        ``(O_b - O_a) / (t_b - t_a)``.
    g : ndarray (n, 3)
        ``dv/dO_b = -dv/dO_a``.
    """
    n = len(O)
    ok = (a >= 0) & (b >= 0)
    velocity = np.full((n, 3), np.nan)
    dt = times[b[ok]] - times[a[ok]]
    velocity[ok] = (O[b[ok]] - O[a[ok]]) / dt[:, None]
    v = np.linalg.norm(velocity, axis=1)
    g = np.full((n, 3), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        g[ok] = velocity[ok] / v[ok, None] / dt[:, None]
    return v, velocity, g


def _as_stack(C, n: int, shapes: dict[tuple, int], what: str) -> np.ndarray:
    """Bring a covariance given in one of ``shapes`` (without or with the
    leading n) to (n, k, k)."""
    C = np.asarray(C, dtype=float)
    for shape, k in shapes.items():
        for full in (shape, (n,) + shape):
            if C.shape == full:
                if shape[-1] != k:   # per-item blocks (m, 3, 3): block diagonal
                    m = shape[0]
                    B = np.broadcast_to(C, (n,) + shape)
                    out = np.zeros((n, k, k))
                    for j in range(m):
                        out[:, 3 * j:3 * j + 3, 3 * j:3 * j + 3] = B[:, j]
                    return out
                return np.array(np.broadcast_to(C, (n, k, k)))
    allowed = ", ".join(f"(n,){s} or {s}" for s in shapes)
    raise InputError(f"{what} covariance has shape {C.shape}", hint=f"use {allowed}")


def input_covariance(n: int, cov_points=None, cov_dirs=None, cov=None) -> np.ndarray:
    """Covariance (n, 18, 18) of the inputs (P1..P4, d1, d2) per exposure.

    Parameters
    ----------
    cov_points : array (n, 12, 12), (n, 4, 3, 3) or without the leading n
        Points P1..P4 (None: error-free).
    cov_dirs : array (n, 6, 6), (n, 2, 3, 3) or without the leading n
        Ski directions d1, d2 (None: error-free); rank-2 covariances (no
        component along the direction) are fine.
    cov : array (n, 18, 18), optional
        The full matrix instead (e.g. with point-direction correlations).
    """
    if cov is not None:
        if cov_points is not None or cov_dirs is not None:
            raise InputError("give either cov= or cov_points=/cov_dirs=, not both")
        C = _as_stack(cov, n, {(18, 18): 18}, "input")
    else:
        C = np.zeros((n, N_INPUTS, N_INPUTS))
        if cov_points is not None:
            C[:, :12, :12] = _as_stack(cov_points, n, {(12, 12): 12, (4, 3, 3): 12}, "point")
        if cov_dirs is not None:
            C[:, 12:, 12:] = _as_stack(cov_dirs, n, {(6, 6): 6, (2, 3, 3): 6}, "direction")
    asym = np.abs(C - np.swapaxes(C, 1, 2))
    if np.nanmax(asym, initial=0.0) > 1e-9 * max(np.nanmax(np.abs(C), initial=0.0), 1e-300):
        raise InputError("covariance matrices must be symmetric")
    return C


def propagate(J: np.ndarray, J_O: np.ndarray, C: np.ndarray, a: np.ndarray,
              b: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Covariance (n, p+1, p+1) of the p per-exposure parameters and ``v``.

    Parameters
    ----------
    J : ndarray (n, p, 18)
        Jacobians of the parameters (all but v) by exposure.
    J_O : ndarray (n, 3, 18)
        Jacobian of O by exposure.
    C : ndarray (n, 18, 18)
        Input covariances (:func:`input_covariance`).
    a, b, g :
        From :func:`speed_pairs` and :func:`speed`.
    """
    n, p, _ = J.shape
    out = np.full((n, p + 1, p + 1), np.nan)
    out[:, :p, :p] = J @ C @ np.swapaxes(J, 1, 2)
    C_O = J_O @ C @ np.swapaxes(J_O, 1, 2)                 # (n, 3, 3)
    ok = (a >= 0) & (b >= 0)
    i = np.flatnonzero(ok)
    ga = g[i]
    CO_sum = C_O[a[i]] + C_O[b[i]]
    out[i, p, p] = np.einsum("ni,nij,nj->n", ga, CO_sum, ga)
    # cross-covariance with the own exposure's parameters (one-sided ends only)
    sign = np.where(b[i] == i, 1.0, np.where(a[i] == i, -1.0, 0.0))
    Jv_own = sign[:, None] * np.einsum("ni,nim->nm", ga, J_O[i])     # (k, 18)
    cross = np.einsum("nm,nmk,npk->np", Jv_own, C[i], J[i])
    out[i, p, :p] = cross
    out[i, :p, p] = cross
    return out
