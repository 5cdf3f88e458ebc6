"""Tables of a motion-capture project: cameras from the project, camera
rotations per frame, limb lengths, 3D joints (truth and results).

``camera_frames`` (pan-tilt-zoom cameras), one row per camera and frame::

    frame,camera,omega,phi,kappa[,<interior parameter>...]

angles in the project's angle unit and rotation direction, frames numbered
like the detections; optional columns named like a parameter of the
camera's model (``fx``, ``fy`` for opencv, ``c`` for brown) override it per
frame (zoom). Every camera needs every frame.

``limb_lengths``: ``from,to,length`` (joint names, project length unit).

3D joints (``joints3d.csv`` of the results, and ``truth``)::

    frame,time,<joint>_X,<joint>_Y,<joint>_Z,...

in the project's length unit and world axes (Z up); empty cells are
missing values.
"""

from __future__ import annotations

import csv
import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.geometry import camera_model, opk_to_matrix
from photogram.mocap.body.skeleton import Skeleton
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.project.atomic import atomic_write_text
from photogram.project.camera_schema import invert_opk
from photogram.project.tables import _delimiter, format_table, read_table, suggest

log = logging.getLogger(__name__)

__all__ = ["cameras_from_project", "read_camera_frames", "read_limb_lengths", "read_joints",
           "write_joints", "cameras_from_views", "write_angles_mot", "write_camera_rotations_mot"]


def cameras_from_views(views) -> MocapCameras:
    """Fixed cameras from OpenCV views (objects with ``name``, ``K``,
    ``dist``, ``R_cv``, ``t_cv``, ``image_size``; e.g. the Pose2Sim reader of
    :mod:`photogram.io.pose2sim`): ``R = diag(1,-1,-1) R_cv``, ``X0 =
    -R_cv^T t_cv`` (docs/camera-models.md). A view whose ``extra`` says
    ``fisheye`` is an ``opencv_fisheye`` camera (``dist`` = k1 k2 k3 k4),
    the others ``opencv`` (k1 k2 p1 p2 [k3])."""
    names, models, io, X0, R, size = [], [], [], [], [], []
    for v in views:
        K = np.asarray(v.K, float)
        fisheye = bool(getattr(v, "extra", {}).get("fisheye", False))
        d = np.zeros(4 if fisheye else 5)
        dist = np.asarray(v.dist, float).ravel()
        d[:len(dist)] = dist
        io.append([K[0, 0], K[1, 1], K[0, 2], K[1, 2], *d])
        models.append("opencv_fisheye" if fisheye else "opencv")
        R_cv = np.asarray(v.R_cv, float)
        R.append(np.diag([1.0, -1.0, -1.0]) @ R_cv)
        X0.append(-R_cv.T @ np.asarray(v.t_cv, float).ravel())
        names.append(str(v.name))
        size.append(v.image_size if v.image_size is not None else (np.nan, np.nan))
    return MocapCameras(names, models, io, np.array(X0), np.array(R), np.array(size, float))


