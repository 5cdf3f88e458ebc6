"""Coarse, integer camera offsets (docs/mocap.md, section 13; step 1 of
:mod:`photogram.mocap.evaluation.sync`): the median distance between two
cameras' rays of the same joints over integer lags (used), and Pose2Sim's
time-lagged correlation of keypoint speed profiles (reported)."""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfiltfilt

__all__ = ["MIN_CONFIDENCE", "speed_profile", "lagged_correlation", "coarse_offsets",
           "world_bearings", "ray_distance_lags"]

#: detections used (Pose2Sim's likelihood threshold, as the reprojection errors)
MIN_CONFIDENCE = 0.3


def speed_profile(obs_c: np.ndarray, fps: float, min_confidence: float = MIN_CONFIDENCE,
                  cutoff_hz: float = 6.0) -> np.ndarray:
    """Speed (F,) of the projection-normalised pose of one camera.

    Per frame the joints are centred on their median and divided by their
    median distance to it; each joint's normalised track is linearly
    interpolated over missing frames (as Pose2Sim's
    ``interpolate_zeros_nans``), the speed is the sum over joints of the 2D
    frame-to-frame displacement, low-pass filtered (Butterworth of order 2
    applied forward and backward, ``cutoff_hz``; Pose2Sim's
    ``filter_cutoff`` 6 Hz). NaN where no joint is tracked.
    """
    ok = (np.nan_to_num(obs_c[..., 2]) >= min_confidence) & np.all(
        np.isfinite(obs_c[..., :2]), -1)
    xy = np.where(ok[..., None], obs_c[..., :2], np.nan)
    F, J = ok.shape
    with np.errstate(invalid="ignore"):
        enough = ok.sum(1) >= 3
        centre = np.full((F, 2), np.nan)
        scale = np.full(F, np.nan)
        if enough.any():
            centre[enough] = np.nanmedian(xy[enough], axis=1)
            scale[enough] = np.nanmedian(np.linalg.norm(xy[enough] - centre[enough, None],
                                                        axis=-1), axis=1)
    p = (xy - centre[:, None]) / np.where(scale > 0, scale, np.nan)[:, None, None]
    good = np.all(np.isfinite(p), -1)
    keep = good.sum(0) >= max(4, F // 2)
    if not keep.any():
        return np.full(F, np.nan)
    t = np.arange(F)
    tracks = []
    for j in np.nonzero(keep)[0]:
        g = good[:, j]
        tracks.append(np.stack([np.interp(t, t[g], p[g, j, k], left=np.nan, right=np.nan)
                                for k in range(2)], -1))
    P = np.stack(tracks, 1)                                   # (F, J', 2)
    v = np.full(F, np.nan)
    v[1:] = np.nansum(np.linalg.norm(np.diff(P, axis=0), axis=-1), axis=1)
    v[1:][np.all(~np.isfinite(np.diff(P, axis=0)[..., 0]), axis=1)] = np.nan
    fin = np.isfinite(v)
    if fin.sum() < 16 or cutoff_hz >= fps / 2:
        return v
    seg = _longest_run(fin)
    sos = butter(2, cutoff_hz / (fps / 2), output="sos")
    out = np.full(F, np.nan)
    vi = np.interp(t[seg], t[fin], v[fin])
    out[seg] = sosfiltfilt(sos, vi, padlen=min(len(vi) - 1, 15))
    return out


def _longest_run(mask):
    idx = np.nonzero(mask)[0]
    return slice(int(idx[0]), int(idx[-1]) + 1)


def lagged_correlation(ref: np.ndarray, other: np.ndarray, max_lag: int,
                       min_overlap: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Pearson r between ``ref[f]`` and ``other[f + k]`` for k in
    ``-max_lag..max_lag`` (Pose2Sim's ``time_lagged_cross_corr``; NaN
    frames left out; NaN where fewer than ``min_overlap`` frames overlap)."""
    lags = np.arange(-max_lag, max_lag + 1)
    r = np.full(len(lags), np.nan)
    F = len(ref)
    for i, k in enumerate(lags):
        a = ref[max(0, -k):F - max(0, k)]
        b = other[max(0, k):F + min(0, k)]
        ok = np.isfinite(a) & np.isfinite(b)
        if ok.sum() >= min_overlap and np.std(a[ok]) > 0 and np.std(b[ok]) > 0:
            r[i] = np.corrcoef(a[ok], b[ok])[0, 1]
    return lags, r


def coarse_offsets(obs: np.ndarray, fps: float, reference: int, max_lag: int):
    """Integer offsets (C,) and their peak correlations (C,) against camera
    ``reference`` (:func:`speed_profile`, :func:`lagged_correlation`); a
    camera without a usable profile gets 0 and correlation NaN."""
    C = obs.shape[1]
    prof = [speed_profile(obs[:, c], fps) for c in range(C)]
    off = np.zeros(C, int)
    peak = np.full(C, np.nan)
    peak[reference] = 1.0
    for c in range(C):
        if c == reference:
            continue
        lags, r = lagged_correlation(prof[reference], prof[c], max_lag)
        if np.any(np.isfinite(r)):
            i = int(np.nanargmax(r))
            off[c], peak[c] = int(lags[i]), float(r[i])
    return off, peak


# --------------------------------------------------------------------------
# fine: triangulate from the others, reproject into the camera under test
def world_bearings(cameras, obs: np.ndarray, min_confidence: float = MIN_CONFIDENCE):
    """Unit rays (F, C, J, 3) in world axes of the detections (NaN: not
    used) and their weights (F, C, J) (the confidences). ``cameras``:
    :class:`photogram.mocap.reconstruction.cameras.MocapCameras` (ideal
    coordinates ``t`` of its ``to_rays``: camera direction ``(t_x, -t_y,
    -1)``, world ``R^T d``)."""
    F = obs.shape[0]
    ok = (np.nan_to_num(obs[..., 2]) >= min_confidence) & np.all(np.isfinite(obs[..., :2]), -1)
    xy = np.where(ok[..., None], obs[..., :2], np.nan)
    t = cameras.to_rays(xy)
    d = np.stack([t[..., 0], -t[..., 1], -np.ones(t.shape[:-1])], -1)
    R = cameras.rotations(F)
    u = np.einsum("fcba,fcjb->fcja", R, d)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    w = np.where(ok & np.all(np.isfinite(u), -1), obs[..., 2], 0.0)
    u[w == 0] = np.nan
    return u, w


def ray_distance_lags(u: np.ndarray, X0: np.ndarray, ref: int, c: int, max_lag: int):
    """Median distance (world unit) between the rays of camera ``ref`` at
    frame f and those of camera ``c`` at frame f + k, for k in
    ``-max_lag..max_lag`` (the epipolar constraint: rays of the same joint
    at the same instant meet; NaN with fewer than 20 pairs)."""
    F = u.shape[0]
    lags = np.arange(-max_lag, max_lag + 1)
    out = np.full(len(lags), np.nan)
    base = X0[c] - X0[ref]
    for i, k in enumerate(lags):
        a = u[max(0, -k):F - max(0, k), ref]
        b = u[max(0, k):F + min(0, k), c]
        n = np.cross(a, b)
        with np.errstate(invalid="ignore", divide="ignore"):
            d = np.abs(n @ base) / np.linalg.norm(n, axis=-1)
        d = d[np.isfinite(d)]
        if len(d) >= 20:
            out[i] = np.median(d)
    return lags, out
