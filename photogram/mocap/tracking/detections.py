"""Candidate detections of one camera: per frame, a bounding box and joints
with confidences, as every observation source gives them
(:mod:`photogram.mocap.sources`) and the athlete tracking
(:mod:`photogram.mocap.tracking.athlete`) takes them.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from photogram.mocap.body.skeleton import Skeleton

__all__ = ["CameraDetections", "boxes_from_joints"]


def boxes_from_joints(joints: np.ndarray, min_confidence: float = 0.0) -> np.ndarray:
    """(…, 4) boxes ``x0, y0, x1, y1`` of the joints (…, J, 3) with a
    confidence above ``min_confidence`` (NaN without any)."""
    j = np.asarray(joints, dtype=float)
    ok = np.isfinite(j[..., 0]) & np.isfinite(j[..., 1]) & (np.nan_to_num(j[..., 2]) > min_confidence)
    x = np.where(ok, j[..., 0], np.nan)
    y = np.where(ok, j[..., 1], np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)       # all-NaN rows
        return np.stack([np.nanmin(x, -1), np.nanmin(y, -1), np.nanmax(x, -1),
                         np.nanmax(y, -1)], -1)


@dataclass
class CameraDetections:
    """All candidate detections of one camera, one row per candidate.

    ``frames`` (n,) 0-based frame index; ``joints`` (n, J, 3) x, y (px, full
    image, y down) and confidence (0 or NaN: not detected); ``boxes`` (n, 4)
    ``x0, y0, x1, y1``; ``person`` (n,) the source's person id (-1:
    unknown); ``n_frames`` frames of the camera (frames without a candidate
    have no row).
    """

    camera: str
    skeleton: Skeleton
    frames: np.ndarray
    joints: np.ndarray
    boxes: np.ndarray
    person: np.ndarray
    n_frames: int

    @classmethod
    def from_joints(cls, camera, skeleton, frames, joints, n_frames, person=None,
                    boxes=None) -> "CameraDetections":
        joints = np.asarray(joints, dtype=float).reshape(-1, skeleton.n_joints, 3)
        frames = np.asarray(frames, dtype=int).reshape(-1)
        person = np.full(len(frames), -1) if person is None else np.asarray(person, int)
        boxes = boxes_from_joints(joints) if boxes is None else np.asarray(boxes, float)
        return cls(camera, skeleton, frames, joints, boxes.reshape(-1, 4), person, int(n_frames))
