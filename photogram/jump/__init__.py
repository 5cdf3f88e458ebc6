"""The ski jumper's stick model (after the ski-jump paper; our definitions in
docs/stick-model.md): per exposure the jumper frame, the angles between body
and skis, the ski slope, the height and speed of O, the ski segments, and the
sigma of every parameter by analytic covariance propagation.

``photogram.jump.figure`` (matplotlib) is imported on demand.
"""

from photogram.jump.definitions import PARAMETERS, POINT_NAMES, POINT_ROLES
from photogram.jump.stick import (PlaneGround, ProfileGround, StickModel, ski_segments,
                                  stick_model)

__all__ = ["stick_model", "StickModel", "ski_segments", "PlaneGround", "ProfileGround",
           "PARAMETERS", "POINT_NAMES", "POINT_ROLES"]
