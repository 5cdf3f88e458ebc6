"""The rig constraint of a project (``[rigs.NAME]`` and the stations'
``frame`` column, :mod:`photogram.project.reader_rigs`) as engine blocks
(:mod:`photogram.adjust.rig_blocks`).

As COLMAP parametrises a rig: the pose of each frame (``rig_from_world``)
and of each non-reference camera in the rig (``sensor_from_rig``) are the
unknowns; the reference camera's pose in the rig is the identity. Here the
frame pose *is* the station of the frame's reference image (its frame is
the rig's), so that a frame needs no extra block; each non-reference camera
adds one station block (its sensor pose) after the project's stations; the
stations of the other images are *derived*: their columns are held fixed
and their values are the composition (eq. (1) of
:mod:`~photogram.adjust.rig_blocks`), kept by every state update
(:meth:`photogram.adjust.state.State.updated`). Per rig: 6 unknowns per
frame and 6 per non-reference camera, instead of 6 per image.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError
from photogram.geometry import opk_to_matrix

__all__ = ["RigPlan", "rig_plan", "rig_warnings", "check_dependent_datum"]


@dataclass
class RigPlan:
    """The rig unknowns of a project (module doc)."""

    n_stations: int                     # the project's stations (sensors follow)
    derived: np.ndarray                 # (n_d,) stations given by the composition
    frame: np.ndarray                   # (n_d,) their frame's station (reference image)
    sensor: np.ndarray                  # (n_d,) their sensor (0-based, after the stations)
    sensors: list = field(default_factory=list)    # (rig name, camera) per sensor
    R: np.ndarray = None                # (n_sensors, 3, 3) start: rig-to-camera
    X0: np.ndarray = None               # (n_sensors, 3) start: centre in the rig
    fixed: np.ndarray = None            # (n_sensors,) bool

    @property
    def n_sensors(self) -> int:
        return len(self.sensors)

    def sensor_station(self) -> np.ndarray:
        """The state's station index of each derived image's sensor."""
        return self.n_stations + self.sensor


def _start_pose(project, rig, cam, frames, R, X0):
    """A sensor's start pose: the project's, else the relative pose of the
    first frame with both its image and the reference image
    (``R_s = R_i R_f^T``, ``X0_s = R_f (X0_i - X0_f)``)."""
    if cam in rig.sensors:
        position, angles = rig.sensors[cam]
        return opk_to_matrix(np.asarray(angles, float)), np.asarray(position, float)
    st = project.stations
    for rows in frames.values():
        cams = [st.camera[i] for i in rows]
        if cam in cams and rig.reference in cams:
            i, f = rows[cams.index(cam)], rows[cams.index(rig.reference)]
            return R[i] @ R[f].T, R[f] @ (X0[i] - X0[f])
    return None


def rig_plan(project, R, X0) -> RigPlan | None:
    """The rig unknowns of ``project`` with the stations' start poses
    ``R``, ``X0`` (None without rigs or frames). A camera none of whose
    frames holds the reference image too has no start: its images stay
    free stations (a sensor needs one frame with both)."""
    st = project.stations
    frame_names = st.frames()
    if not project.rigs or not any(frame_names):
        return None
    frames: dict[str, list[int]] = {}
    for i, fr in enumerate(frame_names):
        if fr:
            frames.setdefault(fr, []).append(i)
    sensors, R_s, X0_s, fixed, index = [], [], [], [], {}
    for name, rig in project.rigs.items():
        for cam in rig.cameras:
            start = _start_pose(project, rig, cam, frames, R, X0)
            if start is None:
                continue
            index[cam] = len(sensors)
            sensors.append((name, cam))
            R_s.append(start[0])
            X0_s.append(start[1])
            fixed.append(rig.fixed)
    derived, frame, sensor = [], [], []
    for rows in frames.values():
        cams = [st.camera[i] for i in rows]
        rig = next(r for r in project.rigs.values() if cams[0] in [r.reference] + r.cameras)
        ref = rows[cams.index(rig.reference)]
        for i, cam in zip(rows, cams):
            if cam != rig.reference and cam in index:
                derived.append(i)
                frame.append(ref)
                sensor.append(index[cam])
    if not derived:
        return None
    return RigPlan(len(st), np.array(derived, int), np.array(frame, int), np.array(sensor, int),
                   sensors, np.array(R_s).reshape(-1, 3, 3), np.array(X0_s).reshape(-1, 3),
                   np.array(fixed, bool))


def rig_warnings(plan, station_sigma, eccentricity=False) -> list[str]:
    """What the rigs leave out: a-priori sigmas of rig images' stations
    other than the reference (their pose is composed) and the ellipse-centre
    correction of their image points (not implemented); 0-2 warnings."""
    if plan is None:
        return []
    out = []
    sig = station_sigma[plan.derived]
    n = int(np.any(np.isfinite(sig) & (sig > 0), axis=1).sum())
    if n:
        out.append(f"{n} station(s) of rig cameras other than the reference have a-priori "
                   f"sigmas, which are not used: their pose is their frame's and their "
                   f"camera's in the rig")
    if eccentricity:
        out.append(f"[targets] eccentricity is not applied to the image points of the "
                   f"{len(plan.derived)} image(s) of rig cameras other than the reference "
                   f"(not implemented with rigs)")
    return out


def check_dependent_datum(project, plan, dependent) -> None:
    """``datum = "dependent"`` holds parameters of stations fixed: they
    must be free stations (a rig image's pose is composed, its own
    parameters are no unknowns)."""
    derived = set(plan.derived.tolist())
    bad = sorted({project.stations.names[j] for j, _ in dependent if j in derived})
    if bad:
        names = ", ".join(bad)
        raise InputError(f'datum = "dependent" fixes station(s) {names}, images of rig '
                         "cameras whose pose is their frame's and camera's in the rig",
                         file=project.path,
                         hint="as dependent_station (and with dependent_coordinate for the "
                              "other fixed coordinate) choose stations of a rig's reference "
                              "camera or of a camera in no rig")
