"""The in-memory project model and its .prj/CSV readers and writers.

Public API::

    read_project(path) -> Project
    write_project(project, path, *, overwrite=False) -> Path
    validate_project(project) -> list[str]            # warnings; raises InputError
    write_results(folder, project, summary, *, camera_sigma=None, station_sigma=None,
                  point_sigma=None, residuals=None, log_text="") -> Path
    read_results(folder) -> Results
    load_cameras_file(path) -> (image_unit, {name: Camera})
    parameter_names(model) -> tuple[str, ...] | None

The format is documented in docs/project-files.md.
"""

from photogram.project.camera_schema import (
    camera_models, invert_opk, load_cameras_file, parameter_names,
)
from photogram.project.model import (
    AdjustmentSettings, Camera, DistanceConstraint, ImageLines, ImagePoints,
    OutputSettings, Parameter, Points, Project, Stations, Units, VerticalConstraint,
)
from photogram.project.reader import read_project
from photogram.project.results import Results, read_results, write_results
from photogram.project.validate import validate_project
from photogram.project.writer import write_project

__all__ = [
    "read_project", "write_project", "validate_project", "write_results", "read_results",
    "Results", "load_cameras_file", "parameter_names", "camera_models", "invert_opk",
    "AdjustmentSettings", "Camera", "DistanceConstraint", "ImageLines", "ImagePoints",
    "OutputSettings", "Parameter", "Points", "Project", "Stations", "Units",
    "VerticalConstraint",
]
