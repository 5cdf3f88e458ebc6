"""COLMAP's binary model files (its default output): ``cameras.bin``,
``images.bin``, ``points3D.bin`` and, COLMAP >= 3.12, ``rigs.bin``,
``frames.bin``; read into and written from
:class:`~photogram.io.colmap_records.Records`.

Layout (little endian; COLMAP's ``src/colmap/scene/reconstruction_io_binary.cc``,
``scripts/python/read_write_model.py``; camera_t, image_t, rig_t, frame_t,
point2D_t are uint32, point3D_t uint64, model ids and sensor types int32)::

    cameras.bin   u64 n, n x (u32 id, i32 model_id, u64 width, u64 height,
                  f64 params[n_params(model)])
    images.bin    u64 n, n x (u32 id, f64 qw qx qy qz tx ty tz, u32 camera_id,
                  name bytes + NUL, u64 m, m x (f64 x, f64 y, u64 point3D_id))
    points3D.bin  u64 n, n x (u64 id, f64 x y z, u8 r g b, f64 error,
                  u64 k, k x (u32 image_id, u32 point2D_idx))
    rigs.bin      u64 n, n x (u32 rig_id, u32 num_sensors,
                  [i32 ref_type, u32 ref_id], (num_sensors - 1) x (i32 type, u32 id,
                  u8 has_pose, [f64 qw qx qy qz tx ty tz]))
    frames.bin    u64 n, n x (u32 frame_id, u32 rig_id, f64 qw qx qy qz tx ty tz,
                  u32 k, k x (i32 sensor_type, u32 sensor_id, u64 data_id))

A point3D_id of 2^64 - 1 is "no 3D point" (-1 in the text files). A file
that ends inside a record is an InputError naming the file and the record.
"""

from __future__ import annotations

import functools
import struct
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.colmap_cameras import COLMAP_CAMERAS, COLMAP_IDS, n_params
from photogram.io.colmap_records import (INVALID_POINT3D, SENSOR_TYPES, CameraRecord,
                                         FrameRecord, ImageRecord, PointRecords, RigRecord)

__all__ = ["read_cameras_bin", "read_images_bin", "read_points_bin", "read_rigs_bin",
           "read_frames_bin", "format_binary"]

_TYPE_IDS = {v: k for k, v in SENSOR_TYPES.items()}


@functools.lru_cache(maxsize=None)
def _struct(fmt: str) -> struct.Struct:
    return struct.Struct("<" + fmt)


@functools.lru_cache(maxsize=None)
def _dtype(fmt: str) -> np.dtype:
    return np.dtype([(f"f{i}", "<" + c) for i, c in enumerate(fmt)])


class _Reader:
    """Sequential little-endian reads of one file; errors name the record."""

    def __init__(self, path: Path, what: str):
        self.path, self.what = Path(path), what
        try:
            self.data = self.path.read_bytes()
        except OSError as exc:
            raise InputError(f"cannot read {what}: {exc.strerror or exc}", file=path) from None
        self.pos = 0
        self.record = 0

    def error(self, what: str, hint: str | None = None) -> InputError:
        where = f"record {self.record}" if self.record else "header"
        return InputError(f"{self.what}, {where} (byte {self.pos}): {what}", file=self.path,
                          hint=hint)

    def take(self, fmt: str):
        st = _struct(fmt)
        if self.pos + st.size > len(self.data):
            raise self.error(f"the file ends {len(self.data) - self.pos} bytes into a "
                             f"{st.size}-byte field", hint="the file is truncated, or not a "
                                                           "COLMAP binary model")
        out = st.unpack_from(self.data, self.pos)
        self.pos += st.size
        return out

    def array(self, fmt: str, count: int) -> np.ndarray:
        dt = _dtype(fmt)
        if self.pos + dt.itemsize * count > len(self.data):
            raise self.error(f"{count} entries of {dt.itemsize} bytes do not fit in the "
                             f"{len(self.data) - self.pos} bytes left",
                             hint="the file is truncated, or not a COLMAP binary model")
        out = np.frombuffer(self.data, dt, count, self.pos)
        self.pos += dt.itemsize * count
        return out

    def name(self) -> str:
        end = self.data.find(b"\0", self.pos)
        if end < 0:
            raise self.error("the image name has no terminating NUL byte",
                             hint="the file is truncated")
        raw = self.data[self.pos:end]
        self.pos = end + 1
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            raise self.error("the image name is not UTF-8") from None

    def count(self, fmt: str = "Q") -> int:
        return self.take(fmt)[0]

    def done(self) -> None:
        if self.pos != len(self.data):
            raise self.error(f"{len(self.data) - self.pos} bytes after the last record",
                             hint="not a COLMAP binary model of this layout")

    def sensor(self) -> tuple[str, int]:
        kind, sid = self.take("iI")
        if kind not in SENSOR_TYPES:
            raise self.error(f"sensor type {kind} is not one of {sorted(SENSOR_TYPES)}")
        return SENSOR_TYPES[kind], sid


