"""Read a .prj project (TOML) and the CSV tables it points at.

See docs/project-files.md for the format. Every user error becomes one
:class:`~photogram.errors.InputError` with file, line and a hint.

This module reads the TOML sections (project, adjustment, output, cameras,
constraints) and dispatches the tables: the CSV tables are read by
:mod:`photogram.project.reader_tables`, DBAT-style projects (DBAT text
tables, DBAT cameras, implied stations) by
:mod:`photogram.project.reader_dbat`; their names are re-exported here.
"""

from __future__ import annotations

from pathlib import Path

from photogram.errors import InputError
from photogram.project.camera_schema import invert_opk, read_camera  # noqa: F401
from photogram.project.model import (  # noqa: F401  (also re-exported)
    ANGLE_UNITS, DAMPINGS, DATUMS, DEPENDENT_COORDINATES, IMAGE_UNITS, LENGTH_UNITS, POINT_KINDS,
    ROBUST_FUNCTIONS, ROTATION_DIRECTIONS, AdjustmentSettings, DistanceConstraint,
    ImageLines, ImagePoints, IntersectSettings, OutputSettings, Points, Project, Stations, Units,
    VerticalConstraint,
)
from photogram.project.model import PERTURBATIONS, TRUTHS, MonteCarloSettings
from photogram.project.reader_targets import read_targets
from photogram.project.reader_dbat import _camera_from_dbat, _read_dbat_style, _uses_dbat_features
from photogram.project.reader_sharing import check_groups
from photogram.project.reader_sections import PROJECT_KEYS, _read_output, _read_project_section  # noqa: F401
from photogram.project.reader_sections import read_report_section
from photogram.project.reader_tables import (_read_observations, _read_points, _read_stations,
                                             _source_table)
from photogram.project.reader_rigs import check_frames, read_rigs
from photogram.project.reader_track import read_track_section
from photogram.project.tables import Table, read_table  # noqa: F401
from photogram.project.validate import DOCS, Section, TomlSource, suggest, validate_project

# The table readers moved to reader_tables / reader_dbat; their constants and
# dynamic_id stay importable from here.
from photogram.project.reader_dbat import (  # noqa: F401,E402  (re-exports)
    DBAT_CAMERA_KEYS, DBAT_CONTROL_COLUMNS, DBAT_IMAGE_COLUMNS, OBSERVATION_ENTRY_KEYS,
)
from photogram.project.reader_tables import (  # noqa: F401,E402  (re-exports)
    ANGLES, POINT_COLUMNS, POINTS_KEYS, POSITION, STATION_COLUMNS, STATIONS_KEYS, TABLE_FORMATS,
    dynamic_id,
)

__all__ = ["read_project", "SECTIONS", "STATION_COLUMNS", "POINT_COLUMNS"]

SECTIONS = ("project", "cameras", "stations", "points", "observations",
            "constraints", "adjustment", "output", "intersect", "montecarlo", "mocap", "targets",
            "track", "board", "rigs", "report")
REQUIRED_SECTIONS = ("project", "cameras", "stations", "observations")
INTERSECT_KEYS = ("fps", "points", "skis", "ski_length", "binding_fraction", "orientation",
                  "swap_skis", "landing_profile")
MONTECARLO_KEYS = ("orient", "calibrate", "intersect", "perturb", "interior_covariance", "truth",
                   "points", "align", "runs", "seed", "chunk", "workers", "scheduler")
#: limits of [montecarlo] (and --runs, --workers): refused before anything is
#: allocated or started (docs/reliability.md)
MAX_RUNS = 100_000
MAX_WORKERS = 256
ADJUSTMENT_KEYS = ("datum", "max_iterations", "tolerance", "sigma_image", "sigma_control",
                   "damping", "robust", "variance_components", "snooping_alpha",
                   "inner_constraints", "dependent_station", "dependent_coordinate")


