"""Composed multi-person detections with known truth (tests and
``benchmarks/mocap_people.py``): the athlete's detections of every camera
plus bystanders, each with a person id (0: the athlete).

Two kinds of bystander:

* :func:`copied_bystander`: the athlete's 2D skeleton of one camera taken
  from another time, scaled about its centre (1.5: larger, as a person
  nearer to that camera) and shifted (a fixed offset, or one per frame: a
  person walking across the athlete), with a high confidence. It is a
  plausible person in that view but belongs to no 3D person.
* :func:`projected_bystander`: a real 3D person (e.g. the athlete's 3D
  skeleton from another time, moved) projected into some cameras: its
  views are consistent with each other, only not with the athlete's.
"""

from __future__ import annotations

import warnings

import numpy as np

from photogram.mocap.tracking.detections import CameraDetections

__all__ = ["copied_bystander", "projected_bystander", "compose"]


def copied_bystander(obs: np.ndarray, lag: int, scale: float = 1.5, shift=(0.0, 0.0),
                     confidence: float = 0.95) -> np.ndarray:
    """(F, J, 3) bystander in one camera from the athlete's detections
    ``obs`` (F, J, 3) of that camera ``lag`` frames later (played back and
    forth past the ends, so that it moves without jumps), scaled by
    ``scale`` about its median joint and shifted by ``shift`` ((2,) or
    (F, 2) px); confidence ``confidence`` where the athlete's joint was
    detected."""
    obs = np.asarray(obs, float)
    F = len(obs)
    k = (np.arange(F) + int(lag)) % max(2 * F - 2, 1)
    src = obs[np.where(k < F, k, 2 * F - 2 - k)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)        # frames without joints
        centre = np.nanmedian(src[..., :2], axis=1, keepdims=True)
    out = np.full(src.shape, np.nan)
    out[..., :2] = centre + scale * (src[..., :2] - centre) + np.broadcast_to(
        np.asarray(shift, float), (F, 2))[:, None, :]
    seen = np.nan_to_num(src[..., 2]) > 0
    out[..., 2] = np.where(seen, confidence, 0.0)
    out[~seen, :2] = np.nan
    return out


def projected_bystander(cameras, X: np.ndarray, confidence: float = 0.9) -> np.ndarray:
    """(F, C, J, 3) detections (noise-free) of a 3D person X (F, J, 3) in
    every camera (NaN, 0 behind a camera)."""
    xy = cameras.project(X)
    out = np.concatenate([xy, np.full(xy.shape[:-1] + (1,), confidence)], -1)
    bad = ~np.all(np.isfinite(xy), -1)
    out[bad] = (np.nan, np.nan, 0.0)
    return out


def compose(obs: np.ndarray, skeleton, names, bystanders=()) -> list[CameraDetections]:
    """Candidate detections per camera: the athlete ``obs`` (F, C, J, 3)
    (person 0; a frame whose joints are all undetected has no row) and
    ``bystanders``: (camera index, joints (F, J, 3)) in order, persons 1, 2...
    (rows only where a joint is detected)."""
    obs = np.asarray(obs, float)
    F, C, J, _ = obs.shape
    out = []
    for c, name in enumerate(names):
        people = [(0, obs[:, c])] + [(k + 1, np.asarray(b, float))
                                     for k, (cb, b) in enumerate(bystanders) if cb == c]
        frames, joints, person = [], [], []
        for pid, jj in people:
            have = np.flatnonzero((np.nan_to_num(jj[..., 2]) > 0).any(-1))
            frames.append(have)
            joints.append(jj[have])
            person.append(np.full(len(have), pid))
        out.append(CameraDetections.from_joints(name, skeleton, np.concatenate(frames),
                                                np.concatenate(joints), F,
                                                person=np.concatenate(person)))
    return out
