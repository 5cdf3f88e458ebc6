"""Synchronisation of the cameras: per-camera frame offsets from the 2D
detections (issue 20, item 5; docs/mocap.md, "Synchronisation").

Convention: camera c has the **offset** ``o_c`` (frames) when its frame
``f + o_c`` shows the instant of frame ``f`` of the reference camera (it
started recording ``o_c`` frames earlier). Applying the offset gives the
camera the detections ``obs_c[f + o_c]`` at frame ``f``
(:func:`shift_series`); a fractional offset interpolates linearly between
the two neighbouring frames.

Estimation, in two steps:

1. **coarse, integer** (:func:`ray_distance_lags`): the lag (within
   +-F/4) that minimises the median distance between the reference
   camera's rays and the camera's rays of the same joints at frames f and
   f + k (the epipolar constraint: rays of one joint at one instant meet).
   Pose2Sim's method (``synchronization.py``: ``synchronize_cams_all``,
   ``time_lagged_cross_corr``: the lag of the highest Pearson correlation
   of low-passed keypoint speed profiles) is computed too
   (:func:`coarse_offsets`, :func:`speed_profile`), with the keypoints first
   made independent of the projection (centred on the athlete's median
   joint and divided by the median distance of the joints to it, per frame,
   so that panning, zoom and distance do not enter), and reported; it is
   not used: on the simulated pan-tilt-zoom ski cameras its peaks are
   0.2-0.5 and its lags wrong by up to 57 frames.
2. **fine, fractional** (:func:`refine_offset`): the joints are
   triangulated from the *other* cameras (their current offsets applied;
   confidence-weighted midpoint of the world rays, Cauchy-reweighted) and
   projected into the camera under test at its frames ``f + k``; the
   weighted spread ``E(k)`` of the residuals about their weighted mean is
   computed at integer shifts ``k - 1, k, k + 1`` around the coarse value
   (moving while a side is lower) and the vertex of the parabola through
   them is the fractional offset. Near the minimum ``E(k) = s^2 + var(v)
   (k - o)^2`` to first order in the image velocity ``v``: a parabola whose
   vertex is the offset (the acceleration adds ``mean(v.a) (k - o)^3``,
   which moves the vertex by ``-mean(v.a) / (2 var(v))``: 0.01-0.03 frames on
   the simulated runs). Integer shifts only are evaluated (interpolating
   the camera's own detections would lower the noise term at half frames
   and pull the vertex there). The passes over all cameras are repeated,
   the others at their latest fractional offsets, until no offset changes
   by more than 0.01 frames (at most 8 passes): two cameras with
   fractional offsets bias each other's triangulations until both are
   known.

**Uncertainty**: a moving-block bootstrap over frames (blocks of 10
frames, 400 replicates; the per-frame sums of the errors are resampled and
the vertex recomputed), reported as the standard deviation of the
replicates. Chosen over the curvature of ``E`` (which assumes independent
errors of known variance) and the spread over joints (the joints of a
frame share the pose's motion and the detector's errors): detector errors
and the pose's motion are correlated over neighbouring frames, and blocks
keep that correlation. Offsets are re-referenced to the reference camera
(the one with the most detections; its offset is 0 by definition) and a
camera's uncertainty combines its own and the reference's in quadrature.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.mocap.evaluation.sync_coarse import (MIN_CONFIDENCE, coarse_offsets,
                                                    lagged_correlation, ray_distance_lags,
                                                    speed_profile, world_bearings)
from photogram.mocap.evaluation.sync_shift import (apply_offsets, shift_observations,
                                                   shift_rotations, shift_series)

__all__ = ["shift_series", "shift_observations", "shift_rotations", "apply_offsets",
           "speed_profile", "lagged_correlation", "coarse_offsets", "ray_distance_lags",
           "world_bearings", "triangulate_bearings", "refine_offset", "estimate_offsets",
           "SyncEstimate", "MIN_CONFIDENCE"]

_BLOCK = 10
_REPLICATES = 400


# --------------------------------------------------------------------------
# fine: triangulate from the others, reproject into the camera under test
def _norm3(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis (3): the sums np.linalg.norm forms,
    in its order (the same bits), without its overhead."""
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])


