"""Geometry: rotations, camera models and their conversions.

See docs/camera-models.md for the equations and conventions.
"""

from photogram.geometry.rotations import (
    ANGLE_FACTORS, angle_increment_map, from_radians, matrix_to_opk, matrix_to_quaternion,
    matrix_to_rodrigues, opk_derivatives, opk_inverse_jacobian, opk_to_matrix, quaternion_to_matrix,
    rodrigues_derivatives, rodrigues_to_matrix, skew, small_rotation, to_radians)
from photogram.geometry.camera import (
    CAMERA_MODELS, CameraModel, camera_frame, camera_model, ideal_projection,
    opencv_pose, photogrammetric_pose, pose_jacobians, rescale_parameters)
from photogram.geometry.brown import BrownModel
from photogram.geometry.opencv_model import OpenCVModel
from photogram.geometry.fisheye_model import OpenCVFisheyeModel
from photogram.geometry.opencv_full_model import OpenCVFullModel
from photogram.geometry.bal_model import BALModel
from photogram.geometry.aicon_model import AiconModel
from photogram.geometry.dbat_models import (
    BrownAffineAfterModel, BrownAspectFirstModel, BrownForwardModel, aspect_first_to_brown,
    brown_to_aspect_first)
from photogram.geometry.conversions import (
    brown_to_opencv, fit_distortion, format_grid, opencv_to_brown)
from photogram.geometry.aicon_conversions import (
    aicon_to_brown, aicon_to_opencv, brown_to_aicon, change_r0, opencv_to_aicon)

__all__ = [
    "ANGLE_FACTORS", "angle_increment_map", "from_radians", "matrix_to_opk", "matrix_to_quaternion",
    "matrix_to_rodrigues", "opk_derivatives", "opk_inverse_jacobian", "opk_to_matrix",
    "quaternion_to_matrix", "rodrigues_derivatives", "rodrigues_to_matrix",
    "skew", "small_rotation", "to_radians",
    "CAMERA_MODELS", "CameraModel", "camera_frame", "camera_model",
    "ideal_projection", "opencv_pose", "photogrammetric_pose", "pose_jacobians",
    "rescale_parameters", "BrownModel", "OpenCVModel", "OpenCVFisheyeModel", "OpenCVFullModel",
    "BALModel",
    "AiconModel", "aicon_to_brown", "aicon_to_opencv", "brown_to_aicon", "change_r0",
    "opencv_to_aicon",
    "BrownAffineAfterModel", "BrownAspectFirstModel", "BrownForwardModel",
    "aspect_first_to_brown", "brown_to_aspect_first",
    "brown_to_opencv", "fit_distortion", "format_grid", "opencv_to_brown",
]
