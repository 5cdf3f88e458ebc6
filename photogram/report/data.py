"""Everything a report shows, read from a results folder.

:func:`load` reads the files the commands write (docs/project-files.md,
"Results folder"): summary.json, cameras.toml, stations.csv, points.csv,
residuals.csv (as numpy :class:`~photogram.report.table.Table`, without
pandas), log.txt;
covariance.npz; the intersect outputs exposures.csv, points3d.csv,
lines3d.csv and stick.png; and, for the reference coordinates of control
points and the list of input files, the project file named in summary.json
when it can still be read. Quantities several pages need (rotation
matrices, image formats, rays and intersection angles per point) are
computed once, on first use.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from photogram.errors import InputError, PhotogramError
from photogram.geometry import opk_to_matrix, to_radians
from photogram.project.limits import check_image, read_json
from photogram.project.camera_schema import load_cameras_file
from photogram.project.results import Results
from photogram.project.results_read import read_covariance, read_results_table
from photogram.project.results_folder import final_folder
from photogram.report.handover import table_from_written
from photogram.report.table import (PANDAS_BYTES, Table, read_table, read_table_pandas,
                                    sorted_subgroups)

__all__ = ["ReportData", "load", "REQUIRED", "read_image"]

#: the files of an adjustment's results folder (calibrate, orient, intersect);
#: other commands (montecarlo, mocap) need only summary.json
REQUIRED = ("summary.json", "cameras.toml", "stations.csv", "points.csv", "residuals.csv")
ADJUSTMENT_COMMANDS = ("calibrate", "orient", "intersect")


@dataclass
class ReportData:
    """A results folder read back for the report (tables in file units, as
    :class:`~photogram.report.table.Table`; the intersect step's tables as
    pandas DataFrames)."""

    folder: Path
    results: Results
    covariance: dict | None = None
    exposures: object = None        # pandas DataFrames of the intersect step, or None
    points3d: object = None
    lines3d: object = None
    project: object = None          # the Project of summary.json's path, if readable
    project_note: str = ""
    extra: dict = field(default_factory=dict)

    # -------------------------------------------------------------- basics
    @property
    def summary(self) -> dict:
        return self.results.summary

    @property
    def command(self) -> str:
        return str(self.summary.get("command") or "adjustment")

    @property
    def info(self) -> dict:
        return _project_of(self.summary)

    @property
    def name(self) -> str:
        return str(self.info.get("name") or final_folder(self.folder).name)

    @property
    def length_unit(self) -> str:
        return str(self.info.get("length_unit") or "")

    @property
    def angle_unit(self) -> str:
        return str(self.info.get("angle_unit") or "rad")

    @property
    def image_unit(self) -> str:
        return str(self.results.image_unit or self.info.get("image_unit") or "px")

    def has(self, name: str) -> bool:
        return (self.folder / name).is_file()

    # --------------------------------------------------------- observations
    @cached_property
    def residuals(self) -> Table:
        """residuals.csv with a boolean ``used`` column (all True if absent)."""
        r = self.results.residuals
        if "used" in r:
            u = np.nan_to_num(r["used"].astype(float), nan=1.0).astype(int).astype(bool)
        else:
            u = np.ones(len(r), dtype=bool)
        return r.with_column("used", u)

    @property
    def has_residuals(self) -> bool:
        r = self.results.residuals
        return len(r) > 0 and all(c in r for c in ("vx", "vy", "x", "y"))

    @cached_property
    def hulls(self) -> dict:
        """Station -> convex hull (k, 2) of its used image points (the
        image coverage: residual-vector and geometry pages)."""
        from photogram.report.shapes import convex_hull

        r = self.residuals
        code, names = r.groups("station")
        used = r["used"]
        code = code[used]
        order = np.argsort(code, kind="stable")
        bounds = np.searchsorted(code[order], np.arange(len(names) + 1))
        xy = r.numbers(["x", "y"])[used][order]
        return {name: convex_hull(xy[bounds[i]:bounds[i + 1]])
                for i, name in enumerate(names)}

    # -------------------------------------------------------------- stations
    @property
    def stations(self) -> Table:
        """stations.csv, keyed by ``station``."""
        return self.results.stations

    @cached_property
    def rotation(self) -> dict:
        """Station -> world-to-camera matrix (from the file's angles and
        rotation direction)."""
        st = self.stations
        if not len(st):
            return {}
        angles = st.numbers(["omega", "phi", "kappa"])
        ok = np.all(np.isfinite(angles), axis=1)
        R = opk_to_matrix(to_radians(angles[ok], self.angle_unit)).reshape(-1, 3, 3)
        if self.info.get("rotation_direction") == "camera_to_world":
            R = np.swapaxes(R, 1, 2)
        out = {}
        for name, m in zip(st.ids[ok], R):          # the first row of a station wins
            out.setdefault(name, m)
        return out

    @cached_property
    def centres(self) -> dict:
        st = self.stations
        if not len(st):
            return {}
        xyz = st.numbers(["X0", "Y0", "Z0"])
        return {n: xyz[i] for n, i in st._lookup().items()}

    def station_camera(self, station: str) -> str | None:
        camera = self.stations.value(station, "camera")
        return None if camera is None else str(camera)

    def image_format(self, camera: str | None):
        """(width, height) of a camera's image in the image unit, or None."""
        cam = self.results.cameras.get(camera) if camera else None
        if cam is None or cam.image_size is None:
            return None
        w, h = (float(v) for v in cam.image_size)
        if self.image_unit == "mm":
            if cam.pixel_size is None:
                return None
            w, h = w * cam.pixel_size[0], h * cam.pixel_size[1]
        return w, h

    # ---------------------------------------------------------------- points
    @property
    def points(self) -> Table:
        """points.csv, keyed by ``id``."""
        return self.results.points

    @cached_property
    def used_point_rows(self) -> np.ndarray:
        """Row in points.csv of the point of every used observation of
        residuals.csv (-1 where absent; computed once: ray statistics and
        the network page, 181,000 lookups for a large network)."""
        r, pts = self.residuals, self.points
        used = r["used"]
        return pts.positions(r["point"][used]) if len(pts) else np.full(int(used.sum()), -1)

    @cached_property
    def ray_stats(self) -> Table:
        """Per observed point (ids sorted), keyed by ``point``: ``rays``
        (used observations) and ``angle`` (largest angle between two of its
        rays, degrees)."""
        from photogram.report.shapes import largest_ray_angles

        r, pts = self.residuals, self.points
        used = r["used"]
        scode, snames = r.groups("station")
        at = self.used_point_rows
        keep = at >= 0
        sc, at = scode[used][keep], at[keep]
        pcode, pnames = r.groups("point")
        code, ids = sorted_subgroups(pcode[used][keep], pnames)
        rays = np.bincount(code, minlength=len(ids))
        centres = self.centres
        known = np.array([n in centres for n in snames], dtype=bool)
        C_station = np.array([centres.get(n, np.full(3, np.nan)) for n in snames],
                             dtype=float).reshape(-1, 3)
        seen = known[sc]
        C = C_station[sc[seen]]
        X = pts.numbers(["X", "Y", "Z"])[at[seen]].reshape(-1, 3)
        angle = largest_ray_angles(C - X, code[seen], len(ids))
        return Table({"point": ids.astype(object), "rays": rays, "angle": angle}, "point")

    @property
    def rays(self):
        """:attr:`ray_stats` as a pandas DataFrame indexed by point (for
        callers outside the report's pages)."""
        import pandas as pd

        t = self.ray_stats
        out = pd.DataFrame({"rays": t["rays"].astype(int), "angle": t["angle"]},
                           index=pd.Index(t["point"].tolist(), name="point"),
                           columns=["rays", "angle"])
        return out

    @cached_property
    def point_sigma(self):
        """(ids, (n, 3) sigmas) of the points with a-posteriori sigmas > 0."""
        p = self.points
        cols = ["est_sX", "est_sY", "est_sZ"]
        if not all(c in p for c in cols) or not len(p):
            return [], np.zeros((0, 3))
        s = p.numbers(cols)
        ok = np.all(np.isfinite(s), axis=1) & (s.max(axis=1) > 0)
        return [str(x) for x in p.ids[ok]], s[ok]


