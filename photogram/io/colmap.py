"""COLMAP text models: ``cameras.txt``, ``images.txt``, ``points3D.txt``.

Layout (``#`` comment lines are skipped)::

    cameras.txt   CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]
    images.txt    IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME
                  X Y POINT3D_ID X Y POINT3D_ID ...        (second line, may be empty)
    points3D.txt  POINT3D_ID X Y Z R G B ERROR IMAGE_ID POINT2D_IDX ...

Conventions (COLMAP's documentation): ``(QW, QX, QY, QZ)`` is the Hamilton
quaternion of the world-to-camera rotation of the OpenCV camera frame and
``T`` its translation, ``x_cv = R X + T``; so ``R_cv = quaternion_to_matrix(q)``,
``t_cv = T``. COLMAP puts the **centre of the top-left pixel at (0.5, 0.5)**,
OpenCV (and photogram's imports from OpenCV, Pose2Sim, BAL) at (0, 0): on
import the principal point and every 2D point are shifted by -0.5 px, on
export by +0.5 px (``pixel_shift``), so that a COLMAP model and a Pose2Sim
or OpenCV calibration of the same camera agree in photogram.

Camera models read: ``SIMPLE_PINHOLE`` (f cx cy), ``PINHOLE`` (fx fy cx cy),
``SIMPLE_RADIAL`` (f cx cy k), ``RADIAL`` (f cx cy k1 k2), ``OPENCV`` (fx fy
cx cy k1 k2 p1 p2) and ``FULL_OPENCV`` with k4 = k5 = k6 = 0; all are
photogram's ``opencv`` model exactly. Fisheye and other models are refused.
Written: ``OPENCV``, or ``FULL_OPENCV`` when k3 is not zero.

Lost on import: 2D points without a 3D point (unmatched features), the
colours and the ERROR column of points3D.txt.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.exchange import LineText, View, build_project, cv_to_station, opencv_camera

__all__ = ["ColmapModel", "read_colmap", "colmap_project", "format_colmap", "write_colmap",
           "PIXEL_SHIFT"]

PIXEL_SHIFT = 0.5
_MODELS = {"SIMPLE_PINHOLE": 3, "PINHOLE": 4, "SIMPLE_RADIAL": 4, "RADIAL": 5, "OPENCV": 8,
           "FULL_OPENCV": 12}
_IMAGE_HEADER = ("# Image list with two lines of data per image:\n"
                 "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
                 "#   POINTS2D[] as (X, Y, POINT3D_ID)\n")


@dataclass
class ColmapModel:
    """A COLMAP model as read: views (one per image, pixel frame already
    shifted to OpenCV's), and points with their tracks."""

    views: list[View]
    image_ids: list[int]
    point_ids: list[str] = field(default_factory=list)
    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rgb: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=int))
    error: np.ndarray = field(default_factory=lambda: np.zeros(0))
    obs_image: list[str] = field(default_factory=list)     # image NAME per observation
    obs_point: list[str] = field(default_factory=list)
    obs_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def _data_lines(text: LineText, keep_blank: bool = False):
    for no, line in enumerate(text.lines, 1):
        s = line.strip()
        if s.startswith("#"):
            continue
        if s or keep_blank:
            yield no, s


def _int(text: LineText, no: int, s: str, what: str) -> int:
    try:
        return int(s)
    except ValueError:
        raise text.error(no, f"{what} {s!r} is not an integer",
                         hint="COLMAP ids are whole numbers (see COLMAP's text format)") from None


