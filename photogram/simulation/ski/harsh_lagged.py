"""SIMULATED lagged rotation differences of the harsh setting: frames t and
t+k (k in ``HarshSettings.dr_lags``) whose views still overlap.

THE DATA OF THIS MODULE ARE SIMULATED (truth + the noise model below). A
pair (t, t+k) of a camera exists when the true rotation between the frames,
``theta = |rotvec(R(t+k) R(t)^T)|``, is below ``dr_lag_max_fraction`` of
the horizontal field of view ``fov = min(fov(t), fov(t+k))`` (from the
simulated zoom, ``2 atan(W / 2 f_x)``), as
:func:`photogram.mocap.motion.homography.rotation_differences` attempts
them (it predicts theta from the chained consecutive differences). Noise
model, per pair, ``u = theta / fov`` (0 .. ``dr_lag_max_fraction``):

* **scale error** (a zoom calibration error): the pan and tilt components
  (x, y of the rotation vector in the camera frame; not the roll) are
  multiplied by ``1 + s``, ``s = +-dr_lag_scale`` (0.3 %), its sign drawn
  once per camera: the same over the camera's run, so the errors of the
  pairs are correlated (they do not average out);
* **noise**: ``dr_noise_deg / (1 - u)`` per axis (0.03 deg, up to twice
  that at half the field of view: fewer, more peripheral common features;
  on rendered frames the median error of lagged pairs rises from about
  0.01 deg below u = 0.2 to 0.02-0.05 deg at u = 0.3-0.5);
* **wrong pairs** at the consecutive rate ``dr_wrong`` (0.5-3 deg off,
  accepted with 15-40 inliers); **failures** at ``dr_failed`` plus
  ``dr_lag_fail * (u / dr_lag_max_fraction)^2`` (up to 30 % more at the
  limit: the overlap shrinks), independently per pair (NaN, ``ok`` 0,
  4-12 inliers);
* **inliers** of a good pair: ``matches * U(0.6, 0.95) * (1 - u)`` (the
  shared part of the view), so that the confident-pair rule
  (:func:`photogram.mocap.motion.unknown_rotations.lagged_arrays`) drops
  some pairs near the limit, as on images.

The consecutive pairs of the simulator carry no scale error (their random
numbers are those of earlier versions, byte for byte): over a chain of
consecutive pairs the real error would add up to 0.3 % of the total turn.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.rotations import matrix_to_rodrigues, rodrigues_to_matrix

__all__ = ["simulated_lagged_differences", "fields_of_view"]


def fields_of_view(io, width: float) -> np.ndarray:
    """(F,) horizontal field of view (rad) of the frames' interior
    orientations ``io`` (F, p), OpenCV (``f_x`` first), image ``width`` px."""
    io = np.atleast_2d(np.asarray(io, float))
    return 2.0 * np.arctan(0.5 * float(width) / io[:, 0])


def _lag(R, fov, k, st, rng, scale):
    """Arrays (first, second, dR, inliers, matches, ok) of lag k of one
    camera (R (F, 3, 3) world-to-camera, fov (F,) rad)."""
    F = len(R)
    n = max(F - k, 0)
    t = np.arange(n)
    # the draws have fixed shapes (every candidate pair), selected afterwards
    noise = rng.normal(0, 1, (n, 3))
    wrong = rng.uniform(0, 1, n) < st.dr_wrong
    big = rng.normal(0, 1, (n, 3))
    big *= (np.radians(rng.uniform(0.5, 3.0, n)) / np.linalg.norm(big, axis=1))[:, None]
    fail_draw = rng.uniform(0, 1, n)
    matches = rng.integers(220, 420, n)
    share = rng.uniform(0.6, 0.95, n)
    bad_inliers, wrong_inliers = rng.integers(4, 12, n), rng.integers(15, 40, n)
    true = R[t + k] @ np.swapaxes(R[t], -1, -2)
    rv = matrix_to_rodrigues(true).reshape(n, 3)
    u = np.linalg.norm(rv, axis=1) / np.minimum(fov[t], fov[t + k])
    keep = u < st.dr_lag_max_fraction
    measured = rv * np.array([1.0 + scale, 1.0 + scale, 1.0])
    noise *= (np.radians(st.dr_noise_deg) / np.maximum(1.0 - u, 0.05))[:, None]
    noise[wrong] = big[wrong]
    dR = rodrigues_to_matrix(noise) @ rodrigues_to_matrix(measured)
    failed = fail_draw < st.dr_failed + st.dr_lag_fail * (u / st.dr_lag_max_fraction) ** 2
    inliers = np.where(failed, bad_inliers,
                       np.where(wrong, wrong_inliers,
                                (matches * share * np.clip(1.0 - u, 0, 1)).astype(int)))
    dR[failed] = np.nan
    return t[keep], t[keep] + k, dR[keep], inliers[keep], matches[keep], ~failed[keep]


def simulated_lagged_differences(R, io, width: float, st, rng):
    """:class:`photogram.mocap.motion.homography.LaggedDifferences` of one
    camera (module doc).

    Parameters
    ----------
    R : (F, 3, 3)
        True world-to-camera rotations.
    io : (F, p)
        Interior orientation per frame (OpenCV, ``f_x`` first).
    width : float
        Image width, px.
    st : HarshSettings
        ``dr_lags``, ``dr_lag_max_fraction``, ``dr_lag_scale``, ``dr_lag_fail``,
        ``dr_noise_deg``, ``dr_failed``, ``dr_wrong``.
    rng : numpy.random.Generator
        The lagged pairs' own stream (the consecutive pairs' draws unchanged).
    """
    from photogram.mocap.motion.homography import LaggedDifferences
    R = np.asarray(R, float)
    fov = fields_of_view(io, width)
    if len(fov) == 1:
        fov = np.repeat(fov, len(R))
    scale = st.dr_lag_scale * (1.0 if rng.uniform() < 0.5 else -1.0)
    parts = [_lag(R, fov, k, st, rng, scale) for k in sorted({int(k) for k in st.dr_lags})]
    if not parts:
        return LaggedDifferences.empty()
    first, second, dR, inliers, matches, ok = (np.concatenate(v) for v in zip(*parts))
    return LaggedDifferences(first.astype(int), second.astype(int), dR.reshape(-1, 3, 3),
                             inliers.astype(int), matches.astype(int), ok.astype(bool))
