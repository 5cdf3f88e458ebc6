"""Export sources: a results folder (or a .prj) read back into a project
with its a-posteriori sigmas, and its stations as OpenCV-style views
(split from :mod:`photogram.io.exchange`, which re-exports these names)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.exchange import View, build_project, opencv_intrinsics, station_to_cv  # noqa: F401
from photogram.project.model import LENGTH_UNITS, Project

log = logging.getLogger("photogram")

@dataclass
class ExportSource:
    """What an exporter reads: a project with estimated values, the
    a-posteriori sigmas (NaN where unknown) and where it came from."""

    project: Project
    point_sigma: np.ndarray
    station_sigma: np.ndarray
    folder: Path
    summary: dict = field(default_factory=dict)
    results: object = None                     # photogram.project.Results or None

    @property
    def metres(self) -> float:
        """Metres per length unit of the project."""
        return LENGTH_UNITS[self.project.units.length]


def load_source(path) -> ExportSource:
    """Read a results folder (summary.json, cameras.toml, stations.csv,
    points.csv) or a project (.prj, or a folder holding one) for export.

    Angles are converted to radians, world-to-camera; the a-posteriori
    sigmas come from the ``est_s*`` columns.
    """
    path = Path(path)
    if path.is_dir() and (path / "summary.json").is_file():
        _refuse_mocap_results(path)
        return _from_results(path)
    from photogram.project import read_project
    if not path.exists():
        raise InputError("not found", file=path,
                         hint="give a results folder (with summary.json) or a .prj")
    folder = path if path.is_dir() else path.parent
    try:
        project = read_project(path)
    except InputError:
        if (folder / "cameras.toml").is_file() and (folder / "stations.csv").is_file():
            return _from_calibration(folder)
        raise
    n, m = len(project.stations), len(project.points)
    return ExportSource(project=project, point_sigma=np.full((m, 3), np.nan),
                        station_sigma=np.full((n, 6), np.nan), folder=project.folder)


def _refuse_mocap_results(folder: Path) -> None:
    """A mocap results folder holds 3D joints, not a network to export."""
    import json
    try:
        summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return                                  # read_results names the problem
    if isinstance(summary, dict) and summary.get("command") == "mocap":
        raise InputError("a results folder of photogram mocap holds 3D joints, not cameras, "
                         "stations and points", file=folder,
                         hint="export its joints with trc, c3d, csv or mot; export the cameras "
                              "from the project (.prj) if they do not move")


def _from_calibration(folder: Path) -> ExportSource:
    """A folder with cameras.toml and stations.csv (see :func:`save_calibration`)."""
    import tomllib
    from photogram.project.camera_schema import load_cameras_file
    from photogram.project.tables import read_table
    unit, cameras = load_cameras_file(folder / "cameras.toml")
    info = tomllib.loads((folder / "cameras.toml").read_text(encoding="utf-8-sig")).get(
        "project", {})
    angle = info.get("angle_unit", "deg")
    table = read_table(folder / "stations.csv", required=("station", "camera"),
                       optional=("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                       what="stations table")
    names, cams = table.text("station"), table.text("camera")
    for k, c in enumerate(cams):
        if c not in cameras:
            raise table.error(k, f"unknown camera '{c}' for station {names[k]}",
                              hint="the camera must be in cameras.toml")
    X0 = np.column_stack([table.floats(c) for c in ("X0", "Y0", "Z0")])
    ang = np.column_stack([table.angles(c, angle) for c in ("omega", "phi", "kappa")])
    if info.get("rotation_direction") == "camera_to_world":
        from photogram.project import invert_opk
        ang = invert_opk(ang)
    project = build_project(str(info.get("name") or folder.name), cameras, stations=names,
                            station_camera=cams, angles=ang, X0=X0,
                            length_unit=info.get("length_unit", "m"), angle_unit=angle,
                            image_unit=unit)
    n = len(names)
    return ExportSource(project=project, point_sigma=np.zeros((0, 3)),
                        station_sigma=np.full((n, 6), np.nan), folder=folder)


def _column(frame, name, n, default=np.nan) -> np.ndarray:
    if name in frame.columns:
        return frame[name].to_numpy(dtype=float)
    return np.full(n, default)


def _from_results(folder: Path) -> ExportSource:
    from photogram.geometry import to_radians
    from photogram.project import invert_opk, read_results
    res = read_results(folder)
    info = res.summary.get("project") or {}
    length = info.get("length_unit", "m")
    angle = info.get("angle_unit", "deg")
    direction = info.get("rotation_direction", "world_to_camera")
    if length not in LENGTH_UNITS:
        raise InputError(f"unknown length unit {length!r} in summary.json",
                         file=folder / "summary.json")
    st = res.stations
    n = len(st)
    names = [str(s) for s in st["station"]] if n else []
    cams = [str(c) for c in st["camera"]] if n else []
    X0 = np.column_stack([_column(st, c, n) for c in ("X0", "Y0", "Z0")]) if n else \
        np.zeros((0, 3))
    ang = np.column_stack([_column(st, c, n) for c in ("omega", "phi", "kappa")]) if n else \
        np.zeros((0, 3))
    ang = to_radians(ang, angle)
    if direction == "camera_to_world" and n:
        ang = invert_opk(ang)
    ssig = np.column_stack([_column(st, c, n) for c in
                            ("est_sX0", "est_sY0", "est_sZ0")] +
                           [to_radians(_column(st, c, n), angle)
                            for c in ("est_somega", "est_sphi", "est_skappa")]) if n else \
        np.zeros((0, 6))
    pt = res.points
    m = len(pt)
    ids = [str(p) for p in pt["id"]] if m else []
    kinds = [str(k) for k in pt["kind"]] if m else []
    xyz = np.column_stack([_column(pt, c, m) for c in "XYZ"]) if m else np.zeros((0, 3))
    prior = np.column_stack([_column(pt, "s" + c, m) for c in "XYZ"]) if m else np.zeros((0, 3))
    psig = np.column_stack([_column(pt, "est_s" + c, m) for c in "XYZ"]) if m else \
        np.zeros((0, 3))
    project = build_project(str(info.get("name") or folder.parent.name), res.cameras,
                            stations=names, station_camera=cams, angles=ang, X0=X0,
                            point_ids=ids, kinds=kinds, xyz=xyz, point_sigma=prior,
                            length_unit=length, angle_unit=angle, image_unit=res.image_unit)
    if info.get("path"):
        project.path = Path(info["path"])
    _rigs_from_results(project, res)
    return ExportSource(project=project, point_sigma=psig, station_sigma=ssig, folder=folder,
                        summary=res.summary, results=res)


def _rigs_from_results(project: Project, res) -> None:
    """The rigs of an adjustment with rigs: the adjusted camera poses in
    their rigs (summary.json ``rigs``) and the stations' ``frame`` column."""
    from photogram.project.model import Rig
    rows = res.summary.get("rigs") or []
    if not rows or "frame" not in res.stations.columns:
        return
    for r in rows:
        rig = project.rigs.setdefault(str(r["rig"]), Rig(str(r["rig"]), str(r["reference"])))
        rig.cameras.append(str(r["camera"]))
        rig.sensors[str(r["camera"])] = (np.asarray(r["position"], float),
                                         np.asarray(r["angles_rad"], float))
    project.stations.frame = ["" if f != f else str(int(f)) if isinstance(f, float) else str(f)
                              for f in res.stations["frame"]]


def views_of(project: Project, *, stations=None, tolerance: float = 0.01) -> list[View]:
    """The stations of ``project`` as OpenCV :class:`View` objects.

    Raises
    ------
    InputError
        A station without an orientation, or a camera that cannot be
        expressed in OpenCV terms.
    """
    st = project.stations
    wanted = set(stations) if stations is not None else None
    intrinsics = {}
    views = []
    for i, name in enumerate(st.names):
        if wanted is not None and name not in wanted:
            continue
        if not (np.all(np.isfinite(st.position[i])) and np.all(np.isfinite(st.angles[i]))):
            raise InputError(f"station {name} has no orientation to export",
                             file=project.path,
                             hint="export a results folder of calibrate, orient or intersect")
        cam = project.cameras[st.camera[i]]
        if cam.name not in intrinsics:
            intrinsics[cam.name] = opencv_intrinsics(cam, project.units.image, tolerance)
        K, dist, misfit = intrinsics[cam.name]
        R_cv, t_cv = station_to_cv(st.angles[i], st.position[i])
        views.append(View(name=name, camera=cam.name, K=K, dist=dist, R_cv=R_cv, t_cv=t_cv,
                          image_size=cam.image_size, extra={"misfit_px": misfit}))
    return views
