"""Reading the CSV tables a .prj points at: stations, points, image points
and image lines (docs/project-files.md).

Ids are checked for duplicates and resolved to indices, angles converted to
radians, image coordinates to the project's image unit; a measured point
with an ``exposure`` becomes the dynamic point ``id@exposure``. Every user
error becomes one :class:`~photogram.errors.InputError` with file, line and
hint.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.project.camera_schema import invert_opk
from photogram.project.model import (IMAGE_UNITS, POINT_KINDS, ImageLines, ImagePoints, Points,
                                     Project, Stations)
from photogram.project.reader_targets import TARGET_COLUMNS
from photogram.project.tables import Table, read_table
from photogram.project.text_input import suggest
from photogram.project.toml_source import Section

__all__ = ["STATION_COLUMNS", "POINT_COLUMNS", "TABLE_FORMATS", "dynamic_id"]

POSITION = ("X0", "Y0", "Z0")
ANGLES = ("omega", "phi", "kappa")
STATION_COLUMNS = ("station", "camera") + POSITION + ANGLES + \
    tuple("s" + c for c in POSITION + ANGLES)
POINT_COLUMNS = ("id", "kind", "X", "Y", "Z", "sX", "sY", "sZ")
#: Formats of the tables a .prj points at: our CSV tables, or DBAT's text
#: tables (read by :mod:`photogram.io.dbat`); see "Reading DBAT projects" in
#: docs/project-files.md.
TABLE_FORMATS = ("csv", "dbat")
STATIONS_KEYS = ("file", "from_observations", "camera")
POINTS_KEYS = ("file", "format", "columns", "check")


def _table_path(sec: Section, key: str, what: str, project: Project) -> Path:
    ref = sec.string(key)
    path = project.folder / ref
    if not path.is_file():
        state = "is a folder" if path.is_dir() else "not found"
        raise sec.error(key, f"{what} '{ref}' {state} ({path})",
                        hint="paths are relative to the .prj folder; check the name")
    return path


def _source_table(sec: Section, key: str, what: str, source: str, project: Project,
                  **columns) -> Table:
    """The table that ``key`` of ``sec`` names, recorded as
    ``project.sources[source]``; ``columns``: ``required``/``optional`` of
    :func:`~photogram.project.tables.read_table`."""
    path = _table_path(sec, key, what, project)
    project.sources[source] = path
    return read_table(path, what=what, **columns)


def _xy_columns(table: Table) -> np.ndarray:
    """The x and y columns as an (n, 2) array (both required)."""
    return np.stack([table.floats("x", required=True), table.floats("y", required=True)],
                    axis=1)


def _sigma_column(table: Table) -> np.ndarray:
    """The optional sigma column (NaN: sigma_image); a given sigma must be > 0."""
    sigma = table.floats("sigma")
    bad = np.flatnonzero(sigma <= 0)
    if len(bad):
        raise table.error(int(bad[0]), "sigma must be > 0",
                          hint="leave it empty to use sigma_image of [adjustment]")
    return sigma


def _ids(table: Table, column: str, what: str) -> list[str]:
    ids = table.text(column)
    seen: dict[str, int] = {}
    for i, value in enumerate(ids):
        if value in seen:
            raise table.error(i, f"duplicate {what} id '{value}' (first on line "
                                 f"{table.records[seen[value]]})",
                              hint=f"every {what} needs its own id")
        seen[value] = i
    return ids


def _lookup(table: Table, column: str, index: dict[str, int], what: str,
            where: str) -> np.ndarray:
    cells = table.text(column)
    out = np.empty(len(cells), dtype=int)
    for i, cell in enumerate(cells):
        j = index.get(cell)
        if j is None:
            raise table.error(i, f"unknown {what} '{cell}' (not in {where})",
                              hint=suggest(cell, list(index), noun=f"{what}s"))
        out[i] = j
    return out


def _block(table: Table, columns, unit: str | None = None) -> np.ndarray:
    """Columns as an (n, k) array; a row must give all or none of them."""
    get = (lambda c: table.angles(c, unit)) if unit else table.floats
    block = np.stack([get(c) for c in columns], axis=1)
    given = np.isfinite(block)
    partial = np.flatnonzero(np.any(given, axis=1) & ~np.all(given, axis=1))
    if len(partial):
        raise table.error(int(partial[0]), f"only some of {', '.join(columns)} are given",
                          hint="give all of them or leave all empty")
    return block


def _sigmas(table: Table, columns, values: np.ndarray, unit: str | None = None) -> np.ndarray:
    get = (lambda c: table.angles(c, unit)) if unit else table.floats
    block = np.stack([get(c) for c in columns], axis=1)
    negative = np.flatnonzero(np.any(block < 0, axis=1))
    if len(negative):
        raise table.error(int(negative[0]), "a sigma is negative",
                          hint="sigmas are >= 0 (0: fixed); leave empty for none")
    orphan = np.flatnonzero(np.any(np.isfinite(block) & ~np.isfinite(values), axis=1))
    if len(orphan):
        raise table.error(int(orphan[0]), f"a sigma ({', '.join(columns)}) is given "
                                          f"without its value",
                          hint="a prior needs a value: fill in the value or clear the sigma")
    return block


def _read_stations(sec: Section, project: Project) -> Stations:
    sec.check_keys(STATIONS_KEYS)
    if "camera" in sec:
        raise sec.error("camera", "camera in [stations] is only used with "
                                  "from_observations = true",
                        hint="the stations table names the camera of each station")
    table = _source_table(sec, "file", "stations table", "stations", project,
                          required=STATION_COLUMNS[:2], optional=STATION_COLUMNS[2:] + ("frame",))
    names = _ids(table, "station", "station")
    cameras = table.text("camera")
    for i, cam in enumerate(cameras):
        if cam not in project.cameras:
            raise table.error(i, f"unknown camera '{cam}' for station {names[i]}",
                              hint=suggest(cam, project.cameras, noun="cameras in the .prj"))
    unit = project.units.angle
    angles = _block(table, ANGLES, unit)
    if project.rotation_direction == "camera_to_world":
        angles = invert_opk(angles)
    position = _block(table, POSITION)
    return Stations(names=names, camera=cameras, position=position, angles=angles,
                    position_sigma=_sigmas(table, ["s" + c for c in POSITION], position),
                    angle_sigma=_sigmas(table, ["s" + c for c in ANGLES], angles, unit),
                    record=table.records,
                    frame=table.text("frame", required=False) if table.has("frame") else [])


def _read_points(sec: Section, project: Project) -> Points:
    sec.check_keys(POINTS_KEYS)
    sec.string("format", "csv", choices=TABLE_FORMATS)
    for key in ("columns", "check"):
        if key in sec:
            raise sec.error(key, f"{key} in [points] is only used with format = \"dbat\"",
                            hint="a CSV points table names its columns in its header and "
                                 "marks check points in its kind column")
    table = _source_table(sec, "file", "points table", "points", project,
                          required=POINT_COLUMNS[:2],
                          optional=POINT_COLUMNS[2:] + TARGET_COLUMNS)
    ids = _ids(table, "id", "point")
    kinds = [k.lower() for k in table.text("kind")]
    for i, kind in enumerate(kinds):
        if kind not in POINT_KINDS:
            raise table.error(i, f"unknown point kind '{table.cells('kind')[i]}'",
                              hint=suggest(kind, POINT_KINDS, noun="use one of"))
    xyz = _block(table, ("X", "Y", "Z"))
    for i, kind in enumerate(kinds):
        if kind != "tie" and not np.all(np.isfinite(xyz[i])):
            raise table.error(i, f"{kind} point {ids[i]} has no coordinates",
                              hint=f"give X, Y and Z of every {kind} point, or make it a tie "
                                   f"point")
    return Points(ids=ids, kind=np.array(kinds, dtype=object), xyz=xyz,
                  sigma=_sigmas(table, ("sX", "sY", "sZ"), xyz), record=table.records,
                  diameter=table.floats("diameter"), normal=_block(table, TARGET_COLUMNS[1:]))


def _read_observations(sec: Section, project: Project) -> None:
    sec.check_keys(("points", "lines", "unit"), required=("points",))
    unit = sec.string("unit", project.units.image, choices=IMAGE_UNITS)
    table = _source_table(sec, "points", "image points table", "image_points", project,
                          required=("station", "point", "x", "y"),
                          optional=("sigma", "exposure", "group"))
    station = _lookup(table, "station", project.stations.index(), "station", "the stations table")
    if table.has("exposure"):
        _add_dynamic_points(table, project)
    point = _lookup(table, "point", project.points.index(), "point", "the points table")
    xy, sigma = _image_xy(table, station, unit, project, sec)
    group = (np.array(table.text("group", required=False), dtype=object) if table.has("group")
             else np.full(len(station), "", dtype=object))
    project.image_points = ImagePoints(station=station, point=point, xy=xy, sigma=sigma,
                                       record=table.records, group=group)
    _read_lines(sec, unit, project)


def dynamic_id(point: str, exposure: str) -> str:
    """Id of a point at one exposure (a moving point: a helmet, a joint)."""
    return f"{point}@{exposure}" if exposure else point


def _add_dynamic_points(table: Table, project: Project) -> None:
    """With an ``exposure`` column, a point measured at an exposure is the
    point ``id@exposure``; such points are tie points with unknown
    coordinates unless the points table lists them."""
    exposure = table.text("exposure", required=False)
    ids = [dynamic_id(p, e) for p, e in zip(table.text("point"), exposure)]
    table.replace_text("point", ids)
    pts = project.points
    known = pts.index()
    new = list(dict.fromkeys(i for i, e in zip(ids, exposure) if e and i not in known))
    if not new:
        return
    n = len(new)
    pts.ids = list(pts.ids) + new
    pts.kind = np.concatenate([np.asarray(pts.kind, dtype=object), np.full(n, "tie", dtype=object)])
    pts.xyz = np.vstack([pts.xyz.reshape(-1, 3), np.full((n, 3), np.nan)])
    pts.sigma = np.vstack([pts.sigma.reshape(-1, 3), np.full((n, 3), np.nan)])
    pts.record = np.concatenate([np.asarray(pts.record, dtype=int), np.zeros(n, dtype=int)])


def _read_lines(sec: Section, unit: str, project: Project) -> None:
    if "lines" in sec:
        table = _source_table(sec, "lines", "image lines table", "image_lines", project,
                              required=("station", "line", "x", "y"),
                              optional=("sigma", "exposure"))
        station = _lookup(table, "station", project.stations.index(), "station",
                          "the stations table")
        xy, sigma = _image_xy(table, station, unit, project, sec)
        lines = table.text("line")
        if table.has("exposure"):
            lines = [dynamic_id(n, e) for n, e in zip(lines, table.text("exposure", required=False))]
        project.image_lines = ImageLines(station=station, line=np.array(lines, dtype=object),
                                         xy=xy, sigma=sigma, record=table.records)


def _image_xy(table: Table, station: np.ndarray, unit: str, project: Project,
              sec: Section) -> tuple[np.ndarray, np.ndarray]:
    """Image coordinates and sigmas, converted from ``unit`` to the image unit."""
    xy = _xy_columns(table)
    sigma = _sigma_column(table)
    if unit == project.units.image:
        return xy, sigma
    scale = np.ones((len(project.stations), 2))
    for i, cam in enumerate(project.stations.camera):
        size = project.cameras[cam].pixel_size
        if size is None:
            raise sec.error("unit", f"camera {cam} has no pixel_size to convert image "
                                    f"points from {unit} to {project.units.image}",
                            hint=f"add pixel_size = [sx, sy] in mm to [cameras.{cam}]")
        scale[i] = size
    s = scale[station] if unit == "px" else 1.0 / scale[station]
    return xy * s, sigma * np.sqrt(s[:, 0] * s[:, 1])
