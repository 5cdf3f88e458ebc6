"""Line photogrammetry (ski-jump paper, appendix C.2-C.3): straight image
lines fitted to measured points, 3D lines from two or more oriented views
(planes through the projection centres, step B, and the one-step
solution), initial values from the stacked planes, line transfer into a
third view and the left/right ski label check.

See docs/lines.md for the equations.
"""

from photogram.lines.image_line import (
    ImageLine, fit_image_line, line_angle, line_distance, normalize_line)
from photogram.lines.views import (
    ViewCamera, cameras_from_project, fit_view_line, lines_from_project)
from photogram.lines.plucker import (
    SpaceLine, closest_point, distance_point_line, line_from_plucker, line_from_points,
    local_basis, point_on_line, project_line, project_line_batch)
from photogram.lines.initial import (
    check_plane_geometry, initial_line_homogeneous, line_planes, plane_angles)
from photogram.lines.space_line import LineIntersection, intersect_line
from photogram.lines.one_step import intersect_line_one_step
from photogram.lines.from_points import intersect_line_from_points
from photogram.lines.transfer import (
    LineComparison, TransferredLine, compare_lines, transfer_line, transfer_line_trifocal,
    trifocal_tensor)
from photogram.lines.skis import (
    SkiCheck, TransferCheck, check_ski_labels, check_ski_sequence, swap_labels)

__all__ = [
    "ImageLine", "fit_image_line", "line_angle", "line_distance", "normalize_line",
    "ViewCamera", "cameras_from_project", "fit_view_line", "lines_from_project",
    "SpaceLine", "closest_point", "distance_point_line", "line_from_plucker",
    "line_from_points", "local_basis", "point_on_line", "project_line", "project_line_batch",
    "check_plane_geometry", "initial_line_homogeneous", "line_planes", "plane_angles",
    "LineIntersection", "intersect_line", "intersect_line_from_points",
    "intersect_line_one_step",
    "LineComparison", "SkiCheck", "TransferCheck", "TransferredLine", "check_ski_labels",
    "check_ski_sequence", "compare_lines", "swap_labels", "transfer_line",
    "transfer_line_trifocal", "trifocal_tensor",
]
