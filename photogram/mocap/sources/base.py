"""The observation-source interface: per camera and frame, candidate
detections (a bounding box and joints with confidences:
:class:`photogram.mocap.tracking.detections.CameraDetections`).

A source is either a *detection source* (detections computed elsewhere,
in full-image pixel coordinates: OpenPose/Pose2Sim JSON folders, CSV) or an
*image detector* (a 2D pose network run by photogram on image crops:
mediapipe, or a user network given as ``"module:function"``); the latter
goes through the crop tracking of :mod:`photogram.mocap.tracking.athlete`.
"""

from __future__ import annotations

import numpy as np

from photogram.mocap.body.skeleton import Skeleton
from photogram.mocap.tracking.detections import CameraDetections

__all__ = ["ObservationSource", "ImageDetector"]


class ObservationSource:
    """Base class: ``skeleton``, ``cameras`` (names, in the order of the
    project's cameras) and :meth:`detections` per camera."""

    kind = ""
    skeleton: Skeleton
    cameras: list[str]

    def detections(self, camera: str) -> CameraDetections:
        raise NotImplementedError

    def track(self, camera: str, settings=None, wide: bool = False):
        """The athlete in ``camera`` (:class:`photogram.mocap.tracking.athlete.TrackedCamera`)."""
        from photogram.mocap.tracking.athlete import track_detections
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
