"""Tick positions and labels: "nice" steps (1, 2, 2.5, 5 x 10^k, as
matplotlib's MaxNLocator) and plain decimal labels without offset."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

__all__ = ["nice_ticks", "tick_labels", "log_ticks", "auto_bins"]

_STEPS = (1.0, 2.0, 2.5, 5.0, 10.0)


def nice_ticks(lo: float, hi: float, nbins: int, integer: bool = False) -> np.ndarray:
    """Ticks inside ``[lo, hi]`` at the smallest nice step at least
    ``(hi - lo) / nbins`` (matplotlib's MaxNLocator), a finer one if that
    leaves fewer than 2 ticks; ``integer`` keeps steps >= 1 and whole."""
    lo, hi = (float(lo), float(hi)) if lo <= hi else (float(hi), float(lo))
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return np.array([])
    if hi - lo <= 1e-300 * max(1.0, abs(hi)):
        return np.array([lo])
    nbins = max(1, int(nbins))
    scale = 10.0 ** math.floor(math.log10((hi - lo) / nbins))
    steps = [s * scale * f for f in (1.0, 10.0) for s in _STEPS]
    if integer:
        steps = [s for s in steps if s >= 1 and abs(s - round(s)) < 1e-9] or [1.0]
    raw = (hi - lo) / nbins
    step = next((s for s in steps if s >= raw * (1 - 1e-9)), steps[-1])
    first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    if last - first < 1 and not integer:        # fewer than 2 ticks: a finer step
        finer = [s for s in steps if s < step]
        if finer:
            step = finer[-1]
            first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    ticks = np.arange(first, last + 1) * step
    ticks[np.abs(ticks) < 1e-12 * step] = 0.0
    return ticks


def _decimals(ticks) -> int:
    """Decimals that tell the ticks apart (at most 10)."""
    t = np.asarray(ticks, float)
    for d in range(0, 11):
        if np.all(np.abs(np.round(t, d) - t) <= 1e-9 * max(1.0, float(np.abs(t).max()))):
            return d
    return 10


def tick_labels(ticks) -> list:
    """Plain decimal labels with the fewest decimals that show every tick
    exactly, as matplotlib's (zero without a minus sign)."""
    return list(_labels(tuple(np.asarray(ticks, float).ravel().tolist())))


@lru_cache(maxsize=1024)
def _labels(ticks: tuple) -> tuple:
    """:func:`tick_labels` of a tuple of floats (cached: the axes of a
    report repeat their ticks, e.g. 21 images of one format)."""
    d = _decimals(ticks)
    out = []
    for t in ticks:
        s = f"{t:.{d}f}"
        out.append(s.lstrip("-") if s.strip("-0.") == "" else s)
    return tuple(out)


def log_ticks(lo: float, hi: float) -> np.ndarray:
    """Exponents k of the decades 10^k inside ``[lo, hi]`` (> 0); every
    second or fifth decade when there are many."""
    a, b = math.ceil(math.log10(lo) - 1e-9), math.floor(math.log10(hi) + 1e-9)
    k = np.arange(a, b + 1)
    step = 1 if len(k) <= 8 else 2 if len(k) <= 16 else 5
    return k[k % step == 0] if len(k) else k


def auto_bins(values, n: int) -> np.ndarray:
    """``n`` equal bins over the range of ``values`` (numpy's default)."""
    v = np.asarray(values, float)
    lo, hi = (float(v.min()), float(v.max())) if len(v) else (0.0, 1.0)
    if hi == lo:
        lo, hi = lo - 0.5, hi + 0.5
    return np.linspace(lo, hi, n + 1)
