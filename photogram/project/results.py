"""The results folder of an adjustment, and reading it back.

Files (all written atomically; see docs/project-files.md):

``summary.json``
    ``status``, ``iterations``, ``sigma0``, ``redundancy``, ``counts``,
    ``timings``, ``warnings``, ``project``, ``software_version`` and whatever
    else the engine put in the summary. NaN and infinity are written as null.
``cameras.toml``
    Estimated interior orientation in the .prj camera schema, with
    ``sigma_estimated`` per parameter: a later project takes it with
    ``[cameras.K1] from = "../lab/results/cameras.toml"``.
``stations.csv``, ``points.csv``
    Estimated values in the project's units and rotation direction, valid as
    input tables; the a-posteriori sigmas are in ``est_s*`` columns (ignored
    by the readers; for camera-to-world angles propagated through the angle
    conversion), the a-priori sigmas in the usual ``s*`` columns.
``residuals.csv``
    One row per observation, columns as given by the engine.
``log.txt``
    The log of the run.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

import photogram
from photogram.errors import InputError
from photogram.project.atomic import atomic_write_text
from photogram.project.camera_schema import camera_to_toml, load_cameras_file
from photogram.project.model import Camera, Project
from photogram.project.tables import format_angle, format_table
from photogram.project.limits import read_json
from photogram.project.toml_writer import comment_string, dumps
from photogram.project.validate import rays_per_point
from photogram.project.writer import check_targets, point_columns, station_columns

__all__ = ["write_results", "read_results", "Results", "project_counts", "to_json_safe",
           "RESULT_FILES", "file_angle_sigmas"]

RESULT_FILES = ("summary.json", "cameras.toml", "stations.csv", "points.csv",
                "residuals.csv", "log.txt")
_STATION_SIGMAS = ("est_sX0", "est_sY0", "est_sZ0", "est_somega", "est_sphi", "est_skappa")


@dataclass
class Results:
    """A results folder read back.

    Tables are pandas DataFrames in the units of the files (the project's
    length and angle unit, its rotation direction); ids are strings.
    """

    folder: Path
    summary: dict
    image_unit: str
    cameras: dict[str, Camera]
    stations: Any
    points: Any
    residuals: Any
    log: str = ""
    extra: dict = field(default_factory=dict)


def to_json_safe(value: Any) -> Any:
    """Plain JSON types: NaN/inf -> None, numpy -> Python, Path -> str."""
    if isinstance(value, Mapping):
        return {str(k): to_json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, np.ndarray)):
        return [to_json_safe(v) for v in (value.tolist() if isinstance(value, np.ndarray)
                                          else value)]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, Path):
        return str(value)
    return str(value)


def project_counts(project: Project) -> dict:
    """Counts of the project's tables, for summaries."""
    kinds = [str(k) for k in project.points.kind]
    rays = rays_per_point(project)
    used = rays[rays > 0]
    return {
        "cameras": len(project.cameras), "stations": len(project.stations),
        "points": len(project.points),
        "points_by_kind": {k: kinds.count(k) for k in ("control", "check", "tie")},
        "image_points": len(project.image_points), "image_lines": len(project.image_lines),
        "distances": len(project.distances), "verticals": len(project.verticals),
        "rays_min": int(used.min()) if len(used) else 0,
        "rays_max": int(used.max()) if len(used) else 0,
    }


def _summary(project: Project, summary: Mapping) -> dict:
    out = {"status": None, "iterations": None, "sigma0": None, "redundancy": None}
    out.update(summary)
    out.setdefault("counts", project_counts(project))
    out.setdefault("timings", {})
    out["warnings"] = list(project.warnings) + list(summary.get("warnings", []))
    out.setdefault("project", {
        "name": project.name, "path": project.path, "length_unit": project.units.length,
        "angle_unit": project.units.angle, "image_unit": project.units.image,
        "rotation": "omega-phi-kappa", "rotation_direction": project.rotation_direction})
    out.setdefault("software_version", photogram.__version__)
    return to_json_safe(out)


def _cameras_toml(project: Project, camera_sigma: Mapping | None) -> str:
    sigma = camera_sigma or {}
    doc = {"project": {"name": project.name, "length_unit": project.units.length,
                       "angle_unit": project.units.angle, "image_unit": project.units.image,
                       "software_version": photogram.__version__},
           "cameras": {n: camera_to_toml(c, sigma.get(n)) for n, c in project.cameras.items()}}
    # the project name is a user string: quoted and escaped, one comment line
    return dumps(doc, header=f"interior orientation estimated by photogram "
                             f"{photogram.__version__} from {comment_string(project.name)}\n"
                             f"take it into another project with "
                             f"[cameras.NAME] from = \"<path of this file>\"")