def _resolve(path: str | Path) -> Path:
    path = Path(path)
    try:
        return _find_prj(path)
    except PermissionError as exc:      # e.g. a folder without execute (search) permission
        where = Path(exc.filename) if exc.filename else path
        folder = where.parent
        raise InputError("permission denied: the project cannot be read", file=where,
                         hint=f"photogram needs read and execute (search) permission on the "
                              f"folder {folder}: e.g. chmod u+rx {folder}") from None


def _find_prj(path: Path) -> Path:
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
    if "board" in root.data:        # a rig calibrated from a board (docs/board-calibration.md)
        from photogram.project.reader_board import read_board_project
        return read_board_project(prj, src, root)
    if "mocap" in root.data:        # a motion-capture project (docs/mocap.md)
        from photogram.project.reader_mocap import read_mocap_project
        return read_mocap_project(prj, src, root)
    # a Monte-Carlo chain file: [project], [montecarlo], [output] and no tables
    chain_only = "montecarlo" in root.data and "cameras" not in root.data
    required = ("project",) if chain_only else REQUIRED_SECTIONS
    if "track" in root.data:      # a tracking project writes its observations
        required = tuple(n for n in required if n != "observations")
    for name in required:
        root.table(name)
    project = Project(path=prj, sources={"project": prj})
    _read_project_section(root.table("project"), project)
    project.montecarlo = _read_montecarlo(root.table("montecarlo", required=False), prj)
    if chain_only:
        for name in ("stations", "points", "observations", "constraints", "intersect"):
            if name in root.data:
                raise root.error(name, f"[{name}] in a Monte-Carlo chain file without [cameras]",
                                 hint="the tables belong in the projects that [montecarlo] names")
        project.adjustment = _read_adjustment(root.table("adjustment", required=False))
        project.output = _read_output(root.table("output", required=False))
        project.report = read_report_section(root.table("report", required=False))
        return project
    project.adjustment = _read_adjustment(root.table("adjustment", required=False))
    project.output = _read_output(root.table("output", required=False))
    project.intersect = _read_intersect(root.table("intersect", required=False), prj)
    project.report = read_report_section(root.table("report", required=False))
    _read_cameras(root.table("cameras"), project)
    _check_sigma_image(root, project)
    if "track" in root.data:     # a tracking project: it writes the observations
        return _read_track_project(root, project)
    tables = [root.table(n, required=n != "points") for n in ("stations", "points", "observations")]
    if tables[1] is None:      # no fixed points: only moving ones (exposures)
        tables[1] = Section(src, ("points",), {}, "[points]")
        no_points = True
    else:
        no_points = False
    if _uses_dbat_features(*tables):
        _read_dbat_style(*tables, project)
    else:
        project.stations = _read_stations(tables[0], project)
        project.points = Points() if no_points else _read_points(tables[1], project)
        _read_observations(tables[2], project)
    _read_constraints(root.table("constraints", required=False), project)
    read_rigs(root.table("rigs", required=False), project)
    check_frames(project)
    read_targets(root.table("targets", required=False), project)
    _check_dependent(root, project)
    project.warnings = project.warnings + validate_project(project, src)
    return project


def _check_dependent(root: Section, project: Project) -> None:
    """``dependent_station`` must name a station (line of the key)."""
    name = project.adjustment.dependent_station
    if name is not None and name not in project.stations.names:
        raise root.table("adjustment").error(
            "dependent_station", f"dependent_station names unknown station {name!r}",
            hint=suggest(name, project.stations.names, noun="stations"))


def _read_track_project(root: Section, project: Project) -> Project:
    """``[track]`` with its cameras and stations (no tables of
    observations: ``photogram track`` writes them; docs/track.md)."""
    for name in ("points", "observations", "constraints", "montecarlo", "targets"):
        if name in root.data:
            raise root.error(name, f"[{name}] in a tracking project (one with [track])",
                             hint="the tracked observations go into the intersect project "
                                  "that reads photogram track's output")
    project.stations = _read_stations(root.table("stations"), project)
    project.track = read_track_section(root.table("track"), project.path,
                                       list(project.stations.names))
    return project


