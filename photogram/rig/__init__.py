"""Multi-camera rig calibration from a board (issue 20): board detections
of several cameras in, every camera's interior and exterior orientation
with sigmas out (:mod:`photogram.rig.calibrate`); start values from
OpenCV's single-camera calibration chained over shared frames
(:mod:`photogram.rig.initial`); the world from the board on the floor or
from scene points of known coordinates (:mod:`photogram.rig.datum`);
detections from videos and image folders (:mod:`photogram.rig.frames`)."""

from photogram.rig.calibrate import RigCamera, RigResult, calibrate_rig
from photogram.rig.datum import SceneControl

__all__ = ["RigCamera", "RigResult", "SceneControl", "calibrate_rig"]