def cameras_from_project(project) -> MocapCameras:
    """The cameras of a mocap project: ``calibration`` (Pose2Sim) or one
    station per camera of ``[cameras]``/``[stations]``.

    With ``rotation = "known"`` every station needs its position and angles
    (``camera_frames``, when given, replaces the rotations per frame). With
    ``rotation = "estimate"`` only the projection centres are read (docs/
    mocap.md, "Unknown camera rotations"): the angles may be left empty;
    where given they are not used, not even as start values (one info line
    says so), and the rotations are identity placeholders until the
    estimate replaces them.

    Raises
    ------
    InputError
        A camera with two stations or none; a station without its position
        (or, rotations known, without its angles); ``file:line``.
    """
    mocap = project.mocap
    estimate = mocap.rotation == "estimate"
    if mocap.calibration is not None:
        from photogram.io.pose2sim import read_pose2sim
        cameras = cameras_from_views(read_pose2sim(mocap.calibration))
        if estimate:
            log.info("rotation = \"estimate\": the rotations of the calibration are not used "
                     "(only its projection centres and interior orientation)")
            cameras = replace(cameras, R=_placeholder_rotations(cameras.n_cameras))
        return cameras
    st = project.stations
    names, models, io, X0, angles, size = [], [], [], [], [], []
    seen = {}
    for i, (station, cam) in enumerate(zip(st.names, st.camera)):
        line = int(st.record[i]) if len(st.record) > i else None
        if cam in seen:
            raise InputError(f"camera {cam} has two stations ({seen[cam]} and {station}); a "
                             f"motion-capture camera has one position",
                             file=project.sources.get("stations"), line=line)
        seen[cam] = station
        camera = project.cameras[cam]
        if not np.all(np.isfinite(st.position[i])):
            raise InputError(f"station {station} needs its position (X0, Y0, Z0)",
                             file=project.sources.get("stations"), line=line,
                             hint="give the projection centre of every camera"
                                  + ("" if estimate else " and its angles"))
        if not estimate and not np.all(np.isfinite(st.angles[i])):
            raise InputError(f"station {station} needs its position and angles",
                             file=project.sources.get("stations"), line=line,
                             hint="give omega, phi, kappa, or set rotation = \"estimate\" "
                                  "in [mocap] (centres only)")
        names.append(cam)
        models.append(camera.model)
        io.append(camera.values())
        X0.append(st.position[i])
        angles.append(st.angles[i])
        size.append(camera.image_size or (np.nan, np.nan))
    missing = [c for c in project.cameras if c not in seen]
    if missing:
        raise InputError(f"camera(s) without a station: {', '.join(missing)}",
                         file=project.sources.get("stations"),
                         hint="give every camera one station (its position" +
                              (")" if estimate else " and angles)"))
    if estimate:
        given = [s for s, a in zip(st.names, angles) if np.any(np.isfinite(a))]
        if given:
            log.info("rotation = \"estimate\": the angles of station(s) %s are not used (the "
                     "rotations are estimated from the detections and the rotation "
                     "differences; only the projection centres are read)", ", ".join(given))
        return MocapCameras(names, models, io, np.array(X0),
                            _placeholder_rotations(len(names)), np.array(size, float))
    from photogram.geometry.rotations import from_radians
    from photogram.mocap.evaluation.checks import check_angle_unit
    note = check_angle_unit(from_radians(np.array(angles).reshape(-1, 3), project.units.angle),
                            project.units.angle, "the stations table",
                            project.sources.get("stations"), st.record)
    if note and note not in project.warnings:
        log.warning("warning: %s", note)
        project.warnings.append(note)
    return MocapCameras(names, models, io, np.array(X0), opk_to_matrix(np.array(angles)),
                        np.array(size, float))


def _placeholder_rotations(n_cameras: int) -> np.ndarray:
    """(1, C, 3, 3) identities: the rotations of ``rotation = "estimate"``
    before they are estimated (never used as values)."""
    return np.broadcast_to(np.eye(3), (1, n_cameras, 3, 3)).copy()


