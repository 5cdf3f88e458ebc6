"""COLMAP models, text and binary: import into and export from photogram.

A COLMAP model folder holds ``cameras``, ``images``, ``points3D`` and, from
COLMAP 3.12 on, ``rigs`` and ``frames``, each as ``.bin`` (COLMAP's
default) or ``.txt``; the reader takes the binary files when
``cameras.bin`` is there, else the text ones (as COLMAP's
``Reconstruction::Read``). Layouts: :mod:`photogram.io.colmap_records`,
:mod:`photogram.io.colmap_text`, :mod:`photogram.io.colmap_binary`.

Conventions (COLMAP's documentation): ``(QW, QX, QY, QZ)`` is the Hamilton
quaternion of the world-to-camera rotation of the OpenCV camera frame and
``T`` its translation, ``x_cv = R X + T``; so ``R_cv = quaternion_to_matrix(q)``,
``t_cv = T``. COLMAP puts the **centre of the top-left pixel at (0.5, 0.5)**,
OpenCV (and photogram's imports from OpenCV, Pose2Sim, BAL) at (0, 0): on
import the principal point and every 2D point are shifted by -0.5 px, on
export by +0.5 px (``pixel_shift``), so that a COLMAP model and a Pose2Sim
or OpenCV calibration of the same camera agree in photogram.

Camera models: :mod:`photogram.io.colmap_cameras` (SIMPLE_PINHOLE, PINHOLE,
SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV -> ``opencv`` / ``opencv_full``;
OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE -> ``opencv_fisheye``;
exact both ways; export writes the smallest model that holds the camera).
Rigs: :mod:`photogram.io.colmap_rigs` (image poses composed from the
frames; multi-camera rigs become project rigs, ``[rigs.NAME]``, and the
frames the stations' ``frame`` column; the export writes rigs and frames
back).

Lost on import: 2D points without a 3D point (unmatched features), the
colours and the ERROR column of points3D, non-camera sensors (IMU) of rigs.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io import colmap_binary as binary
from photogram.io import colmap_text as text
from photogram.io.colmap_cameras import (colmap_ties, colmap_to_model, intrinsics_model,
                                         model_camera, model_to_colmap, view_intrinsics)
from photogram.io.colmap_records import CameraRecord, ImageRecord, PointRecords, Records
from photogram.io.colmap_rigs import frame_poses, project_rigs, rig_records, rig_summary
from photogram.io.exchange import View, build_project, cv_to_station

__all__ = ["ColmapModel", "read_colmap", "read_records", "colmap_project", "format_colmap",
           "colmap_records", "write_colmap", "PIXEL_SHIFT", "COLMAP_FILES"]

log = logging.getLogger("photogram")

PIXEL_SHIFT = 0.5
COLMAP_FILES = ("cameras", "images", "points3D")


@dataclass
class ColmapModel:
    """A COLMAP model as read: views (one per image, pixel frame already
    shifted to OpenCV's; ``extra`` has ``image_id``, ``colmap_model``,
    ``model`` and ``params`` (photogram's), ``fisheye``, and ``rig``,
    ``frame`` for images of frames), and points with their tracks."""

    views: list[View]
    image_ids: list[int]
    point_ids: list[str] = field(default_factory=list)
    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rgb: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=int))
    error: np.ndarray = field(default_factory=lambda: np.zeros(0))
    obs_image: list[str] = field(default_factory=list)     # image NAME per observation
    obs_point: list[str] = field(default_factory=list)
    obs_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    records: Records | None = None
    binary: bool = False


def _folder(folder) -> Path:
    folder = Path(folder)
    return folder.parent if folder.is_file() else folder


def read_records(folder) -> tuple[Records, bool]:
    """The records of the COLMAP model in ``folder`` and whether they came
    from the binary files."""
    folder = _folder(folder)
    is_bin = (folder / "cameras.bin").is_file()
    ext = ".bin" if is_bin else ".txt"
    for f in COLMAP_FILES:
        if not (folder / (f + ext)).is_file():
            models = sorted(p.name for p in folder.glob("*") if p.is_dir() and any(
                (p / ("cameras" + e)).is_file() for e in (".bin", ".txt")))
            hint = (f"COLMAP writes one model per sub-folder; give one of: "
                    f"{', '.join(models)}" if models else
                    "give the folder of a COLMAP model (cameras, images, points3D as .bin "
                    "or .txt)")
            raise InputError(f"no {f}{ext} here", file=folder, hint=hint)
    mod = binary if is_bin else text
    sfx = "bin" if is_bin else "text"
    rec = Records(files={k: folder / (k + ext) for k in COLMAP_FILES})
    rec.cameras = getattr(mod, f"read_cameras_{sfx}")(rec.files["cameras"])
    rec.images = getattr(mod, f"read_images_{sfx}")(rec.files["images"])
    rec.points = getattr(mod, f"read_points_{sfx}")(rec.files["points3D"])
    for kind in ("rigs", "frames"):
        if (folder / (kind + ext)).is_file():
            rec.files[kind] = folder / (kind + ext)
            setattr(rec, kind, getattr(mod, f"read_{kind}_{sfx}")(rec.files[kind]))
    return rec, is_bin


def _error(rec: Records, kind: str, item, what: str, hint: str | None = None,
           line: int | None = None) -> InputError:
    """InputError at the line of ``item`` (text; ``line`` if given) or its
    record number (binary)."""
    line = line if line is not None else getattr(item, "line", None)
    if line is None and getattr(item, "record", 0):
        what = f"record {item.record}: {what}"
    return InputError(what, file=rec.files.get(kind), line=line, hint=hint)


def _views(rec: Records, shift: float) -> list[View]:
    from photogram.geometry import quaternion_to_matrix
    cams = {}
    for cid, c in rec.cameras.items():
        model, values = colmap_to_model(c.model, c.params, shift)
        cams[cid] = (model, values, *view_intrinsics(model, values))
    poses, rigs = frame_poses(rec)
    views, names = [], set()
    for im in rec.images:
        if im.camera_id not in cams:
            raise _error(rec, "images", im, f"unknown CAMERA_ID {im.camera_id}",
                         hint="not in cameras")
        norm = np.linalg.norm(im.q)
        if not 0.5 < norm < 2:
            raise _error(rec, "images", im, f"the quaternion has norm {norm:g}, not 1")
        if im.name in names:
            raise _error(rec, "images", im, f"image NAME {im.name} is given twice")
        names.add(im.name)
        R, t = poses.get(im.image_id, (quaternion_to_matrix(im.q / norm), np.asarray(im.t)))
        model, values, K, dist, fisheye = cams[im.camera_id]
        c = rec.cameras[im.camera_id]
        extra = {"image_id": im.image_id, "line": im.line, "colmap_model": c.model,
                 "model": model, "params": values, "fisheye": fisheye}
        if im.image_id in rigs:
            extra["rig"], extra["frame"] = rigs[im.image_id]
        views.append(View(name=im.name, camera=str(im.camera_id), K=K, dist=dist, R_cv=R,
                          t_cv=np.asarray(t, float), image_size=(int(c.width), int(c.height)),
                          extra=extra))
    return views


def read_colmap(folder, pixel_shift: float = PIXEL_SHIFT) -> ColmapModel:
    """Read a COLMAP model (binary or text) from ``folder`` (or the folder
    of one of its files).

    Raises
    ------
    InputError
        Missing files, malformed lines or records (file and line or
        record), unknown camera or point ids, unsupported camera models.
    """
    rec, is_bin = read_records(folder)
    _unique(rec, "images", [im.image_id for im in rec.images], rec.images, "IMAGE_ID")
    pts = rec.points
    _unique(rec, "points3D", pts.ids.tolist(), None, "POINT3D_ID")
    views = _views(rec, pixel_shift)
    obs_image, obs_point, obs_xy = _observations(rec)
    return ColmapModel(views=views, image_ids=[im.image_id for im in rec.images],
                       point_ids=[str(int(p)) for p in pts.ids], xyz=pts.xyz,
                       rgb=pts.rgb, error=pts.error, obs_image=obs_image, obs_point=obs_point,
                       obs_xy=obs_xy - pixel_shift, records=rec, binary=is_bin)


def _unique(rec: Records, kind: str, ids: list, items, what: str) -> None:
    """Refuse an id given twice (naming the line or record of the second)."""
    seen = set()
    for k, i in enumerate(ids):
        if i in seen:
            item = items[k] if items is not None else None
            line = rec.points.lines[k] if items is None and rec.points.lines else None
            if item is None and line is None:
                raise InputError(f"record {k + 1}: {what} {i} is given twice",
                                 file=rec.files.get(kind))
            raise _error(rec, kind, item, f"{what} {i} is given twice", line=line)
        seen.add(i)


def _observations(rec: Records):
    """Image NAME, POINT3D_ID (text) and xy (COLMAP's frame) of every 2D
    point with a 3D point, all images at once."""
    counts = [len(im.point3d) for im in rec.images]
    ids = np.concatenate([np.asarray(im.point3d, np.int64) for im in rec.images])
    xy = np.concatenate([np.asarray(im.xy, float).reshape(-1, 2) for im in rec.images])
    image = np.repeat(np.arange(len(rec.images)), counts)
    keep = ids != -1
    ids, xy, image = ids[keep], xy[keep], image[keep]
    known = np.isin(ids, rec.points.ids)
    if not np.all(known):
        k = int(np.flatnonzero(~known)[0])
        im = rec.images[image[k]]
        raise _error(rec, "images", im, f"POINT3D_ID {ids[k]} of image {im.name} is not in "
                                        f"points3D", line=im.points_line)
    names = [im.name for im in rec.images]
    return [names[i] for i in image], ids.astype(str).tolist(), xy


def colmap_project(folder, name: str | None = None, pixel_shift: float = PIXEL_SHIFT):
    """Import a COLMAP model as a project: one camera per CAMERA_ID (named
    by the id, in the photogram model that holds the COLMAP one exactly),
    one station per image (named by NAME), the 3D points as tie points with
    COLMAP's coordinates as approximations, the 2D points that have a 3D
    point as observations; free datum (COLMAP's model has no control).
    Multi-camera rigs become project rigs and their frames the stations'
    frames (:func:`photogram.io.colmap_rigs.project_rigs`)."""
    folder = _folder(folder)
    model = read_colmap(folder, pixel_shift)
    rigs, frames = project_rigs(model.records, model.image_ids)
    lost = rig_summary(model.records, kept=rigs)
    if lost:
        log.warning(lost)
    cameras = {}
    for v in model.views:
        if v.camera not in cameras:
            cameras[v.camera] = model_camera(v.camera, v.extra["model"], v.extra["params"],
                                             v.image_size,
                                             source=str(model.records.files["cameras"]),
                                             ties=colmap_ties(v.extra["colmap_model"]))
    poses = [cv_to_station(v.R_cv, v.t_cv) for v in model.views]
    project = build_project(name or folder.name, cameras,
                            stations=[v.name for v in model.views],
                            station_camera=[v.camera for v in model.views],
                            angles=np.array([p[0] for p in poses]),
                            X0=np.array([p[1] for p in poses]), point_ids=model.point_ids,
                            xyz=model.xyz, obs_station=model.obs_image,
                            obs_point=model.obs_point, obs_xy=model.obs_xy, length_unit="m",
                            datum="free")
    if rigs:
        project.rigs, project.stations.frame = rigs, frames
    return project


# --------------------------------------------------------------------------
# export
# --------------------------------------------------------------------------

def _integer_ids(names, limit: int = 2 ** 32 - 1) -> list[int] | None:
    """The names as COLMAP ids if all are distinct whole numbers in
    [0, limit) (camera_t, image_t: uint32; point3D_t: uint64 with 2^64-1
    reserved), else None (the caller numbers them)."""
    try:
        ids = [int(n) for n in names]
    except ValueError:
        return None
    ok = all(str(i) == str(n).strip() and 0 <= i < limit for i, n in zip(ids, names))
    return ids if ok and len(set(ids)) == len(ids) else None


def _camera_record(v: View, cid: int, shift: float) -> CameraRecord:
    if v.image_size is None:
        raise InputError(f"camera {v.camera} has no image_size, which COLMAP needs")
    model, values = intrinsics_model(v.K, v.dist, bool(v.extra.get("fisheye")))
    colmap, params = model_to_colmap(model, values, shift, name=v.camera)
    return CameraRecord(cid, colmap, int(v.image_size[0]), int(v.image_size[1]), params)


def colmap_records(views: list[View], point_ids=(), xyz=None, obs=(), error=None,
                   pixel_shift: float = PIXEL_SHIFT, rgb=None) -> Records:
    """The records of a COLMAP model of ``views`` and points.

    ``obs`` is a list of ``(view index, point index, x, y)`` in photogram's
    (OpenCV's) pixel frame. Camera and point ids are kept where they are
    integers, else numbered from 1; image ids likewise from the views'
    ``extra["image_id"]``, else 1..n in view order. Points without a finite
    position or without a track are left out (COLMAP has none such).
    """
    from photogram.geometry import matrix_to_quaternion
    cam_names = list(dict.fromkeys(v.camera for v in views))
    cam_ids = _integer_ids(cam_names) or list(range(1, len(cam_names) + 1))
    cid = dict(zip(cam_names, cam_ids))
    rec = Records()
    for v in views:
        if cid[v.camera] not in rec.cameras:
            rec.cameras[cid[v.camera]] = _camera_record(v, cid[v.camera], pixel_shift)
    image_ids = _integer_ids([v.extra.get("image_id", "") for v in views]) or \
        list(range(1, len(views) + 1))
    point_ids = [str(p) for p in point_ids]
    pids = _integer_ids(point_ids, 2 ** 63 - 1) or list(range(1, len(point_ids) + 1))
    per_view: list[list] = [[] for _ in views]
    track: list[list] = [[] for _ in point_ids]
    for vi, pi, x, y in obs:
        track[pi].append((image_ids[vi], len(per_view[vi])))
        per_view[vi].append((x + pixel_shift, y + pixel_shift, pids[pi]))
    for k, v in enumerate(views):
        pv = np.array(per_view[k], float).reshape(-1, 3)
        rec.images.append(ImageRecord(image_ids[k], matrix_to_quaternion(v.R_cv),
                                      np.asarray(v.t_cv, float), cid[v.camera], v.name,
                                      pv[:, :2], np.array([p[2] for p in per_view[k]],
                                                          np.int64)))
    xyz = np.zeros((0, 3)) if xyz is None else np.asarray(xyz, float)
    err = np.zeros(len(point_ids)) if error is None else np.asarray(error, float)
    keep = [i for i in range(len(point_ids)) if np.all(np.isfinite(xyz[i])) and track[i]]
    colours = np.full((len(point_ids), 3), 128) if rgb is None else np.asarray(rgb)
    rec.points = PointRecords(ids=np.array([pids[i] for i in keep], np.int64),
                              xyz=xyz[keep].reshape(-1, 3),
                              rgb=colours[keep].reshape(-1, 3).astype(np.int64),
                              error=np.where(np.isfinite(err[keep]), err[keep], 0.0),
                              tracks=[np.array(track[i], np.int64) for i in keep])
    return rec


def format_colmap(views: list[View], point_ids=(), xyz=None, obs=(), error=None,
                  pixel_shift: float = PIXEL_SHIFT, binary_files: bool = False) -> dict:
    """Contents of cameras, images and points3D (``.txt`` texts, or
    ``.bin`` bytes with ``binary_files``); see :func:`colmap_records`."""
    rec = colmap_records(views, point_ids, xyz, obs, error, pixel_shift)
    return binary.format_binary(rec) if binary_files else text.format_text(rec)


def write_records(folder, rec: Records, *, binary_files: bool = False,
                  force: bool = False) -> list[Path]:
    """Write ``rec`` into ``folder`` (created; every file written atomically;
    existing ones are refused unless ``force``); returns the files."""
    from photogram.io.exchange import write_new_bytes, write_new_text
    folder = Path(folder)
    files = binary.format_binary(rec) if binary_files else text.format_text(rec)
    if folder.exists() and not folder.is_dir():
        raise InputError("is a file; COLMAP models are folders", file=folder)
    folder.mkdir(parents=True, exist_ok=True)
    if not force:
        for f in files:
            if (folder / f).exists():
                raise InputError("file exists", file=folder / f,
                                 hint="choose a new folder, or pass --force")
    write = write_new_bytes if binary_files else write_new_text
    return [write(folder / f, data, force) for f, data in files.items()]


def write_colmap(folder, views, point_ids=(), xyz=None, obs=(), error=None, *,
                 force: bool = False, pixel_shift: float = PIXEL_SHIFT,
                 binary_files: bool = False, project=None) -> Path:
    """Write a COLMAP model (text, or binary with ``binary_files``) into
    ``folder``; see :func:`colmap_records` and :func:`write_records`. With
    ``project`` (whose stations are the views), its rigs and frames too
    (:func:`photogram.io.colmap_rigs.rig_records`)."""
    rec = colmap_records(views, point_ids, xyz, obs, error, pixel_shift)
    if project is not None:
        rig_records(project, rec)
    write_records(folder, rec, binary_files=binary_files, force=force)
    return Path(folder)


def colmap_views(project) -> list[View]:
    """The stations of ``project`` as views for COLMAP: cameras of model
    opencv, opencv_full and opencv_fisheye exactly, brown fitted and bal
    exactly through OpenCV's model
    (:func:`photogram.io.colmap_cameras.camera_intrinsics`)."""
    from photogram.io.colmap_cameras import camera_intrinsics
    from photogram.io.exchange import station_to_cv
    st = project.stations
    intrinsics, views = {}, []
    for i, name in enumerate(st.names):
        if not (np.all(np.isfinite(st.position[i])) and np.all(np.isfinite(st.angles[i]))):
            raise InputError(f"station {name} has no orientation to export",
                             file=project.path,
                             hint="export a results folder of calibrate, orient or intersect")
        cam = project.cameras[st.camera[i]]
        if cam.name not in intrinsics:
            intrinsics[cam.name] = camera_intrinsics(cam, project.units.image)
        K, dist, fisheye, misfit = intrinsics[cam.name]
        R_cv, t_cv = station_to_cv(st.angles[i], st.position[i])
        views.append(View(name=name, camera=cam.name, K=K, dist=dist, R_cv=R_cv, t_cv=t_cv,
                          image_size=cam.image_size,
                          extra={"misfit_px": misfit, "fisheye": fisheye}))
    return views
