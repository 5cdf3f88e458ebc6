"""Write a project: the .prj (TOML) and its CSV tables beside it.

Values are written so that :func:`~photogram.project.reader.read_project`
reads back exactly the same floats: lengths and image coordinates via
``repr``, angles converted to the project's angle unit with
:func:`~photogram.project.tables.format_angle`, and, for
``rotation_direction = "camera_to_world"``, inverted so that the inversion on
reading gives back the same world-to-camera angles.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

import photogram
from photogram.errors import InputError
from photogram.project.atomic import atomic_write_text, same_file
from photogram.project.camera_schema import camera_to_toml, invert_opk
from photogram.project.model import Project
from photogram.project.tables import format_angle, format_table
from photogram.project.toml_writer import Inline, comment_string, dumps

__all__ = ["write_project", "project_to_toml", "station_columns", "point_columns",
           "input_files", "check_targets"]

_POSITION = ("X0", "Y0", "Z0")
_ANGLES = ("omega", "phi", "kappa")


def input_files(project: Project) -> list[Path]:
    """Every file the project was read from (the .prj, tables, cameras files)."""
    files = list(project.sources.values())
    if project.path is not None:
        files.append(project.path)
    return [Path(f) for f in files]


def check_targets(targets: list[Path], project: Project, *, overwrite: bool) -> None:
    """Refuse to write over the project's input files, or over existing files
    unless ``overwrite``.

    Raises
    ------
    InputError
    """
    inputs = input_files(project)
    for target in targets:
        if any(same_file(target, f) for f in inputs):
            raise InputError("refusing to write over an input file of the project",
                             file=target, hint="choose another output name or folder")
        if target.exists() and not overwrite:
            raise InputError("file exists", file=target,
                             hint="choose another name, or pass overwrite=True "
                                  "(command line: --force)")


def write_project(project: Project, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``project`` as a .prj with its CSV tables beside it.

    The tables are called ``<stem>_stations.csv``, ``<stem>_points.csv``,
    ``<stem>_image_points.csv`` and ``<stem>_image_lines.csv`` (if any).
    Cameras taken ``from`` an earlier result are written out in full.
    Every file is written atomically; the .prj last.

    Parameters
    ----------
    project : Project
    path : str or Path
        The .prj to write (its folder must exist).
    overwrite : bool
        Replace existing files (never the project's own input files).

    Returns
    -------
    Path
        The .prj written.

    Raises
    ------
    InputError
        A target exists (without ``overwrite``) or is one of the inputs.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise InputError("the folder does not exist", file=path.parent,
                         hint="create it first")
    tables = _tables(project, path.stem)
    targets = [path.parent / name for name in tables] + [path]
    check_targets(targets, project, overwrite=overwrite)
    for name, (columns, comment) in tables.items():
        atomic_write_text(path.parent / name, format_table(columns, comment=comment))
    names = {key: name for name, key in zip(tables, _table_keys(project))}
    atomic_write_text(path, project_to_toml(project, names))
    return path


def _table_keys(project: Project) -> list[str]:
    keys = ["stations", "points", "image_points"]
    return keys + (["image_lines"] if len(project.image_lines) else [])


def _tables(project: Project, stem: str) -> dict[str, tuple[dict, str | None]]:
    builders = {"stations": station_columns, "points": point_columns,
                "image_points": _image_point_columns, "image_lines": _image_line_columns}
    return {f"{stem}_{key}.csv": (builders[key](project), None)
            for key in _table_keys(project)}


def _angles_for_file(project: Project, angles: np.ndarray) -> np.ndarray:
    """World-to-camera radians -> the file's direction (still radians)."""
    if project.rotation_direction != "camera_to_world":
        return angles
    return np.array([_exact_inverse(a) for a in np.atleast_2d(angles)]).reshape(-1, 3)


def _exact_inverse(r: np.ndarray) -> np.ndarray:
    """Camera-to-world angles whose inversion gives back ``r`` bit for bit,
    searched among a few neighbouring floats of the plain inverse."""
    guess = invert_opk(r)[0]
    if not np.all(np.isfinite(guess)):
        return guess
    steps = sorted(itertools.product(range(-2, 3), repeat=3), key=lambda s: sum(map(abs, s)))
    candidates = np.array([[_ulps(g, s) for g, s in zip(guess, step)] for step in steps])
    back = invert_opk(candidates)
    hit = np.flatnonzero(np.all(back == r, axis=1))
    return candidates[hit[0]] if len(hit) else guess


def _ulps(x: float, n: int) -> float:
    for _ in range(abs(n)):
        x = np.nextafter(x, np.inf if n > 0 else -np.inf)
    return float(x)


def station_columns(project: Project, *, include_sigma: bool | None = None) -> dict:
    """Columns of the stations table in the file's units and direction.

    ``include_sigma`` None: write a-priori sigma columns only if any is set.
    """
    st = project.stations
    unit = project.units.angle
    angles = _angles_for_file(project, st.angles)
    cols: dict = {"station": list(st.names), "camera": list(st.camera)}
    for j, c in enumerate(_POSITION):
        cols[c] = st.position[:, j]
    for j, c in enumerate(_ANGLES):
        cols[c] = [format_angle(a, unit) for a in angles[:, j]]
    if include_sigma or include_sigma is None and (
            np.isfinite(st.position_sigma).any() or np.isfinite(st.angle_sigma).any()):
        for j, c in enumerate(_POSITION):
            cols["s" + c] = st.position_sigma[:, j]
        for j, c in enumerate(_ANGLES):
            cols["s" + c] = [format_angle(a, unit) for a in st.angle_sigma[:, j]]
    if any(st.frames()):
        cols["frame"] = st.frames()
    return cols


