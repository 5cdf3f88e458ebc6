"""Pose2Sim / anipose calibration files (``Calib_*.toml``).

One table per camera::

    [cam_01]
    name = "cam_01"
    size = [ 1088.0, 1920.0]                 # width, height in px
    matrix = [ [fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    distortions = [ k1, k2, p1, p2]          # OpenCV order (k3 optional)
    rotation = [ rx, ry, rz]                 # Rodrigues vector of R_cv (world to camera)
    translation = [ tx, ty, tz]              # t_cv in metres: x_cv = R_cv X + t_cv
    fisheye = false

    [metadata]
    adjusted = false
    error = 0.0

This is OpenCV's camera (docs/camera-models.md, section 5): each table
becomes a camera of model ``opencv`` and a station of the same name, with
``R = diag(1,-1,-1) rodrigues(rotation)`` and ``X0 = -R_cv^T translation``
(world axes and unit as in the file; Pose2Sim's calibration world is Z up,
metres). A table with ``fisheye = true`` (OpenCV's fisheye model, as
``photogram calibrate`` writes for ``model = "opencv_fisheye"`` and anipose
for its fisheye cameras) has ``distortions = [k1, k2, k3, k4]`` and becomes
a camera of model ``opencv_fisheye`` (docs/camera-models.md, section 5.0).
anipose writes the same layout (``name``, ``size``, ``matrix``,
``distortions``, ``rotation``, ``translation``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.exchange import (View, build_project, cv_to_station, fisheye_camera,
                                   opencv_camera)

__all__ = ["read_pose2sim", "pose2sim_project", "format_pose2sim", "write_pose2sim"]

_CAMERA_KEYS = ("name", "size", "matrix", "distortions", "rotation", "translation", "fisheye")


def _array(sec, key, shape, what):
    value = sec.data.get(key)
    if value is None:
        raise sec.error(None, f"{sec.label} has no {key}", hint=f"{key} = {what}")
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise sec.error(key, f"{key} in {sec.label} is not {what}") from None
    if shape is not None and a.shape != shape or not np.all(np.isfinite(a)):
        raise sec.error(key, f"{key} in {sec.label} is not {what}",
                        hint="the file is damaged or not a Pose2Sim calibration")
    return a


def read_pose2sim(path) -> list[View]:
    """The cameras of a Pose2Sim/anipose calibration file, in file order.

    Raises
    ------
    InputError
        TOML syntax, missing or malformed keys (file and line), fisheye.
    """
    from photogram.project.toml_source import TomlSource
    path = Path(path)
    try:
        src = TomlSource.load(path, what="Pose2Sim calibration")
    except InputError as exc:
        if exc.line is not None or exc.file is None:
            raise
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
        raise InputError(exc.what.replace(" at the end of the file", "") +
                         " at the end of the file", file=path, line=max(len(lines), 1),
                         hint="the file is truncated") from None
    root = src.root()
    views = []
    for key, value in root.data.items():
        if key == "metadata" or not isinstance(value, dict):
            continue
        sec = root.table(key)
        sec.check_keys(_CAMERA_KEYS + ("extra",), required=("matrix", "rotation", "translation"))
        name = str(sec.data.get("name", key))
        fisheye = sec.data.get("fisheye", False)
        if not isinstance(fisheye, bool):
            raise sec.error("fisheye", f"fisheye in {sec.label} must be true or false")
        K = _array(sec, "matrix", (3, 3), "a 3 x 3 matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]")
        dist = _array(sec, "distortions", None, "a list of numbers [k1, k2, p1, p2]") \
            if "distortions" in sec else np.zeros(4)
        if fisheye and (dist.ndim != 1 or dist.size != 4):
            raise sec.error("fisheye", f"fisheye = true in {sec.label} needs distortions = "
                                       f"[k1, k2, k3, k4] (OpenCV's fisheye model), not "
                                       f"{dist.size} values",
                            hint="set fisheye = false for OpenCV's standard model")
        if dist.ndim != 1 or dist.size not in (4, 5):
            raise sec.error("distortions", f"distortions in {sec.label} must be [k1, k2, p1, p2]"
                                           f" or [k1, k2, p1, p2, k3]")
        rvec = _array(sec, "rotation", (3,), "a Rodrigues vector [rx, ry, rz]")
        tvec = _array(sec, "translation", (3,), "a vector [tx, ty, tz]")
        size = None
        if "size" in sec:
            s = _array(sec, "size", (2,), "[width, height] in pixels")
            if np.any(s <= 0):
                raise sec.error("size", f"size in {sec.label} must be positive")
            size = (int(round(s[0])), int(round(s[1])))
        try:
            (fisheye_camera if fisheye else opencv_camera)(name, K, dist, size)
        except InputError as exc:
            raise sec.error("matrix", exc.what, hint=exc.hint) from None
        from photogram.geometry import rodrigues_to_matrix
        views.append(View(name=name, camera=name, K=K, dist=dist, R_cv=rodrigues_to_matrix(rvec),
                          t_cv=tvec, image_size=size,
                          extra={"section": key, "rotation": rvec, "fisheye": fisheye,
                                 "line": src.line_of((key,))}))
    if not views:
        raise InputError("no camera table in the file", file=path, line=1,
                         hint="a Pose2Sim calibration has [cam_01], [cam_02], ... tables")
    names = [v.name for v in views]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise InputError(f"camera name {sorted(dup)[0]} is used twice", file=path,
                         line=src.line_of((views[names.index(sorted(dup)[0])].extra["section"],)))
    return views


def views_project(views: list[View], name: str, *, length_unit: str = "m",
                  source: str | None = None):
    """A project with one ``opencv`` (``opencv_fisheye`` for a view whose
    ``extra["fisheye"]`` is true) camera and one station per view."""
    cameras, angles, X0 = {}, [], []
    for v in views:
        make = fisheye_camera if v.extra.get("fisheye", False) else opencv_camera
        cameras[v.camera] = make(v.camera, v.K, v.dist, v.image_size, source=source)
        a, x = cv_to_station(v.R_cv, v.t_cv)
        angles.append(a)
        X0.append(x)
    return build_project(name, cameras, stations=[v.name for v in views],
                         station_camera=[v.camera for v in views],
                         angles=np.array(angles).reshape(-1, 3), X0=np.array(X0).reshape(-1, 3),
                         length_unit=length_unit)


def pose2sim_project(path, name: str | None = None):
    """Import a Pose2Sim/anipose calibration as a :class:`Project` (metres)."""
    path = Path(path)
    return views_project(read_pose2sim(path), name or path.stem, source=str(path))


def _vec(a) -> str:
    return "[ " + ", ".join(repr(float(x)) for x in np.asarray(a).ravel()) + "]"


def format_pose2sim(views: list[View], *, error: float = 0.0) -> str:
    """The text of a Pose2Sim calibration file (floats with ``repr``: exact)."""
    from photogram.geometry import matrix_to_rodrigues
    out = []
    for v in views:
        size = v.image_size if v.image_size is not None else (2 * v.K[0, 2], 2 * v.K[1, 2])
        dist = np.asarray(v.dist, float)
        fisheye = bool(v.extra.get("fisheye", False))     # dist: k1 k2 k3 k4
        if not fisheye:
            dist = dist[:4] if dist.size < 5 or dist[4] == 0 else dist[:5]
        rvec = matrix_to_rodrigues(v.R_cv)
        name = v.name.replace("\\", "\\\\").replace('"', '\\"')
        out += [f'[{_section(v.name)}]', f'name = "{name}"',
                f"size = {_vec([float(size[0]), float(size[1])])}",
                "matrix = [ " + ", ".join(_vec(r) for r in v.K) + "]",
                f"distortions = {_vec(dist)}", f"rotation = {_vec(rvec)}",
                f"translation = {_vec(v.t_cv)}", f"fisheye = {str(fisheye).lower()}", ""]
    out += ["[metadata]", "adjusted = false", f"error = {float(error)!r}", ""]
    return "\n".join(out)


def _section(name: str) -> str:
    import re
    if re.fullmatch(r"[A-Za-z0-9_-]+", name):
        return name
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


def write_pose2sim(path, views: list[View], *, force: bool = False, error: float = 0.0) -> Path:
    """Write a Pose2Sim calibration file atomically (refuses to replace an
    existing file unless ``force``)."""
    from photogram.io.exchange import write_new_text
    return write_new_text(path, format_pose2sim(views, error=error), force)
