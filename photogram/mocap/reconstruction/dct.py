"""Trajectories as inverse DCTs, and the windows a sequence is cut into.

Eq. (1) of the paper represents every joint coordinate over a sequence of T
frames by N_Pi DCT coefficients::

    x(t) = sum_{k=0}^{K-1} a_k B[t, k],   t = 0 ... T-1,   K = N_Pi

with the orthonormal DCT-II basis (the inverse of ``scipy.fft.dct(...,
norm="ortho")``)::

    B[t, 0] = sqrt(1/T),   B[t, k] = sqrt(2/T) cos(pi k (2t + 1) / (2T))

so that keeping K coefficients is a low-pass filter: basis k oscillates at
``k / (2T)`` cycles per frame, ``k fps / (2T)`` Hz.

Cut-off in Hz (:func:`coefficients_for_cutoff`): the count is chosen per
window so that every basis function at or below the cut-off ``fc`` is kept
and none above it, ``K = floor(2 T fc / fps) + 1`` (basis 0, the constant,
plus the ``floor(2 T fc / fps)`` oscillating ones), at most T. This is the
form implemented (not the nearest count ``round(2 T fc / fps)``): 12 Hz at
50 fps over 50 frames gives K = 25, the paper's N_Pi; at 60 fps, K = 21.
A window shorter than ``window`` (a short segment) gets its own smaller
count, so the cut-off in Hz is the same in every window.

Windowing (our choice; the paper optimises sequences in windows without
details available here): a sequence is cut into windows of ``window`` frames
(default 50) that overlap by ``overlap`` frames (default 25, i.e. a hop of
half a window); the last window of a segment is moved back to end at the
segment's last frame, and a segment shorter than a window is one window of
its own length (with at most as many coefficients as frames). Every window
is optimised on its own (all windows at once, as one batch) and the
trajectories are blended with the weights ``sin^2(pi (t + 1/2) / T)``
normalised per frame: with a hop of T/2 every frame is the sum of one
window's middle and another's end, the weights adding up to one (sin^2 +
cos^2). With 25 coefficients over 50 frames the basis reaches 12 Hz at 50
fps (the default cut-off, ``cutoff_hz`` of ``ReconstructionSettings``); a
straight run at 17 m/s is represented to 5 mm (weighted RMS) by such a
window, against 1.1 cm over 100 frames.

Linear trend (the pose basis, :func:`trend_basis`): a truncated DCT-II
series has zero slope at both ends of its window (the basis is the even
extension of the window), so a skier translating at 16 m/s is bent flat at
every window end: over 50 frames the residual of a straight run is 0.27 deg
of camera pan or several cm of position with 11 coefficients. Overlapping
windows then blend two bent ends (CoM jumps at the seams, a speed error
that rings at the cut-off, 7 m/s at the first and last frames of a run).
The pose basis therefore spans the constant, a linear trend ``t - (T-1)/2``
and the K-1 oscillating DCT terms, orthonormalised in this order (QR): a
straight run is represented exactly, the leading-coefficient rule of
partly observed joints extrapolates linearly instead of flat, and column 0
is still the constant ``1/sqrt(T)``.

``breaks`` lists the first frames of independent segments (e.g. several
runs in one project): windows never cross them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import InputError

__all__ = ["dct_basis", "trend_basis", "Window", "plan_windows", "blend_weights",
           "coefficients_for_cutoff", "basis_frequencies"]


def dct_basis(T: int, K: int) -> np.ndarray:
    """(T, K) orthonormal inverse-DCT-II basis (module doc)."""
    if T < 1 or K < 1:
        raise InputError(f"a DCT basis needs T >= 1 and K >= 1, got T={T}, K={K}")
    K = min(K, T)
    t = np.arange(T)[:, None]
    k = np.arange(K)[None, :]
    B = np.sqrt(2.0 / T) * np.cos(np.pi * k * (2 * t + 1) / (2 * T))
    B[:, 0] = np.sqrt(1.0 / T)
    return B


def trend_basis(T: int, K: int) -> np.ndarray:
    """(T, K + 1) orthonormal basis spanning the constant, the linear trend
    and the DCT terms 1 ... K-1 (module doc); the plain DCT basis when
    ``T < 3`` or ``K >= T`` (it spans every trajectory already)."""
    B = dct_basis(T, K)
    if T < 3 or B.shape[1] >= T:
        return B
    t = (np.arange(T) - (T - 1) / 2.0)[:, None]
    Q, R = np.linalg.qr(np.concatenate([B[:, :1], t, B[:, 1:]], axis=1))
    return Q * np.sign(np.diag(R))[None, :]


def basis_frequencies(T: int, fps: float) -> np.ndarray:
    """Frequency (Hz) of every basis function of a window of T frames,
    ``k fps / (2T)`` for k = 0 ... T-1 (module doc)."""
    return np.arange(T) * float(fps) / (2.0 * T)


def coefficients_for_cutoff(T: int, cutoff_hz: float, fps: float) -> int:
    """Number of DCT coefficients of a window of T frames whose basis
    frequencies are at or below ``cutoff_hz``: ``floor(2 T fc / fps) + 1``,
    between 1 and T (module doc).

    Raises
    ------
    InputError
        ``T < 1``, a cut-off or frame rate that is not positive.
    """
    if T < 1:
        raise InputError(f"a window needs at least 1 frame, got {T}")
    if not (cutoff_hz > 0 and fps > 0):
        raise InputError(f"cutoff_hz and fps must be positive, got {cutoff_hz} and {fps}")
    n = int(np.floor(2.0 * T * float(cutoff_hz) / float(fps) + 1e-9)) + 1
    return int(min(max(n, 1), T))


@dataclass(frozen=True)
class Window:
    """Frames ``start ... start + length - 1`` with ``n_coefficients``."""

    start: int
    length: int
    n_coefficients: int

    @property
    def stop(self) -> int:
        return self.start + self.length


def plan_windows(n_frames: int, window: int = 50, overlap: int = 25, n_coefficients=25,
                 breaks=()) -> list[Window]:
    """Cut ``n_frames`` into overlapping windows (module doc).

    ``n_coefficients``: a count (a shorter window keeps at most its length)
    or a function of the window's length (e.g. the count of a cut-off,
    :func:`coefficients_for_cutoff`).

    Raises
    ------
    InputError
        ``window < 2``, ``overlap`` not in ``[0, window)``, no frames.
    """
    if n_frames < 1:
        raise InputError("no frames to reconstruct")
    if window < 2:
        raise InputError(f"window must be at least 2 frames, not {window}")
    if not 0 <= overlap < window:
        raise InputError(f"overlap must be in [0, window), not {overlap}")
    hop = window - overlap
    count = n_coefficients if callable(n_coefficients) else (
        lambda length: min(int(n_coefficients), length))
    cuts = sorted({0, n_frames} | {int(b) for b in breaks if 0 < int(b) < n_frames})
    out = []
    for s, e in zip(cuts[:-1], cuts[1:]):
        n = e - s
        if n <= window:
            out.append(Window(s, n, count(n)))
            continue
        starts = list(range(s, e - window + 1, hop))
        if starts[-1] + window < e:
            starts.append(e - window)
        out += [Window(st, window, count(window)) for st in starts]
    return out


def blend_weights(length: int, overlap: int | None = None) -> np.ndarray:
    """Blending weights of a window (module doc): 1 in the middle, rising as
    ``sin^2(pi (t + 1/2) / (2 overlap))`` over the first ``overlap`` frames
    and falling symmetrically over the last (the whole window for an overlap
    of half its length or more); never 0."""
    t = np.arange(length, dtype=float)
    o = length / 2.0 if overlap is None else min(max(float(overlap), 1.0), length / 2.0)
    w = np.ones(length)
    head = t < o
    w[head] = np.sin(np.pi * (t[head] + 0.5) / (2 * o)) ** 2
    tail = t > length - 1 - o
    w[tail] = np.sin(np.pi * (length - t[tail] - 0.5) / (2 * o)) ** 2
    return w
