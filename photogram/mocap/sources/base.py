"""The observation-source interface: per camera and frame, candidate
detections (a bounding box and joints with confidences).

A source is either a *detection source* (detections computed elsewhere,
in full-image pixel coordinates: OpenPose/Pose2Sim JSON folders, CSV) or an
*image detector* (a 2D pose network run by photogram on image crops:
mediapipe, or a user network given as ``"module:function"``); the latter
goes through the crop tracking of :mod:`photogram.mocap.tracking`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from photogram.mocap.skeleton import Skeleton

__all__ = ["CameraDetections", "ObservationSource", "ImageDetector", "boxes_from_joints"]


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


class ObservationSource:
    """Base class: ``skeleton``, ``cameras`` (names, in the order of the
    project's cameras) and :meth:`detections` per camera."""

    kind = ""
    skeleton: Skeleton
    cameras: list[str]

    def detections(self, camera: str) -> CameraDetections:
        raise NotImplementedError

    def track(self, camera: str, settings=None, wide: bool = False):
        """The athlete in ``camera`` (:class:`photogram.mocap.tracking.TrackedCamera`)."""
        from photogram.mocap.tracking import track_detections
        return track_detections(self.detections(camera), settings, wide)

    def describe(self) -> str:
        return f"{self.kind} ({self.skeleton.name}, {len(self.cameras)} cameras)"


class ImageDetector:
    """A 2D pose network: ``__call__(image)`` with an RGB image (H, W, 3)
    uint8 returns (J, 3) joints (x, y in that image's pixels, confidence) of
    one person, or None when it finds nobody; ``skeleton`` names the joints."""

    skeleton: Skeleton

    def __call__(self, image: np.ndarray):   # pragma: no cover - interface
        raise NotImplementedError
