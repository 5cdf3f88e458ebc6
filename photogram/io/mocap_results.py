"""The results folder of ``photogram mocap`` as trajectories for export
(TRC, C3D, CSV, .mot; :mod:`photogram.io.trajectories`).

Read from the files only (``joints3d.csv``, ``metrics.csv``,
``summary.json``; docs/mocap.md, section 8), so that the exporters do not
depend on the motion-capture pipeline:

* markers: every joint of ``joints3d.csv`` (``frame, time, <joint>_X/_Y/_Z``
  in the project's length unit, world axes, Z up), converted to metres;
  exposures are the frame numbers; empty cells stay gaps;
* sigmas: unknown (the reconstruction gives none): NaN, i.e. empty CSV
  cells and the C3D residual 0 ("not computed") of valid samples;
* .mot columns from ``metrics.csv``: the angles (degrees, as written),
  ``speed`` (length unit per second, converted to m/s), the centre of mass
  ``com_x/y/z`` and ``fore_aft_distance`` converted to metres.

The frame rate (TRC ``DataRate``, C3D ``POINT:RATE``) is ``fps`` of
``summary.json`` when the times step by 1/fps (joints3d.csv rounds them to
1e-6 s, which would make 60 fps read as 59.9988), else it comes from the
times.

The length unit is read from ``summary.json`` (``project.length_unit`` or
``length_unit``), else from the comment of ``joints3d.csv`` (``# 3D joints
(m, world axes, Z up) ...``), else from the ``Units`` of ``joints3d.trc``;
a folder that gives none is refused rather than guessed.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.model import LENGTH_UNITS

__all__ = ["is_mocap_results", "load_mocap_trajectories", "MOT_ANGLES", "angle_columns",
           "pan_tilt_roll", "camera_rotation_columns"]

#: metrics.csv columns that are angles in degrees
MOT_ANGLES = ("knee_flexion_r", "knee_flexion_l", "hip_flexion_r", "hip_flexion_l", "lean",
              "fore_aft_angle")
_LENGTHS = ("com_x", "com_y", "com_z", "fore_aft_distance")
_COMMENT_UNIT = re.compile(r"^#.*\(\s*(m|dm|cm|mm)\s*,")


def is_mocap_results(folder: Path, summary: dict) -> bool:
    """A results folder of photogram mocap (its summary.json says so, or it
    holds joints3d.csv and no points3d.csv)."""
    folder = Path(folder)
    if summary.get("command") == "mocap":
        return True
    return (folder / "joints3d.csv").is_file() and not (folder / "points3d.csv").is_file()


def _length_unit(folder: Path, summary: dict) -> str:
    info = summary.get("project")
    for value in ((info or {}).get("length_unit") if isinstance(info, dict) else None,
                  summary.get("length_unit")):
        if value is not None:
            if value not in LENGTH_UNITS:
                raise InputError(f"unknown length unit {value!r}", file=folder / "summary.json",
                                 hint=f"use one of {', '.join(LENGTH_UNITS)}")
            return str(value)
    joints = folder / "joints3d.csv"
    try:
        with joints.open(encoding="utf-8") as handle:
            for line in handle:
                if not line.startswith("#"):
                    break
                m = _COMMENT_UNIT.match(line)
                if m:
                    return m.group(1)
    except (OSError, UnicodeDecodeError):
        pass
    trc = folder / "joints3d.trc"
    if trc.is_file():
        from photogram.io.trc import read_trc
        try:
            unit = read_trc(trc).units
        except InputError:
            unit = None
        if unit in LENGTH_UNITS:
            return unit
    raise InputError("cannot tell the length unit of the joints", file=joints,
                     hint="summary.json (length_unit), the comment of joints3d.csv or "
                          "joints3d.trc must give it; rerun photogram mocap")


def load_mocap_trajectories(folder, summary: dict, read_csv):
    """:class:`~photogram.io.trajectories.Trajectories` of a mocap results
    folder (module doc); ``read_csv(path, required, ids)`` is the table
    reader of :mod:`photogram.io.trajectories`.

    Raises
    ------
    InputError
        No joints3d.csv, missing or malformed columns, repeated or
        decreasing times, no length unit.
    """
    from photogram.io.trajectory_data import Trajectories
    folder = Path(folder)
    path = folder / "joints3d.csv"
    if not path.is_file():
        raise InputError("no joints3d.csv in this mocap results folder", file=folder,
                         hint="rerun photogram mocap; its results folder holds joints3d.csv")
    unit = _length_unit(folder, summary)
    to_m = LENGTH_UNITS[unit]
    table = read_csv(path, ("frame", "time"), ())
    times = table["time"].to_numpy(float)
    if not np.all(np.isfinite(times)):
        row = int(np.flatnonzero(~np.isfinite(times))[0])
        raise InputError("a frame without a time", file=path, line=row + 2)
    if np.any(np.diff(times) <= 0):
        row = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise InputError("the times do not increase", file=path, line=row + 2)
    frames = table["frame"].to_numpy(float)
    joints = [c[:-2] for c in table.columns if c.endswith("_X")]
    joints = [j for j in joints if f"{j}_Y" in table.columns and f"{j}_Z" in table.columns]
    if not joints:
        raise InputError("no joint columns (<joint>_X, _Y, _Z)", file=path, line=1)
    n = len(times)
    markers = {j: table[[f"{j}_X", f"{j}_Y", f"{j}_Z"]].to_numpy(float) * to_m for j in joints}
    sigma = {j: np.full((n, 3), np.nan) for j in joints}
    name = summary.get("project")
    name = name.get("name") if isinstance(name, dict) else name
    traj = Trajectories(times=times, exposures=[str(int(f)) for f in frames], markers=markers,
                        sigma=sigma, angle_unit="deg", length_unit=unit,
                        name=str(name or folder.parent.name))
    traj.cameras = {j: np.zeros(n, dtype=int) for j in joints}
    traj.mot = _mot_columns(folder / "metrics.csv", times, to_m, read_csv)
    fps = summary.get("fps")
    if isinstance(fps, (int, float)) and not isinstance(fps, bool) and np.isfinite(fps) \
            and fps > 0 and n > 1 and np.allclose(np.diff(times), 1.0 / fps, rtol=0,
                                                  atol=2e-6):
        traj.fps = float(fps)          # the project's rate: times are rounded to 1e-6 s
    return traj


def _mot_columns(path: Path, times, to_m: float, read_csv):
    """``{column: values}`` for the .mot file (degrees, m, m/s), or None."""
    if not path.is_file():
        return None
    table = read_csv(path, ("time",), ("outside", "gap_joints"))
    t = table["time"].to_numpy(float)
    if len(t) != len(times) or not np.allclose(t, times, rtol=0, atol=1e-5):
        raise InputError("metrics.csv and joints3d.csv have different frames or times",
                         file=path, hint="both come from one photogram mocap run; rerun it")
    cols = {"time": times}
    for c in table.columns:
        if c in MOT_ANGLES:
            cols[c] = table[c].to_numpy(float)
        elif c in _LENGTHS or c == "speed":              # length unit (per second)
            cols[c] = table[c].to_numpy(float) * to_m
    return cols


def angle_columns(times, metrics: dict) -> dict:
    """``{"time": times, <angle>: degrees}`` for ``angles.mot``: every
    column of ``metrics`` named in :data:`MOT_ANGLES`, in that order
    (degrees, as metrics.csv has them; NaN gaps stay NaN)."""
    cols = {"time": np.asarray(times, float)}
    for name in MOT_ANGLES:
        if name in metrics:
            cols[name] = np.asarray(metrics[name], float)
    return cols


def pan_tilt_roll(R) -> np.ndarray:
    """Pan, tilt and roll (degrees, (..., 3)) of world-to-camera rotations
    ``R`` (..., 3, 3) in photogram's convention (``Xc = R (X - X0)``; the
    camera's x right, y up, looking along -z), about the world's up axis Z.

    With the camera's right axis ``r = R[0]``, up axis ``u = R[1]`` and
    viewing direction ``d = -R[2]`` in world coordinates::

        pan  = atan2(d_y, d_x)                 heading of the view, from +X towards +Y
        tilt = atan2(d_z, hypot(d_x, d_y))     elevation of the view, positive up
        roll = atan2(r_z, u_z)                 positive when the image's right side is up

    These are the yaw, pitch (up positive) and roll (right side up
    positive) of the camera body (forward = ``d``, left = ``-r``, up =
    ``u``), Tait-Bryan Z-Y'-X'' angles: the body frame is
    ``Rz(pan) Ry(-tilt) Rx(-roll)``. A camera turned by an angle a about the
    world's vertical (``R -> R Rz(a)^T``) has its pan increased by a, its
    tilt and roll unchanged. Pan is undefined when the camera looks
    straight up or down (``|tilt| = 90``).
    """
    R = np.asarray(R, float)
    r, u, d = R[..., 0, :], R[..., 1, :], -R[..., 2, :]
    pan = np.arctan2(d[..., 1], d[..., 0])
    tilt = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))
    roll = np.arctan2(r[..., 2], u[..., 2])
    return np.degrees(np.stack([pan, tilt, roll], axis=-1))


def camera_rotation_columns(times, names, R) -> dict:
    """``{"time", <camera>_pan, <camera>_tilt, <camera>_roll, ...}`` of
    per-frame rotations ``R`` (F, C, 3, 3) (:func:`pan_tilt_roll`, degrees);
    pan and roll are unwrapped along the frames of each camera (continuous,
    no jump at +-180 deg; the first frame in (-180, 180])."""
    a = pan_tilt_roll(R)                                  # (F, C, 3)
    ok = np.all(np.isfinite(a), axis=-1)
    for k in (0, 2):
        for c in range(a.shape[1]):
            good = ok[:, c]
            if np.count_nonzero(good) > 1:
                a[good, c, k] = np.degrees(np.unwrap(np.radians(a[good, c, k])))
    cols = {"time": np.asarray(times, float)}
    for c, name in enumerate(names):
        for k, what in enumerate(("pan", "tilt", "roll")):
            cols[f"{name}_{what}"] = a[:, c, k]
    return cols
