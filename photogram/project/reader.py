"""Read a .prj project (TOML) and the CSV tables it points at.

See docs/project-files.md for the format. Every user error becomes one
:class:`~photogram.errors.InputError` with file, line and a hint.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.camera_schema import invert_opk, read_camera
from photogram.project.model import (
    ANGLE_UNITS, DAMPINGS, DATUMS, IMAGE_UNITS, LENGTH_UNITS, POINT_KINDS,
    ROBUST_FUNCTIONS, ROTATION_DIRECTIONS, AdjustmentSettings, DistanceConstraint,
    ImageLines, ImagePoints, OutputSettings, Points, Project, Stations, Units,
    VerticalConstraint,
)
from photogram.project.tables import Table, read_table
from photogram.project.validate import DOCS, Section, TomlSource, suggest, validate_project

__all__ = ["read_project", "SECTIONS", "STATION_COLUMNS", "POINT_COLUMNS"]

SECTIONS = ("project", "cameras", "stations", "points", "observations",
            "constraints", "adjustment", "output")
REQUIRED_SECTIONS = ("project", "cameras", "stations", "points", "observations")
PROJECT_KEYS = ("name", "length_unit", "angle_unit", "image_unit", "rotation",
                "rotation_direction")
ADJUSTMENT_KEYS = ("datum", "max_iterations", "tolerance", "sigma_image", "sigma_control",
                   "damping", "robust", "variance_components", "snooping_alpha",
                   "inner_constraints")
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
OBSERVATION_ENTRY_KEYS = ("file", "format", "columns", "sxy")
DBAT_CAMERA_KEYS = ("from_dbat", "camera", "free")
#: DBAT control-point formats that photogram.io.dbat.read_control_points reads.
DBAT_CONTROL_COLUMNS = ("id,label,x,y,z", "id,label,x,y,z,sxyz", "id,label,x,y,z,sx,sy,sz")
DBAT_IMAGE_COLUMNS = "im,id,x,y,sxy"


def _resolve(path: str | Path) -> Path:
    path = Path(path)
    if path.is_dir():
        found = sorted(path.glob("*.prj"))
        if len(found) == 1:
            return found[0]
        raise InputError("is a folder" + (f" with {len(found)} .prj files" if found else
                                          " without a .prj file"), file=path,
                         hint="give the path of the .prj file")
    if not path.exists():
        raise InputError("project file not found", file=path,
                         hint="check the path; it is relative to the current folder")
    return path


def read_project(path: str | Path) -> Project:
    """Read and validate a project.

    Parameters
    ----------
    path : str or Path
        The .prj file, or a folder holding exactly one.

    Returns
    -------
    Project
        Angles in radians (world-to-camera), image coordinates in the
        project's image unit, ids as strings, observations as indices;
        ``project.warnings`` lists oddities that are not errors.

    Raises
    ------
    InputError
        For any problem in the files, with file, line and hint.
    """
    prj = _resolve(path)
    src = TomlSource.load(prj, what="project file")
    root = src.root()
    root.check_keys(SECTIONS, noun="section")
    for name in REQUIRED_SECTIONS:
        root.table(name)
    project = Project(path=prj, sources={"project": prj})
    _read_project_section(root.table("project"), project)
    project.adjustment = _read_adjustment(root.table("adjustment", required=False))
    project.output = _read_output(root.table("output", required=False))
    _read_cameras(root.table("cameras"), project)
    _check_sigma_image(root, project)
    tables = [root.table(n) for n in ("stations", "points", "observations")]
    if _uses_dbat_features(*tables):
        _read_dbat_style(*tables, project)
    else:
        project.stations = _read_stations(tables[0], project)
        project.points = _read_points(tables[1], project)
        _read_observations(tables[2], project)
    _read_constraints(root.table("constraints", required=False), project)
    project.warnings = project.warnings + validate_project(project, src)
    return project


# --------------------------------------------------------------------------
# settings
# --------------------------------------------------------------------------

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


def _read_adjustment(sec: Section | None) -> AdjustmentSettings:
    adj = AdjustmentSettings()
    if sec is None:
        return adj
    sec.check_keys(ADJUSTMENT_KEYS)
    robust = sec.string("robust", "none", choices=("none",) + ROBUST_FUNCTIONS)
    return AdjustmentSettings(
        datum=sec.string("datum", adj.datum, choices=DATUMS),
        max_iterations=sec.integer("max_iterations", adj.max_iterations, minimum=1),
        tolerance=sec.number("tolerance", adj.tolerance, positive=True),
        sigma_image=_sigma_image(sec, adj.sigma_image),
        sigma_control=sec.number("sigma_control", adj.sigma_control, nonnegative=True),
        damping=sec.string("damping", adj.damping, choices=DAMPINGS),
        robust=None if robust == "none" else robust,
        variance_components=sec.boolean("variance_components", adj.variance_components),
        snooping_alpha=sec.number("snooping_alpha", adj.snooping_alpha, positive=True,
                                  below=1.0),
        inner_constraints=sec.ids("inner_constraints", adj.inner_constraints),
    )


def _sigma_image(sec: Section, default):
    """``sigma_image = 0.5`` for all cameras, or per camera as an inline
    table ``sigma_image = { K1 = 0.3, K2 = 0.5 }`` (checked against the
    cameras once they are read)."""
    if isinstance(sec.data.get("sigma_image"), dict):
        sub = sec.table("sigma_image")
        return {k: sub.number(k, positive=True) for k in sub.data}
    return sec.number("sigma_image", default, positive=True)


def _check_sigma_image(root: Section, project: Project) -> None:
    sig = project.adjustment.sigma_image
    if isinstance(sig, dict):
        sub = root.table("adjustment").table("sigma_image")
        for name in sig:
            if name not in project.cameras:
                raise sub.error(name, f"sigma_image names unknown camera '{name}'",
                                hint=suggest(name, project.cameras, noun="cameras"))
        missing = [c for c in project.cameras if c not in sig]
        if missing:
            raise sub.error(None, f"sigma_image gives no sigma for camera(s) {', '.join(missing)}",
                            hint="give every camera a sigma, or one number for all")


def _read_output(sec: Section | None) -> OutputSettings:
    if sec is None:
        return OutputSettings()
    sec.check_keys(("folder",))
    return OutputSettings(folder=sec.string("folder", "results"))


def _read_cameras(sec: Section, project: Project) -> None:
    if not sec.data:
        raise sec.error(None, "[cameras] has no cameras",
                        hint='add a section [cameras.K1] with model = "brown", c = ...')
    for name in sec.data:
        cam_sec = sec.table(name)
        if "from_dbat" in cam_sec:
            camera = _camera_from_dbat(cam_sec, name, project)
        else:
            camera = read_camera(cam_sec, name, image_unit=project.units.image,
                                 folder=project.folder)
        project.cameras[name] = camera
        if camera.source:
            project.sources[f"cameras:{name}"] = project.folder / camera.source


# --------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------

def _table_path(sec: Section, key: str, what: str, project: Project) -> Path:
    ref = sec.string(key)
    path = project.folder / ref
    if not path.is_file():
        state = "is a folder" if path.is_dir() else "not found"
        raise sec.error(key, f"{what} '{ref}' {state} ({path})",
                        hint="paths are relative to the .prj folder; check the name")
    return path


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
    path = _table_path(sec, "file", "stations table", project)
    project.sources["stations"] = path
    table = read_table(path, required=STATION_COLUMNS[:2], optional=STATION_COLUMNS[2:],
                       what="stations table")
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
                    record=table.records)


def _read_points(sec: Section, project: Project) -> Points:
    sec.check_keys(POINTS_KEYS)
    sec.string("format", "csv", choices=TABLE_FORMATS)
    for key in ("columns", "check"):
        if key in sec:
            raise sec.error(key, f"{key} in [points] is only used with format = \"dbat\"",
                            hint="a CSV points table names its columns in its header and "
                                 "marks check points in its kind column")
    path = _table_path(sec, "file", "points table", project)
    project.sources["points"] = path
    table = read_table(path, required=POINT_COLUMNS[:2], optional=POINT_COLUMNS[2:],
                       what="points table")
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
                  sigma=_sigmas(table, ("sX", "sY", "sZ"), xyz), record=table.records)


def _read_observations(sec: Section, project: Project) -> None:
    sec.check_keys(("points", "lines", "unit"), required=("points",))
    unit = sec.string("unit", project.units.image, choices=IMAGE_UNITS)
    path = _table_path(sec, "points", "image points table", project)
    project.sources["image_points"] = path
    table = read_table(path, required=("station", "point", "x", "y"),
                       optional=("sigma", "exposure", "group"), what="image points table")
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
        path = _table_path(sec, "lines", "image lines table", project)
        project.sources["image_lines"] = path
        table = read_table(path, required=("station", "line", "x", "y"),
                           optional=("sigma", "exposure"), what="image lines table")
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
    xy = np.stack([table.floats("x", required=True), table.floats("y", required=True)], axis=1)
    sigma = table.floats("sigma")
    bad = np.flatnonzero(sigma <= 0)
    if len(bad):
        raise table.error(int(bad[0]), "sigma must be > 0",
                          hint="leave it empty to use sigma_image of [adjustment]")
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


# --------------------------------------------------------------------------
# constraints
# --------------------------------------------------------------------------

_CONSTRAINTS = {
    "distance": (("from", "to", "value", "sigma"), "distances table"),
    "vertical": (("top", "bottom", "sigma"), "verticals table"),
}


def _read_constraints(sec: Section | None, project: Project) -> None:
    if sec is None:
        return
    sec.check_keys(tuple(_CONSTRAINTS))
    for kind, (fields, what) in _CONSTRAINTS.items():
        for n, entry in enumerate(sec.table_array(kind)):
            if "file" in entry:
                entry.check_keys(("file",))
                path = _table_path(entry, "file", what, project)
                project.sources[f"{kind}:{n}"] = path
                rows = _constraint_rows(read_table(path, required=fields, what=what),
                                        fields, project)
            else:
                rows = [_constraint_entry(entry, fields, project)]
            for row in rows:
                if kind == "distance":
                    project.distances.append(DistanceConstraint(*row))
                else:
                    project.verticals.append(VerticalConstraint(*row))


def _check_pair(a: str, b: str, known: dict[str, int], project: Project, fail) -> None:
    for pid in (a, b):
        if pid not in known:
            fail(f"unknown point '{pid}' (not in the points table)",
                 suggest(pid, project.points.ids, noun="points"))
    if a == b:
        fail(f"a constraint needs two different points, not {a} twice", "fix from/to")


def _constraint_entry(entry: Section, fields, project: Project) -> tuple:
    entry.check_keys(fields + ("file",), required=fields)
    a, b = entry.ident(fields[0]), entry.ident(fields[1])

    def fail(what, hint):
        raise entry.error(fields[0], f"{what} in {entry.label}", hint=hint)

    _check_pair(a, b, project.points.index(), project, fail)
    numbers = tuple(entry.number(f, positive=True) for f in fields[2:])
    return (a, b) + numbers


def _constraint_rows(table: Table, fields, project: Project) -> list[tuple]:
    ids = [table.text(f) for f in fields[:2]]
    numbers = [table.floats(f, required=True) for f in fields[2:]]
    known = project.points.index()
    rows = []
    for i in range(len(table)):
        def fail(what, hint, i=i):
            raise table.error(i, what, hint=hint)

        _check_pair(ids[0][i], ids[1][i], known, project, fail)
        for f, col in zip(fields[2:], numbers):
            if col[i] <= 0:
                fail(f"{f} must be > 0, not {col[i]!r}", f"see {DOCS}")
        rows.append((ids[0][i], ids[1][i]) + tuple(float(c[i]) for c in numbers))
    return rows


# --------------------------------------------------------------------------
# DBAT projects: tables in DBAT's text formats, cameras from DBAT camera XML,
# stations and tie points implied by the observations. The files are parsed
# by photogram.io.dbat; this part only wires them into the .prj schema.
# --------------------------------------------------------------------------

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
    return sec.table_array("points")


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
        sigma = table.floats("sigma")
        bad = np.flatnonzero(sigma <= 0)
        if len(bad):
            raise table.error(int(bad[0]), "sigma must be > 0",
                              hint="leave it empty to use sigma_image of [adjustment]")
        xy = np.stack([table.floats("x", required=True), table.floats("y", required=True)],
                      axis=1)
        return _Measured(entry, path, table.text("station"), table.text("point"), xy, sigma,
                         table.records, unit)
    from photogram.io.dbat import read_image_points
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
    from photogram.io.dbat import read_control_points
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
    key = station.astype(np.int64) * (len(project.points) + 1) + point
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        seen: dict = {}
        for row, k in enumerate(key):
            if k in seen:
                raise InputError(f"point {project.points.ids[point[row]]} is measured twice in "
                                 f"station {project.stations.names[station[row]]} (first: "
                                 f"{files[seen[k]].name}:{lines[seen[k]]})",
                                 file=files[row], line=int(lines[row]),
                                 hint="keep one measurement per point and image")
            seen[k] = row
    pairs = np.unique(np.stack([point, station], axis=1), axis=0)
    rays = np.bincount(pairs[:, 0], minlength=len(project.points))
    for i in np.flatnonzero(rays == 1):
        kind = project.points.kind[i]
        if kind in ("tie", "check"):
            row = int(np.flatnonzero(point == i)[0])
            raise InputError(f"point {project.points.ids[i]} is seen in 1 image (station "
                             f"{project.stations.names[station[row]]}); a {kind} point needs "
                             f"at least 2 rays", file=files[row], line=int(lines[row]),
                             hint="measure it in another image or remove it")


def _camera_from_dbat(sec: Section, name: str, project: Project):
    """``[cameras.NAME] from_dbat = "camera.xml"``: a DBAT camera (camera
    file or script XML) as a brown camera, everything fixed except ``free``."""
    from photogram.io.dbat import _brown_camera, read_camera_xml
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
    camera = _brown_camera(cam, name, ref)
    free = sec.ids("free", [])
    for p in free:
        if p not in camera.parameters:
            raise sec.error("free", f"unknown parameter '{p}' in free of {sec.label}",
                            hint=suggest(p, camera.parameters, noun="parameters"))
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
    if cam.model not in (None, 3):
        project.warnings.append(f"camera {name}: DBAT lens distortion model {cam.model} is "
                                f"read as the brown model (DBAT's model 3)")
    project.warnings.extend(f"camera {name}: {note}" for note in cam.notes)
    return camera
