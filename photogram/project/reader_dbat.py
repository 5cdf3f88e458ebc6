"""The DBAT-style reading path of a .prj project (docs/project-files.md,
"Reading DBAT projects").

Tables in DBAT's text formats, cameras from DBAT camera XML, stations and
tie points implied by the observations, several image point tables. The
files are parsed by :mod:`photogram.io.dbat`; this module only wires them
into the .prj schema. :func:`_uses_dbat_features` tells
:func:`photogram.project.reader.read_project` which path a project takes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.camera_schema import free_parameters
from photogram.project.model import IMAGE_UNITS, ImagePoints, Points, Project, Stations
from photogram.project.reader_tables import (POINTS_KEYS, STATIONS_KEYS, TABLE_FORMATS,
                                             _read_lines, _read_points, _read_stations,
                                             _sigma_column, _table_path, _xy_columns)
from photogram.project.tables import read_table
from photogram.project.text_input import suggest
from photogram.project.toml_source import Section
from photogram.project.validate import check_single_rays, observation_rays, repeated_observation

__all__ = ["DBAT_CONTROL_COLUMNS", "DBAT_IMAGE_COLUMNS"]

OBSERVATION_ENTRY_KEYS = ("file", "format", "columns", "sxy")
DBAT_CAMERA_KEYS = ("from_dbat", "camera", "free", "lens_model", "per_station", "tie",
                    "shared")
#: DBAT control-point formats that photogram.io.dbat.read_control_points reads.
DBAT_CONTROL_COLUMNS = ("id,label,x,y,z", "id,label,x,y,z,sxyz", "id,label,x,y,z,sx,sy,sz")
DBAT_IMAGE_COLUMNS = "im,id,x,y,sxy"


@dataclass
class _Measured:
    """One image points table as read, before ids are resolved."""

    entry: Section              # its entry in [observations], for messages
    path: Path
    station: list               # station (image) ids as text
    point: list                 # point ids as text
    xy: np.ndarray              # (n, 2) in ``unit``
    sigma: np.ndarray           # (n,) NaN: sigma_image
    line: np.ndarray            # (n,) 1-based line numbers in ``path``
    unit: str


def _uses_dbat_features(stations: Section, points: Section, observations: Section) -> bool:
    """Whether the project uses DBAT tables or implied stations (the second
    reading path); plain .prj files keep the original one."""
    return ("from_observations" in stations or points.data.get("format") == "dbat"
            or isinstance(observations.data.get("points"), (dict, list)))


def _read_dbat_style(st_sec: Section, pt_sec: Section, obs_sec: Section,
                     project: Project) -> None:
    obs_sec.check_keys(("points", "lines", "unit"), required=("points",))
    unit = obs_sec.string("unit", project.units.image, choices=IMAGE_UNITS)
    measured = [_read_measured(entry, obs_sec, unit, project)
                for entry in _observation_entries(obs_sec)]
    for k, m in enumerate(measured):
        project.sources["image_points" if k == 0 else f"image_points:{k}"] = m.path
    project.stations = _implied_stations(st_sec, project, measured)
    project.points = _dbat_points(pt_sec, project, measured)
    project.image_points = _resolve_measured(measured, project)
    _read_lines(obs_sec, unit, project)


def _observation_entries(sec: Section) -> list[Section]:
    """``points = "file"``, ``points = { file = ... }`` or ``[[observations.points]]``."""
    value = sec.data["points"]
    if isinstance(value, str):
        return [Section(sec.source, sec.keypath + ("points",), {"file": value},
                        "[observations] points")]
    entries = sec.table_array("points")
    if not entries:
        raise sec.error("points", "points = [] names no image points table",
                        hint='give a file, e.g. points = "image_points.csv"')
    return entries


def _dbat_columns(text: str) -> str:
    return ",".join(c.strip().lower() for c in text.split(","))


def _read_measured(entry: Section, obs_sec: Section, unit: str, project: Project) -> _Measured:
    entry.check_keys(OBSERVATION_ENTRY_KEYS, required=("file",))
    fmt = entry.string("format", "csv", choices=TABLE_FORMATS)
    path = _table_path(entry, "file", "image points table", project)
    if fmt == "csv":
        for key in ("columns", "sxy"):
            if key in entry:
                raise entry.error(key, f"{key} in {entry.label} is only used with "
                                       f"format = \"dbat\"",
                                  hint="a CSV table names its columns in its header and "
                                       "gives sigmas in its sigma column")
        table = read_table(path, required=("station", "point", "x", "y"), optional=("sigma",),
                           what="image points table")
        sigma = _sigma_column(table)
        xy = _xy_columns(table)
        return _Measured(entry, path, table.text("station"), table.text("point"), xy, sigma,
                         table.records, unit)
    from photogram.project.dbat_tables import read_image_points
    if "unit" in obs_sec and unit != "px":
        raise obs_sec.error("unit", f"DBAT image tables are in pixels, not {unit}",
                            hint="remove unit from [observations]; the image points are "
                                 "converted to image_unit with the cameras' pixel_size")
    columns = _dbat_columns(entry.string("columns", DBAT_IMAGE_COLUMNS))
    missing = [c for c in ("im", "id", "x", "y") if c not in columns.split(",")]
    if missing:
        raise entry.error("columns", f"columns '{columns}' in {entry.label} has no "
                                     f"{', '.join(missing)}",
                          hint='DBAT image point columns, e.g. "im,id,x,y,sxy" or "id,im,x,y"')
    sxy = entry.number("sxy", None, positive=True)
    if sxy is not None and "sxy" in columns.split(","):
        raise entry.error("sxy", f"{entry.label} gives sxy both as a column and as a key",
                          hint="remove one of them")
    ip = read_image_points(path, columns, sxy)
    return _Measured(entry, path, ip.image, ip.point, ip.xy, ip.sxy, ip.line, "px")


def _implied_stations(sec: Section, project: Project, measured: list[_Measured]) -> Stations:
    sec.check_keys(STATIONS_KEYS)
    if not sec.boolean("from_observations", False):
        return _read_stations(sec, project)
    if "file" in sec:
        raise sec.error("file", "[stations] has both file and from_observations = true",
                        hint="give either a stations table or from_observations = true")
    camera = sec.ident("camera", None)
    if camera is None:
        if len(project.cameras) != 1:
            raise sec.error("from_observations", "from_observations needs the camera of the "
                                                 "stations",
                            hint=f"add camera = \"...\" to [stations]; "
                                 f"{suggest('', project.cameras, noun='cameras')}")
        camera = next(iter(project.cameras))
    elif camera not in project.cameras:
        raise sec.error("camera", f"unknown camera '{camera}' in [stations]",
                        hint=suggest(camera, project.cameras, noun="cameras in the .prj"))
    names = list(dict.fromkeys(s for m in measured for s in m.station))
    n = len(names)
    nan = np.full((n, 3), np.nan)
    return Stations(names=names, camera=[camera] * n, position=nan.copy(), angles=nan.copy(),
                    position_sigma=nan.copy(), angle_sigma=nan.copy(),
                    record=np.zeros(n, dtype=int))


def _dbat_points(sec: Section, project: Project, measured: list[_Measured]) -> Points:
    if sec.string("format", "csv", choices=TABLE_FORMATS) == "csv":
        return _read_points(sec, project)
    from photogram.project.dbat_tables import read_control_points
    sec.check_keys(POINTS_KEYS, required=("file",))
    path = _table_path(sec, "file", "control points table", project)
    project.sources["points"] = path
    columns = sec.string("columns", None)
    if columns is not None and _dbat_columns(columns) not in DBAT_CONTROL_COLUMNS:
        raise sec.error("columns", f"unsupported DBAT control point columns '{columns}'",
                        hint=f"use one of: {'; '.join(DBAT_CONTROL_COLUMNS)}")
    cp = read_control_points(path)
    if columns is not None:
        _check_control_columns(cp, len(_dbat_columns(columns).split(",")), columns)
    check = sec.ids("check", [])
    for pid in check:
        if pid not in cp.ids:
            raise sec.error("check", f"check point {pid} is not in {path.name}",
                            hint=suggest(pid, cp.ids, noun="points there"))
    known = set(cp.ids)
    tie = [p for p in dict.fromkeys(p for m in measured for p in m.point) if p not in known]
    ids = list(cp.ids) + tie
    kinds = ["check" if p in check else "control" for p in cp.ids] + ["tie"] * len(tie)
    nan = np.full((len(tie), 3), np.nan)
    return Points(ids=ids, kind=np.array(kinds, dtype=object), xyz=np.vstack([cp.xyz, nan]),
                  sigma=np.vstack([cp.sigma, nan]),
                  record=np.concatenate([cp.line, np.zeros(len(tie), int)]).astype(int))


def _check_control_columns(cp, n: int, columns: str) -> None:
    """What the file holds must agree with the columns the .prj names."""
    s = cp.sigma
    if n == 5:
        bad = np.flatnonzero(np.any(s != 0, axis=1))
        what = "has sigma columns"
    elif n == 6:
        bad = np.flatnonzero((s[:, 0] != s[:, 1]) | (s[:, 1] != s[:, 2]))
        what = "has three different sigmas"
    else:
        bad = np.zeros(0, int)
    if len(bad):
        raise InputError(f"this row {what} but columns = \"{columns}\" in the .prj",
                         file=cp.path, line=int(cp.line[bad[0]]),
                         hint="make columns match the file")


def _resolve_measured(measured: list[_Measured], project: Project) -> ImagePoints:
    """Ids -> indices, units -> image unit, and the checks of
    validate_project that name a file (here per row, for several files)."""
    st_index, pt_index = project.stations.index(), project.points.index()
    parts = []
    for m in measured:
        for ids, index, what, where in ((m.station, st_index, "station", "the stations table"),
                                        (m.point, pt_index, "point", "the points table")):
            found = [index.get(i, -1) for i in ids]
            if -1 in found:
                i = found.index(-1)
                raise InputError(f"unknown {what} '{ids[i]}' (not in {where})", file=m.path,
                                 line=int(m.line[i]), hint=suggest(ids[i], index,
                                                                   noun=f"{what}s"))
            parts.append(np.array(found, dtype=int))
    station = np.concatenate(parts[0::2])
    point = np.concatenate(parts[1::2])
    xy = np.vstack([m.xy for m in measured])
    sigma = np.concatenate([m.sigma for m in measured])
    scale = np.ones((len(station), 2))
    start = 0
    for m in measured:
        rows = slice(start, start + len(m.line))
        start += len(m.line)
        if m.unit == project.units.image:
            continue
        for k, cam in enumerate(project.stations.camera):
            if project.cameras[cam].pixel_size is None and np.any(station[rows] == k):
                raise m.entry.error("file", f"camera {cam} has no pixel_size to convert the "
                                            f"image points of {m.path.name} from {m.unit} to "
                                            f"{project.units.image}",
                                    hint=f"add pixel_size = [sx, sy] in mm to [cameras.{cam}]")
        size = np.array([project.cameras[c].pixel_size or (1.0, 1.0)
                         for c in project.stations.camera])[station[rows]]
        scale[rows] = size if m.unit == "px" else 1.0 / size
    xy, sigma = xy * scale, sigma * np.sqrt(scale[:, 0] * scale[:, 1])
    files = [m.path for m in measured for _ in m.line]
    lines = np.concatenate([m.line for m in measured]).astype(int)
    _check_measured(station, point, files, lines, project)
    return ImagePoints(station=station, point=point, xy=xy, sigma=sigma, record=lines)


def _check_measured(station, point, files, lines, project: Project) -> None:
    """The observation checks of :mod:`photogram.project.validate`, naming the
    file and line of the offending row."""
    found = repeated_observation(station, point, len(project.points))
    if found is not None:
        row, first = found
        raise InputError(f"point {project.points.ids[point[row]]} is measured twice in "
                         f"station {project.stations.names[station[row]]} (first: "
                         f"{files[first].name}:{lines[first]})",
                         file=files[row], line=int(lines[row]),
                         hint="keep one measurement per point and image")
    rays = observation_rays(point, station, len(project.points))
    check_single_rays(project, point, station, rays, lambda row: (files[row], int(lines[row])))


def _camera_from_dbat(sec: Section, name: str, project: Project):
    """``[cameras.NAME] from_dbat = "camera.xml"``: a DBAT camera (camera
    file or script XML) in the photogram model of its DBAT lens model (the
    XML's ``<model>`` or the key ``lens_model``; docs/camera-models.md,
    section 4.5), everything fixed except ``free``."""
    from photogram.project.dbat_tables import read_camera_xml
    sec.check_keys(DBAT_CAMERA_KEYS)
    ref = sec.string("from_dbat")
    path = project.folder / ref
    if not path.is_file():
        raise sec.error("from_dbat", f"DBAT camera file '{ref}' of {sec.label} not found "
                                     f"({path})",
                        hint="paths are relative to the .prj folder; check the name")
    cams = read_camera_xml(path)
    wanted = sec.ident("camera", None)
    if wanted is None:
        if len(cams) != 1:
            raise sec.error("from_dbat", f"{ref} holds {len(cams)} cameras",
                            hint="choose one with camera = \"<id or name>\": " +
                                 ", ".join(f"{c.id} ({c.name})" for c in cams))
        cam = cams[0]
    else:
        match = [c for c in cams if wanted in (c.id, c.name)]
        if not match:
            raise sec.error("camera", f"camera '{wanted}' is not in {ref}",
                            hint=suggest(wanted, [c.name for c in cams] + [c.id for c in cams],
                                         noun="cameras there"))
        cam = match[0]
    camera, lens = _dbat_lens_camera(sec, cam, name, ref, project)
    free = free_parameters(sec, camera)
    _check_no_affinity(sec, lens, free)
    for p, par in camera.parameters.items():
        par.free = p in free
    if project.units.image == "mm":
        px, py = camera.pixel_size
        if px != py:
            raise sec.error("from_dbat", f"the pixels of {cam.name} are not square "
                                         f"({px:g} x {py:g} mm)",
                            hint='use image_unit = "px" for this project')
        from photogram.geometry import camera_model, rescale_parameters
        values = rescale_parameters(camera_model(camera.model), camera.values(), px)
        for par, v in zip(camera.parameters.values(), values):
            par.value = float(v)
    project.warnings.extend(f"camera {name}: {note}" for note in cam.notes)
    return _dbat_sharing(sec, camera)


def _dbat_sharing(sec: Section, camera):
    """The sharing keys (``per_station``, ``tie``, ``shared``;
    docs/project-files.md, "Parameter sharing") of a ``from_dbat`` camera:
    e.g. DBAT's image-variant calibration, a principal point per image."""
    from photogram.project.camera_schema import parameter_dims
    from photogram.project.reader_sharing import apply_sharing, read_sharing
    if not any(k in sec.data for k in ("per_station", "tie", "shared")):
        return camera
    camera.per_station, camera.ties, camera.shared = read_sharing(
        sec, camera.model, tuple(camera.parameters), parameter_dims(camera.model))
    return apply_sharing(sec, camera, ())


