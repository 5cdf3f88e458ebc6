"""Trajectories as inverse DCTs, and the windows a sequence is cut into.

Eq. (1) of the paper represents every joint coordinate over a sequence of T
frames by N_Pi DCT coefficients::

    x(t) = sum_{k=0}^{K-1} a_k B[t, k],   t = 0 ... T-1,   K = N_Pi

with the orthonormal DCT-II basis (the inverse of ``scipy.fft.dct(...,
norm="ortho")``)::

    B[t, 0] = sqrt(1/T),   B[t, k] = sqrt(2/T) cos(pi k (2t + 1) / (2T))

so that keeping K coefficients is a low-pass filter with cut-off
``K / (2T)`` cycles per frame.

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
cos^2). With 25 coefficients over 50 frames the cut-off is a quarter of the
frame rate (12.5 Hz at 50 fps); a straight run at 17 m/s is represented to
5 mm (weighted RMS) by such a window, against 1.1 cm over 100 frames.

``breaks`` lists the first frames of independent segments (e.g. several
runs in one project): windows never cross them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import InputError

__all__ = ["dct_basis", "Window", "plan_windows", "blend_weights"]


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


@dataclass(frozen=True)
class Window:
    """Frames ``start ... start + length - 1`` with ``n_coefficients``."""

    start: int
    length: int
    n_coefficients: int

    @property
    def stop(self) -> int:
        return self.start + self.length


def plan_windows(n_frames: int, window: int = 50, overlap: int = 25, n_coefficients: int = 25,
                 breaks=()) -> list[Window]:
    """Cut ``n_frames`` into overlapping windows (module doc).

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
    cuts = sorted({0, n_frames} | {int(b) for b in breaks if 0 < int(b) < n_frames})
    out = []
    for s, e in zip(cuts[:-1], cuts[1:]):
        n = e - s
        if n <= window:
            out.append(Window(s, n, min(n_coefficients, n)))
            continue
        starts = list(range(s, e - window + 1, hop))
        if starts[-1] + window < e:
            starts.append(e - window)
        out += [Window(st, window, min(n_coefficients, window)) for st in starts]
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