def read_cameras_bin(path: Path) -> dict[int, CameraRecord]:
    r = _Reader(path, "COLMAP cameras.bin")
    cams = {}
    for k in range(r.count()):
        r.record = k + 1
        cid, mid, w, h = r.take("IiQQ")
        if mid not in COLMAP_IDS:
            known = ", ".join(f"{n} ({COLMAP_CAMERAS[n][0]})" for n in COLMAP_CAMERAS)
            raise r.error(f"camera model id {mid} is not supported",
                          hint=f"supported: {known}; undistort the images (colmap "
                               f"image_undistorter) for other models")
        model = COLMAP_IDS[mid]
        params = np.array(r.take("d" * n_params(model)))
        if cid in cams:
            raise r.error(f"CAMERA_ID {cid} is given twice")
        if not np.all(np.isfinite(params)):
            raise r.error(f"camera {cid}: a parameter is not a finite number")
        cams[cid] = CameraRecord(cid, model, w, h, params, record=k + 1)
    r.done()
    if not cams:
        raise InputError("no cameras in the file", file=path)
    return cams


def read_images_bin(path: Path) -> list[ImageRecord]:
    r = _Reader(path, "COLMAP images.bin")
    out = []
    for k in range(r.count()):
        r.record = k + 1
        head = r.take("I7dI")
        name = r.name()
        pts = r.array("ddQ", r.count())
        ids = pts["f2"].astype(np.uint64)
        p3d = np.where(ids == np.uint64(INVALID_POINT3D), -1, ids.astype(np.int64))
        out.append(ImageRecord(head[0], np.array(head[1:5]), np.array(head[5:8]), head[8], name,
                               np.column_stack([pts["f0"], pts["f1"]]).astype(float), p3d,
                               record=k + 1))
    r.done()
    if not out:
        raise InputError("no images in the file", file=path)
    return out


def read_points_bin(path: Path) -> PointRecords:
    r = _Reader(path, "COLMAP points3D.bin")
    n = r.count()
    rows, tracks = [], []
    for k in range(n):
        r.record = k + 1
        rows.append(r.take("Q3d3Bd"))
        tracks.append(r.array("I", 2 * r.count())["f0"].astype(np.int64).reshape(-1, 2))
    r.done()
    ids = np.array([v[0] for v in rows], np.uint64).astype(np.int64)
    v = np.array([v[1:] for v in rows], float).reshape(-1, 7)
    return PointRecords(ids=ids, xyz=v[:, :3], rgb=v[:, 3:6].astype(np.int64), error=v[:, 6],
                        tracks=tracks, lines=[None] * n)


def read_rigs_bin(path: Path) -> list[RigRecord]:
    r = _Reader(path, "COLMAP rigs.bin")
    out = []
    for k in range(r.count()):
        r.record = k + 1
        rid, n = r.take("II")
        rig = RigRecord(rid, r.sensor() if n > 0 else None, record=k + 1)
        for _ in range(max(n - 1, 0)):
            kind, sid = r.sensor()
            has = r.take("B")[0]
            pose = r.take("7d") if has else None
            rig.sensors.append((kind, sid, None if pose is None else np.array(pose[:4]),
                                None if pose is None else np.array(pose[4:])))
        out.append(rig)
    r.done()
    return out