def triangulate_bearings(u: np.ndarray, w: np.ndarray, X0: np.ndarray,
                         iterations: int = 4) -> np.ndarray:
    """Points (F, J, 3) closest to the rays ``X0[c] + s u[f, c, j]``
    (weighted least squares of the perpendicular distances, the midpoint
    method of Hartley & Zisserman, section 12.1, generalised to n rays:
    ``sum w (I - u u^T) X = sum w (I - u u^T) X0``), reweighted by a Cauchy
    function of the ray's angular residual (scale: 2 x the median
    residual); NaN where fewer than two rays."""
    ok = w > 0
    uu = np.where(ok[..., None], u, 0.0)                            # (F, C, J, 3)
    X0c = X0[None, :, None, :]
    ux0 = np.sum(uu * X0c, -1)                                      # (F, C, J)
    weights = np.where(ok, w, 0.0)
    two = ok.sum(1) >= 2
    eye = np.eye(3)
    uT = uu.transpose(0, 2, 1, 3)                                   # (F, J, C, 3)
    uc = uu.transpose(0, 2, 3, 1)                                   # (F, J, 3, C)
    X = np.full(u.shape[:1] + u.shape[2:], np.nan)
    for it in range(iterations):
        sw = weights.sum(1)                                         # (F, J)
        wu = weights.transpose(0, 2, 1)[:, :, None, :] * uc          # (F, J, 3, C)
        A = sw[..., None, None] * eye - wu @ uT
        b = weights.transpose(0, 2, 1) @ X0 - np.einsum("fjac,fcj->fja", wu, ux0)
        det = np.linalg.det(A)
        good = two & (np.abs(det) > 1e-12 * np.maximum(sw, 1e-300) ** 3)
        X = np.full(b.shape, np.nan)
        X[good] = np.linalg.solve(A[good], b[good][..., None])[..., 0]
        if it == iterations - 1:
            break
        d = X[:, None] - X0c                                        # (F, C, J, 3)
        along = np.sum(uu * d, -1)
        with np.errstate(invalid="ignore", divide="ignore"):
            ang = _norm3(d - along[..., None] * uu) / _norm3(d)
        if not np.any(ok & np.isfinite(ang)):
            break
        scale = 2.0 * np.median(ang[ok & ~np.isnan(ang)]) + 1e-12    # = nanmedian
        weights = np.where(ok, w / (1.0 + (np.nan_to_num(ang) / scale) ** 2), 0.0)
    return X


def _projected(cameras, c: int, X: np.ndarray, k: int) -> np.ndarray:
    """Projections (F, J, 2) of X (F, J, 3) (frame f) into camera c at its
    frames f + k (its per-frame rotation and zoom; edge frames repeated)."""
    F = X.shape[0]
    cam = cameras.select_cameras([cameras.names[c]])
    if cam.n_frames:
        cam = cam.select_frames(np.clip(np.arange(F) + k, 0, cam.n_frames - 1))
    return cam.project(X)[:, 0]


def _residuals(cameras, c, X, obs_c, k):
    """(F, J, 2) reprojection residuals, detection ``obs_c[f + k]`` minus
    X[f] projected into camera c at its frame f + k (NaN: not available)."""
    det = shift_series(np.where((np.nan_to_num(obs_c[..., 2]) >= MIN_CONFIDENCE)[..., None],
                                obs_c[..., :2], np.nan), k)
    return det - _projected(cameras, c, X, k)


def _vertex(Em, E0, Ep):
    den = Em - 2 * E0 + Ep
    with np.errstate(invalid="ignore", divide="ignore"):
        v = 0.5 * (Em - Ep) / den
    return np.where(den > 0, np.clip(v, -1.0, 1.0), np.where(Em < Ep, -1.0, 1.0))


def _block_weights(F: int, rng, block: int = _BLOCK, replicates: int = _REPLICATES):
    """(B, F) how often each frame is drawn by a moving-block bootstrap
    (Kunsch 1989): ceil(F / block) blocks of ``block`` consecutive frames."""
    block = max(1, min(block, F))
    n_blocks = int(np.ceil(F / block))
    starts = rng.integers(0, F - block + 1, (replicates, n_blocks))
    idx = (starts[..., None] + np.arange(block)).reshape(replicates, -1)[:, :F]
    W = np.zeros((replicates, F))
    np.add.at(W, (np.repeat(np.arange(replicates), idx.shape[1]), idx.ravel()), 1.0)
    return W


def _segment_distance(p, q):
    """Distance (...) from the origin to the segments p-q (..., 2)."""
    d = q - p
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip(-np.sum(p * d, -1) / np.sum(d * d, -1), 0.0, 1.0)
    t = np.nan_to_num(t)
    return np.linalg.norm(p + t[..., None] * d, axis=-1)


