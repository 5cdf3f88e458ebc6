"""What the chain of measured rotation differences says about the
offsets of :mod:`photogram.mocap.reconstruction.chain_offsets`, and the
noise figures that weight it (unknown rotations, issue 22).

* :class:`ChainLinks`: the random walk between consecutive knots and the
  lagged differences (over more than one frame) as linear links between
  knots;
* the consecutive differences' error per pair:
  :func:`photogram.mocap.motion.rotation_series.difference_noise`;
* :func:`lagged_noise`: the lagged differences' error, from their
  disagreement with the chain;
* :func:`correlation_inflation`: how much the detections' temporal
  correlation inflates the variance of their mean.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.rotations import matrix_to_rodrigues

__all__ = ["ChainLinks", "lagged_noise", "correlation_inflation", "observation_joints"]


def observation_joints(use):
    """Joint index of every used observation, in the order of :func:`_terms`."""
    return np.nonzero(use > 0)[2]


def correlation_inflation(r, f, c, j, inlier, shape, max_lag: int) -> float:
    """``1 + 2 sum_k rho_k``: how much the temporal correlation of the
    detection errors inflates the variance of their mean (the effective
    number of independent detections is the count divided by it; Geyer's
    initial positive sequence, lags 1 .. ``max_lag``). ``r`` (N, 2)
    residuals of the observations at frame ``f``, camera ``c``, joint ``j``
    (N,), only the ``inlier`` ones counted; ``shape`` (F, C, J). Detectors
    err alike on consecutive video frames and per joint definition (the
    harsh simulator: half the variance smoothed over 4 frames plus a bias
    per camera and joint); counted as independent, 450 frames would
    overrule the chain's prior."""
    F, C, J = shape
    res = np.full((F, C * J, 2), np.nan)
    keep = inlier & np.all(np.isfinite(r), axis=1)
    res[f[keep], (c * J + j)[keep]] = r[keep]
    if not keep.any():
        return 1.0
    var = np.nanmean(res ** 2)
    if not np.isfinite(var) or var <= 0:
        return 1.0
    total = 0.0
    for k in range(1, min(max_lag, F - 1) + 1):
        prod = res[k:] * res[:-k]
        rho = np.nanmean(prod) / var if np.isfinite(prod).any() else 0.0
        if not np.isfinite(rho) or rho <= 0:
            break
        total += rho
    return float(1.0 + 2.0 * total)


class ChainLinks:
    """What the chain says about the offsets: between consecutive knots of
    a camera the random walk of its differences (``r = log(O_k0^T O_k1)``,
    variance ``sigma^2`` per pair times the frames between them; residual
    ``r + theta_k1 - theta_k0``), and for every measured difference over
    more than one frame (``lagged``: camera, first frame a, second frame b,
    dR, sigma) ``r = log(O(a)^T P^T O(b))`` with ``P = Q(b)^T dR Q(a)``,
    zero where ``R = Q O`` reproduces it (residual ``r + theta(b) -
    theta(a)``, theta interpolated between knots by ``interpolate`` (the
    offsets' :func:`~photogram.mocap.reconstruction.chain_offsets.interpolate_offsets`); variance its own plus the
    random walk's between each frame and its knots, :func:`_bridge`). ``knots`` (M, 4),
    ``coefs`` (M, 4) and ``var`` (M,) give the linearisation."""

    def __init__(self, track, Q, sigma_pair, lagged=None, interpolate=None):
        k0, k1 = _knot_pairs(track)
        self.n_walk = len(k0)
        knots = [np.column_stack([k0, k1, k0, k0])]
        coefs = [np.column_stack([-np.ones(len(k0)), np.ones(len(k0)), np.zeros((len(k0), 2))])]
        var = [sigma_pair[track.camera[k0]] ** 2 * (track.frame[k1] - track.frame[k0])]
        self.lagged = None
        if lagged is not None and len(lagged[0]):
            cam, a, b, dR, sig = (np.asarray(v) for v in lagged)
            F = track.knot.shape[0]
            inside = (a >= 0) & (b < F) & (a < b)
            a, b = np.where(inside, a, 0), np.where(inside, b, 0)
            ok = inside & (track.knot[a, cam, 0] >= 0) & np.isfinite(dR).all(axis=(1, 2)) \
                & (sig > 0) & (_segment(track, a, cam) == _segment(track, b, cam))
            cam, a, b, dR, sig = cam[ok], a[ok], b[ok], dR[ok], sig[ok]
            P = np.swapaxes(Q[b, cam], -1, -2) @ dR @ Q[a, cam]
            self.lagged = (cam, a, b, P)
            ka, kb = track.knot[a, cam], track.knot[b, cam]
            al, bl = track.alpha[a, cam], track.alpha[b, cam]
            knots.append(np.column_stack([ka[:, 0], ka[:, 1], kb[:, 0], kb[:, 1]]))
            coefs.append(np.column_stack([al - 1.0, -al, 1.0 - bl, bl]))
            var.append(sig.astype(float) ** 2 + sigma_pair[cam] ** 2 * (
                _bridge(track, ka, al) + _bridge(track, kb, bl)))
        self.knots = np.concatenate(knots).astype(int)
        self.coefs = np.concatenate(coefs)
        self.var = np.concatenate(var)
        self._k0, self._k1 = k0, k1
        self._interpolate = interpolate     # track -> O(t) (F, C, 3, 3), for lagged links

    def residuals(self, track) -> np.ndarray:
        """r0 (M, 3) of the links at the current knots."""
        out = [matrix_to_rodrigues(np.swapaxes(track.O[self._k0], -1, -2) @ track.O[self._k1])]
        if self.lagged is not None:
            cam, a, b, P = self.lagged
            Oi = self._interpolate(track)
            out.append(matrix_to_rodrigues(np.swapaxes(Oi[a, cam], -1, -2)
                                           @ np.swapaxes(P, -1, -2) @ Oi[b, cam]))
        return np.concatenate(out)