def read_camera_frames(path: Path, cameras: MocapCameras, project, first_frame: int,
                       n_frames: int, rotations: bool = True) -> MocapCameras:
    """Rotations (and interior parameters) per frame (module doc); with
    ``rotations`` False (rotations estimated from the images) the angle
    columns are not needed and ignored: the table gives the zoom."""
    extra = sorted({p for m in cameras.models for p in camera_model(m).parameter_names})
    angle_cols = ("omega", "phi", "kappa")
    table = read_table(path, required=("frame", "camera") + (angle_cols if rotations else ()),
                       optional=extra + ([] if rotations else list(angle_cols)),
                       what="camera frames table")
    frame = table.floats("frame", required=True)
    bad = np.flatnonzero((frame != np.round(frame)) | (np.abs(frame) >= 2**31))
    if len(bad):
        raise table.error(int(bad[0]), "frame must be an integer",
                          hint="frames count from 0 (or the first frame) upwards")
    frame = frame.astype(int) - first_frame
    cams = table.text("camera")
    unit = project.units.angle
    if rotations:
        from photogram.mocap.evaluation.checks import check_angle_unit
        note = check_angle_unit(np.stack([table.floats(k) for k in angle_cols], -1), unit,
                                f"{Path(path).name} (omega, phi, kappa)", path, table.records)
        if note and note not in project.warnings:
            log.warning("warning: %s", note)
            project.warnings.append(note)
        angles = np.stack([table.angles(k, unit) for k in angle_cols], -1)
    else:
        angles = np.zeros((len(frame), 3))
    if np.any(~np.isfinite(angles)):
        raise table.error(int(np.flatnonzero(~np.all(np.isfinite(angles), 1))[0]),
                          "every row needs omega, phi and kappa")
    if project.rotation_direction == "camera_to_world":
        angles = invert_opk(angles)
    C = cameras.n_cameras
    R = np.full((n_frames, C, 3, 3), np.nan)
    io = [np.repeat(p[:1], n_frames, axis=0) for p in cameras.io]
    filled = np.zeros((n_frames, C), bool)
    first_row = np.zeros((n_frames, C), int)
    index = {n: k for k, n in enumerate(cameras.names)}
    Rm = opk_to_matrix(angles)
    cols = {p: table.floats(p) for p in extra if table.has(p)}
    for i, (f, name) in enumerate(zip(frame, cams)):
        if name not in index:
            raise table.error(i, f"unknown camera '{name}'",
                              hint=suggest(name, cameras.names, noun="cameras"))
        if not 0 <= f < n_frames:
            continue
        c = index[name]
        if filled[f, c]:
            raise table.error(i, f"a second row for camera {name}, frame {f + first_frame} "
                                 f"(first on line {first_row[f, c]})",
                              hint="give every camera one row per frame")
        first_row[f, c] = table.records[i]
        R[f, c] = Rm[i]
        filled[f, c] = True
        m = camera_model(cameras.models[c])
        for p, values in cols.items():
            if p in m.parameter_names and np.isfinite(values[i]):
                io[c][f, m.index(p)] = values[i]
    if not filled.all():
        f, c = np.argwhere(~filled)[0]
        raise InputError(f"camera {cameras.names[c]} has no row for frame {f + first_frame}",
                         file=path, hint="give every camera a row for every frame")
    if not rotations:
        R = np.broadcast_to(np.eye(3), (1, C, 3, 3)).copy()
    return MocapCameras(cameras.names, cameras.models, io, cameras.X0, R, cameras.image_size)


def write_camera_frames(path: Path, frames, cameras: MocapCameras, project,
                        comment: str = "") -> Path:
    """Rotations per camera and frame in the layout of ``camera_frames``
    (angles in the project's angle unit and rotation direction, the
    per-frame interior parameters of the OpenCV/Brown model), atomically."""
    from photogram.geometry.rotations import from_radians, matrix_to_opk
    F, C = len(frames), cameras.n_cameras
    R = cameras.rotations(F)
    opk = matrix_to_opk(R.reshape(-1, 3, 3))
    if project.rotation_direction == "camera_to_world":
        opk = invert_opk(opk)
    opk = from_radians(opk, project.units.angle).reshape(F, C, 3)
    cols = {"frame": np.repeat(np.asarray(frames), C),
            "camera": np.tile(np.array(cameras.names), F)}
    for k, name in enumerate(("omega", "phi", "kappa")):
        cols[name] = np.round(opk[..., k].ravel(), 7)
    zoom = [p for p in ("fx", "fy", "c") if all(p in camera_model(m).parameter_names
                                                for m in cameras.models)]
    for p in zoom:
        cols[p] = np.round(np.stack([cameras._io_rows(c, F)[:, camera_model(
            cameras.models[c]).index(p)] for c in range(C)], 1).ravel(), 3)
    return atomic_write_text(path, format_table(cols, comment=comment))


def write_angles_mot(path: Path, times, metrics: dict) -> Path:
    """``angles.mot``: OpenSim storage (``photogram.io.trajectories.mot_text``,
    ``inDegrees=yes``) of time (s, as metrics.csv) and every angle of
    metrics.csv (``photogram.io.mocap_results.MOT_ANGLES``) in degrees,
    rounded as metrics.csv writes them; gaps NaN. Atomically."""
    from photogram.io.mocap_results import angle_columns
    from photogram.io.trajectories import mot_text
    cols = {k: np.round(v, 6) for k, v in angle_columns(times, metrics).items()}
    return atomic_write_text(path, mot_text(Path(path).name, cols))


