"""Project folders written by the importers, and files that are never replaced.

:func:`build_project` makes a :class:`~photogram.project.model.Project` from
plain lists; :func:`save_project` and :func:`save_calibration` write it as a
new project folder (existing files are never replaced; every file written
atomically, the .prj last); :func:`check_new_file`, :func:`write_new_text`
and :func:`write_new_bytes` write an export without replacing a file unless
asked (``--force``). Re-exported by :mod:`photogram.io.exchange`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.atomic import atomic_write_bytes, atomic_write_text
from photogram.project.model import (Camera, ImagePoints, Points, Project, Stations,
                                     Units)

__all__ = ["build_project", "save_project", "save_calibration", "check_new_file",
           "write_new_text", "write_new_bytes"]


def _nan3(n: int) -> np.ndarray:
    return np.full((n, 3), np.nan)


def build_project(name: str, cameras: dict[str, Camera], *, stations=(), station_camera=(),
                  angles=None, X0=None, point_ids=(), kinds=None, xyz=None, point_sigma=None,
                  obs_station=(), obs_point=(), obs_xy=None, obs_sigma=None,
                  length_unit: str = "m", angle_unit: str = "deg", image_unit: str = "px",
                  datum: str = "free", sigma_image: float = 1.0) -> Project:
    """A :class:`Project` from plain lists (ids as text, angles in radians,
    world-to-camera; observations by station and point id)."""
    names = [str(s) for s in stations]
    n = len(names)
    st = Stations(names=names, camera=[str(c) for c in station_camera],
                  position=_nan3(n) if X0 is None else np.asarray(X0, float).reshape(n, 3),
                  angles=_nan3(n) if angles is None else np.asarray(angles, float).reshape(n, 3),
                  position_sigma=_nan3(n), angle_sigma=_nan3(n),
                  record=np.zeros(n, dtype=int))
    ids = [str(p) for p in point_ids]
    m = len(ids)
    pts = Points(ids=ids, kind=np.array(kinds if kinds is not None else ["tie"] * m,
                                         dtype=object),
                 xyz=_nan3(m) if xyz is None else np.asarray(xyz, float).reshape(m, 3),
                 sigma=_nan3(m) if point_sigma is None else
                 np.asarray(point_sigma, float).reshape(m, 3),
                 record=np.zeros(m, dtype=int))
    sidx = {s: i for i, s in enumerate(names)}
    pidx = {p: i for i, p in enumerate(ids)}
    k = len(obs_station)
    obs = ImagePoints(
        station=np.array([sidx[str(s)] for s in obs_station], dtype=int),
        point=np.array([pidx[str(p)] for p in obs_point], dtype=int),
        xy=np.zeros((0, 2)) if obs_xy is None else np.asarray(obs_xy, float).reshape(k, 2),
        sigma=np.full(k, np.nan) if obs_sigma is None else np.asarray(obs_sigma, float),
        record=np.zeros(k, dtype=int))
    project = Project(name=name, units=Units(length=length_unit, angle=angle_unit,
                                             image=image_unit),
                      cameras=dict(cameras), stations=st, points=pts, image_points=obs)
    project.adjustment.datum = datum
    project.adjustment.sigma_image = float(sigma_image)
    return project


def save_project(project: Project, folder, name: str | None = None) -> Path:
    """Write ``project`` as ``FOLDER/NAME.prj`` with its tables beside it.

    The folder is created if needed. Nothing is replaced: an existing file
    of the same name, or another .prj in the folder (a folder holds one
    project), is an error. Every file is written atomically, the .prj last.
    """
    from photogram.project.writer import write_project
    folder = _check_import_folder(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder: {exc.strerror}", file=folder) from None
    stem = _safe_stem(name or project.name or folder.name)
    project.name = project.name or stem
    return write_project(project, folder / f"{stem}.prj", overwrite=False)


def save_calibration(project: Project, folder, name: str | None = None) -> Path:
    """Write a project that has cameras and stations but no measurements yet
    (a calibration from Pose2Sim, OpenCV, ...).

    A .prj cannot be read without image points, so the folder gets what a
    results folder gives a later project (docs/interoperability.md):

    * ``cameras.toml``: the cameras (``[cameras.NAME] from = "cameras.toml"``),
    * ``stations.csv``: the stations with their orientation (degrees,
      world-to-camera, the project's length unit),
    * ``NAME.prj`` taking both, with an empty ``points.csv`` and
      ``image_points.csv`` (header only) to be filled with measurements;
      ``photogram check`` says so until they are.

    Exports read such a folder directly (:func:`load_source`). Nothing is
    replaced; every file is written atomically, the .prj last.
    """
    import photogram
    from photogram.project.camera_schema import camera_to_toml
    from photogram.project.tables import format_table
    from photogram.project.toml_writer import dumps
    from photogram.project.writer import project_section, station_columns
    folder = _check_import_folder(folder)
    stem = _safe_stem(name or project.name or folder.name)
    project.name = project.name or stem
    project.rotation_direction = "world_to_camera"
    files = {"cameras.toml": None, "stations.csv": None, "points.csv": None,
             "image_points.csv": None, f"{stem}.prj": None}
    for f in files:
        if (folder / f).exists():
            raise InputError("file exists", file=folder / f,
                             hint="import into a new folder; existing files are never replaced")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder: {exc.strerror}", file=folder) from None
    sec = project_section(project)
    sec.pop("rotation", None)
    sec["software_version"] = photogram.__version__
    doc = {"project": sec,
           "cameras": {n: camera_to_toml(c) for n, c in project.cameras.items()}}
    src = {c.source for c in project.cameras.values() if c.source}
    files["cameras.toml"] = dumps(doc, header="cameras imported by photogram " +
                                  photogram.__version__ +
                                  (f" from {sorted(src)[0]}" if src else ""))
    files["stations.csv"] = format_table(station_columns(project))
    files["points.csv"] = format_table({"id": [], "kind": [], "X": [], "Y": [], "Z": []},
                                       comment="object points: id,kind (control/check/tie),X,Y,Z")
    files["image_points.csv"] = format_table(
        {"station": [], "point": [], "x": [], "y": [], "sigma": []},
        comment="image measurements (px): add one row per measured point")
    prj = {"project": project_section(project),
           "cameras": {n: {"from": "cameras.toml"} for n in project.cameras},
           "stations": {"file": "stations.csv"}, "points": {"file": "points.csv"},
           "observations": {"points": "image_points.csv"},
           "adjustment": {"datum": "control"}, "output": {"folder": "results"}}
    files[f"{stem}.prj"] = dumps(prj, header="imported by photogram: cameras and stations "
                                             "are in cameras.toml and stations.csv;\n"
                                             "add object points and image measurements "
                                             "before running a command")
    for f, text in files.items():
        atomic_write_text(folder / f, text)
    return folder / f"{stem}.prj"


def _check_import_folder(folder) -> Path:
    """The folder an import writes: a new folder, or one without a project."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InputError("is a file, not a folder", file=folder,
                         hint="give a new or empty folder with --to")
    others = sorted(folder.glob("*.prj")) if folder.is_dir() else []
    if others:
        raise InputError(f"the folder already holds a project ({others[0].name})", file=folder,
                         hint="import into a new folder; existing files are never replaced")
    return folder


def _safe_stem(name: str) -> str:
    from photogram.project.safe_names import safe_name
    return safe_name(name, default="project")


def check_new_file(path, force: bool = False) -> Path:
    """Refuse to replace an existing file unless ``force``; the folder must exist."""
    path = Path(path)
    if path.is_dir():
        raise InputError("is a folder", file=path, hint="give the path of the file to write")
    if path.exists() and not force:
        raise InputError("file exists", file=path,
                         hint="choose another name, or pass --force to replace it")
    if not path.parent.is_dir():
        raise InputError("the folder does not exist", file=path.parent, hint="create it first")
    return path


def write_new_text(path, text: str, force: bool = False) -> Path:
    """:func:`check_new_file`, then write atomically."""
    return atomic_write_text(check_new_file(path, force), text)


def write_new_bytes(path, data: bytes, force: bool = False) -> Path:
    return atomic_write_bytes(check_new_file(path, force), data)