def _read_cameras(path: Path, shift: float) -> dict[int, tuple]:
    text = LineText(path, "COLMAP cameras.txt")
    cams = {}
    for no, s in _data_lines(text):
        f = s.split()
        if len(f) < 4:
            raise text.error(no, f"expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], found "
                                 f"{len(f)} fields", hint="the file is truncated")
        cid = _int(text, no, f[0], "CAMERA_ID")
        model = f[1]
        if model not in _MODELS:
            raise text.error(no, f"camera model {model} is not supported",
                             hint=f"supported: {', '.join(_MODELS)}; undistort the images "
                                  f"(colmap image_undistorter) for other models")
        w, h = text.numbers(no, f[2:4], what="WIDTH HEIGHT")
        p = text.numbers(no, f[4:], _MODELS[model], what=f"parameters of {model}")
        if model == "SIMPLE_PINHOLE":
            vals = [p[0], p[0], p[1], p[2]]
        elif model == "PINHOLE":
            vals = p[:4]
        elif model == "SIMPLE_RADIAL":
            vals = [p[0], p[0], p[1], p[2], p[3]]
        elif model == "RADIAL":
            vals = [p[0], p[0], p[1], p[2], p[3], p[4]]
        elif model == "OPENCV":
            vals = p
        else:
            if any(p[9:12]):
                raise text.error(no, "FULL_OPENCV with k4, k5, k6 (rational model) is not "
                                     "supported", hint="only k1, k2, p1, p2, k3")
            vals = p[:9]
        fx, fy, cx, cy = vals[:4]
        K = np.array([[fx, 0.0, cx - shift], [0.0, fy, cy - shift], [0.0, 0.0, 1.0]])
        dist = np.zeros(5)
        dist[:len(vals) - 4] = vals[4:]
        if cid in cams:
            raise text.error(no, f"CAMERA_ID {cid} is given twice")
        cams[cid] = (K, dist, (int(w), int(h)), model, no)
    if not cams:
        raise InputError("no cameras in the file", file=path, line=1)
    return cams


def read_colmap(folder, pixel_shift: float = PIXEL_SHIFT) -> ColmapModel:
    """Read a COLMAP text model from ``folder`` (or the folder of one of its
    files).

    Raises
    ------
    InputError
        Missing files, malformed lines (file and line), unknown camera or
        point ids, unsupported camera models.
    """
    from photogram.geometry import quaternion_to_matrix
    folder = Path(folder)
    if folder.is_file():
        folder = folder.parent
    for f in ("cameras.txt", "images.txt", "points3D.txt"):
        if not (folder / f).is_file():
            raise InputError(f"no {f} here", file=folder,
                             hint="give the folder of a COLMAP text model (colmap "
                                  "model_converter --output_type TXT)")
    cams = _read_cameras(folder / "cameras.txt", pixel_shift)
    text = LineText(folder / "images.txt", "COLMAP images.txt")
    views, image_ids, obs = [], [], []
    lines = list(_data_lines(text, keep_blank=True))
    i = 0
    names = set()
    while i < len(lines):
        no, s = lines[i]
        if not s:
            i += 1
            continue
        f = s.split(maxsplit=9)
        if len(f) < 10:
            raise text.error(no, f"expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, found "
                                 f"{len(f)} fields", hint="the file is truncated")
        iid = _int(text, no, f[0], "IMAGE_ID")
        q = np.array(text.numbers(no, f[1:5], what="QW QX QY QZ"))
        t = np.array(text.numbers(no, f[5:8], what="TX TY TZ"))
        cid = _int(text, no, f[8], "CAMERA_ID")
        if cid not in cams:
            raise text.error(no, f"unknown CAMERA_ID {cid}", hint="not in cameras.txt")
        norm = np.linalg.norm(q)
        if not 0.5 < norm < 2:
            raise text.error(no, f"the quaternion has norm {norm:g}, not 1")
        name = f[9].strip()
        if name in names:
            raise text.error(no, f"image NAME {name} is given twice")
        names.add(name)
        K, dist, size, _, _ = cams[cid]
        views.append(View(name=name, camera=str(cid), K=K, dist=dist,
                          R_cv=quaternion_to_matrix(q / norm), t_cv=t, image_size=size,
                          extra={"image_id": iid, "line": no}))
        image_ids.append(iid)
        pts_no, pts = lines[i + 1] if i + 1 < len(lines) else (no + 1, "")
        values = pts.split()
        if len(values) % 3:
            raise text.error(pts_no, f"POINTS2D needs triples (X, Y, POINT3D_ID), found "
                                     f"{len(values)} values", hint="the file is truncated")
        for k in range(0, len(values), 3):
            x, y = text.numbers(pts_no, values[k:k + 2], what="X Y of a 2D point")
            pid = _int(text, pts_no, values[k + 2], "POINT3D_ID")
            if pid != -1:
                obs.append((name, str(pid), x - pixel_shift, y - pixel_shift, pts_no))
        i += 2
    if not views:
        raise InputError("no images in the file", file=text.path, line=1)
    ptext = LineText(folder / "points3D.txt", "COLMAP points3D.txt")
    ids, xyz, rgb, err = [], [], [], []
    for no, s in _data_lines(ptext):
        f = s.split()
        if len(f) < 8 or (len(f) - 8) % 2:
            raise ptext.error(no, "expected POINT3D_ID X Y Z R G B ERROR (IMAGE_ID POINT2D_IDX)*",
                              hint="the file is truncated")
        ids.append(str(_int(ptext, no, f[0], "POINT3D_ID")))
        v = ptext.numbers(no, f[1:8], what="X Y Z R G B ERROR")
        xyz.append(v[:3])
        rgb.append([int(c) for c in v[3:6]])
        err.append(v[6])
    known = set(ids)
    obs = [o for o in obs if o[1] in known or _unknown_point(text, o)]
    return ColmapModel(views=views, image_ids=image_ids, point_ids=ids,
                       xyz=np.array(xyz, float).reshape(-1, 3),
                       rgb=np.array(rgb, int).reshape(-1, 3), error=np.array(err, float),
                       obs_image=[o[0] for o in obs], obs_point=[o[1] for o in obs],
                       obs_xy=np.array([o[2:4] for o in obs], float).reshape(-1, 2))


