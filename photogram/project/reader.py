"""Read a .prj project (TOML) and the CSV tables it points at.

See docs/project-files.md for the format. Every user error becomes one
:class:`~photogram.errors.InputError` with file, line and a hint.
"""

from __future__ import annotations

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
    project.stations = _read_stations(root.table("stations"), project)
    project.points = _read_points(root.table("points"), project)
    _read_observations(root.table("observations"), project)
    _read_constraints(root.table("constraints", required=False), project)
    project.warnings = validate_project(project, src)
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
        sigma_image=sec.number("sigma_image", adj.sigma_image, positive=True),
        sigma_control=sec.number("sigma_control", adj.sigma_control, nonnegative=True),
        damping=sec.string("damping", adj.damping, choices=DAMPINGS),
        robust=None if robust == "none" else robust,
        variance_components=sec.boolean("variance_components", adj.variance_components),
        snooping_alpha=sec.number("snooping_alpha", adj.snooping_alpha, positive=True,
                                  below=1.0),
        inner_constraints=sec.ids("inner_constraints", adj.inner_constraints),
    )


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
        camera = read_camera(sec.table(name), name, image_unit=project.units.image,
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
    sec.check_keys(("file",))
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
    sec.check_keys(("file",))
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
    table = read_table(path, required=("station", "point", "x", "y"), optional=("sigma",),
                       what="image points table")
    station = _lookup(table, "station", project.stations.index(), "station", "the stations table")
    point = _lookup(table, "point", project.points.index(), "point", "the points table")
    xy, sigma = _image_xy(table, station, unit, project, sec)
    project.image_points = ImagePoints(station=station, point=point, xy=xy, sigma=sigma,
                                       record=table.records)
    if "lines" in sec:
        path = _table_path(sec, "lines", "image lines table", project)
        project.sources["image_lines"] = path
        table = read_table(path, required=("station", "line", "x", "y"), optional=("sigma",),
                           what="image lines table")
        station = _lookup(table, "station", project.stations.index(), "station",
                          "the stations table")
        xy, sigma = _image_xy(table, station, unit, project, sec)
        project.image_lines = ImageLines(station=station,
                                         line=np.array(table.text("line"), dtype=object),
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
