"""``[rigs.NAME]``: cameras rigidly mounted together, and the ``frame``
column of the stations table (COLMAP's rigs and frames; docs/project-files.md)::

    [rigs.head]
    reference = "left"         # the camera whose frame is the rig's
    cameras = ["right", "top"] # the other cameras of the rig
    fixed = false              # true: the sensor poses are held at `sensors`
    sensors = { right = [0.12, 0.0, 0.0, 0.0, 2.5, 0.0] }
                               # X0 Y0 Z0 omega phi kappa of a camera in the rig
                               # (length_unit, angle_unit, rotation_direction as
                               # the stations table); absent: unknown (fixed = false)

Every station of a rig camera names its frame (one exposure of the rig) in
the stations table's ``frame`` column; a frame holds at most one image of
each camera of one rig, one of them of the reference camera.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import InputError
from photogram.project.camera_schema import invert_opk
from photogram.project.model import Project, Rig
from photogram.project.tables import angle_to_rad
from photogram.project.text_input import suggest
from photogram.project.toml_source import Section

__all__ = ["RIG_KEYS", "read_rigs", "check_frames", "rig_of_camera"]

RIG_KEYS = ("reference", "cameras", "fixed", "sensors")


def _camera(sec: Section, key: str, name, project: Project) -> str:
    if not isinstance(name, str) or name not in project.cameras:
        raise sec.error(key, f"{sec.label}: unknown camera '{name}'",
                        hint=suggest(str(name), project.cameras, noun="cameras in the .prj"))
    return name


def _sensor_pose(sec: Section, cam: str, value, project: Project):
    if not (isinstance(value, list) and len(value) == 6 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise sec.error("sensors", f"{sec.label}: the pose of camera {cam} must be 6 numbers "
                                   "X0 Y0 Z0 omega phi kappa",
                        hint=f"e.g. {cam} = [0.12, 0.0, 0.0, 0.0, 2.5, 0.0]")
    angles = np.array([angle_to_rad(repr(float(v)), project.units.angle) for v in value[3:]])
    if project.rotation_direction == "camera_to_world":
        angles = invert_opk(angles[None])[0]
    return np.asarray(value[:3], float), angles


def _read_rig(sec: Section, project: Project) -> Rig:
    sec.check_keys(RIG_KEYS, required=("reference", "cameras"))
    ref = _camera(sec, "reference", sec.data["reference"], project)
    cams = sec.data["cameras"]
    if not isinstance(cams, list) or not cams:
        raise sec.error("cameras", f"{sec.label}: cameras must be a list of the rig's other "
                                   "cameras", hint='e.g. cameras = ["right"]')
    cams = [_camera(sec, "cameras", c, project) for c in cams]
    if ref in cams or len(set(cams)) < len(cams):
        twice = ref if ref in cams else next(c for c in cams if cams.count(c) > 1)
        raise sec.error("cameras", f"{sec.label}: camera {twice} is named twice",
                        hint="reference names the rig's reference camera, cameras the others, "
                             "each once")
    fixed = sec.boolean("fixed", False)
    sensors = {}
    given = sec.data.get("sensors", {})
    if not isinstance(given, dict):
        raise sec.error("sensors", f"{sec.label}: sensors must be a table camera = [X0, Y0, "
                                   "Z0, omega, phi, kappa]")
    for cam, value in given.items():
        if cam not in cams:
            raise sec.error("sensors", f"{sec.label}: sensors names camera {cam}, which is not "
                                       f"one of the rig's cameras",
                            hint="the reference camera's pose is the identity; give the others")
        sensors[cam] = _sensor_pose(sec, cam, value, project)
    if fixed and len(sensors) < len(cams):
        miss = next(c for c in cams if c not in sensors)
        raise sec.error("fixed", f"{sec.label}: fixed = true but camera {miss} has no pose in "
                                 "sensors", hint="give every camera's pose, or fixed = false")
    return Rig(name=sec.keypath[-1], reference=ref, cameras=cams, fixed=fixed, sensors=sensors,
               line=sec.source.line_of(sec.keypath))


def read_rigs(sec: Section | None, project: Project) -> None:
    """``[rigs.NAME]`` into ``project.rigs``; every camera in one rig at most."""
    if sec is None:
        return
    owner = {}
    for name in sec.data:
        rig = _read_rig(sec.table(name), project)
        for cam in [rig.reference] + rig.cameras:
            if cam in owner:
                raise sec.error(name, f"camera {cam} is in rigs {owner[cam]} and {name}",
                                hint="a camera is mounted on one rig")
            owner[cam] = name
        project.rigs[name] = rig


def rig_of_camera(project: Project) -> dict[str, str]:
    """camera -> the name of its rig (rig cameras only)."""
    return {c: name for name, r in project.rigs.items() for c in [r.reference] + r.cameras}


def check_frames(project: Project) -> None:
    """The ``frame`` column against ``[rigs]`` (module doc).

    Raises
    ------
    InputError
        At the station's line: a frame without rigs, a station of a rig
        camera without a frame (or the reverse), a frame of two rigs, two
        images of one camera in a frame, a frame without its reference
        camera.
    """
    st = project.stations
    frames = st.frames()
    if not project.rigs and not any(frames):
        return
    file = project.sources.get("stations", project.path)

    def fail(i, what, hint):
        line = int(st.record[i]) if len(st.record) > i else None
        return InputError(what, file=file, line=line, hint=hint)

    owner = rig_of_camera(project)
    members: dict[str, list[int]] = {}
    for i, (name, cam, fr) in enumerate(zip(st.names, st.camera, frames)):
        if fr and cam not in owner:
            raise fail(i, f"station {name} is in frame {fr} but its camera {cam} is in no rig",
                       "add the camera to a [rigs.NAME] section, or leave its frame empty")
        if cam in owner and not fr:
            raise fail(i, f"station {name} of camera {cam} (rig {owner[cam]}) names no frame",
                       "give its exposure in the stations table's frame column")
        if fr:
            members.setdefault(fr, []).append(i)
    for fr, rows in members.items():
        rigs = {owner[st.camera[i]] for i in rows}
        if len(rigs) > 1:
            raise fail(rows[-1], f"frame {fr} holds images of rigs {', '.join(sorted(rigs))}",
                       "a frame is one exposure of one rig")
        cams = [st.camera[i] for i in rows]
        for i in rows:
            if cams.count(st.camera[i]) > 1:
                raise fail(rows[[st.camera[j] for j in rows].index(st.camera[i], cams.index(
                    st.camera[i]) + 1)], f"frame {fr} has two images of camera {st.camera[i]}",
                    "a frame holds one image per camera of its rig")
        rig = project.rigs[rigs.pop()]
        if rig.reference not in cams:
            raise fail(rows[0], f"frame {fr} has no image of its rig's reference camera "
                                f"{rig.reference}",
                       "every frame needs the reference camera's image (its pose is the frame's)")
