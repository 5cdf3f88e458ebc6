"""COLMAP's rigs and frames (COLMAP >= 3.12): the pose of every image.

A rig is a set of sensors with fixed poses ``sensor_from_rig`` relative to
its reference sensor (identity for the reference); a frame is one exposure
of a rig, with the pose ``rig_from_world`` and the images (data ids) its
cameras took. The pose of an image is (COLMAP's ``Frame::SensorFromWorld``,
``src/colmap/scene/frame.h``)::

    cam_from_world = sensor_from_rig * rig_from_world
    R = R_s R_r,   t = R_s t_r + t_s

When a model has rigs and frames, COLMAP takes the image poses from them
and ignores the pose columns of images.txt / images.bin (which it writes
as the composition); so does this reader. Without rigs.* and frames.*
(COLMAP < 3.12, or photogram's export), every image is its own rig.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError

__all__ = ["frame_poses", "rig_summary"]


def _where(rec, files, kind):
    return dict(file=files.get(kind), line=getattr(rec, "line", None))


def _rig_sensors(rig) -> dict:
    """(type, id) -> (R, t) or None of every sensor of ``rig``."""
    from photogram.geometry import quaternion_to_matrix
    out = {}
    if rig.ref is not None:
        out[rig.ref] = (np.eye(3), np.zeros(3))
    for kind, sid, q, t in rig.sensors:
        out[(kind, sid)] = None if q is None else (quaternion_to_matrix(_unit(q)),
                                                   np.asarray(t, float))
    return out


def _unit(q) -> np.ndarray:
    q = np.asarray(q, float)
    return q / np.linalg.norm(q)


def frame_poses(records) -> tuple[dict, dict]:
    """``{IMAGE_ID: (R_cv, t_cv)}`` of the images in ``records.frames``
    (composed as in the module docstring) and ``{IMAGE_ID: (rig id, frame
    id)}``.

    Images whose sensor has no calibrated pose in its rig (HAS_POSE 0) are
    left out (the caller keeps their images.* pose).

    Raises
    ------
    InputError
        A frame of an unknown rig, a camera that is not a sensor of its
        frame's rig, an image that is in no frame.
    """
    from photogram.geometry import quaternion_to_matrix
    if not records.frames:
        return {}, {}
    files = records.files
    rigs = {r.rig_id: _rig_sensors(r) for r in records.rigs}
    poses, info = {}, {}
    for fr in records.frames:
        if fr.rig_id not in rigs:
            raise InputError(f"frame {fr.frame_id} is of rig {fr.rig_id}, which rigs.* does "
                             f"not list", **_where(fr, files, "frames"))
        Rr, tr = quaternion_to_matrix(_unit(fr.q)), np.asarray(fr.t, float)
        for kind, sid, did in fr.data:
            if kind != "CAMERA":
                continue
            if (kind, sid) not in rigs[fr.rig_id]:
                raise InputError(f"frame {fr.frame_id}: camera {sid} is not a sensor of rig "
                                 f"{fr.rig_id}", **_where(fr, files, "frames"))
            info[did] = (fr.rig_id, fr.frame_id)
            sensor = rigs[fr.rig_id][(kind, sid)]
            if sensor is not None:
                Rs, ts = sensor
                poses[did] = (Rs @ Rr, Rs @ tr + ts)
    missing = [im for im in records.images if im.image_id not in info]
    if missing:
        im = missing[0]
        raise InputError(f"image {im.image_id} ({im.name}) is in no frame of frames.*, and "
                         f"{len(missing)} image(s) in all", file=files.get("frames"),
                         hint="COLMAP needs every registered image in a frame once frames.* "
                              "exists; remove rigs.* and frames.* for one rig per camera")
    return poses, info


def rig_summary(records) -> str | None:
    """One line on the rigs with more than one camera (what the import
    loses), or None."""
    multi = [r for r in records.rigs if len(r.sensors) + (r.ref is not None) > 1]
    if not multi:
        return None
    n = sum(len(r.sensors) + 1 for r in multi)
    return (f"{len(multi)} COLMAP rig(s) with {n} cameras: imported as independent stations; "
            f"the rigs' fixed relative poses (sensor_from_rig) are not kept as a constraint")