def rigs_section(project: Project) -> dict:
    """The ``[rigs.NAME]`` tables (photogram.project.reader_rigs)."""
    out = {}
    for name, rig in project.rigs.items():
        doc = {"reference": rig.reference, "cameras": list(rig.cameras), "fixed": rig.fixed}
        sensors = Inline()
        for cam, (position, angles) in rig.sensors.items():
            a = _angles_for_file(project, np.asarray(angles, float)[None])[0]
            sensors[cam] = [float(v) for v in position] + [
                float(format_angle(v, project.units.angle)) for v in a]
        if sensors:
            doc["sensors"] = sensors
        out[name] = doc
    return out


def point_columns(project: Project, *, include_sigma: bool | None = None) -> dict:
    """Columns of the points table."""
    pts = project.points
    cols: dict = {"id": list(pts.ids), "kind": [str(k) for k in pts.kind]}
    for j, c in enumerate("XYZ"):
        cols[c] = pts.xyz[:, j]
    if include_sigma or include_sigma is None and np.isfinite(pts.sigma).any():
        for j, c in enumerate("XYZ"):
            cols["s" + c] = pts.sigma[:, j]
    targets = getattr(project, "targets", None)
    if targets is not None:                      # circular targets (docs/project-files.md)
        r, n = targets.for_points(pts.ids)
        cols["diameter"] = 2 * r
        for j, c in enumerate(("nX", "nY", "nZ")):
            cols[c] = n[:, j]
    return cols


def _observation_columns(project: Project, obs, key: str, labels: list) -> dict:
    cols = {"station": [project.stations.names[i] for i in obs.station], key: labels,
            "x": obs.xy[:, 0], "y": obs.xy[:, 1]}
    if np.isfinite(obs.sigma).any():
        cols["sigma"] = obs.sigma
    return cols


def _image_point_columns(project: Project) -> dict:
    obs = project.image_points
    return _observation_columns(project, obs, "point",
                                [project.points.ids[i] for i in obs.point])


def _image_line_columns(project: Project) -> dict:
    obs = project.image_lines
    return _observation_columns(project, obs, "line", [str(v) for v in obs.line])


def _settings(project: Project) -> dict:
    adj = project.adjustment
    out = _base_settings(adj)
    if adj.datum == "dependent":
        if adj.dependent_station is not None:
            out["dependent_station"] = str(adj.dependent_station)
        out["dependent_coordinate"] = adj.dependent_coordinate
    return out


def _base_settings(adj) -> dict:
    return {
        "datum": adj.datum, "max_iterations": int(adj.max_iterations),
        "tolerance": float(adj.tolerance), "sigma_image": float(adj.sigma_image),
        "sigma_control": None if adj.sigma_control is None else float(adj.sigma_control),
        "damping": adj.damping, "robust": adj.robust or "none",
        "variance_components": bool(adj.variance_components),
        "snooping_alpha": None if adj.snooping_alpha is None else float(adj.snooping_alpha),
        "inner_constraints": None if adj.inner_constraints is None
        else list(adj.inner_constraints),
    }


def project_section(project: Project) -> dict:
    """The ``[project]`` table."""
    return {"name": project.name, "length_unit": project.units.length,
            "angle_unit": project.units.angle, "image_unit": project.units.image,
            "rotation": "omega-phi-kappa", "rotation_direction": project.rotation_direction}


def project_to_toml(project: Project, tables: dict[str, str]) -> str:
    """The .prj text, with ``tables`` mapping table keys to file names."""
    doc: dict = {"project": project_section(project),
                 "cameras": {n: camera_to_toml(c) for n, c in project.cameras.items()},
                 "stations": {"file": tables["stations"]},
                 "points": {"file": tables["points"]},
                 "observations": {"points": tables["image_points"],
                                  "lines": tables.get("image_lines")}}
    constraints = {}
    if project.distances:
        constraints["distance"] = [{"from": d.point_a, "to": d.point_b,
                                    "value": float(d.value), "sigma": float(d.sigma)}
                                   for d in project.distances]
    if project.verticals:
        constraints["vertical"] = [{"top": v.top, "bottom": v.bottom, "sigma": float(v.sigma)}
                                   for v in project.verticals]
    if constraints:
        doc["constraints"] = constraints
    doc["adjustment"] = _settings(project)
    if project.rigs:
        doc["rigs"] = rigs_section(project)
    if getattr(project, "targets", None) is not None:
        doc["targets"] = {"eccentricity": bool(project.targets.eccentricity)}
    doc["output"] = {"folder": project.output.folder}
    comments = {("cameras", n): f"taken from {comment_string(c.source)}"
                for n, c in project.cameras.items() if c.source}
    return dumps(doc, header=f"written by photogram {photogram.__version__}",
                 comments=comments)
