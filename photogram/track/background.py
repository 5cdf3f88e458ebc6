"""The static background of a stationary camera and the moving foreground.

A camera on a tripod sees the arena (snow, the landing slope, the static
ball targets of the field orientation) unchanged while the jumper crosses
the image; each pixel shows the jumper in a few frames only. The **per-pixel
median over the frames** is then the background (the temporal median
filter of background subtraction, Cucchiara et al. 2003, "Detecting moving
objects, ghosts, and shadows in video streams"; Piccardi 2004, "Background
subtraction techniques: a review", sec. 3). It is taken over at most
``n_samples`` frames spread evenly over the recording (the median does not
need every frame, and the cost is linear in the samples).

The noise is a robust estimate from the same samples. The image's noise
level is the mean of the smallest 80 % of all absolute deviations from the
median, divided by its expectation for a unit normal (0.5586): the
jumper's few frames are outliers the trimming drops, and unlike the MAD
(``1.4826`` times the median absolute deviation) it is not quantised by
8-bit grey levels (the MAD of integer samples is an integer: a noise sigma
of 2 reads 1.48). A pixel's noise is the mean of its absolute deviations
capped at 3 noise levels (winsorised: the jumper's frames count at most 3
levels each) over the normal expectation 0.7972 (flickering JPEG edges of
the static targets get their larger noise),
floored by the image's median noise so that a pixel that happens
to be constant in the samples does not get zero noise. The foreground of a
frame is where it is brighter than the background by more than ``k`` noise
sigmas, after removing a global brightness change of the frame (the median
difference over the frame: auto-exposure, a cloud). The static targets are
in the background and disappear in the difference.

A marker, though, need not be brighter than the background: a white
marker on a dark suit in front of white snow is about as bright as the snow
it hides. The markers are therefore found as small bright *spots*
(:func:`band_pass`, :mod:`photogram.track.markers`) that are new: the
band-pass of the difference image (frame minus median) must show them too.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError

__all__ = ["Background", "sorted_images", "estimate_background", "frame_gain", "foreground",
           "difference", "band_pass", "band_pass_gain"]

#: fraction of the smallest absolute deviations the image's noise level is taken from
TRIM = 0.8
# E|X| over the smallest 80 % of |X|, X ~ N(0, 1): sqrt(2/pi) (1 - exp(-q^2/2)) / 0.8
# with q = 1.2816 the 80th percentile of |X|
_TRIMMED_HALF_NORMAL = 0.5586
#: a pixel's absolute deviations are capped at this many noise levels
WINSOR = 3.0
# E min(|X|, 3), X ~ N(0, 1): sqrt(2/pi) (1 - exp(-4.5)) + 3 * 2 (1 - Phi(3))
_WINSOR_MEAN = 0.7972


def _trimmed_level(hist: np.ndarray) -> float:
    """Noise sigma from the histogram of integer absolute deviations: the
    mean of the smallest ``TRIM`` of them over its normal expectation."""
    n = hist.sum()
    m = TRIM * n
    c = np.cumsum(hist)
    take = np.minimum(hist, np.maximum(m - (c - hist), 0))
    return float((take * np.arange(len(hist))).sum() / m / _TRIMMED_HALF_NORMAL)


@dataclass
class Background:
    """Background model of one static camera.

    Attributes
    ----------
    median : (H, W) float32
        Per-pixel median grey level.
    noise : (H, W) float32
        Per-pixel robust noise sigma (grey levels), floored by ``noise_level``.
    noise_level : float
        The image's noise sigma (trimmed mean of all absolute deviations).
    n_samples : int
        Frames the median was taken over.
    cache : dict
        What the detector derives once per camera: per-pixel thresholds,
        the band-pass of the median.
    """

    median: np.ndarray
    noise: np.ndarray
    noise_level: float
    n_samples: int
    cache: dict = field(default_factory=dict, repr=False)


def estimate_background(frames: np.ndarray, n_samples: int = 15,
                        min_noise: float = 0.5) -> Background:
    """Median background and robust noise of a static camera (module doc).

    Parameters
    ----------
    frames : (F, H, W) uint8
        All frames of the camera.
    n_samples : int
        At most this many frames, evenly spread, enter the median.
    min_noise : float
        Smallest noise sigma (grey levels) of any pixel: the quantisation
        of 8-bit images (``1 / sqrt(12)`` = 0.29) and a little more.

    Returns
    -------
    Background
    """
    import cv2
    frames = np.asarray(frames)
    if frames.ndim != 3 or len(frames) < 3:
        raise InputError(f"a background needs at least 3 frames (F, H, W), got shape "
                         f"{frames.shape}", hint="give the whole recording of the camera")
    idx = np.unique(np.linspace(0, len(frames) - 1, min(n_samples, len(frames))).round()
                    .astype(int))
    samples = np.ascontiguousarray(frames[idx])
    med8 = _lower_median(samples)
    dev = np.stack([cv2.absdiff(f, med8) for f in samples])
    # the level from every other pixel of every other row (plenty, 4x faster)
    level = max(_trimmed_level(np.bincount(dev[:, ::2, ::2].ravel(), minlength=256)),
                min_noise)
    cap = min(255, int(np.ceil(WINSOR * level)))
    acc = np.zeros(med8.shape, np.uint16)
    for d in dev:
        acc += cv2.min(d, cap)
    noise = acc.astype(np.float32) * np.float32(1.0 / (len(samples) * _WINSOR_MEAN))
    np.maximum(noise, level, out=noise)
    med = med8.astype(np.float32)
    return Background(med, noise, level, len(samples))


def sorted_images(samples: np.ndarray) -> list:
    """The ``n`` images (n, H, W) sorted per pixel: a list of ``n`` images,
    the i-th holding every pixel's i-th smallest value, by an odd-even
    transposition sorting network (``n`` rounds of compare-exchanges, each
    ``np.minimum`` / ``np.maximum`` of two whole images; exact, ``n^2 / 2``
    of them: for the few dozen frames of a background much faster than
    ``np.sort`` or ``np.partition`` along the first axis, a strided
    selection per pixel)."""
    a = list(samples)
    n = len(a)
    for r in range(n):
        for i in range(r % 2, n - 1, 2):
            a[i], a[i + 1] = np.minimum(a[i], a[i + 1]), np.maximum(a[i], a[i + 1])
    return a


def _lower_median(samples: np.ndarray, network_max: int = 32) -> np.ndarray:
    """Per pixel the lower median (element ``(n - 1) // 2`` in order) of
    ``n`` images (n, H, W), exactly: :func:`sorted_images` up to
    ``network_max`` images (15 images of 640x480 in 2 ms, where
    ``np.partition`` along the first axis took 37 ms), ``np.partition``
    beyond."""
    n = len(samples)
    k = (n - 1) // 2
    if n > network_max:
        return np.partition(samples, k, axis=0)[k]
    return sorted_images(samples)[k].copy()


def band_pass(image: np.ndarray, scales: tuple = (1.0, 2.0)) -> np.ndarray:
    """Difference of Gaussians ``G(s1) * I - G(s2) * I`` (float32): a
    band-pass matched to spots of about ``2 sqrt(2) s1`` px (Lowe 2004,
    "Distinctive image features from scale-invariant keypoints", sec. 3:
    the DoG approximates the scale-normalised Laplacian)."""
    import cv2
    f = np.asarray(image, np.float32)
    return cv2.GaussianBlur(f, (0, 0), scales[0]) - cv2.GaussianBlur(f, (0, 0), scales[1])


def band_pass_gain(scales: tuple = (1.0, 2.0)) -> float:
    """Noise sigma of :func:`band_pass` for unit white noise: the 2-norm of
    its kernel."""
    import cv2
    s1, s2 = scales
    r = int(np.ceil(4 * s2))
    k1 = cv2.getGaussianKernel(2 * r + 1, s1)
    k2 = cv2.getGaussianKernel(2 * r + 1, s2)
    return float(np.linalg.norm(k1 @ k1.T - k2 @ k2.T))


def difference(frame: np.ndarray, background: Background) -> np.ndarray:
    """Frame minus background (float32), with the global brightness change
    of the frame (median difference over a grid of every 4th pixel)
    removed."""
    d = np.asarray(frame, np.float32) - background.median
    d -= np.float32(np.median(d[::4, ::4]))
    return d


def foreground(frame: np.ndarray, background: Background, k: float = 4.0) -> np.ndarray:
    """Pixels brighter than the background by more than ``k`` noise sigmas
    (bool (H, W); module doc)."""
    return difference(frame, background) > k * background.noise


def frame_gain(img, bgd) -> float:
    """Median ratio frame / background over the well-exposed pixels (a
    frame's brightness change against the background: auto exposure)."""
    img, bgd = img[::4, ::4], bgd[::4, ::4]          # a sample of the frame suffices
    ok = (bgd > 20) & (bgd < 250) & (img > 5) & (img < 250)
    if ok.sum() < 100:
        return 1.0
    return float(np.median(img[ok] / bgd[ok]))