def _weighted_parabola(r):
    """Vertex (frames, in -1..1 about the middle shift) of the weighted
    mean squared residuals of ``r`` (3, F, J, 2) (shifts k-1, k, k+1).

    The weight of a detection is a Cauchy function (scale 2.385 x 1.4826 x
    the median: 95 % efficiency) of the smallest residual it reaches over
    the shifts k-1..k+1, the detection interpolated linearly in time (the
    distance from the origin to the polyline r[0], r[1], r[2]): an outlier
    fits at no shift, and the weight does not depend on where the vertex
    lies (weights taken at a trial vertex would pull the estimate towards
    it). ``E`` is the weighted mean squared deviation of the residuals from
    their weighted mean (per shift): a static bias of the camera (e.g. a
    principal point off by 20 px) would otherwise move the vertex by
    ``-b . mean(v) / mean|v|^2`` when the athlete drifts in the image.
    Returns the vertex, the per-frame sums (w |r|^2 (3, F), w r (3, F, 2),
    w (F,)) and E (3,)."""
    sq = np.sum(r * r, -1)                                          # (3, F, J)
    use = np.all(np.isfinite(sq), 0)
    sq = np.where(use[None], sq, 0.0)
    rr = np.where(use[None, ..., None], r, 0.0)
    e = np.minimum(_segment_distance(rr[0], rr[1]), _segment_distance(rr[1], rr[2]))
    scale = 2.385 * 1.4826 * float(np.median(e[use])) + 1e-9
    w = np.where(use, 1.0 / (1.0 + (e / scale) ** 2), 0.0)
    sums = (np.einsum("fj,kfj->kf", w, sq), np.einsum("fj,kfjd->kfd", w, rr), w.sum(1))
    E = _spread(sums[0].sum(1), sums[1].sum(1), sums[2].sum())
    return float(_vertex(E[0], E[1], E[2])), sums, E


def _spread(S2, S1, n):
    """Weighted mean squared deviation from the weighted mean residual,
    from the sums of w |r|^2 (..., 3), w r (..., 3, 2) and w (...)."""
    n = np.asarray(n, float)[..., None]
    return S2 / n - np.sum((S1 / n[..., None]) ** 2, -1)


def refine_offset(cameras, c: int, X: np.ndarray, obs_c: np.ndarray, start: int,
                  max_lag: int, rng) -> dict:
    """Fractional offset of camera c (module doc, step 2) against the points
    X (F, J, 3) triangulated from the other cameras, starting at the
    integer shift ``start``.

    Returns
    -------
    dict
        ``offset`` (frames), ``sigma`` (block bootstrap), ``shift`` (the
        integer shift at the minimum), ``errors_px`` (weighted RMS
        residuals at shifts -1, 0, +1 about it), ``n`` (detections used),
        ``bracketed`` (the minimum lies between the shifts tried); offset
        NaN when the camera has fewer than 10 usable detections.
    """
    cache = {}

    def res(k):
        if k not in cache:
            cache[k] = _residuals(cameras, c, X, obs_c, k)
        return cache[k]

    k = int(start)
    tried = set()
    while True:
        r = np.stack([res(k - 1), res(k), res(k + 1)])
        n_use = int(np.all(np.isfinite(r), axis=(0, 3)).sum())
        if n_use < 10:
            return {"offset": np.nan, "sigma": np.nan, "shift": k, "errors_px": None, "n": 0,
                    "bracketed": False}
        s, (S2, S1, n), E = _weighted_parabola(r)
        tried.add(k)
        step = int(np.sign(s)) if abs(s) >= 1.0 else 0
        if step == 0 or abs(k + step) > max_lag or (k + step) in tried:
            break
        k += step
    frames = np.nonzero(n > 0)[0]
    W = _block_weights(len(frames), rng)
    Eb = _spread(W @ S2[:, frames].T, np.einsum("bf,kfd->bkd", W, S1[:, frames]),
                 W @ n[frames])                                      # (B, 3)
    boot = _vertex(Eb[:, 0], Eb[:, 1], Eb[:, 2])
    return {"offset": float(k + s), "sigma": float(np.std(boot)), "shift": k,
            "errors_px": [float(np.sqrt(e)) for e in E], "n": n_use,
            "bracketed": bool(step == 0)}


