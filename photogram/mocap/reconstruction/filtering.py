"""Zero-lag Butterworth low-pass filter of reconstructed joints, as
Pose2Sim's ``filtering.butterworth_filter_1d`` (Pose2Sim/filtering.py).

Pose2Sim filters every coordinate of its triangulated TRC with
``b, a = scipy.signal.butter(order / 2, cutoff / (fps / 2))`` and
``scipy.signal.filtfilt(b, a, x)`` (forward and backward: no phase lag, the
magnitude response squared, so the pair is a filter of ``order`` with
|H|^2 = 1/2, -6 dB, at the cut-off), on each contiguous run of values
longer than ``padlen = 3 max(len(a), len(b))`` frames (filtfilt's default
odd padding); gaps (NaN) split the runs and shorter runs stay unfiltered.
Its default is order 4 at 6 Hz (``[filtering.butterworth]`` of Pose2Sim's
Config.toml). We do the same per joint and coordinate, and also split at
``breaks`` (the first frames of independent runs, ``runs`` of ``[mocap]``).

The gain of the pair at frequency f is that of the single pass squared,
``|H(f)|^2 = 1 / (1 + (tan(pi f / fps) / tan(pi fc / fps))^(2 n))`` with
n = order/2 (the bilinear Butterworth, scipy pre-warps the cut-off);
:func:`response` computes it from the coefficients (``scipy.signal.freqz``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, filtfilt, freqz

from photogram.errors import InputError

__all__ = ["FilterSettings", "FILTER_TYPES", "butterworth_coefficients", "response",
           "contiguous_runs", "filter_joints"]

FILTER_TYPES = ("butterworth", "none")


@dataclass(frozen=True)
class FilterSettings:
    """``[mocap.filter]``: ``type`` "butterworth" (default) or "none", the
    ``order`` of the zero-lag pair (even; Pose2Sim's default 4) and its
    ``cutoff_hz`` (Pose2Sim's default 6 Hz)."""

    type: str = "butterworth"
    order: int = 4
    cutoff_hz: float = 6.0

    def __post_init__(self):
        if self.type not in FILTER_TYPES:
            raise InputError(f"unknown filter type {self.type!r}",
                             hint="use " + " or ".join(FILTER_TYPES))
        if self.order < 2 or self.order % 2:
            raise InputError(f"the filter order must be even and at least 2, not {self.order}",
                             hint="filtfilt runs a Butterworth of order/2 twice (Pose2Sim)")
        if not self.cutoff_hz > 0:
            raise InputError(f"the filter cut-off must be positive, not {self.cutoff_hz}")


def butterworth_coefficients(order: int, cutoff_hz: float, fps: float):
    """(b, a) of the Butterworth low-pass of order ``order // 2`` that
    filtfilt applies twice (Pose2Sim: ``signal.butter(order/2, cutoff/(fps/2))``)."""
    if not 0 < cutoff_hz < fps / 2:
        raise InputError(f"the filter cut-off {cutoff_hz} Hz must be below the Nyquist "
                         f"frequency fps/2 = {fps / 2:g} Hz")
    return butter(int(order) // 2, float(cutoff_hz) / (float(fps) / 2.0), "low")


def response(order: int, cutoff_hz: float, fps: float, freqs_hz) -> np.ndarray:
    """Gain of the zero-lag pair at ``freqs_hz``: ``|H(f)|^2`` of the
    single pass (``scipy.signal.freqz``), since filtfilt applies it twice."""
    b, a = butterworth_coefficients(order, cutoff_hz, fps)
    _, h = freqz(b, a, worN=np.atleast_1d(np.asarray(freqs_hz, float)), fs=float(fps))
    return np.abs(h) ** 2


def contiguous_runs(finite: np.ndarray, breaks=()) -> list[tuple[int, int, np.ndarray]]:
    """Contiguous runs of finite values of every column of ``finite`` (F, M)
    as ``(start, stop, columns)``, the columns sharing the run grouped; runs
    never cross ``breaks``."""
    F, M = finite.shape
    cut = np.zeros(F + 1, bool)
    cut[[0, F]] = True
    cut[[int(b) for b in breaks if 0 < int(b) < F]] = True
    padded = np.zeros((F + 2, M), bool)
    padded[1:-1] = finite
    # a run starts where a value is finite and the previous is not (or a break)
    start = padded[1:-1] & (~padded[:-2] | cut[:-1, None])
    stop = padded[1:-1] & (~padded[2:] | cut[1:, None])         # last frame of a run
    groups: dict[tuple[int, int], list[int]] = {}
    for col in range(M):
        s, e = np.flatnonzero(start[:, col]), np.flatnonzero(stop[:, col]) + 1
        for a, b in zip(s.tolist(), e.tolist()):
            groups.setdefault((a, b), []).append(col)
    return [(a, b, np.array(cols)) for (a, b), cols in sorted(groups.items())]


def filter_joints(X: np.ndarray, fps: float, settings: FilterSettings | None = None,
                  breaks=()) -> tuple[np.ndarray, dict]:
    """Filter joints X (F, ...) along the frames, every coordinate on its
    own, over contiguous runs of finite values (module doc).

    Returns
    -------
    Y : array like X
        Filtered; NaN where X is NaN; runs of at most ``padlen`` frames
        unchanged.
    report : dict
        The filter (type, order, cut-off, zero lag), the runs filtered and
        left unfiltered (too short) and the values in them.
    """
    s = settings or FilterSettings()
    X = np.asarray(X, dtype=float)
    if s.type == "none":
        return X.copy(), {"type": "none"}
    b, a = butterworth_coefficients(s.order, s.cutoff_hz, fps)
    padlen = 3 * max(len(a), len(b))
    flat = X.reshape(len(X), -1)
    Y = flat.copy()
    n_done = n_short = v_short = 0
    for start, stop, cols in contiguous_runs(np.isfinite(flat), breaks):
        if stop - start <= padlen:
            n_short += len(cols)
            v_short += (stop - start) * len(cols)
            continue
        Y[start:stop, cols] = filtfilt(b, a, flat[start:stop, cols], axis=0, padlen=padlen)
        n_done += len(cols)
    report = {"type": "butterworth", "order": int(s.order), "cutoff_hz": float(s.cutoff_hz),
              "zero_lag": "scipy.signal.filtfilt (forward-backward), odd padding",
              "design": f"scipy.signal.butter({s.order // 2}, {s.cutoff_hz:g}/(fps/2)), filtfilt",
              "min_run_frames": padlen + 1, "runs_filtered": n_done,
              "runs_unfiltered_too_short": n_short, "values_unfiltered": v_short}
    if n_short:
        report["note"] = (f"{n_short} coordinate runs of at most {padlen} frames "
                          f"({v_short} values) left unfiltered (too short for filtfilt)")
    return Y.reshape(X.shape), report