# --------------------------------------------------------------------------
# settings
# --------------------------------------------------------------------------

def _read_intersect(sec: Section | None, prj: Path) -> IntersectSettings:
    """``[intersect]`` (see :class:`IntersectSettings`)."""
    out = IntersectSettings()
    if sec is None:
        return out
    sec.check_keys(INTERSECT_KEYS)
    points = tuple(sec.ids("points", list(out.points)))
    skis = tuple(sec.ids("skis", list(out.skis)))
    if len(points) != 4:
        raise sec.error("points", f"points in [intersect] must name 4 points, not {len(points)}",
                        hint='points = ["P1", "P2", "P3", "P4"] (helmet, hip, right and left binding)')
    if len(skis) != 2:
        raise sec.error("skis", f"skis in [intersect] must name 2 lines, not {len(skis)}",
                        hint='skis = ["L1", "L2"] (right and left ski)')
    fraction = sec.number("binding_fraction", out.binding_fraction, positive=True, below=1.0)
    orientation = None
    if "orientation" in sec:
        value = sec.data["orientation"]
        folders = sec.ids("orientation") if isinstance(value, list) else [sec.string("orientation")]
        orientation = [str(Path(f) if Path(f).is_absolute() else prj.parent / f) for f in folders]
    profile = None
    if "landing_profile" in sec:
        value = Path(sec.string("landing_profile"))
        full = value if value.is_absolute() else prj.parent / value
        if not full.is_file():
            raise sec.error("landing_profile", f"landing_profile: {value} not found",
                            hint="a CSV with columns distance,height (the slope's surface "
                                 "along world X), relative to the folder of this file")
        profile = str(full)
    return IntersectSettings(fps=sec.number("fps", out.fps, positive=True), points=points,
                             skis=skis, ski_length=sec.number("ski_length", out.ski_length,
                                                              positive=True),
                             binding_fraction=fraction, orientation=orientation,
                             swap_skis=sec.boolean("swap_skis", out.swap_skis),
                             landing_profile=profile)


def _read_montecarlo(sec: Section | None, prj: Path) -> MonteCarloSettings | None:
    """``[montecarlo]`` (see :class:`MonteCarloSettings`); step projects
    must exist."""
    if sec is None:
        return None
    sec.check_keys(MONTECARLO_KEYS)
    out = MonteCarloSettings()

    def path(key, folder=False):
        if key not in sec:
            return None
        value = Path(sec.string(key))
        full = value if value.is_absolute() else prj.parent / value
        ok = full.is_dir() if folder else full.is_file() or full.is_dir()
        if not ok:
            what = "results folder" if folder else "project"
            raise sec.error(key, f"{key} in {sec.label}: {what} {value} not found",
                            hint="the path is relative to the folder of this file"
                                 + ("; run photogram calibrate first" if folder else ""))
        return str(full)

    steps = [k for k in ("orient", "calibrate") if k in sec]
    if len(steps) != 1:
        raise sec.error(steps[1] if len(steps) > 1 else None,
                        f"{sec.label} needs exactly one of orient and calibrate, not "
                        f"{' and '.join(steps) or 'none'}",
                        hint='e.g. orient = "../field/field.prj" (interior fixed) or '
                             'calibrate = "network.prj" (interior as that project says)')
    perturb = sec.ids("perturb", list(out.perturb))
    for p in perturb:
        if p not in PERTURBATIONS:
            raise sec.error("perturb", f"unknown perturbation '{p}' in {sec.label}",
                            hint=suggest(p, PERTURBATIONS, noun="use any of"))
    if not perturb:
        raise sec.error("perturb", f"perturb in {sec.label} is empty",
                        hint='e.g. perturb = ["image", "reference"]')
    if "scheduler" in sec:
        # a cluster receives the pickled project and sends back pickles that
        # photogram loads: only the person running the command may choose it
        raise sec.error("scheduler", f"scheduler in {sec.label} is not allowed in a project "
                                     f"file: a Dask cluster address is given only on the "
                                     f"command line",
                        hint="remove the line; to run on a cluster you trust, add "
                             "--scheduler tcp://HOST:PORT to the command")
    for key, top in (("runs", MAX_RUNS), ("workers", MAX_WORKERS)):
        value = sec.data.get(key)
        if isinstance(value, int) and not isinstance(value, bool) and value > top:
            raise sec.error(key, f"{key} in {sec.label} must be at most {top}, not {value}",
                            hint="1000 runs give sigmas to 2 %" if key == "runs" else
                            "one worker per CPU core")
    return MonteCarloSettings(
        orient=path("orient"), calibrate=path("calibrate"), intersect=path("intersect"),
        perturb=tuple(dict.fromkeys(perturb)),
        interior_covariance=path("interior_covariance", folder=True),
        truth=sec.string("truth", out.truth, choices=TRUTHS),
        points=tuple(sec.ids("points", list(out.points))),
        align=sec.string("align", out.align, choices=("none", "plan")),
        runs=sec.integer("runs", out.runs, minimum=1),
        seed=sec.integer("seed", out.seed, minimum=0),
        chunk=sec.integer("chunk", out.chunk, minimum=1),
        workers=sec.integer("workers", out.workers, minimum=1))


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
        dependent_station=_optional_name(sec, "dependent_station"),
        dependent_coordinate=sec.string("dependent_coordinate", adj.dependent_coordinate,
                                        choices=DEPENDENT_COORDINATES),
    )