def read_image(path: Path) -> np.ndarray:
    """A picture of the results folder (stick.png, ...) for a report page;
    its size is checked from the header before it is decoded."""
    import matplotlib.image as mpimg

    check_image(path)
    try:
        return np.asarray(mpimg.imread(path))
    except Exception as exc:      # PIL: OSError, SyntaxError, DecompressionBombError, ...
        raise InputError(f"cannot read this image ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:100]})", file=path,
                         hint="the file is damaged: run the command again") from None


def _read_covariance(path: Path) -> dict | None:
    if not path.is_file():
        return None
    return read_covariance(path)       # allow_pickle=False; damage is an InputError


def _read_table(path: Path, ids=("exposure", "point", "line")):
    if not path.is_file():
        return None
    return read_results_table(path, ids, text=("stations",), keep_default_na=True)


def _project_path(folder: Path, text) -> Path | None:
    if not text:
        return None
    p = Path(str(text))
    if p.is_absolute():
        return p if p.is_file() else None
    # a relative path is relative to where the command ran: look above the
    # results folder first (the same answer from any working directory),
    # then in the working directory
    candidates = [a / p for a in Path(folder).resolve().parents] + [Path.cwd() / p,
                                                                    folder.parent / p.name]
    return next((c for c in candidates if c.is_file()), None)


def _read_project(folder: Path, summary: dict):
    from photogram.project import read_project

    named = _project_of(summary).get("path")
    if not named:
        return None, "summary.json names no project file"
    path = _project_path(folder, named)
    if path is None:
        return None, f"the project file named in summary.json ({named}) was not found"
    logger = logging.getLogger("photogram")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        return read_project(path), ""
    except (PhotogramError, OSError) as exc:
        return None, f"the project file could not be read ({' '.join(str(exc).split())})"
    finally:
        logger.setLevel(level)