def _unknown_point(text: LineText, o) -> bool:
    raise text.error(o[4], f"POINT3D_ID {o[1]} of image {o[0]} is not in points3D.txt")


def colmap_project(folder, name: str | None = None, pixel_shift: float = PIXEL_SHIFT):
    """Import a COLMAP text model as a project: one ``opencv`` camera per
    CAMERA_ID (named by the id), one station per image (named by NAME), the
    3D points as tie points with COLMAP's coordinates as approximations, the
    2D points that have a 3D point as observations; free datum (COLMAP's
    model has no control)."""
    folder = Path(folder)
    if folder.is_file():
        folder = folder.parent
    model = read_colmap(folder, pixel_shift)
    cameras = {}
    for v in model.views:
        if v.camera not in cameras:
            cameras[v.camera] = opencv_camera(v.camera, v.K, v.dist, v.image_size,
                                              source=str(folder / "cameras.txt"))
    poses = [cv_to_station(v.R_cv, v.t_cv) for v in model.views]
    return build_project(name or folder.name, cameras, stations=[v.name for v in model.views],
                         station_camera=[v.camera for v in model.views],
                         angles=np.array([p[0] for p in poses]),
                         X0=np.array([p[1] for p in poses]), point_ids=model.point_ids,
                         xyz=model.xyz, obs_station=model.obs_image, obs_point=model.obs_point,
                         obs_xy=model.obs_xy, length_unit="m", datum="free")


def _r(x) -> str:
    return repr(float(x))


def _integer_ids(names) -> list[int] | None:
    try:
        ids = [int(n) for n in names]
    except ValueError:
        return None
    return ids if len(set(ids)) == len(ids) and all(str(i) == str(n).strip()
                                                    for i, n in zip(ids, names)) else None