def _dbat_lens_camera(sec: Section, cam, name: str, ref: str, project: Project):
    """The camera in the model of its DBAT lens model and that number
    (``lens_model`` of the section, else the XML's ``<model>``, else 3)."""
    from photogram.project.dbat_tables import DBAT_LENS_MODELS, dbat_lens_camera
    known = ", ".join(str(k) for k in sorted(DBAT_LENS_MODELS))
    lens = sec.integer("lens_model", None)
    if lens is not None and lens not in DBAT_LENS_MODELS:
        raise sec.error("lens_model", f"unknown DBAT lens model {lens} in {sec.label}",
                        hint=f"DBAT's lens models: {known}")
    if lens is None:
        lens = 3 if cam.model is None else cam.model
        if lens not in DBAT_LENS_MODELS:
            project.warnings.append(f"camera {name}: DBAT lens distortion model {lens} is "
                                    f"unknown ({known}); read as the brown model (DBAT's "
                                    f"model 3)")
            lens = 3
    return dbat_lens_camera(cam, name, ref, DBAT_LENS_MODELS[lens]), lens


def _check_no_affinity(sec: Section, lens: int, free: list) -> None:
    """DBAT's lens models 1 and 2 have no aspect and skew: B1, B2 stay 0."""
    from photogram.project.dbat_tables import DBAT_NO_AFFINITY
    bad = [p for p in ("B1", "B2") if p in free]
    if lens in DBAT_NO_AFFINITY and bad:
        raise sec.error("free", f"{' and '.join(bad)} in free of {sec.label}: DBAT lens model "
                                f"{lens} has no aspect or skew",
                        hint="remove them from free, or use lens_model = 3 (brown, affinity "
                             "first), 4 or 5")
