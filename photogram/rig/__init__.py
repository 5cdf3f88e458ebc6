"""Multi-camera rig calibration from a board (issue 20): board detections
of several cameras in, every camera's interior and exterior orientation
with sigmas out (:mod:`photogram.rig.calibrate`); start values from
OpenCV's single-camera calibration chained over shared frames
(:mod:`photogram.rig.initial`)."""

from photogram.rig.calibrate import RigCamera, RigResult, calibrate_rig

__all__ = ["RigCamera", "RigResult", "calibrate_rig"]