def _is_project_of(project, folder: Path, summary: dict) -> bool:
    """Whether ``project`` was read from the project file of ``summary``."""
    path = _project_path(folder, _project_of(summary).get("path"))
    mine = getattr(project, "path", None)
    return path is not None and mine is not None and Path(mine).resolve() == path.resolve()


def _read_summary(folder: Path) -> dict:
    return read_json(folder / "summary.json", "summary.json")


def _summary_only(folder: Path, summary: dict) -> Results:
    """The results of a command without adjustment tables (Monte Carlo,
    motion capture): the summary and empty tables."""
    image_unit = str(_project_of(summary).get("image_unit") or "px")

    def empty(names, key):
        return Table({n: np.zeros(0, dtype=object) for n in names}, key)

    return Results(folder=folder, summary=summary, image_unit=image_unit, cameras={},
                   stations=empty(["station", "camera", "X0", "Y0", "Z0", "omega", "phi",
                                   "kappa"], "station"),
                   points=empty(["id", "kind", "X", "Y", "Z"], "id"),
                   residuals=empty(["station", "point", "x", "y", "vx", "vy"], None),
                   log="")


def _read_results(folder: Path, summary: dict, tables: dict | None = None) -> Results:
    """A results folder read for the report: the tables as :class:`Table`
    (numpy columns, no pandas), keyed by station and point id; a table the
    command handed over (``tables``, :mod:`photogram.report.handover`) is
    not parsed again."""
    unit, cameras = load_cameras_file(folder / "cameras.toml")
    log = folder / "log.txt"
    specs = {"stations.csv": (("station", "camera"), "station"),
             "points.csv": (("id", "kind"), "id"),
             "residuals.csv": (("station", "point", "line"), None)}
    tables = tables or {}
    read = {name: table_from_written(tables.get(name), folder / name, text, key)
            for name, (text, key) in specs.items()}
    unread = [name for name, table in read.items() if table is None]
    big = sum((folder / n).stat().st_size for n in unread) > PANDAS_BYTES
    reader = read_table_pandas if big else read_table
    for name in unread:
        text, key = specs[name]
        read[name] = reader(folder / name, text, key=key)
    return Results(folder=folder, summary=summary, image_unit=unit, cameras=cameras,
                   stations=read["stations.csv"], points=read["points.csv"],
                   residuals=read["residuals.csv"],
                   log=log.read_text(encoding="utf-8") if log.is_file() else "")


def load(folder: str | Path, project=None, tables: dict | None = None) -> ReportData:
    """Read a results folder for the report.

    ``project``, if given, is the project the results were computed from,
    as read from its file (a command that has it in memory saves reading
    it again: 1.9 s for 181,000 observations); it is used only if its path
    is the project file named in summary.json, otherwise that file is read.
    ``tables``, if given, are the tables the command has just written
    (file name -> :class:`~photogram.project.results.WrittenTable`), used
    instead of parsing those files where they are sure to give the same
    values (:func:`~photogram.report.handover.table_from_written`).

    Raises
    ------
    InputError
        The folder holds no results, or a results file is missing or damaged
        (one line naming the folder and the file).
    """
    folder = Path(folder)
    if folder.is_file():
        raise InputError("a file, not a results folder", file=folder,
                         hint="photogram report takes the output folder of calibrate, orient "
                              "or intersect, e.g. projects/lab/results")
    if not folder.is_dir():
        raise InputError("no such results folder", file=folder,
                         hint="give the output folder of calibrate, orient or intersect")
    missing = [f for f in REQUIRED if not (folder / f).is_file()]
    hint = ("run calibrate, orient or intersect first, or give its output folder "
            "(e.g. projects/lab/results)")
    if "summary.json" in missing:
        raise InputError(f"not a results folder: {', '.join(missing)} missing", file=folder,
                         hint=hint)
    summary = _read_summary(folder)
    if missing:
        if summary.get("command") in ADJUSTMENT_COMMANDS or "redundancy" in summary:
            raise InputError(f"incomplete results folder: {', '.join(missing)} missing",
                             file=folder, hint="run the command again")
        results = _summary_only(folder, summary)
    else:
        results = _read_results(folder, summary, tables)
    if _is_project_of(project, folder, results.summary):
        note = ""
    else:
        project, note = _read_project(folder, results.summary)
    return ReportData(folder=folder, results=results,
                      covariance=_read_covariance(folder / "covariance.npz"),
                      exposures=_read_table(folder / "exposures.csv", ids=("exposure",)),
                      points3d=_read_table(folder / "points3d.csv"),
                      lines3d=_read_table(folder / "lines3d.csv"),
                      project=project, project_note=note)


def _project_of(summary) -> dict:
    """summary["project"] as a dict (mocap writes only the project's name)."""
    project = summary.get("project")
    if isinstance(project, dict):
        return project
    return {"name": project} if project else {}