def read_frames_bin(path: Path) -> list[FrameRecord]:
    r = _Reader(path, "COLMAP frames.bin")
    out = []
    for k in range(r.count()):
        r.record = k + 1
        fid, rid = r.take("II")
        pose = r.take("7d")
        fr = FrameRecord(fid, rid, np.array(pose[:4]), np.array(pose[4:]), record=k + 1)
        for _ in range(r.count("I")):
            kind, sid = r.sensor()
            fr.data.append((kind, sid, r.take("Q")[0]))
        out.append(fr)
    r.done()
    return out


# --------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------

def _pack(fmt: str, *values) -> bytes:
    return struct.pack("<" + fmt, *values)


def format_binary(rec) -> dict[str, bytes]:
    """Bytes of cameras.bin, images.bin, points3D.bin and, when ``rec`` has
    rigs or frames, rigs.bin and frames.bin."""
    cams = [_pack("Q", len(rec.cameras))]
    for cid in sorted(rec.cameras):
        c = rec.cameras[cid]
        cams.append(_pack("IiQQ", cid, COLMAP_CAMERAS[c.model][0], int(c.width), int(c.height)))
        cams.append(_pack(f"{len(c.params)}d", *map(float, c.params)))
    imgs = [_pack("Q", len(rec.images))]
    for im in rec.images:
        imgs.append(_pack("I7dI", im.image_id, *map(float, im.q), *map(float, im.t),
                          im.camera_id))
        imgs.append(im.name.encode("utf-8") + b"\0")
        imgs.append(_pack("Q", len(im.xy)))
        pts = np.zeros(len(im.xy), np.dtype([("x", "<f8"), ("y", "<f8"), ("id", "<u8")]))
        pts["x"], pts["y"] = im.xy[:, 0], im.xy[:, 1]
        ids = np.asarray(im.point3d, np.int64)
        pts["id"] = np.where(ids < 0, np.uint64(INVALID_POINT3D), ids.astype(np.uint64))
        imgs.append(pts.tobytes())
    p = rec.points
    pts = [_pack("Q", len(p.ids))]
    for i, pid in enumerate(p.ids):
        pts.append(_pack("Q3d3Bd", int(pid), *map(float, p.xyz[i]), *map(int, p.rgb[i]),
                         float(p.error[i])))
        track = np.asarray(p.tracks[i], np.int64).reshape(-1, 2)
        pts.append(_pack("Q", len(track)) + track.astype("<u4").tobytes())
    out = {"cameras.bin": b"".join(cams), "images.bin": b"".join(imgs),
           "points3D.bin": b"".join(pts)}
    if rec.rigs or rec.frames:
        out.update(_format_rigs(rec))
    return out


def _format_rigs(rec) -> dict[str, bytes]:
    rigs = [_pack("Q", len(rec.rigs))]
    for rig in rec.rigs:
        rigs.append(_pack("II", rig.rig_id, len(rig.sensors) + (rig.ref is not None)))
        if rig.ref is not None:
            rigs.append(_pack("iI", _TYPE_IDS[rig.ref[0]], rig.ref[1]))
        for kind, sid, q, t in rig.sensors:
            rigs.append(_pack("iIB", _TYPE_IDS[kind], sid, q is not None))
            if q is not None:
                rigs.append(_pack("7d", *map(float, q), *map(float, t)))
    frames = [_pack("Q", len(rec.frames))]
    for fr in rec.frames:
        frames.append(_pack("II7dI", fr.frame_id, fr.rig_id, *map(float, fr.q),
                            *map(float, fr.t), len(fr.data)))
        for kind, sid, did in fr.data:
            frames.append(_pack("iIQ", _TYPE_IDS[kind], sid, did))
    return {"rigs.bin": b"".join(rigs), "frames.bin": b"".join(frames)}