def _segment(track, t, cam):
    """Run segment (an index) of frames ``t`` of cameras ``cam``: knots are
    numbered camera by camera and segment by segment (:func:`offset_knots`),
    and a knot starts a segment where it is not linked to the one before."""
    k0, k1 = _knot_pairs(track)
    linked = np.zeros(len(track.frame), bool)
    linked[k1[k1 == k0 + 1]] = True
    seg = np.cumsum(~linked)
    return seg[track.knot[t, cam, 0]]


def lagged_noise(Q, lagged, sigma_pair) -> np.ndarray:
    """Error per axis (rad) of every camera's lagged differences, from their
    disagreement with the chain of consecutive ones over the same frames:
    ``e = log((Q(b) Q(a)^T)^T dR)`` has variance ``sigma_lag^2 + (b - a)
    sigma_pair^2`` per axis (the chain's random walk over b - a pairs);
    robustly (1.4826 MAD), floored at ``sigma_pair / 2``. ``lagged`` =
    (camera, a, b, dR); returns (C,) (NaN for cameras without)."""
    cam, a, b, dR = (np.asarray(v) for v in lagged[:4])
    C = Q.shape[1]
    out = np.full(C, np.nan)
    if not len(cam):
        return out
    pred = Q[b, cam] @ np.swapaxes(Q[a, cam], -1, -2)
    e = matrix_to_rodrigues(np.swapaxes(pred, -1, -2) @ dR)
    for c in np.unique(cam):
        m = cam == c
        ec = e[m] - np.median(e[m], axis=0)
        var = (1.4826 * np.median(np.abs(ec))) ** 2 - np.median(b[m] - a[m]) * sigma_pair[c] ** 2
        out[c] = np.sqrt(max(var, (sigma_pair[c] / 2) ** 2))
    return out


def _bridge(track, k, alpha):
    """Frames' worth of random-walk variance between a frame and the
    interpolation of its two knots ``k`` (n, 2) at ``alpha`` (the Brownian
    bridge: ``(t - f0)(f1 - t) / (f1 - f0)``): the offsets' model error."""
    span = track.frame[k[:, 1]] - track.frame[k[:, 0]]
    return alpha * (1.0 - alpha) * span


def _knot_pairs(track):
    """Consecutive knots of one camera and segment: (first, second) indices."""
    k = track.knot.reshape(-1, 2)
    k = np.unique(k[(k[:, 0] >= 0) & (k[:, 0] != k[:, 1])], axis=0)
    return k[:, 0], k[:, 1]