def write_camera_rotations_mot(path: Path, times, cameras: MocapCameras) -> Path:
    """``camera_rotations.mot``: OpenSim storage of time and, per camera,
    ``<camera>_pan``, ``_tilt``, ``_roll`` in degrees about the world's up
    axis Z (``photogram.io.mocap_results.pan_tilt_roll``: heading of the
    view from +X towards +Y, elevation positive up, roll positive with the
    image's right side up; pan and roll unwrapped over time). Atomically."""
    from photogram.io.mocap_results import camera_rotation_columns
    from photogram.io.trajectories import mot_text
    cols = camera_rotation_columns(times, cameras.names, cameras.rotations(len(times)))
    cols = {k: np.round(v, 6 if k == "time" else 7) + 0.0     # time as metrics.csv; no -0.0
            for k, v in cols.items()}
    return atomic_write_text(path, mot_text(Path(path).name, cols))


def read_limb_lengths(path: Path, skeleton: Skeleton) -> dict:
    table = read_table(path, required=("from", "to", "length"), what="limb lengths table")
    a, b, L = table.text("from"), table.text("to"), table.floats("length", required=True)
    out = {}
    limbs = {tuple(sorted(x)) for x in skeleton.limbs}
    for i in range(len(a)):
        for n in (a[i], b[i]):
            if n not in skeleton.joints:
                raise table.error(i, f"unknown joint '{n}' of skeleton {skeleton.name}",
                                  hint=suggest(n, skeleton.joints, noun="joints"))
        if tuple(sorted((a[i], b[i]))) not in limbs:
            raise table.error(i, f"{a[i]}-{b[i]} is not a limb of skeleton {skeleton.name}")
        if L[i] <= 0:
            raise table.error(i, "length must be > 0")
        out[(a[i], b[i])] = float(L[i])
    return out


def read_joints(path: Path, skeleton: Skeleton):
    """Frames (n,) and joints (n, J, 3) of a joints table (module doc);
    joints missing from the table, and empty cells, are NaN. Columns of
    other joints are ignored.

    Raises
    ------
    InputError
        Missing or non-UTF-8 file, no column ``frame``, a cell that is not a
        finite number, a frame that is not an integer (``file:line``).
    """
    from photogram.project.text_input import read_text
    path = Path(path)
    text = read_text(path, "joints table")
    header = next((ln for ln in text.splitlines()
                   if ln.strip() and not ln.strip().startswith("#")), "")
    try:
        columns = [c.strip() for c in next(csv.reader([header], delimiter=_delimiter(header)),
                                           [])]
    except csv.Error:           # e.g. a cell over 128 KiB: read_table names the line
        columns = []
    table = read_table(path, required=("frame",),
                       optional=[c for c in dict.fromkeys(columns) if c and c != "frame"],
                       what="joints table")
    frame = table.floats("frame", required=True)
    bad = np.flatnonzero((frame != np.round(frame)) | (np.abs(frame) >= 2**31))
    if len(bad):
        raise table.error(int(bad[0]), "frame must be an integer",
                          hint="frames count from 0 upwards")
    if table.has("time"):
        table.floats("time")                     # checked, not used
    X = np.full((len(table), skeleton.n_joints, 3), np.nan)
    for j, name in enumerate(skeleton.joints):
        for k, ax in enumerate("XYZ"):
            col = f"{name}_{ax}"
            if table.has(col):
                X[:, j, k] = table.floats(col)
    return frame.astype(int), X


def write_joints(path: Path, frames, times, X: np.ndarray, skeleton: Skeleton,
                 comment: str | None = None) -> Path:
    cols = {"frame": np.asarray(frames, int), "time": np.round(np.asarray(times, float), 6)}
    for j, name in enumerate(skeleton.joints):
        for k, ax in enumerate("XYZ"):
            cols[f"{name}_{ax}"] = np.round(X[:, j, k], 5)
    return atomic_write_text(path, format_table(cols, comment=comment))
