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
(COLMAP < 3.12), every image is its own rig.

A rig of two or more cameras becomes a project rig (``[rigs.NAME]``,
:mod:`photogram.project.reader_rigs`) and its frames the stations'
``frame`` column (:func:`project_rigs`); the export writes them back
(:func:`rig_records`). photogram's rig frame is the reference camera's
photogrammetric frame (``FLIP = diag(1, -1, -1)`` times COLMAP's), so a
sensor pose in the project is the station of ``(R_s FLIP, t_s)``::

    R_s' = FLIP R_s FLIP,   X0_s' = FLIP (-R_s^T t_s)
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError

__all__ = ["frame_poses", "rig_summary", "project_rigs", "rig_records"]


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


def _multi_camera(rig) -> bool:
    return rig.ref is not None and rig.ref[0] == "CAMERA" and \
        any(kind == "CAMERA" for kind, *_ in rig.sensors)


def rig_summary(records, kept=()) -> str | None:
    """One line on the rigs with more than one camera that the import
    could not keep (not in ``kept``), or None."""
    lost = [r for r in records.rigs if _multi_camera(r) and str(r.rig_id) not in kept]
    if not lost:
        return None
    return (f"{len(lost)} COLMAP rig(s) ({', '.join(str(r.rig_id) for r in lost[:5])}) with a "
            f"frame without an image of the reference camera: imported as independent "
            f"stations, without the rig constraint")


def project_rigs(records, image_ids) -> tuple[dict, list[str]]:
    """The project rigs (``{name: Rig}``, named by RIG_ID, cameras by
    CAMERA_ID) of the multi-camera rigs of ``records`` and the frame
    (FRAME_ID, "" for none) of each image of ``image_ids``. A rig with a
    frame that has no image of its reference camera is left out (its
    images stay independent stations, :func:`rig_summary`)."""
    from photogram.geometry import quaternion_to_matrix
    from photogram.geometry.camera import FLIP_YZ
    from photogram.io.exchange import cv_to_station
    from photogram.project.model import Rig
    rigs, frame_of = {}, {}
    for r in records.rigs:
        if not _multi_camera(r):
            continue
        frames = [f for f in records.frames if f.rig_id == r.rig_id]
        if any(("CAMERA", r.ref[1]) not in [(k, s) for k, s, _ in f.data] for f in frames):
            continue
        sensors = {}
        for kind, sid, q, t in r.sensors:
            if kind == "CAMERA" and q is not None:
                Rs = quaternion_to_matrix(_unit(q))
                angles, X0 = cv_to_station(Rs @ FLIP_YZ, np.asarray(t, float))
                sensors[str(sid)] = (X0, angles)
        name = str(r.rig_id)
        rigs[name] = Rig(name=name, reference=str(r.ref[1]),
                         cameras=[str(sid) for kind, sid, *_ in r.sensors if kind == "CAMERA"],
                         fixed=False, sensors=sensors)
        for f in frames:
            for kind, _, did in f.data:
                if kind == "CAMERA":
                    frame_of[did] = str(f.frame_id)
    return rigs, [frame_of.get(i, "") for i in image_ids]


def rig_records(project, rec) -> None:
    """Add COLMAP's rigs and frames of ``project.rigs`` and the stations'
    frames to ``rec`` (whose images are the stations, by NAME): a rig per
    project rig (ids kept where the names are integers), the sensors'
    poses (HAS_POSE 0 where the project has none), each frame's pose
    ``rig_from_world`` = the pose of its reference camera's image."""
    from photogram.geometry import matrix_to_quaternion
    from photogram.geometry.camera import FLIP_YZ
    from photogram.io.colmap_records import FrameRecord, RigRecord
    from photogram.io.exchange import station_to_cv
    if not project.rigs:
        return
    images = {im.name: im for im in rec.images}
    st = project.stations
    cam_id = {st.camera[i]: images[n].camera_id for i, n in enumerate(st.names)}
    rig_ids = _ids(list(project.rigs))
    for (name, rig), rid in zip(project.rigs.items(), rig_ids):
        sensors = []
        for cam in rig.cameras:
            if cam not in cam_id:
                continue
            if cam in rig.sensors:
                X0, angles = rig.sensors[cam]
                R, t = station_to_cv(angles, X0)
                sensors.append(("CAMERA", cam_id[cam], matrix_to_quaternion(R @ FLIP_YZ), t))
            else:
                sensors.append(("CAMERA", cam_id[cam], None, None))
        rec.rigs.append(RigRecord(rid, ("CAMERA", cam_id.get(rig.reference, 0)), sensors))
    rig_id = dict(zip(project.rigs, rig_ids))
    frames = st.frames()
    names = list(dict.fromkeys(f for f in frames if f))
    for fid, fr in zip(_ids(names), names):
        rows = [i for i, f in enumerate(frames) if f == fr]
        rig = next(n for n, r in project.rigs.items()
                   if st.camera[rows[0]] in [r.reference] + r.cameras)
        ref = next(images[st.names[i]] for i in rows if st.camera[i] == project.rigs[rig].reference)
        data = [("CAMERA", images[st.names[i]].camera_id, images[st.names[i]].image_id)
                for i in rows]
        rec.frames.append(FrameRecord(fid, rig_id[rig], np.array(ref.q, float),
                                      np.array(ref.t, float), data))


def _ids(names) -> list[int]:
    """COLMAP ids (uint32) of ``names``: the names where all are distinct
    whole numbers, else 1..n."""
    try:
        ids = [int(n) for n in names]
    except ValueError:
        ids = []
    ok = len(ids) == len(names) and len(set(ids)) == len(ids) and all(
        str(i) == n and 0 <= i < 2 ** 32 - 1 for i, n in zip(ids, names))
    return ids if ok else list(range(1, len(names) + 1))