def format_colmap(views: list[View], point_ids=(), xyz=None, obs=(), error=None,
                  pixel_shift: float = PIXEL_SHIFT) -> dict[str, str]:
    """Texts of cameras.txt, images.txt and points3D.txt.

    ``obs`` is a list of ``(view index, point index, x, y)`` in photogram's
    (OpenCV's) pixel frame. Camera and point ids are kept where they are
    integers, else numbered from 1; image ids are 1..n in view order.
    """
    from photogram.geometry import matrix_to_quaternion
    cam_names = list(dict.fromkeys(v.camera for v in views))
    cam_ids = _integer_ids(cam_names) or list(range(1, len(cam_names) + 1))
    cid = dict(zip(cam_names, cam_ids))
    lines = ["# Camera list with one line of data per camera:",
             "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
             f"# Number of cameras: {len(cam_names)}"]
    done = set()
    for v in views:
        if v.camera in done:
            continue
        done.add(v.camera)
        K, d = v.K, np.zeros(5)
        d[:min(5, len(v.dist))] = np.asarray(v.dist, float)[:5]
        if v.image_size is None:
            raise InputError(f"camera {v.camera} has no image_size, which COLMAP needs")
        params = [K[0, 0], K[1, 1], K[0, 2] + pixel_shift, K[1, 2] + pixel_shift, *d[:4]]
        model = "OPENCV"
        if d[4] != 0:
            model = "FULL_OPENCV"
            params += [d[4], 0.0, 0.0, 0.0]
        lines.append(" ".join([str(cid[v.camera]), model, str(int(v.image_size[0])),
                               str(int(v.image_size[1]))] + [_r(p) for p in params]))
    cameras_txt = "\n".join(lines) + "\n"

    point_ids = [str(p) for p in point_ids]
    pids = _integer_ids(point_ids) or list(range(1, len(point_ids) + 1))
    per_view: list[list] = [[] for _ in views]
    track: list[list] = [[] for _ in point_ids]
    for vi, pi, x, y in obs:
        track[pi].append((vi + 1, len(per_view[vi])))
        per_view[vi].append((x + pixel_shift, y + pixel_shift, pids[pi]))
    n_obs = sum(len(p) for p in per_view)
    lines = [_IMAGE_HEADER.rstrip("\n"),
             f"# Number of images: {len(views)}, mean observations per image: "
             f"{n_obs / max(len(views), 1):g}"]
    for k, v in enumerate(views):
        q = matrix_to_quaternion(v.R_cv)
        lines.append(" ".join([str(k + 1)] + [_r(c) for c in q] + [_r(c) for c in v.t_cv] +
                              [str(cid[v.camera]), v.name]))
        lines.append(" ".join(f"{_r(x)} {_r(y)} {p}" for x, y, p in per_view[k]))
    images_txt = "\n".join(lines) + "\n"

    xyz = np.zeros((0, 3)) if xyz is None else np.asarray(xyz, float)
    err = np.zeros(len(point_ids)) if error is None else np.asarray(error, float)
    rows, n_track = [], 0
    for i in range(len(point_ids)):
        if not np.all(np.isfinite(xyz[i])) or not track[i]:
            continue                      # COLMAP has no 3D point without a track
        n_track += len(track[i])
        e = err[i] if np.isfinite(err[i]) else 0.0
        rows.append(" ".join([str(pids[i])] + [_r(c) for c in xyz[i]] + ["128", "128", "128",
                                                                          _r(e)] +
                             [f"{a} {b}" for a, b in track[i]]))
    mean_track = n_track / max(len(rows), 1)
    lines = ["# 3D point list with one line of data per point:",
             "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
             f"# Number of points: {len(rows)}, mean track length: {mean_track:g}"] + rows
    return {"cameras.txt": cameras_txt, "images.txt": images_txt,
            "points3D.txt": "\n".join(lines) + "\n"}


def write_colmap(folder, views, point_ids=(), xyz=None, obs=(), error=None, *,
                 force: bool = False, pixel_shift: float = PIXEL_SHIFT) -> Path:
    """Write a COLMAP text model into ``folder`` (created; the three files
    are written atomically; existing ones are refused unless ``force``)."""
    from photogram.io.exchange import write_new_text
    folder = Path(folder)
    texts = format_colmap(views, point_ids, xyz, obs, error, pixel_shift)
    if folder.exists() and not folder.is_dir():
        raise InputError("is a file; COLMAP models are folders", file=folder)
    folder.mkdir(parents=True, exist_ok=True)
    if not force:
        for f in texts:
            if (folder / f).exists():
                raise InputError("file exists", file=folder / f,
                                 hint="choose a new folder, or pass --force")
    for f, t in texts.items():
        write_new_text(folder / f, t, force)
    return folder
