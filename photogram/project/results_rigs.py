"""``rigs.csv`` of a results folder: the adjusted pose of every rig camera
other than the reference in its rig (``sensor_from_rig``,
docs/project-files.md ``[rigs.NAME]``), one row per camera, with its
a-posteriori sigmas. Written only for an adjustment with rigs (the rows are
``summary["rigs"]``, :func:`photogram.bundle.statistics.collect`); the
frames' poses are their reference images' stations in stations.csv.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from photogram.project.model import Project
from photogram.project.tables import format_angle, format_table

__all__ = ["RIGS_FILE", "rigs_table"]

RIGS_FILE = "rigs.csv"


def rigs_table(project: Project, rows, file_angle_sigmas) -> str:
    """CSV text: ``rig``, ``camera``, ``reference``, ``X0 Y0 Z0`` (the
    camera's centre in the rig frame, length unit), ``omega phi kappa``
    (angle unit, the stations table's rotation direction) and their sigmas
    ``est_sX0 .. est_skappa`` (0: fixed). ``file_angle_sigmas``:
    :func:`photogram.project.results.file_angle_sigmas` (passed in: that
    module writes this table)."""
    from photogram.project.writer import _angles_for_file
    angles = np.array([r["angles_rad"] for r in rows], float).reshape(-1, 3)
    cov = np.array([r["angle_covariance_rad"] for r in rows], float).reshape(-1, 3, 3)
    # the sigmas of the file's angles (camera_to_world: propagated through the
    # inversion at these angles, as for the stations)
    as_stations = dataclasses.replace(project, stations=dataclasses.replace(
        project.stations, angles=angles))
    sig = file_angle_sigmas(as_stations, np.sqrt(np.diagonal(cov, axis1=1, axis2=2)), cov)
    file_angles = _angles_for_file(project, angles)
    unit = project.units.angle
    cols: dict = {"rig": [r["rig"] for r in rows], "camera": [r["camera"] for r in rows],
                  "reference": [r["reference"] for r in rows]}
    position = np.array([r["position"] for r in rows], float).reshape(-1, 3)
    psig = np.array([r["position_sigma"] for r in rows], float).reshape(-1, 3)
    for j, c in enumerate(("X0", "Y0", "Z0")):
        cols[c] = position[:, j]
    for j, c in enumerate(("omega", "phi", "kappa")):
        cols[c] = [format_angle(a, unit) for a in file_angles[:, j]]
    for j, c in enumerate(("X0", "Y0", "Z0")):
        cols["est_s" + c] = psig[:, j]
    for j, c in enumerate(("omega", "phi", "kappa")):
        cols["est_s" + c] = [format_angle(a, unit) for a in sig[:, j]]
    return format_table(cols, comment="rig cameras in their rigs (sensor_from_rig); the "
                                      "reference camera's pose is the identity")