def _optional_name(sec: Section, key: str) -> str | None:
    """A station name given as a string or an integer (``"1"`` or ``1``)."""
    value = sec.data.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise sec.error(key, f"{key} must be a station name", hint='e.g. dependent_station = "1"')
    return str(value)


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
    check_groups(sec, project.cameras)


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
                table = _source_table(entry, "file", what, f"{kind}:{n}", project,
                                      required=fields)
                rows = _constraint_rows(table, fields, project)
            else:
                rows = [_constraint_entry(entry, fields, project)]
            for row in rows:
                if kind == "distance":
                    project.distances.append(DistanceConstraint(*row))
                else:
                    project.verticals.append(VerticalConstraint(*row))


def _check_pair(a: str, b: str, known: dict[str, int], project: Project, fail) -> None:
    for k, pid in enumerate((a, b)):
        if pid not in known:
            fail(f"unknown point '{pid}' (not in the points table)",
                 suggest(pid, project.points.ids, noun="points"), k)
    if a == b:
        fail(f"a constraint needs two different points, not {a} twice", "fix from/to", 1)


def _constraint_entry(entry: Section, fields, project: Project) -> tuple:
    entry.check_keys(fields + ("file",), required=fields)
    a, b = entry.ident(fields[0]), entry.ident(fields[1])

    def fail(what, hint, k=0):
        # k: the field (0 from, 1 to) whose line the message names
        raise entry.error(fields[k], f"{what} in {entry.label}", hint=hint)

    _check_pair(a, b, project.points.index(), project, fail)
    numbers = tuple(entry.number(f, positive=True) for f in fields[2:])
    return (a, b) + numbers


def _constraint_rows(table: Table, fields, project: Project) -> list[tuple]:
    ids = [table.text(f) for f in fields[:2]]
    numbers = [table.floats(f, required=True) for f in fields[2:]]
    known = project.points.index()
    rows = []
    for i in range(len(table)):
        def fail(what, hint, k=0, i=i):
            raise table.error(i, what, hint=hint)

        _check_pair(ids[0][i], ids[1][i], known, project, fail)
        for f, col in zip(fields[2:], numbers):
            if col[i] <= 0:
                fail(f"{f} must be > 0, not {col[i]!r}", f"see {DOCS}")
        rows.append((ids[0][i], ids[1][i]) + tuple(float(c[i]) for c in numbers))
    return rows
