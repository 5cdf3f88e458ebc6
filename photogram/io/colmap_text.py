"""COLMAP's text model files: read into and written from
:class:`~photogram.io.colmap_records.Records`.

Layout and conventions: :mod:`photogram.io.colmap_records` (COLMAP's
``reconstruction_io_text.cc``). ``#`` lines are comments; every error names
the file and line. Numbers are written with ``repr`` (the shortest text
that reads back to the same double), so a write-read round trip is exact.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.colmap_cameras import COLMAP_CAMERAS, n_params
from photogram.io.colmap_records import (SENSOR_TYPES, CameraRecord, FrameRecord, ImageRecord,
                                         PointRecords, RigRecord)
from photogram.io.exchange import LineText

__all__ = ["read_cameras_text", "read_images_text", "read_points_text", "read_rigs_text",
           "read_frames_text", "format_text"]

_TYPES = set(SENSOR_TYPES.values())


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


def read_cameras_text(path: Path) -> dict[int, CameraRecord]:
    text = LineText(path, "COLMAP cameras.txt")
    cams = {}
    for no, s in _data_lines(text):
        f = s.split()
        if len(f) < 4:
            raise text.error(no, f"expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], found "
                                 f"{len(f)} fields", hint="the file is truncated")
        cid = _int(text, no, f[0], "CAMERA_ID")
        if f[1] not in COLMAP_CAMERAS:
            raise text.error(no, f"camera model {f[1]} is not supported",
                             hint=f"supported: {', '.join(COLMAP_CAMERAS)}; undistort the "
                                  f"images (colmap image_undistorter) for other models")
        w, h = (_int(text, no, v, "WIDTH HEIGHT") for v in f[2:4])
        p = text.numbers(no, f[4:], n_params(f[1]), what=f"parameters of {f[1]}")
        if cid in cams:
            raise text.error(no, f"CAMERA_ID {cid} is given twice")
        cams[cid] = CameraRecord(cid, f[1], w, h, np.array(p), line=no)
    if not cams:
        raise InputError("no cameras in the file", file=path, line=1)
    return cams


def read_images_text(path: Path) -> list[ImageRecord]:
    text = LineText(path, "COLMAP images.txt")
    lines = list(_data_lines(text, keep_blank=True))
    out, i = [], 0
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
        pts_no, pts = lines[i + 1] if i + 1 < len(lines) else (no + 1, "")
        values = pts.split()
        if len(values) % 3:
            raise text.error(pts_no, f"POINTS2D needs triples (X, Y, POINT3D_ID), found "
                                     f"{len(values)} values", hint="the file is truncated")
        xy = np.array(text.numbers(pts_no, values[0::3] + values[1::3], what="X Y of 2D points"),
                      float).reshape(2, -1).T
        ids = np.array([_int(text, pts_no, v, "POINT3D_ID") for v in values[2::3]], np.int64)
        out.append(ImageRecord(iid, q, t, cid, f[9].strip(), xy, ids, line=no,
                               points_line=pts_no))
        i += 2
    if not out:
        raise InputError("no images in the file", file=path, line=1)
    return out


def read_points_text(path: Path) -> PointRecords:
    text = LineText(path, "COLMAP points3D.txt")
    ids, rows, tracks, nos = [], [], [], []
    for no, s in _data_lines(text):
        f = s.split()
        if len(f) < 8 or (len(f) - 8) % 2:
            raise text.error(no, "expected POINT3D_ID X Y Z R G B ERROR (IMAGE_ID POINT2D_IDX)*",
                             hint="the file is truncated")
        ids.append(_int(text, no, f[0], "POINT3D_ID"))
        rows.append(text.numbers(no, f[1:8], what="X Y Z R G B ERROR"))
        tracks.append(np.array([_int(text, no, v, "track id") for v in f[8:]],
                               np.int64).reshape(-1, 2))
        nos.append(no)
    v = np.array(rows, float).reshape(-1, 7)
    return PointRecords(ids=np.array(ids, np.int64), xyz=v[:, :3], rgb=v[:, 3:6].astype(np.int64),
                        error=v[:, 6], tracks=tracks, lines=nos)


def _sensor_type(text: LineText, no: int, s: str) -> str:
    if s not in _TYPES:
        raise text.error(no, f"sensor type {s!r} is not one of {', '.join(sorted(_TYPES))}")
    return s


def _pose(text: LineText, no: int, fields, what: str):
    v = text.numbers(no, fields, 7, what=what)
    return np.array(v[:4]), np.array(v[4:])


def read_rigs_text(path: Path) -> list[RigRecord]:
    text = LineText(path, "COLMAP rigs.txt")
    out = []
    for no, s in _data_lines(text):
        f = s.split()
        try:
            rid, n = _int(text, no, f[0], "RIG_ID"), _int(text, no, f[1], "NUM_SENSORS")
            rig = RigRecord(rid, None, line=no)
            k = 2
            if n > 0:
                rig.ref = (_sensor_type(text, no, f[k]), _int(text, no, f[k + 1], "SENSOR_ID"))
                k += 2
            for _ in range(n - 1):
                kind = _sensor_type(text, no, f[k])
                sid = _int(text, no, f[k + 1], "SENSOR_ID")
                has = f[k + 2] == "1"
                q, t = _pose(text, no, f[k + 3:k + 10], "QW QX QY QZ TX TY TZ") if has \
                    else (None, None)
                rig.sensors.append((kind, sid, q, t))
                k += 10 if has else 3
        except IndexError:
            raise text.error(no, "the line ends before its NUM_SENSORS sensors",
                             hint="RIG_ID NUM_SENSORS REF_SENSOR_TYPE REF_SENSOR_ID then per "
                                  "sensor SENSOR_TYPE SENSOR_ID HAS_POSE [QW..TZ]") from None
        if k != len(f):
            raise text.error(no, f"{len(f) - k} values after the last sensor")
        out.append(rig)
    return out


def read_frames_text(path: Path) -> list[FrameRecord]:
    text = LineText(path, "COLMAP frames.txt")
    out = []
    for no, s in _data_lines(text):
        f = s.split()
        if len(f) < 10:
            raise text.error(no, f"expected FRAME_ID RIG_ID QW QX QY QZ TX TY TZ NUM_DATA_IDS "
                                 f"DATA_IDS[], found {len(f)} fields")
        q, t = _pose(text, no, f[2:9], "QW QX QY QZ TX TY TZ")
        fr = FrameRecord(_int(text, no, f[0], "FRAME_ID"), _int(text, no, f[1], "RIG_ID"), q, t,
                         line=no)
        n = _int(text, no, f[9], "NUM_DATA_IDS")
        if len(f) != 10 + 3 * n:
            raise text.error(no, f"NUM_DATA_IDS is {n} but {len(f) - 10} values follow, "
                                 f"not {3 * n}", hint="DATA_IDS are (SENSOR_TYPE SENSOR_ID "
                                                      "DATA_ID) triples")
        for k in range(10, len(f), 3):
            fr.data.append((_sensor_type(text, no, f[k]), _int(text, no, f[k + 1], "SENSOR_ID"),
                            _int(text, no, f[k + 2], "DATA_ID")))
        out.append(fr)
    return out


# --------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------

def _r(x) -> str:
    return repr(float(x))


def _rows_pose(q, t) -> list[str]:
    return [_r(c) for c in q] + [_r(c) for c in t]


def format_text(rec) -> dict[str, str]:
    """Texts of cameras.txt, images.txt, points3D.txt and, when ``rec`` has
    rigs and frames, rigs.txt and frames.txt."""
    cams = ["# Camera list with one line of data per camera:",
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
            f"# Number of cameras: {len(rec.cameras)}"]
    for cid in sorted(rec.cameras):
        c = rec.cameras[cid]
        cams.append(" ".join([str(cid), c.model, str(int(c.width)), str(int(c.height))] +
                             [_r(p) for p in c.params]))
    n_obs = sum(int(np.count_nonzero(im.point3d != -1)) for im in rec.images)
    imgs = ["# Image list with two lines of data per image:",
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
            "#   POINTS2D[] as (X, Y, POINT3D_ID)",
            f"# Number of images: {len(rec.images)}, mean observations per image: "
            f"{n_obs / max(len(rec.images), 1):g}"]
    for im in rec.images:
        imgs.append(" ".join([str(im.image_id)] + _rows_pose(im.q, im.t) +
                             [str(im.camera_id), im.name]))
        imgs.append(" ".join(f"{_r(x)} {_r(y)} {int(p)}" for (x, y), p in zip(im.xy, im.point3d)))
    pts = rec.points
    mean_track = sum(len(t) for t in pts.tracks) / max(len(pts.ids), 1)
    rows = ["# 3D point list with one line of data per point:",
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
            f"# Number of points: {len(pts.ids)}, mean track length: {mean_track:g}"]
    for i, pid in enumerate(pts.ids):
        rows.append(" ".join([str(int(pid))] + [_r(c) for c in pts.xyz[i]] +
                             [str(int(c)) for c in pts.rgb[i]] + [_r(pts.error[i])] +
                             [f"{int(a)} {int(b)}" for a, b in pts.tracks[i]]))
    out = {"cameras.txt": "\n".join(cams) + "\n", "images.txt": "\n".join(imgs) + "\n",
           "points3D.txt": "\n".join(rows) + "\n"}
    if rec.rigs or rec.frames:
        out.update(_format_rigs(rec))
    return out


def _format_rigs(rec) -> dict[str, str]:
    rigs = ["# Rig calib list with one line of data per calib:",
            "#   RIG_ID, NUM_SENSORS, REF_SENSOR_TYPE, REF_SENSOR_ID, SENSORS[] as "
            "(SENSOR_TYPE, SENSOR_ID, HAS_POSE, [QW, QX, QY, QZ, TX, TY, TZ])",
            f"# Number of rigs: {len(rec.rigs)}"]
    for rig in rec.rigs:
        f = [str(rig.rig_id), str(len(rig.sensors) + (rig.ref is not None))]
        if rig.ref is not None:
            f += [rig.ref[0], str(rig.ref[1])]
        for kind, sid, q, t in rig.sensors:
            f += [kind, str(sid)] + (["0"] if q is None else ["1"] + _rows_pose(q, t))
        rigs.append(" ".join(f))
    frames = ["# Frame list with one line of data per frame:",
              "#   FRAME_ID, RIG_ID, RIG_FROM_WORLD[QW, QX, QY, QZ, TX, TY, TZ], NUM_DATA_IDS, "
              "DATA_IDS[] as (SENSOR_TYPE, SENSOR_ID, DATA_ID)",
              f"# Number of frames: {len(rec.frames)}"]
    for fr in rec.frames:
        frames.append(" ".join([str(fr.frame_id), str(fr.rig_id)] + _rows_pose(fr.q, fr.t) +
                               [str(len(fr.data))] +
                               [f"{k} {s} {d}" for k, s, d in fr.data]))
    return {"rigs.txt": "\n".join(rigs) + "\n", "frames.txt": "\n".join(frames) + "\n"}
