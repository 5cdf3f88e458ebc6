"""Applying frame offsets to a camera's detections and per-frame
parameters (docs/mocap.md, section 13; the convention in
:mod:`photogram.mocap.evaluation.sync`): ``b[f] = a[f + offset]``, linear
interpolation for a fractional offset."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

__all__ = ["shift_series", "shift_observations", "shift_rotations", "apply_offsets"]


def shift_series(a: np.ndarray, offset: float, *, edge: bool = False) -> np.ndarray:
    """``b[f] = a[f + offset]`` along axis 0, linearly interpolated for a
    fractional offset.

    Parameters
    ----------
    a : ndarray (F, ...)
    offset : float
        Frames (docs/mocap.md, "Synchronisation").
    edge : bool
        Outside ``a``: NaN (False, detections) or the nearest frame (True,
        camera parameters).

    Returns
    -------
    ndarray (F, ...)
        A NaN in either neighbour gives NaN (no extrapolation over gaps).
    """
    a = np.asarray(a, dtype=float)
    F = a.shape[0]
    t = np.arange(F) + float(offset)
    if edge:
        t = np.clip(t, 0, F - 1)
    lo = np.floor(t + 1e-9).astype(int)
    w = t - lo
    w = np.where(np.abs(w) < 1e-9, 0.0, w)
    inside = (lo >= 0) & (lo <= F - 1) & ((lo < F - 1) | (w == 0))
    lo_c = np.clip(lo, 0, F - 1)
    hi_c = np.clip(lo + 1, 0, F - 1)
    shape = (F,) + (1,) * (a.ndim - 1)
    wv = w.reshape(shape)
    a_hi = np.where(wv > 0, a[hi_c], 0.0)
    out = (1 - wv) * a[lo_c] + wv * a_hi
    out[~inside] = np.nan
    return out


def shift_observations(obs_c: np.ndarray, offset: float) -> np.ndarray:
    """The detections (F, J, 3) of one camera shifted by ``offset``
    (:func:`shift_series`); a detection interpolated between two frames
    needs both (its confidence the lower of the two); missing: x, y NaN,
    confidence 0."""
    obs_c = np.asarray(obs_c, dtype=float)
    xy = np.where((np.nan_to_num(obs_c[..., 2]) > 0)[..., None], obs_c[..., :2], np.nan)
    out = np.empty(obs_c.shape)
    out[..., :2] = shift_series(xy, offset)
    frac = offset - np.floor(offset)
    conf = np.nan_to_num(obs_c[..., 2])
    lo = shift_series(conf, np.floor(offset))
    hi = shift_series(conf, np.floor(offset) + 1) if frac > 1e-9 else lo
    c = np.fmin(lo, hi)
    ok = np.all(np.isfinite(out[..., :2]), -1) & np.isfinite(c)
    out[..., 2] = np.where(ok, np.nan_to_num(c), 0.0)
    out[~ok, :2] = np.nan
    return out


def shift_rotations(R: np.ndarray, offset: float) -> np.ndarray:
    """Rotations (F, 3, 3) shifted by ``offset`` (edge frames repeated): the
    matrices interpolated linearly, then the nearest rotation (SVD)."""
    M = shift_series(R, offset, edge=True)
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    U[..., :, 2] *= d[..., None]
    return U @ Vt


def apply_offsets(obs: np.ndarray, cameras, offsets: dict):
    """Detections (F, C, J, 3) and cameras with ``offsets`` (camera index ->
    frames) applied: the camera's detections shifted
    (:func:`shift_observations`) and, when they are given per frame, its
    rotations (:func:`shift_rotations`) and interior orientation (zoom),
    which are numbered like its detections."""
    obs = np.array(obs, dtype=float)
    R = np.array(cameras.R)
    io = [np.array(p) for p in cameras.io]
    for c, o in offsets.items():
        if o == 0:
            continue
        obs[:, c] = shift_observations(obs[:, c], o)
        if R.shape[0] > 1:
            R[:, c] = shift_rotations(R[:, c], o)
        if io[c].shape[0] > 1:
            io[c] = shift_series(io[c], o, edge=True)
    return obs, replace(cameras, R=R, io=io)
