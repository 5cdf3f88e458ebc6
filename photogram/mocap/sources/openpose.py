"""OpenPose / Pose2Sim JSON folders: one folder per camera, one JSON file
per frame (files in name order), ``people[].pose_keypoints_2d`` = J x (x, y,
confidence) in full-image pixels; an undetected joint is (0, 0, 0).

The skeleton must be named (``body25b`` for Pose2Sim's default model,
``body25`` for OpenPose's default, ``coco17``...): 25 keypoints do not say
which 25.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import Skeleton
from photogram.mocap.sources.base import ObservationSource
from photogram.mocap.tracking.detections import CameraDetections

__all__ = ["OpenPoseSource", "read_openpose_folder"]


def read_openpose_folder(folder: Path, skeleton: Skeleton, camera: str = "") -> CameraDetections:
    """All people of all frames of one camera folder."""
    folder = Path(folder)
    files = sorted(folder.glob("*.json"))
    if not files:
        raise InputError("no OpenPose JSON files (*.json) in the folder", file=folder,
                         hint="give the folder that holds one JSON file per frame")
    J = skeleton.n_joints
    frames, joints, persons = [], [], []
    for f, path in enumerate(files):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            people = data.get("people", [])
        except (OSError, ValueError, AttributeError) as exc:
            raise InputError(f"not an OpenPose JSON file ({exc})", file=path) from None
        for k, person in enumerate(people):
            kp = np.asarray(person.get("pose_keypoints_2d", []), dtype=float)
            if kp.size != 3 * J:
                raise InputError(f"person {k} has {kp.size // 3} keypoints, skeleton "
                                 f"{skeleton.name} has {J}", file=path,
                                 hint="set skeleton in [mocap.source] to the detector's model")
            kp = kp.reshape(J, 3)
            missing = kp[:, 2] <= 0
            kp[missing] = (np.nan, np.nan, 0.0)
            frames.append(f)
            joints.append(kp)
            pid = person.get("person_id", -1)
            persons.append(int(pid[0] if isinstance(pid, list) and pid else
                               pid if isinstance(pid, (int, float)) else -1))
    return CameraDetections.from_joints(camera, skeleton, frames,
                                        np.array(joints).reshape(-1, J, 3), len(files),
                                        person=persons)


class OpenPoseSource(ObservationSource):
    """``folders`` maps camera names to their JSON folders."""

    kind = "openpose"

    def __init__(self, folders: dict[str, Path], skeleton: Skeleton):
        self.folders = {k: Path(v) for k, v in folders.items()}
        self.skeleton = skeleton
        self.cameras = list(self.folders)

    def detections(self, camera: str) -> CameraDetections:
        return read_openpose_folder(self.folders[camera], self.skeleton, camera)