# --------------------------------------------------------------------------
@dataclass
class SyncEstimate:
    """Offsets (frames) per camera against ``reference`` (module doc)."""

    names: list
    reference: str
    offsets: np.ndarray          # (C,) fractional, reference 0
    sigma: np.ndarray            # (C,) block bootstrap (with the reference's)
    coarse: np.ndarray           # (C,) integer, from the speed profiles
    correlation: np.ndarray      # (C,) peak Pearson r of the speed profiles
    details: dict = field(default_factory=dict)
    changes: list = field(default_factory=list)   # largest offset change per pass

    def as_dict(self) -> dict:
        """For summary.json."""
        out = {"reference": self.reference, "unit": "frames",
               "convention": "frame f + offset of the camera shows frame f of the reference",
               "uncertainty": "1 sigma, moving-block bootstrap over frames (10-frame blocks)",
               "pass_changes": [round(c, 5) for c in self.changes], "cameras": {}}
        for i, name in enumerate(self.names):
            d = self.details.get(name, {})
            out["cameras"][name] = {
                "offset": _num(self.offsets[i]), "sigma": _num(self.sigma[i]),
                "coarse": int(self.coarse[i]), "correlation": _num(self.correlation[i]),
                "speed_lag": d.get("speed_lag"),
                "errors_px": d.get("errors_px"), "n": d.get("n", 0),
                "bracketed": d.get("bracketed", False)}
        return out

    def lines(self) -> list[str]:
        """One log line per camera."""
        return [f"synchronisation: {name} offset {self.offsets[i]:+.2f} +- "
                f"{self.sigma[i]:.2f} frames against {self.reference} (coarse "
                f"{int(self.coarse[i]):+d}, speed correlation {self.correlation[i]:.2f})"
                for i, name in enumerate(self.names)]


def _num(v):
    return float(v) if np.isfinite(v) else None


def estimate_offsets(obs: np.ndarray, cameras, fps: float, *, max_lag: int | None = None,
                     reference: int | None = None, seed: int = 0, passes: int = 8,
                     tolerance: float = 0.01) -> SyncEstimate:
    """Offsets of every camera (module doc): coarse integer offsets from the
    rays (:func:`ray_distance_lags`), then passes of :func:`refine_offset`
    over all cameras (the others at their latest offsets) until the offsets
    change by less than ``tolerance`` frames (at most ``passes``).

    Parameters
    ----------
    obs : ndarray (F, C, J, 3)
        Detections x, y, confidence (unshifted).
    cameras : MocapCameras
        Per-frame rotations/zoom numbered like the detections.
    fps : float
    max_lag : int, optional
        Largest offset searched (default F // 4).
    reference : int, optional
        Default: the camera with the most detections.
    seed : int
        Of the bootstrap.
    """
    F, C = obs.shape[:2]
    valid = (np.nan_to_num(obs[..., 2]) >= MIN_CONFIDENCE).sum(axis=(0, 2))
    ref = int(np.argmax(valid)) if reference is None else int(reference)
    max_lag = max(1, F // 4) if max_lag is None else int(max_lag)
    speed_lag, corr = coarse_offsets(obs, fps, ref, max_lag)
    u, w = world_bearings(cameras, obs)
    coarse = np.zeros(C, int)
    for c in range(C):
        if c != ref and valid[c] > 0:
            lags, d = ray_distance_lags(u, cameras.X0, ref, c, max_lag)
            if np.any(np.isfinite(d)):
                coarse[c] = int(lags[np.nanargmin(d)])
    rng = np.random.default_rng(seed)
    current = coarse.astype(float)
    details = {}
    history = []
    for _ in range(passes):
        new = current.copy()
        for c in range(C):
            others = [o for o in range(C) if o != c and valid[o] > 0]
            if len(others) < 2 or valid[c] == 0:
                details[cameras.names[c]] = {"offset": np.nan, "sigma": np.nan, "n": 0}
                new[c] = np.nan
                continue
            us = np.stack([shift_series(u[:, o], current[o]) for o in others], 1)
            us /= np.linalg.norm(us, axis=-1, keepdims=True)
            ws = np.stack([np.nan_to_num(shift_series(w[:, o], current[o])) for o in others], 1)
            ws = np.where(np.all(np.isfinite(us), -1), ws, 0.0)
            X = triangulate_bearings(us, ws, cameras.X0[others])
            start = int(np.rint(current[c])) if np.isfinite(current[c]) else 0
            r = refine_offset(cameras, c, X, obs[:, c], start, max_lag, rng)
            details[cameras.names[c]] = r
            new[c] = r["offset"]
        change = np.nanmax(np.abs(new - current)) if np.any(np.isfinite(new)) else 0.0
        history.append(float(change))
        current = np.where(np.isfinite(new), new, current)
        if change < tolerance:
            break
    off = np.array([details[n]["offset"] for n in cameras.names], float)
    sig = np.array([details[n]["sigma"] for n in cameras.names], float)
    off_rel = off - off[ref]
    sig_rel = np.sqrt(sig ** 2 + sig[ref] ** 2)
    sig_rel[ref] = 0.0
    for c, name in enumerate(cameras.names):
        details[name]["speed_lag"] = int(speed_lag[c])
    return SyncEstimate(list(cameras.names), cameras.names[ref], off_rel, sig_rel, coarse,
                        corr, details, history)
