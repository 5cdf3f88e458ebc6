"""Frame-to-frame rotations of pan-tilt-zoom cameras from their images.

After Bachmann et al. (alpine skiing), eqs. (12)-(13): a camera that only
turns about its projection centre (and zooms) maps the background of frame
``t`` onto frame ``t+1`` by the homography ``H = K_{t+1} dR_cv K_t^{-1}``,
so ``dR_cv = K_{t+1}^{-1} H K_t``. Per camera and pair of consecutive frames:

1. ORB features (``cv2.ORB_create``) of every frame, computed once and used
   for both pairs the frame belongs to, *outside* the athlete's box (the box
   enlarged by ``box_margin`` of its size on every side; boxes in
   full-resolution px, NaN: no box);
2. keypoints back to full-resolution px (``x_full = (x + 0.5) / s - 0.5``),
   undistorted with the camera model (``image_to_ray``; the radial OpenCV
   model by :func:`photogram.mocap.motion.lens.undistort_radius`) and put on an
   ideal pinhole image of the same resolution (``K_t``: the model's scale
   and principal point at the image centre, times ``s``);
3. Hamming matching, guided by the previous pair's rotation (features within
   ``search_px`` of their predicted position, mutual best), exhaustive with
   cross-check for the first pair or when guiding finds too few inliers;
   RANSAC homography (``cv2.findHomography``, ``ransac_px`` at the image's
   resolution);
4. the rotation: ``method="homography"`` is eq. (13), the rotation nearest
   to ``K_{t+1}^{-1} H K_t`` scaled to determinant 1 (SVD);
   ``method="rays"`` (default) refits a pure rotation to the homography's
   inliers (orthogonal Procrustes on the unit rays, inliers re-selected by
   their reprojection error): with a narrow field of view the perspective
   terms of H are poorly determined, and eq. (13) inherits their errors
   (about 0.5 deg per pair on the simulated zoomed cameras, against 0.001
   deg for the refit). The photogrammetric difference is
   ``dR = D dR_cv D``, ``D = diag(1, -1, -1)``, with ``R(t+1) = dR[t] R(t)``;
5. a pair with fewer than ``min_inliers`` inliers failed (its dR is NaN);
6. lagged pairs (frames t-k and t for k in ``lags``, as panorama/keyframe
   registration does): the features of the last ``max(lags)`` frames are kept
   (a ring buffer); a pair is attempted when the consecutive pairs between
   the two frames were all measured and the rotation of their chain is
   below ``max_lag_fraction`` of the horizontal field of view of the
   narrower of the two frames (the views still overlap); it is matched
   guided by that chain (no exhaustive fallback) and fitted like a
   consecutive pair, with the same ``min_inliers``. A chain of consecutive
   differences is a random walk; a lagged pair measures the sum of k steps
   at once, with about the error of one step.

Filtering (median 3 and Gaussian sigma 3 of the rotation vectors; the paper's
median is 7), errors against the truth, the check of a camera and the CSV files
are in :mod:`photogram.mocap.motion.rotation_series`.

Assumed: the camera does not translate (pan-tilt head turning about the
projection centre), the background is static and far enough from the
athlete's box, and the interior orientation of every frame is known (zoom
read from the lens or estimated beforehand).
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np

from photogram.errors import InputError
from photogram.geometry import camera_model
from photogram.mocap.motion.homography_pair import (D, guided_matches, horizontal_fov,
                                                   pinhole_matrices, rotation_from_homography,
                                                   rotation_from_rays, undistort_points)

__all__ = ["HomographySettings", "LaggedDifferences", "RotationDifferences",
           "rotation_differences",
           "rotation_from_homography", "rotation_from_rays", "pinhole_matrices",
           "guided_matches", "undistort_points", "horizontal_fov"]

@dataclass
class HomographySettings:
    """Settings of the rotation estimation (module doc).

    ``n_levels``/``scale_factor`` are ORB's pyramid (frame-to-frame zoom
    changes are small, so few levels suffice), ``fast_threshold`` ORB's FAST
    threshold (snow has little contrast). ``method``: ``"homography"`` is
    eq. (13) as in the paper (the rotation nearest to ``K^-1 H K``);
    ``"rays"`` (default) refits a pure rotation to the RANSAC inliers of the
    homography (orthogonal Procrustes on the unit rays, twice, re-selecting
    the inliers by their reprojection error): the perspective terms of H are
    poorly determined by a narrow field of view, and eq. (13) inherits their
    errors (see :func:`rotation_from_rays`). ``search_px``: matching is
    guided by the previous pair's rotation (constant angular velocity): a
    feature is matched only with features within ``search_px`` of its
    predicted position (mutual best, Hamming distance <= ``max_hamming``);
    the first pair, a pair after a failure, or a guided pair with too few
    inliers is matched exhaustively (cross-checked); 0 disables guiding.
    ``median``/``sigma``: the filter of the rotation vectors (median of 3
    pairs, the paper's 7 clipped the peaks of fast pans and left a step of
    up to 7 deg in the chain); ``min_inlier_fraction``: a pair with fewer
    inliers than this fraction of the camera's median counts as failed in
    the filter (a homography fitted to few background points, often a wrong
    one; :func:`photogram.mocap.motion.rotation_series.confident_pairs`).
    ``lags``: the frame distances k > 1 of the lagged pairs (empty: none);
    ``max_lag_fraction``: a lagged pair is attempted only when the rotation
    predicted by the chained consecutive differences is below this fraction
    of the horizontal field of view at the narrower of the two zooms.
    """

    n_features: int = 1000
    ransac_px: float = 2.0
    min_inliers: int = 30
    box_margin: float = 0.25
    median: int = 3
    sigma: float = 3.0
    max_failed: float = 0.2
    min_inlier_fraction: float = 0.3
    n_levels: int = 3
    scale_factor: float = 1.3
    fast_threshold: int = 12
    method: str = "rays"
    search_px: float = 16.0
    max_hamming: int = 64
    lags: tuple = (10, 25)
    max_lag_fraction: float = 0.5


@dataclass
class LaggedDifferences:
    """Rotation differences of one camera between frames further apart.

    ``first``, ``second`` (M,) int: frame indices counted like the pairs of
    :class:`RotationDifferences` (0 = the camera's first frame), ``second >
    first + 1``; ``dR`` (M, 3, 3) with ``R(second) = dR R(first)``
    (photogrammetric; NaN where the pair failed); ``inliers``, ``matches``
    (M,) int; ``ok`` (M,) bool.
    """

    first: np.ndarray
    second: np.ndarray
    dR: np.ndarray
    inliers: np.ndarray
    matches: np.ndarray
    ok: np.ndarray

    @classmethod
    def empty(cls) -> "LaggedDifferences":
        """No lagged pair."""
        z = np.zeros(0, int)
        return cls(z, z.copy(), np.zeros((0, 3, 3)), z.copy(), z.copy(), np.zeros(0, bool))

    def __len__(self) -> int:
        return len(self.ok)


@dataclass
class RotationDifferences:
    """Rotation differences of one camera.

    ``dR[t]`` (F-1, 3, 3) maps frame t to t+1 (``R(t+1) = dR[t] R(t)``,
    photogrammetric; NaN where the pair failed); ``inliers``, ``matches``
    (F-1,) int; ``ok`` (F-1,) bool; ``seconds`` the processing time (CPU of
    this process, images excluded); ``frames`` = F; ``lagged`` the pairs of
    frames further apart (:class:`LaggedDifferences`), None: none measured.
    """

    dR: np.ndarray
    inliers: np.ndarray
    matches: np.ndarray
    ok: np.ndarray
    seconds: float
    frames: int
    lagged: LaggedDifferences | None = None

    @property
    def pairs(self) -> int:
        return len(self.ok)

    @property
    def failed(self) -> int:
        return int(np.count_nonzero(~self.ok))

    @property
    def median_inliers(self) -> float:
        return float(np.median(self.inliers)) if len(self.inliers) else 0.0


# --------------------------------------------------------------------------
def _mask(shape, box, scale, margin, mask):
    """Detection mask: 255 outside the enlarged athlete box."""
    mask[:] = 255
    if box is None or not np.all(np.isfinite(box)):
        return mask
    x0, y0, x1, y1 = (scale * (np.asarray(box, float) + 0.5) - 0.5)
    mw, mh = margin * (x1 - x0), margin * (y1 - y0)
    H, W = shape
    a, b = int(max(0, np.floor(x0 - mw))), int(min(W, np.ceil(x1 + mw) + 1))
    c, d = int(max(0, np.floor(y0 - mh))), int(min(H, np.ceil(y1 + mh) + 1))
    if a < b and c < d:
        mask[c:d, a:b] = 0
    return mask


def rotation_differences(images, model: str, io, image_scale: float = 0.5, boxes=None,
                         settings: HomographySettings | None = None) -> RotationDifferences:
    """Rotation differences of consecutive frames of one camera (module doc).

    Parameters
    ----------
    images : iterable of ndarray
        The frames (BGR or grey uint8), e.g. :func:`photogram.mocap.motion.video.read_frames`
        or :func:`photogram.simulation.ski.render.render_camera`; read once, in order.
    model : str
        Camera model name (``camera_model``).
    io : array_like, (F, p) or (p,)
        Interior orientation per frame at FULL resolution.
    image_scale : float
        Image width / full-resolution width (0.5 for 960 x 540 of 1920 x 1080).
    boxes : array_like (F, 4), optional
        Athlete box per frame, full-resolution px ``x0, y0, x1, y1`` (NaN:
        none); features inside the enlarged box are not used.
    settings : HomographySettings, optional

    Returns
    -------
    RotationDifferences
    """
    st = settings or HomographySettings()
    camera_model(model)                                   # InputError if unknown
    io = np.atleast_2d(np.asarray(io, dtype=float))
    boxes = None if boxes is None else np.asarray(boxes, dtype=float).reshape(-1, 4)
    orb = cv2.ORB_create(nfeatures=st.n_features, scaleFactor=st.scale_factor,
                         nlevels=st.n_levels, fastThreshold=st.fast_threshold)
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)
    s = float(image_scale)
    dR, inl, nm = [], [], []
    prev = None
    mask = None
    K_all = pinhole_matrices(model, io, s)
    cpu = 0.0
    n = 0
    lags = _check_lags(st)
    ring = deque(maxlen=max(lags, default=1))
    lagged = []
    for img in images:
        t0 = time.process_time()
        img = np.asarray(img)
        grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        if mask is None or mask.shape != grey.shape:
            mask = np.empty(grey.shape, np.uint8)
        row = io[min(n, len(io) - 1)]
        box = None if boxes is None else boxes[min(n, len(boxes) - 1)]
        kps, desc = orb.detectAndCompute(grey, _mask(grey.shape, box, s, st.box_margin, mask))
        K = K_all[min(n, len(K_all) - 1)]
        if kps:
            xy = cv2.KeyPoint_convert(kps).astype(float)
            full = (xy + 0.5) / s - 0.5
            t = undistort_points(model, full, row)
            ideal = t @ K[:2, :2].T + K[:2, 2]
        else:
            ideal, desc = np.zeros((0, 2)), None
        cur = (ideal, desc, K)
        if prev is not None:
            last = dR[-1] if dR and inl[-1] >= st.min_inliers else None
            R, k_in, k_m = _pair(prev, cur, matcher, st, last)
            dR.append(R)
            inl.append(k_in)
            nm.append(k_m)
        _lagged_pairs(n, cur, ring, dR, inl, matcher, st, lags, grey.shape[1], lagged)
        ring.append(cur)
        prev = cur
        n += 1
        cpu += time.process_time() - t0
    if n < 2:
        raise InputError(f"{n} image(s): rotation differences need at least two frames")
    for name, arr in (("interior orientations", io), ("athlete boxes", boxes)):
        if arr is not None and len(arr) > 1 and len(arr) != n:
            raise InputError(f"{len(arr)} {name} for {n} images",
                             hint="give one row per frame (or a single row)")
    inl, nm = np.array(inl, int), np.array(nm, int)
    ok = inl >= st.min_inliers
    dR = np.array(dR)
    dR[~ok] = np.nan
    return RotationDifferences(dR, inl, nm, ok, cpu, n, _lagged_result(lagged, lags, st))


def _check_lags(st) -> tuple:
    """The settings' lags as ints > 1 (InputError otherwise)."""
    lags = tuple(st.lags or ())
    if any(isinstance(k, bool) or int(k) != k or k < 2 for k in lags):
        raise InputError(f"lags {list(lags)}: each lag must be an integer of at least 2",
                         hint="lags are frame distances of lagged pairs, e.g. [10, 25]; "
                              "[] for none")
    if not np.isfinite(st.max_lag_fraction) or st.max_lag_fraction <= 0:
        raise InputError(f"max_lag_fraction {st.max_lag_fraction} is not positive",
                         hint="a fraction of the field of view, e.g. 0.5")
    return tuple(sorted({int(k) for k in lags}))


def _lagged_pairs(n, cur, ring, dR, inl, matcher, st, lags, width, out):
    """Attempt the lagged pairs (n-k, n), k in ``lags``, of the frame n
    (features ``cur``) whose frame n-k is in ``ring``; appends (n-k, n, dR,
    inliers, matches) to ``out``."""
    for k in lags:
        m = n - k
        if m < 0 or len(ring) < k or any(inl[j] < st.min_inliers for j in range(m, n)):
            continue
        chain = np.eye(3)
        for j in range(m, n):
            chain = dR[j] @ chain
        first = ring[-k]
        fov = min(horizontal_fov(first[2], width), horizontal_fov(cur[2], width))
        angle = np.arccos(np.clip(0.5 * (np.trace(chain) - 1.0), -1.0, 1.0))
        if angle >= st.max_lag_fraction * fov:
            continue
        R, k_in, k_m = _pair(first, cur, matcher, st, chain, fallback=st.search_px <= 0)
        out.append((m, n, R, k_in, k_m))


def _lagged_result(pairs, lags, st) -> LaggedDifferences | None:
    """LaggedDifferences of the attempted pairs (None when no lags were asked)."""
    if not lags:
        return None
    if not pairs:
        return LaggedDifferences.empty()
    first, second, R, k_in, k_m = (np.array(v) for v in zip(*pairs))
    k_in = k_in.astype(int)
    ok = k_in >= st.min_inliers
    R = R.astype(float)
    R[~ok] = np.nan
    return LaggedDifferences(first.astype(int), second.astype(int), R, k_in,
                             k_m.astype(int), ok)


def _pair(prev, cur, matcher, st, predicted, fallback: bool = True):
    """(dR, inliers, matches) of one pair; ``predicted`` is the previous
    pair's dR (or None, or a lagged pair's chain). ``fallback``: match
    exhaustively when guiding finds too few inliers."""
    (p0, d0, K0), (p1, d1, K1) = prev, cur
    nan = np.full((3, 3), np.nan)
    if d0 is None or d1 is None or len(d0) < 4 or len(d1) < 4:
        return nan, 0, 0
    if predicted is not None and st.search_px > 0:
        H = K1 @ (D @ predicted @ D) @ np.linalg.inv(K0)
        i0, i1 = guided_matches(p0, d0, p1, d1, H, st.search_px, st.max_hamming)
        result = _fit(p0[i0], p1[i1], K0, K1, st)
        if result[1] >= st.min_inliers or not fallback:
            return result
    matches = matcher.match(d0, d1)
    i0 = np.fromiter((mt.queryIdx for mt in matches), int, len(matches))
    i1 = np.fromiter((mt.trainIdx for mt in matches), int, len(matches))
    return _fit(p0[i0], p1[i1], K0, K1, st)


def _fit(a, b, K0, K1, st):
    nan = np.full((3, 3), np.nan)
    if len(a) < 4:
        return nan, 0, len(a)
    H, inliers = cv2.findHomography(a, b, cv2.RANSAC, st.ransac_px, maxIters=2000,
                                    confidence=0.999)
    if H is None:
        return nan, 0, len(a)
    if st.method == "homography":
        return rotation_from_homography(H, K0, K1), int(inliers.sum()), len(a)
    inl = inliers.ravel().astype(bool)
    if inl.sum() < 3:
        return nan, int(inl.sum()), len(a)
    R, keep = rotation_from_rays(a[inl], b[inl], K0, K1, st.ransac_px)
    return R, int(keep.sum()), len(a)
