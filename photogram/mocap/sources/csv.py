"""Detections in one CSV table (long format), in full-image pixels::

    frame,camera,joint,x,y,confidence[,person]
    0,C1,head,1012.4,388.1,0.93
    0,C1,neck,1010.9,421.7,0.91

``frame`` integers (the first frame of the file is frame 0 of the
sequence; gaps are frames without detections; the frames of a table span
at most :data:`MAX_FRAMES`), ``camera`` names of the
project's cameras, ``joint`` names of the source skeleton (or 0-based
indices), ``confidence`` in [0, 1] (0 or empty: not detected), ``person``
optional ids when a camera sees several people. Comment lines start with
``#``. The same layout is written by the simulator (projects/ski-ptz).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import Skeleton
from photogram.mocap.sources.base import ObservationSource
from photogram.mocap.tracking.detections import CameraDetections
from photogram.project.tables import read_table, suggest

__all__ = ["CsvSource", "COLUMNS"]

COLUMNS = ("frame", "camera", "joint", "x", "y", "confidence")
MAX_FRAMES = 100_000        # frames a table may span (33 min at 50 fps)


class CsvSource(ObservationSource):
    """Detections of all cameras from one table (module doc)."""

    kind = "csv"

    def __init__(self, path: Path, skeleton: Skeleton, cameras: list[str]):
        self.path = Path(path)
        self.skeleton = skeleton
        table = read_table(self.path, required=COLUMNS, optional=("person",),
                           what="detections table")
        frame = table.floats("frame", required=True)
        bad = np.flatnonzero(frame != np.round(frame))
        if len(bad):
            raise table.error(int(bad[0]), "frame must be an integer")
        if len(frame):
            # a frame far from the others (a typo, 1e300) would make the
            # sequence absurdly long: name its row
            mid = np.median(frame)
            far = int(np.argmax(np.abs(frame - mid)))
            if not abs(frame[far]) < 2**31 or np.ptp(frame) >= MAX_FRAMES:
                raise table.error(far, f"frame {table.cells('frame')[far]} is out of range: "
                                       f"the frames of a table span at most {MAX_FRAMES}",
                                  hint="frames count from 0 (or the first frame) upwards")
        frame = frame.astype(int)
        cams = np.array(table.text("camera"))
        known = set(cameras)
        for name in np.unique(cams):
            if name not in known:
                i = int(np.flatnonzero(cams == name)[0])
                raise table.error(i, f"unknown camera '{name}'",
                                  hint=suggest(name, cameras, noun="cameras"))
        names = table.text("joint")
        index = {n: k for k, n in enumerate(skeleton.joints)}
        index.update({str(k): k for k in range(skeleton.n_joints)})
        joint = np.empty(len(names), int)
        for i, n in enumerate(names):
            if n not in index:
                raise table.error(i, f"unknown joint '{n}' of skeleton {skeleton.name}",
                                  hint=suggest(n, skeleton.joints, noun="joints"))
            joint[i] = index[n]
        xy = np.stack([table.floats("x"), table.floats("y")], -1)
        conf = np.nan_to_num(table.floats("confidence"))
        person = table.floats("person") if table.has("person") else np.full(len(frame), -1.0)
        person = np.where(np.isfinite(person), person, -1).astype(int)
        self.first_frame = int(frame.min())
        self.n_frames = int(frame.max()) - self.first_frame + 1
        self._rows = (frame - self.first_frame, cams, joint, xy, conf, person)
        self.cameras = [c for c in cameras if c in set(cams.tolist())]
        if not self.cameras:
            raise InputError("the detections table has no rows", file=self.path)

    def detections(self, camera: str) -> CameraDetections:
        frame, cams, joint, xy, conf, person = self._rows
        sel = cams == camera
        f, j, p = frame[sel], joint[sel], person[sel]
        keys, inverse = np.unique(np.stack([f, p], 1), axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        joints = np.full((len(keys), self.skeleton.n_joints, 3), np.nan)
        joints[..., 2] = 0.0
        ok = conf[sel] > 0
        joints[inverse[ok], j[ok], :2] = xy[sel][ok]
        joints[inverse[ok], j[ok], 2] = conf[sel][ok]
        return CameraDetections.from_joints(camera, self.skeleton, keys[:, 0], joints,
                                            self.n_frames, person=keys[:, 1])
