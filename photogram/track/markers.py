"""Bright marker candidates of one frame with subpixel centres and sigmas.

The reflective markers of the jumper's suit are 2-4 px blobs at 50-80 m.
Per frame, all at once (no loop over candidates):

1. **Candidates**: local maxima (3 x 3) of the difference of Gaussians
   ``G(1 px) * I - G(2 px) * I``, a band-pass matched to 2-4 px spots (the
   DoG approximation of the scale-normalised Laplacian, Lowe 2004,
   "Distinctive image features from scale-invariant keypoints", sec. 3),
   above ``k`` times its noise sigma (the background's per-pixel noise
   times the 2-norm of the DoG kernel). Maxima, not thresholded regions: a
   marker need not be brighter than the background (a white marker on a
   dark suit in front of white snow is not), and the bright snow between
   dark limbs would join a marker into one region. Maxima on a ridge (such
   a gap of snow) are dropped by the ratio of the principal curvatures
   (``max_edge``; Lowe 2004, sec. 4.1). And the spot must be *new*: the
   band-pass of the frame minus that of the median background (the
   band-pass of the difference image: the foreground) must exceed the
   threshold too, so the static targets and the snow's texture are no
   candidates while a marker on the suit is (the suit around it is the
   change).
2. **Duplicates**: of maxima closer than ``duplicate`` px only the
   brightest stays.
3. **Subpixel centre**: all windows of ``(2 half + 1)^2`` px around the
   maxima of the white top-hat ``I - open(I)`` (a ``tophat`` square;
   Soille, *Morphological Image Analysis*, 2nd ed., sec. 4.4.2), the grey
   values above the local background (the suit behind the marker, not the
   arena) less those of the background's top-hat where the frame shows the
   background (a static target beside the marker does not pull its
   centre), are gathered into one array, less
   the median of the window's border (the top-hat of noise is positive);
   the centre is the
   *iteratively Gaussian-weighted centroid* of the
   background-subtracted grey values ``max(I - b, 0)``: weights
   ``exp(-|x - c|^2 / (2 s^2))`` about the current centre ``c``, repeated
   (the iterative weighted centroid of star trackers; Shortis, Clarke &
   Short 1994 for the plain centroid it improves on). A plain centroid over
   the window is pulled towards the window's middle, an integer pixel, by
   the noise of the empty pixels; the weights centred on the estimate are
   symmetric about the true centre of a symmetric blob, which is their
   fixed point. Measured on the rendered normal set
   (``/work/jumpvideo/normal``, the isolated markers P1 and P2 of all
   three views, 143 discs of 2.4-3.1 px): Gaussian weights of 1.2 px
   0.043 px RMS (1.0 px: 0.041, 1.5 px: 0.047), the plain centroid over the
   9 x 9 window 0.149 (over 5 x 5: 0.052), and the ellipse fit to edge
   points of :func:`photogram.measure.detect.detect_targets` (bright,
   32 rays, 142 of the 143 found) 0.049 px: close, but it needs edges of a
   few pixels' length and costs a loop per blob; the weighted centroid is
   kept (``tests/test_track_markers.py`` repeats the comparison).
4. **Sigma** of a centre coordinate: the linear propagation of the pixel
   noise ``sigma_n`` through the weighted centroid,
   ``sigma_x^2 = sigma_n^2 sum g_i^2 (x_i - c_x)^2 / S^2`` (``g`` the
   Gaussian weights, ``S = sum g_i (I_i - b)``), root-sum-squared with a
   floor ``sigma_floor`` for the rendering/pixelisation error the noise
   does not explain. On the normal set the centre errors over these sigmas
   have an RMS of 0.99 per coordinate (``benchmarks/track.py``); on the
   harsh set (not tuned on) 3.8: the sigma describes the pixel noise, not
   JPEG at quality 60 or the blur of a 3-4 px streak over the suit. The
   marker table raises it to the scatter of each track
   (:func:`photogram.track.tracks2d.scatter_sigma`), which leaves 1.9 on
   the harsh set: the rest is bias constant along a track.

Coordinates: x right, y down, by default in photogram's image frame with
the first pixel's centre at (0.5, 0.5) (:data:`PIXEL_OFFSET`, as
:mod:`photogram.measure.pipeline` writes the observations the orientation
comes from); ``pixel_offset=0`` gives OpenCV's frame (centres at integers),
the frame of the rendered test videos of
``photogram.simulation.jump_video``. The seeds, the cameras and the
output must share one frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.track.background import Background, band_pass, band_pass_gain

__all__ = ["Candidates", "detect_markers", "PIXEL_OFFSET"]

#: array index -> photogram image frame (pixel centres at half integers)
PIXEL_OFFSET = 0.5


@dataclass
class Candidates:
    """Marker candidates of one frame (arrays of equal length n).

    Attributes
    ----------
    xy : (n, 2)        subpixel centres, photogram image frame (px)
    sigma : (n,)       standard deviation of a centre coordinate (px)
    flux : (n,)        background-subtracted grey sum inside radius 2.5 px
    peak : (n,)        brightest pixel above the local background
    area : (n,)        candidate pixels of the blob
    snr : (n,)         peak / noise sigma
    elongation : (n,)  major / minor RMS radius of the background-subtracted
                       blob (1 for a round marker; two merged markers more)
    """

    xy: np.ndarray
    sigma: np.ndarray
    flux: np.ndarray
    peak: np.ndarray
    area: np.ndarray
    snr: np.ndarray
    elongation: np.ndarray

    def __len__(self) -> int:
        return len(self.xy)

    @classmethod
    def empty(cls) -> "Candidates":
        z = np.zeros(0)
        return cls(np.zeros((0, 2)), z, z, z, z, z, z)


def _windows(img: np.ndarray, centres: np.ndarray, half: int) -> np.ndarray:
    """(n, 2h+1, 2h+1) float32 windows of ``img`` around integer centres
    (col, row), edge pixels repeated outside the image."""
    h, w = img.shape
    o = np.arange(-half, half + 1)
    rows = np.clip(centres[:, 1, None] + o, 0, h - 1)
    cols = np.clip(centres[:, 0, None] + o, 0, w - 1)
    return img[rows[:, :, None], cols[:, None, :]].astype(np.float32)


def detect_markers(frame: np.ndarray, background: Background, *, k: float = 5.0,
                   scales: tuple = (1.0, 2.0), max_edge: float = 6.0,
                   half: int = 3, tophat: int = 7, gauss_sigma: float = 1.2, n_iter: int = 6,
                   sigma_floor: float = 0.03, method: str = "gaussian",
                   duplicate: float = 1.5,
                   pixel_offset: float = PIXEL_OFFSET) -> Candidates:
    """Bright marker candidates of one frame (module doc).

    Parameters
    ----------
    frame : (H, W) uint8
    background : Background
        Of the frame's camera (:func:`photogram.track.background.estimate_background`).
    k : float
        Candidates are maxima of the difference of Gaussians above ``k``
        times its noise sigma.
    scales : (float, float)
        Sigmas (px) of the two Gaussians.
    max_edge : float
        Largest ratio of the principal curvatures of the difference of
        Gaussians at a maximum (round spots 1; a bright ridge between dark
        limbs much more; Lowe 2004, sec. 4.1 uses 10).
    half : int
        Half side of the centring window (px).
    tophat : int
        Side of the top-hat's square (px) giving the grey values above the
        local background: larger than a marker.
    gauss_sigma : float
        Sigma of the Gaussian weights (px).
    n_iter : int
        Iterations of the weighted centroid.
    sigma_floor : float
        Added in quadrature to the propagated centre sigma (px).
    duplicate : float
        Of candidates closer than this (px) only the brightest is kept.
    pixel_offset : float
        Added to the array indices: 0.5 gives photogram's image frame (the
        first pixel's centre at (0.5, 0.5), as ``photogram measure``
        writes), 0 OpenCV's (centres at integers).
    method : "gaussian" | "centroid"
        Iteratively Gaussian-weighted centroid (default) or the plain
        grey-value weighted centroid over the window.

    Returns
    -------
    Candidates
    """
    import cv2
    if method not in ("gaussian", "centroid"):
        raise ValueError(f"method {method!r}: gaussian or centroid")
    g = np.asarray(frame)
    if g.dtype != np.uint8:
        g = np.clip(np.rint(g), 0, 255).astype(np.uint8)
    noise = background.noise
    dog = band_pass(g, scales)
    key = ("dog_threshold", k, tuple(scales))
    thr = background.cache.get(key)
    if thr is None:
        thr = background.cache[key] = (k * band_pass_gain(scales)) * noise
    peak = (dog > thr) & (dog >= cv2.dilate(dog, np.ones((3, 3), np.uint8)))
    peak[[0, -1], :] = False
    peak[:, [0, -1]] = False
    nz = cv2.findNonZero(peak.view(np.uint8))
    if nz is None:
        return Candidates.empty()
    nz = nz.reshape(-1, 2)
    cols, rows = nz[:, 0].astype(np.intp), nz[:, 1].astype(np.intp)
    # new spots only: the band-pass of the frame minus that of the background
    # (the band-pass of the difference image) above the threshold as well;
    # tested at the maxima only (the same float32 values as over the frame)
    bkey = ("band_pass", tuple(scales))
    dog_bg = background.cache.get(bkey)
    if dog_bg is None:
        dog_bg = background.cache[bkey] = band_pass(background.median, scales)
    new = (dog[rows, cols] - dog_bg[rows, cols]) > np.broadcast_to(thr, dog.shape)[rows, cols]
    if not new.all():
        rows, cols = rows[new], cols[new]
        if len(rows) == 0:
            return Candidates.empty()
    # principal curvatures of the DoG at the maxima (Lowe 2004, eq. 4-5)
    dxx = dog[rows, cols + 1] + dog[rows, cols - 1] - 2 * dog[rows, cols]
    dyy = dog[rows + 1, cols] + dog[rows - 1, cols] - 2 * dog[rows, cols]
    dxy = 0.25 * (dog[rows + 1, cols + 1] - dog[rows + 1, cols - 1]
                  - dog[rows - 1, cols + 1] + dog[rows - 1, cols - 1])
    tr, det = dxx + dyy, dxx * dyy - dxy ** 2
    round_ = (det > 0) & (tr * tr < det * (max_edge + 1) ** 2 / max_edge)
    rows, cols = rows[round_], cols[round_]
    if len(rows) == 0:
        return Candidates.empty()
    c0 = np.column_stack([cols, rows])
    se = np.ones((tophat, tophat), np.uint8)
    tkey = ("tophat", tophat)
    th_bg = background.cache.get(tkey)
    if th_bg is None:
        med8 = np.clip(np.rint(background.median), 0, 255).astype(np.uint8)
        th_bg = background.cache[tkey] = cv2.morphologyEx(med8, cv2.MORPH_TOPHAT, se)
    # the new small bright details: the frame's top-hat less the background's
    # (a static target beside the marker does not pull its centre)
    # where the frame shows the background (unchanged within 3 sigmas; not
    # where the suit hides the snow's texture)
    th = _windows(cv2.morphologyEx(g, cv2.MORPH_TOPHAT, se), c0, half)
    same = np.abs(_windows(g, c0, half) - _windows(background.median, c0, half)) \
        <= 3.0 * _windows(noise, c0, half)
    win = th - _windows(th_bg, c0, half) * same                   # (n, S, S)
    # the top-hat of noise is positive (the noise above its local minimum,
    # about two sigmas): its level from the window's border, at most 3 sigmas
    border = np.concatenate([win[:, 0, :], win[:, -1, :], win[:, 1:-1, 0],
                             win[:, 1:-1, -1]], axis=1)
    nz = noise[rows, cols]
    b = np.minimum(np.median(border, axis=1), 3.0 * nz)
    v = win - b[:, None, None]
    vp = np.maximum(v, 0.0)
    o = np.arange(-half, half + 1, dtype=np.float32)
    dx = o[None, None, :]                                          # window coords
    dy = o[None, :, None]
    cx = np.zeros(len(v), np.float32)
    cy = np.zeros(len(v), np.float32)
    wgt = vp
    for _ in range(n_iter if method == "gaussian" else 1):
        if method == "gaussian":
            gw = np.exp(-((dx - cx[:, None, None]) ** 2 + (dy - cy[:, None, None]) ** 2)
                        / (2 * gauss_sigma ** 2))
            wgt = vp * gw
        else:
            gw = np.ones_like(vp)
        S = wgt.sum(axis=(1, 2))
        S = np.where(S > 0, S, 1.0)
        cx = np.clip((wgt * dx).sum(axis=(1, 2)) / S, -half, half)
        cy = np.clip((wgt * dy).sum(axis=(1, 2)) / S, -half, half)
    noise = nz
    # propagation of the pixel noise through the weighted centroid (weights held)
    g2 = gw ** 2 * (vp > 0)
    sx = noise * np.sqrt((g2 * (dx - cx[:, None, None]) ** 2).sum(axis=(1, 2))) / S
    sy = noise * np.sqrt((g2 * (dy - cy[:, None, None]) ** 2).sum(axis=(1, 2))) / S
    sigma = np.sqrt(0.5 * (sx ** 2 + sy ** 2) + sigma_floor ** 2)
    r2 = (dx - cx[:, None, None]) ** 2 + (dy - cy[:, None, None]) ** 2
    inner = r2 <= 2.5 ** 2
    flux = (vp * inner).sum(axis=(1, 2))
    peak = v.reshape(len(v), -1).max(axis=1)
    # second moments of the background-subtracted blob inside radius 2.5
    m = vp * inner
    M = np.where(m.sum(axis=(1, 2)) > 0, m.sum(axis=(1, 2)), 1.0)
    ex, ey = dx - cx[:, None, None], dy - cy[:, None, None]
    sxx = (m * ex * ex).sum(axis=(1, 2)) / M
    syy = (m * ey * ey).sum(axis=(1, 2)) / M
    sxy = (m * ex * ey).sum(axis=(1, 2)) / M
    tr, det = sxx + syy, sxx * syy - sxy ** 2
    disc = np.sqrt(np.maximum(tr ** 2 / 4 - det, 0))
    lam1, lam2 = tr / 2 + disc, np.maximum(tr / 2 - disc, 1e-6)
    xy = np.column_stack([c0[:, 0] + cx, c0[:, 1] + cy]).astype(float) + pixel_offset
    out = Candidates(xy, sigma.astype(float), flux.astype(float), peak.astype(float),
                     (v > 0.5 * peak[:, None, None]).sum(axis=(1, 2)).astype(float),
                     (peak / noise).astype(float),
                     np.sqrt(lam1 / lam2).astype(float))
    return _unique(out, duplicate)


def _unique(c: Candidates, radius: float) -> Candidates:
    """Drop candidates within ``radius`` px of a brighter one: two pieces of
    one blob (split by a pixel below the threshold) that centred on the
    same spot."""
    if len(c) < 2:
        return c
    d = np.linalg.norm(c.xy[:, None] - c.xy[None], axis=2)
    brighter = c.flux[None, :] > c.flux[:, None]
    drop = ((d < radius) & brighter).any(axis=1)
    if not drop.any():
        return c
    keep = ~drop
    return Candidates(c.xy[keep], c.sigma[keep], c.flux[keep], c.peak[keep], c.area[keep],
                      c.snr[keep], c.elongation[keep])