def file_angle_sigmas(project: Project, sigma, covariance=None) -> np.ndarray:
    """Sigmas of the station angles in the file's rotation direction.

    For ``rotation_direction = "camera_to_world"`` the angles in the file
    are those of the inverse rotation, ``b = inv(a)``, so their covariance
    is ``J C J^T`` with ``J = db/da`` (:func:`photogram.geometry.
    opk_inverse_jacobian`, analytic) and ``C`` the covariance of the
    world-to-camera angles; copying the sigmas of ``a`` is wrong by a factor
    that reaches 7 and more for near-horizontal cameras.

    Parameters
    ----------
    project : Project
        Its ``stations.angles`` (world-to-camera, radians) are where ``J``
        is taken.
    sigma : (n, 3) array
        Sigmas of the world-to-camera angles (radians).
    covariance : (n, 3, 3) array, optional
        Their covariance (the correlations matter); default: ``diag(sigma^2)``.

    Returns
    -------
    (n, 3) array
        Sigmas in the file's direction (radians); NaN where not estimated
        or at gimbal lock.
    """
    sigma = np.asarray(sigma, float).reshape(-1, 3)
    if project.rotation_direction != "camera_to_world":
        return sigma
    from photogram.geometry import opk_inverse_jacobian
    C = (np.asarray(covariance, float).reshape(-1, 3, 3) if covariance is not None
         else sigma[:, :, None] * np.eye(3) * sigma[:, None, :])
    J = opk_inverse_jacobian(project.stations.angles)
    with np.errstate(invalid="ignore"):
        var = np.einsum("nij,njk,nik->ni", J, C, J)
        out = np.sqrt(np.clip(var, 0, None))
    return np.where(np.all(np.isfinite(sigma), axis=1, keepdims=True) & np.isfinite(out),
                    out, np.nan)


def _station_table(project: Project, station_sigma, station_covariance=None) -> dict:
    """stations.csv's columns (name -> values, as :func:`format_table` writes them)."""
    cols = station_columns(project)
    if station_sigma is not None:
        if isinstance(station_sigma, Mapping):
            sig = np.hstack([np.asarray(station_sigma["position"], float),
                             np.asarray(station_sigma["angles"], float)])
        else:
            sig = np.asarray(station_sigma, float).reshape(len(project.stations), 6)
        cov = None if station_covariance is None else \
            np.asarray(station_covariance, float).reshape(-1, 6, 6)[:, 3:, 3:]
        sig = sig.copy()
        sig[:, 3:] = file_angle_sigmas(project, sig[:, 3:], cov)
        for j, name in enumerate(_STATION_SIGMAS):
            cols[name] = sig[:, j] if j < 3 else \
                [format_angle(a, project.units.angle) for a in sig[:, j]]
    return cols


def _point_table(project: Project, point_sigma, point_extra=None) -> dict:
    """points.csv's columns."""
    cols = point_columns(project)
    if point_sigma is not None:
        sig = np.asarray(point_sigma, float).reshape(len(project.points), 3)
        for j, c in enumerate("XYZ"):
            cols[f"est_s{c}"] = sig[:, j]
    for name, values in dict(point_extra or {}).items():
        cols[str(name)] = np.asarray(values).reshape(len(project.points))
    return cols


def _residual_table(project: Project, residuals, codes: dict | None = None) -> dict:
    """residuals.csv's columns; ``codes``, if given, receives column ->
    ``(row indices, ids)`` of the station and point columns given as
    indices into the project's ids."""
    if residuals is None:
        return {"station": [], "point": [], "x": [], "y": [], "vx": [], "vy": []}
    cols = {str(k): np.asarray(v) for k, v in dict(residuals).items()} \
        if isinstance(residuals, Mapping) else \
        {str(k): residuals[k].to_numpy() for k in residuals.columns}
    for key, ids in (("station", project.stations.names), ("point", project.points.ids)):
        if key in cols and np.issubdtype(cols[key].dtype, np.integer):
            if codes is not None:
                codes[key] = (cols[key], ids)
            cols[key] = np.array(ids, dtype=object)[cols[key]]
    return cols


@dataclass
class WrittenTable:
    """A CSV table as :func:`write_results` wrote it: the columns it was
    formatted from (name -> values; floats written by repr, so that they
    read back exactly), the size of the file in bytes, its ``(inode,
    modification time in ns)`` just after writing, and for id columns
    written from indices into the project's ids ``column -> (indices,
    ids)``. A command hands these to
    its report (:func:`photogram.report.write_report`, ``tables=``), which
    then need not parse the file again (if it is still that file)."""

    columns: dict
    nbytes: int
    signature: tuple | None = None
    codes: dict = field(default_factory=dict)   # column -> (indices, ids), see _residual_table


