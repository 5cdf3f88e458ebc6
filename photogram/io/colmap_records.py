"""The records of a COLMAP model as its files hold them, text or binary.

One record type per file (COLMAP's ``src/colmap/scene/reconstruction_io_text.cc``
and ``reconstruction_io_binary.cc``, COLMAP >= 3.12 for rigs and frames):

* ``cameras``  CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]
* ``images``   IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, POINTS2D[] as
  (X, Y, POINT3D_ID) (-1: no 3D point)
* ``points3D`` POINT3D_ID X Y Z R G B ERROR TRACK[] as (IMAGE_ID, POINT2D_IDX)
* ``rigs``     RIG_ID NUM_SENSORS REF_SENSOR_TYPE REF_SENSOR_ID SENSORS[] as
  (SENSOR_TYPE SENSOR_ID HAS_POSE [QW QX QY QZ TX TY TZ]) (sensor_from_rig)
* ``frames``   FRAME_ID RIG_ID QW QX QY QZ TX TY TZ (rig_from_world)
  NUM_DATA_IDS DATA_IDS[] as (SENSOR_TYPE SENSOR_ID DATA_ID)

The readers (:mod:`photogram.io.colmap_text`,
:mod:`photogram.io.colmap_binary`) fill :class:`Records`; the writers
format them. Poses are COLMAP's: Hamilton quaternion (w, x, y, z) and
translation of ``x_target = R x_source + t`` in OpenCV's camera frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CameraRecord", "ImageRecord", "PointRecords", "RigRecord", "FrameRecord",
           "Records", "SENSOR_TYPES", "INVALID_POINT3D"]

#: COLMAP's SensorType (enum value -> name), MAKE_ENUM_CLASS(SensorType, -1, ...)
SENSOR_TYPES = {-1: "INVALID", 0: "CAMERA", 1: "IMU"}
#: kInvalidPoint3DId = max uint64 (-1 in the text files and as int64)
INVALID_POINT3D = 2 ** 64 - 1


@dataclass
class CameraRecord:
    camera_id: int
    model: str
    width: int
    height: int
    params: np.ndarray
    line: int | None = None          # text line, or None (binary: see ``record``)
    record: int = 0


@dataclass
class ImageRecord:
    image_id: int
    q: np.ndarray                    # cam_from_world (w, x, y, z)
    t: np.ndarray
    camera_id: int
    name: str
    xy: np.ndarray                   # (n, 2), COLMAP's pixel frame
    point3d: np.ndarray              # (n,) int64, -1 where there is none
    line: int | None = None
    points_line: int | None = None
    record: int = 0


@dataclass
class PointRecords:
    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rgb: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    error: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tracks: list = field(default_factory=list)      # (k, 2) int arrays (IMAGE_ID, POINT2D_IDX)
    lines: list = field(default_factory=list)


@dataclass
class RigRecord:
    rig_id: int
    ref: tuple[str, int] | None                      # (sensor type, sensor id)
    sensors: list = field(default_factory=list)      # (type, id, q or None, t or None)
    line: int | None = None
    record: int = 0


@dataclass
class FrameRecord:
    frame_id: int
    rig_id: int
    q: np.ndarray                                    # rig_from_world (w, x, y, z)
    t: np.ndarray
    data: list = field(default_factory=list)         # (type, sensor id, data id)
    line: int | None = None
    record: int = 0


@dataclass
class Records:
    """Everything a COLMAP model folder holds; ``files`` maps each kind
    (cameras, images, points3D, rigs, frames) to the file it was read from."""

    cameras: dict = field(default_factory=dict)      # CAMERA_ID -> CameraRecord
    images: list = field(default_factory=list)
    points: PointRecords = field(default_factory=PointRecords)
    rigs: list = field(default_factory=list)
    frames: list = field(default_factory=list)
    files: dict = field(default_factory=dict)
