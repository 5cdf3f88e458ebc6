"""The [project] and [output] sections, read alike by every kind of
project file (:mod:`photogram.project.reader` for photogrammetric and
Monte-Carlo projects, :mod:`photogram.project.reader_mocap` for
motion-capture ones): one module both import, so that neither reader
imports the other's module back.
"""

from __future__ import annotations

from photogram.project.model import (ANGLE_UNITS, IMAGE_UNITS, LENGTH_UNITS, REPORT_UNITS,
                                     ROTATION_DIRECTIONS, OutputSettings, Project,
                                     ReportSettings, Units)
from photogram.project.toml_source import Section

PROJECT_KEYS = ("name", "length_unit", "angle_unit", "image_unit", "rotation",
                "rotation_direction")


def _read_project_section(sec: Section, project: Project) -> None:
    sec.check_keys(PROJECT_KEYS)
    project.name = sec.ident("name", project.path.stem)
    project.units = Units(length=sec.string("length_unit", "m", choices=tuple(LENGTH_UNITS)),
                          angle=sec.string("angle_unit", "deg", choices=ANGLE_UNITS),
                          image=sec.string("image_unit", "px", choices=IMAGE_UNITS))
    rotation = sec.string("rotation", "omega-phi-kappa", choices=("omega-phi-kappa", "opk"))
    project.rotation = "opk" if rotation in ("omega-phi-kappa", "opk") else rotation
    project.rotation_direction = sec.string("rotation_direction", "world_to_camera",
                                            choices=ROTATION_DIRECTIONS)


def _read_output(sec: Section | None) -> OutputSettings:
    if sec is None:
        return OutputSettings()
    sec.check_keys(("folder",))
    return OutputSettings(folder=sec.string("folder", "results"))


def read_report_section(sec: Section | None) -> ReportSettings:
    """``[report]``: ``units = "project"`` (default) or ``"coach"``."""
    if sec is None:
        return ReportSettings()
    sec.check_keys(("units",))
    return ReportSettings(units=sec.string("units", "project", choices=REPORT_UNITS))