def write_results(folder: str | Path, project: Project, summary: Mapping, *,
                  camera_sigma: Mapping | None = None, station_sigma=None, point_sigma=None,
                  residuals=None, log_text: str = "", point_extra: Mapping | None = None,
                  station_covariance=None, tables: dict | None = None) -> Path:
    """Write a results folder.

    Parameters
    ----------
    folder : str or Path
        Created if needed; existing result files are replaced.
    project : Project
        The project holding the *estimated* values.
    summary : mapping
        At least ``status``, ``iterations``, ``sigma0``, ``redundancy``.
    camera_sigma : mapping, optional
        Camera name -> {parameter: sigma} or sigmas in model order.
    station_sigma : array (n_stations, 6) or mapping, optional
        Sigmas of X0, Y0, Z0, omega, phi, kappa (world-to-camera angles in
        radians), or ``{"position": (n, 3), "angles": (n, 3)}``. NaN where
        not estimated. With ``rotation_direction = "camera_to_world"`` the
        angle sigmas written are propagated to the file's angles
        (:func:`file_angle_sigmas`).
    point_sigma : array (n_points, 3), optional
        Sigmas of X, Y, Z.
    residuals : pandas.DataFrame or mapping of columns, optional
        One row per observation; integer ``station``/``point`` columns are
        written as ids.
    log_text : str
        Content of log.txt.
    point_extra : mapping, optional
        Further points.csv columns, name -> (n_points,) values (the
        engine's ``est_angle``, the largest intersection angle in degrees,
        and ``est_weak_angle`` 0/1; ``est_`` columns are ignored by the readers).
    station_covariance : array (n_stations, 6, 6), optional
        Covariance of X0, Y0, Z0, omega, phi, kappa per station (angles
        world-to-camera, radians), for the propagation to camera-to-world
        angles with their correlations (default: from the sigmas alone).
    tables : dict, optional
        If given, receives file name -> :class:`WrittenTable` of
        stations.csv, points.csv and residuals.csv (what the command's
        report is handed instead of parsing those files again).

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    InputError
        The folder would overwrite an input file of the project, or cannot
        be created.
    """
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the results folder: {exc.strerror}", file=folder,
                         hint="check the path and permissions ([output] folder)") from None
    check_targets([folder / f for f in RESULT_FILES], project, overwrite=True)
    text = json.dumps(_summary(project, summary), indent=2, allow_nan=False)
    codes = {}
    columns = {"stations.csv": _station_table(project, station_sigma, station_covariance),
               "points.csv": _point_table(project, point_sigma, point_extra),
               "residuals.csv": _residual_table(project, residuals, codes)}
    files = {"summary.json": text + "\n",
             "cameras.toml": _cameras_toml(project, camera_sigma),
             **{name: format_table(cols) for name, cols in columns.items()},
             "log.txt": log_text}
    if summary.get("interior"):        # cameras that share parameters
        from photogram.project.results_interior import INTERIOR_FILE, interior_table
        check_targets([folder / INTERIOR_FILE], project, overwrite=True)
        files[INTERIOR_FILE] = interior_table(summary["interior"])
    if summary.get("rigs"):            # an adjustment with rigs
        from photogram.project.results_rigs import RIGS_FILE, rigs_table
        check_targets([folder / RIGS_FILE], project, overwrite=True)
        files[RIGS_FILE] = rigs_table(project, summary["rigs"], file_angle_sigmas)
    for name, content in files.items():
        atomic_write_text(folder / name, content)
    if tables is not None:
        for name, cols in columns.items():
            text, st = files[name], (folder / name).stat()
            tables[name] = WrittenTable(cols, len(text) if text.isascii()
                                        else len(text.encode("utf-8")),
                                        (st.st_ino, st.st_mtime_ns),
                                        codes if name == "residuals.csv" else {})
    return folder


def _read_csv(path: Path, ids: tuple[str, ...]):
    from photogram.project.results_read import read_results_table

    if not path.is_file():
        raise InputError("results table not found", file=path,
                         hint="the results folder is incomplete: run the command again")
    return read_results_table(path, ids)


def read_results(folder: str | Path) -> Results:
    """Read a results folder written by :func:`write_results`.

    Raises
    ------
    InputError
        The folder or a file is missing or malformed.
    """
    folder = Path(folder)
    path = folder / "summary.json"
    if not path.is_file():
        raise InputError("no results here (summary.json not found)", file=folder,
                         hint="run calibrate/orient/intersect first, or give the results folder")
    summary = read_json(path, "summary.json")     # size, nesting, an object
    unit, cameras = load_cameras_file(folder / "cameras.toml")
    log = folder / "log.txt"
    return Results(folder=folder, summary=summary, image_unit=unit, cameras=cameras,
                   stations=_read_csv(folder / "stations.csv", ("station", "camera")),
                   points=_read_csv(folder / "points.csv", ("id", "kind")),
                   residuals=_read_csv(folder / "residuals.csv", ("station", "point", "line")),
                   log=log.read_text(encoding="utf-8") if log.is_file() else "")
