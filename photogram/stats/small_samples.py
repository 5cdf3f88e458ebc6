"""Statistics of a few numbers at a time, for the inner loops of the
trackers (per marker or tracklet and frame), where numpy's per-call
overhead outweighs the work; the values are numpy's, bit for bit."""

from __future__ import annotations

import numpy as np

__all__ = ["median_of_few"]


def median_of_few(values) -> np.float64:
    """``np.median`` of a short list of numbers, the same value bit for bit
    (the middle one, or ``(a + b) / 2`` of the two middle ones, as np.mean
    takes it), without numpy's array overhead (about 20 us a call: the
    trackers call it per marker or tracklet and frame); an empty or
    NaN-holding list goes to np.median."""
    v = sorted(values)
    n = len(v)
    if n == 0 or any(x != x for x in v):
        return np.median(values)
    h = n // 2
    return np.float64(v[h]) if n % 2 else (np.float64(v[h - 1]) + np.float64(v[h])) / 2
