"""mediapipe 0.10.21's legacy pose solution as an image detector (optional).

Install with ``pip install 'photogram[mediapipe]'`` (mediapipe 0.10.21 is
the last version that ships its pose models; it pulls in jax and
opencv-contrib-python). Only ``model_complexity=1`` works offline. Each crop
is processed on its own (``static_image_mode=True``): one person, 33
landmarks with a visibility, which is used as the confidence. The
landmarks are reconstructed as the generic ``mediapipe33`` skeleton or
mapped onto SKI24 (head: mean of the ears, neck: mean of the shoulders,
hands: wrists, toes: foot index; no poles, no skis), see
:mod:`photogram.mocap.body.skeleton`.

The package is imported only when a detector is created; without it the
error is one line.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import MEDIAPIPE33
from photogram.mocap.sources.base import ImageDetector

__all__ = ["MediapipeDetector", "landmarks_to_joints"]


def landmarks_to_joints(landmarks, width: int, height: int) -> np.ndarray:
    """(33, 3) pixel coordinates and visibility of a mediapipe result's
    ``pose_landmarks`` (normalised x, y in [0, 1]); NaN/0 for None."""
    out = np.full((MEDIAPIPE33.n_joints, 3), np.nan)
    out[:, 2] = 0.0
    if landmarks is None:
        return out
    for k, lm in enumerate(landmarks.landmark[:MEDIAPIPE33.n_joints]):
        out[k] = (lm.x * width, lm.y * height, float(getattr(lm, "visibility", 1.0)))
    return out


class MediapipeDetector(ImageDetector):
    """mediapipe pose (BlazePose full, model_complexity 1) on RGB images."""

    skeleton = MEDIAPIPE33

    def __init__(self, model_complexity: int = 1, min_detection_confidence: float = 0.5):
        try:
            import mediapipe as mp   # noqa: F401  (optional dependency)
        except ImportError:
            raise InputError("the mediapipe source needs the optional package mediapipe "
                             "0.10.21, which is not installed",
                             hint="pip install 'photogram[mediapipe]'") from None
        if model_complexity != 1:
            raise InputError("only model_complexity = 1 works offline with mediapipe 0.10.21",
                             hint="use model_complexity = 1")
        self._pose = mp.solutions.pose.Pose(static_image_mode=True,
                                            model_complexity=model_complexity,
                                            min_detection_confidence=min_detection_confidence)

    def __call__(self, image: np.ndarray):
        h, w = image.shape[:2]
        result = self._pose.process(np.ascontiguousarray(image))
        if result.pose_landmarks is None:
            return None
        return landmarks_to_joints(result.pose_landmarks, w, h)
