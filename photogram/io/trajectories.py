"""3D trajectories of moving points for biomechanics tools: TRC (OpenSim),
C3D, OpenSim .mot (angles) and a plain CSV.

Source: a results folder with ``points3d.csv`` (one row per exposure and
point: ``exposure, time, point, X, Y, Z, sX, sY, sZ`` in the project's
length unit), as ``photogram intersect`` writes it (and the motion-capture
pipeline is to write it), optionally ``exposures.csv`` (the stick model:
angles in the project's angle unit with ``sigma_*`` columns, ``Z0``, ``v``,
``O_x, O_y, O_z``) and ``summary.json`` (units, the project for the camera
masks).

Conventions (docs/interoperability.md):

* Units: TRC, .mot and CSV in **metres** (and m/s), C3D in **millimetres**
  (``POINT:UNITS = "mm"``); angles in .mot in **degrees**.
* Axes: the project's world is Z up. TRC is written Y up for OpenSim,
  ``(X_trc, Y_trc, Z_trc) = (Y, Z, X)`` (photogram.io.trc); C3D and CSV keep
  the project axes (C3D's ``POINT:X_SCREEN = +X``, ``Y_SCREEN = +Z``).
* Gaps (a point not reconstructed at an exposure) stay gaps: empty TRC/CSV
  fields, invalid C3D samples (residual -1), ``NaN`` in .mot. Nothing is
  interpolated or filtered.
* C3D residual word: the point's 3D standard error
  ``sqrt((sX^2 + sY^2 + sZ^2) / 3)`` in mm (C3D's "residual" is an accuracy
  figure of the reconstruction; photogram gives the propagated one),
  quantised to ``|POINT:SCALE|``; the camera mask has bit k set when station
  k (in the order of the project's stations table, first 7) measured the point
  at that exposure.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.trajectory_data import Trajectories
from photogram.project.model import LENGTH_UNITS

__all__ = ["Trajectories", "load_trajectories", "write_trc_export", "write_c3d", "read_c3d",
           "write_mot", "read_mot", "mot_text", "write_trajectory_csv", "csv_sidecar"]

log = logging.getLogger("photogram")


def load_trajectories(folder) -> Trajectories:
    """Read ``points3d.csv`` (+ ``exposures.csv``, ``summary.json``) of a
    results folder.

    Raises
    ------
    InputError
        No points3d.csv, missing columns or bad numbers.
    """
    import json
    folder = Path(folder)
    path = folder / "points3d.csv"
    summary = {}
    if (folder / "summary.json").is_file():
        try:
            summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise InputError(f"not valid JSON: {exc.msg}", file=folder / "summary.json",
                             line=exc.lineno) from None
    from photogram.io.mocap_results import is_mocap_results, load_mocap_trajectories
    if is_mocap_results(folder, summary):
        return load_mocap_trajectories(folder, summary, _read_csv)
    info = summary.get("project") or {}
    unit = info.get("length_unit", "m")
    if unit not in LENGTH_UNITS:
        raise InputError(f"unknown length unit {unit!r}", file=folder / "summary.json")
    to_m = LENGTH_UNITS[unit]
    if not path.is_file():
        raise InputError("no points3d.csv (intersect) or joints3d.csv (mocap) in this folder",
                         file=folder,
                         hint="give the results folder of photogram intersect or mocap")
    table = _read_csv(path, ("exposure", "time", "point", "X", "Y", "Z"), ("exposure", "point"))
    exposures = list(dict.fromkeys(table["exposure"]))
    times = np.array([table["time"][table["exposure"] == e].iloc[0] for e in exposures], float)
    order = np.argsort(times, kind="stable")
    exposures = [exposures[i] for i in order]
    times = times[order]
    if np.any(np.diff(times) <= 0):
        raise InputError("two exposures have the same time", file=path)
    row_of = {e: i for i, e in enumerate(exposures)}
    n = len(exposures)
    markers, sigma = {}, {}
    for name in dict.fromkeys(table["point"]):
        sub = table[table["point"] == name]
        idx = np.array([row_of[e] for e in sub["exposure"]], int)
        xyz = np.full((n, 3), np.nan)
        s = np.full((n, 3), np.nan)
        xyz[idx] = sub[["X", "Y", "Z"]].to_numpy(float) * to_m
        if all(c in sub.columns for c in ("sX", "sY", "sZ")):
            s[idx] = sub[["sX", "sY", "sZ"]].to_numpy(float) * to_m
        markers[str(name)] = xyz
        sigma[str(name)] = s
    angles = None
    if (folder / "exposures.csv").is_file():
        angles = _read_csv(folder / "exposures.csv", ("time",), ("exposure",))
        if len(angles) == n and all(c in angles.columns for c in ("O_x", "O_y", "O_z")) \
                and "O" not in markers:
            t = angles["time"].to_numpy(float)
            rows = np.array([int(np.argmin(np.abs(times - ti))) for ti in t])
            xyz = np.full((n, 3), np.nan)
            xyz[rows] = angles[["O_x", "O_y", "O_z"]].to_numpy(float) * to_m
            markers["O"] = xyz
            sigma["O"] = np.full((n, 3), np.nan)
    traj = Trajectories(times=times, exposures=exposures, markers=markers, sigma=sigma,
                        angles=angles, angle_unit=info.get("angle_unit", "deg"),
                        length_unit=unit, name=str(info.get("name") or folder.parent.name))
    _camera_masks(traj, info.get("path"))
    return traj


def _read_csv(path: Path, required, ids):
    import pandas as pd
    try:
        frame = pd.read_csv(path, comment="#", dtype={k: str for k in ids},
                            keep_default_na=False, na_values=[""])
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"cannot read the table: {str(exc).splitlines()[0]}", file=path) \
            from None
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise InputError(f"column {missing[0]} is missing", file=path, line=1)
    for c in frame.columns:
        if c in ids or pd.api.types.is_numeric_dtype(frame[c]):
            continue
        bad = pd.to_numeric(frame[c], errors="coerce").isna() & frame[c].notna()
        if c not in ("point", "exposure", "stations", "line") and bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise InputError(f"{frame[c].iloc[row]!r} in column {c} is not a number",
                             file=path, line=row + 2)
    return frame


def _camera_masks(traj: Trajectories, prj) -> None:
    """Bit k of the mask: station k measured the point at the exposure."""
    n = len(traj.times)
    traj.cameras = {m: np.zeros(n, dtype=int) for m in traj.markers}
    if not prj or not Path(prj).is_file():
        return
    from photogram.project import read_project
    try:
        project = read_project(prj)
    except Exception as exc:                     # the mask is optional information
        log.warning("camera masks left empty: cannot read %s (%s)", prj, exc)
        return
    traj.stations = list(project.stations.names)
    row = {e: i for i, e in enumerate(traj.exposures)}
    obs = project.image_points
    for s, p in zip(obs.station, obs.point):
        pid = project.points.ids[p]
        name, _, exposure = pid.partition("@")
        if name in traj.cameras and exposure in row and s < 7:
            traj.cameras[name][row[exposure]] |= 1 << int(s)


# --------------------------------------------------------------------------
# writers
# --------------------------------------------------------------------------

def write_trc_export(path, traj: Trajectories, *, force: bool = False) -> Path:
    """OpenSim .trc, metres, Y up (photogram.io.trc), gaps empty."""
    from photogram.io.exchange import check_new_file
    from photogram.io.trc import write_trc
    check_new_file(path, force)
    return write_trc(path, traj.times, traj.markers, units="m", rotate_to_y_up=True,
                     data_rate=traj.rate)


def _scale(sig_mm: float) -> float:
    """|POINT:SCALE| (mm): the residual step, so that the largest residual
    fits C3D's 8 bits (1-2-5 series, at least 0.01 mm)."""
    need = max(sig_mm / 250.0, 0.01)
    for decade in 10.0 ** np.arange(-2, 6):
        for m in (1, 2, 5):
            if m * decade >= need:
                return float(m * decade)
    return 1e6


def write_c3d(path, traj: Trajectories, *, force: bool = False) -> Path:
    """C3D (float storage, mm, Z up) with residual and camera mask per sample."""
    import io

    import warnings

    import c3d

    from photogram.io.exchange import write_new_bytes
    names = list(traj.markers)
    n = len(traj.times)
    xyz = np.stack([traj.markers[m] for m in names], axis=1) * 1000.0       # (n, k, 3) mm
    sig = np.stack([traj.sigma[m] for m in names], axis=1) * 1000.0
    known = np.all(np.isfinite(sig), axis=2)
    res = np.sqrt(np.mean(np.where(known[..., None], sig, 0.0) ** 2, axis=2))
    scale = _scale(float(np.nanmax(res)) if res.size else 0.0)
    writer = c3d.Writer(point_rate=float(traj.rate), point_scale=-scale, point_units="mm  ")
    writer.set_point_labels([m[:30] for m in names])
    writer.set_screen_axis(X="+X", Y="+Z")
    for i in range(n):
        points = np.zeros((len(names), 5), dtype=np.float32)
        ok = np.all(np.isfinite(xyz[i]), axis=1)
        points[ok, :3] = xyz[i, ok]
        points[:, 3] = np.where(ok, np.minimum(res[i], 254 * scale), -1.0)
        points[:, 4] = [traj.cameras.get(m, np.zeros(n, int))[i] & 0x7F for m in names]
        writer.add_frames([(points, np.zeros((0, 0), dtype=np.float32))])
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")           # c3d warns about the empty analog block
        writer.write(buf)
    return write_new_bytes(path, buf.getvalue(), force)


def read_c3d(path) -> dict:
    """A C3D file as ``{"labels", "rate", "units", "xyz" (n, k, 3) with NaN
    gaps, "residual" (n, k), "cameras" (n, k) bit masks}`` (for tests and
    for checking an export)."""
    import warnings

    import c3d
    path = Path(path)
    try:
        handle = path.open("rb")
    except OSError as exc:
        raise InputError(f"cannot read C3D file: {exc.strerror}", file=path) from None
    with handle:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                reader = c3d.Reader(handle)
                labels = [s.strip() for s in reader.point_labels]
                frames = [p.copy() for _, p, _ in reader.read_frames()]
        except Exception as exc:
            raise InputError(f"not a readable C3D file: {exc}", file=path) from None
        units = reader.get("POINT:UNITS").string_value.strip()
        rate = float(reader.point_rate)
    data = np.stack(frames) if frames else np.zeros((0, len(labels), 5))
    xyz = data[:, :, :3].astype(float)
    invalid = data[:, :, 3] < 0
    xyz[invalid] = np.nan
    return {"labels": labels, "rate": rate, "units": units, "xyz": xyz,
            "residual": np.where(invalid, -1.0, data[:, :, 3]),
            "cameras": data[:, :, 4].astype(int)}


def _fmt(x: float) -> str:
    return repr(float(x)) if np.isfinite(x) else ""


def mot_text(name: str, columns: dict, *, in_degrees: bool = True) -> str:
    """The text of an OpenSim storage file (.mot/.sto) of ``columns``
    (name -> values; the first is ``time``).

    OpenSim's layout (the header of the files its tools write, e.g. the
    inverse kinematics' ``.mot``; read by ``opensim.Storage`` and
    ``opensim.TimeSeriesTable``): the file name, ``version=1``,
    ``nRows=<rows>``, ``nColumns=<columns, time included>``,
    ``inDegrees=yes|no``, free text, ``endheader``, then the tab-separated
    column names and one tab-separated line per row, floats with ``repr``
    (round trip exact) and ``NaN`` for a missing value.
    """
    names = list(columns)
    if not names or names[0] != "time":
        raise ValueError("the first column of a .mot file is time")
    data = [np.asarray(columns[c], float) for c in names]
    rows = len(data[0])
    if any(len(d) != rows for d in data):
        raise ValueError("the columns of a .mot file must have the same length")
    unit = "degrees" if in_degrees else "radians"
    lines = [name, "version=1", f"nRows={rows}", f"nColumns={len(names)}",
             f"inDegrees={'yes' if in_degrees else 'no'}", "",
             "Units are S.I. units (second, meters, Newtons, ...)",
             f"Angles are in {unit}.", "", "endheader", "\t".join(names)]
    for i in range(rows):
        lines.append("\t".join(repr(float(d[i])) if np.isfinite(d[i]) else "NaN"
                               for d in data))
    return "\n".join(lines) + "\n"


def write_mot(path, traj: Trajectories, *, force: bool = False) -> Path:
    """OpenSim storage (.mot, :func:`mot_text`): time, the stick-model angles
    in degrees with their sigmas (``sigma_*``), ``Z0`` in m and ``v`` in
    m/s; NaN where a value is unknown (exposures.csv of photogram
    intersect), or the columns of a mocap results folder
    (:mod:`photogram.io.mocap_results`)."""
    from photogram.geometry import ANGLE_FACTORS
    from photogram.io.exchange import write_new_text
    from photogram.project.results_schema import ANGLE_PARAMETERS
    table = traj.angles
    if traj.mot is not None:
        cols = dict(traj.mot)
    elif table is None:
        raise InputError("no exposures.csv (stick-model angles) or metrics.csv (mocap) in the "
                         "results folder",
                         hint="the .mot export needs photogram intersect's exposures.csv or "
                              "photogram mocap's metrics.csv")
    else:
        to_deg = ANGLE_FACTORS[traj.angle_unit] / ANGLE_FACTORS["deg"]     # radians per unit
        to_m = LENGTH_UNITS[traj.length_unit]
        cols = {"time": table["time"].to_numpy(float)}
        for c in table.columns:
            base = c[6:] if c.startswith("sigma_") else c
            if base in ANGLE_PARAMETERS:
                cols[c] = table[c].to_numpy(float) * to_deg
            elif base in ("Z0", "v"):
                cols[c] = table[c].to_numpy(float) * to_m
    return write_new_text(path, mot_text(Path(path).name, cols), force)


def read_mot(path) -> dict:
    """An OpenSim .mot/.sto file as ``{column: array}`` (+ ``"_header"``)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", file=path) from None
    try:
        end = next(i for i, ln in enumerate(lines) if ln.strip() == "endheader")
    except StopIteration:
        raise InputError("no endheader line", file=path, line=len(lines),
                         hint="not an OpenSim storage file, or truncated") from None
    if end + 1 >= len(lines):
        raise InputError("no column names after endheader", file=path, line=end + 1)
    names = lines[end + 1].split("\t")
    data = []
    for k, ln in enumerate(lines[end + 2:], start=end + 3):
        if not ln.strip():
            continue
        f = ln.split("\t")
        if len(f) != len(names):
            raise InputError(f"{len(f)} values for {len(names)} columns", file=path, line=k)
        try:
            data.append([float(v) for v in f])
        except ValueError:
            raise InputError("bad number", file=path, line=k) from None
    arr = np.array(data, float).reshape(-1, len(names))
    out = {n: arr[:, j] for j, n in enumerate(names)}
    out["_header"] = lines[:end]
    return out


def csv_sidecar(path) -> Path:
    """The metadata file beside a trajectory CSV: ``NAME.csv.json``."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def write_trajectory_csv(path, traj: Trajectories, *, force: bool = False) -> Path:
    """One row per exposure: ``exposure, time`` and ``<point>_X, _Y, _Z,
    _sX, _sY, _sZ`` in metres, project axes (Z up); gaps empty.

    The CSV is a plain table whose first line is the header (no comment
    lines: ``pandas.read_csv(path)`` reads it as it is); units, axes and
    the source are in the sidecar ``NAME.csv.json`` (:func:`csv_sidecar`).
    Returns the CSV's path.
    """
    import csv
    import io
    import json

    from photogram.io.exchange import check_new_file, write_new_text
    meta_path = csv_sidecar(path)
    check_new_file(path, force)
    check_new_file(meta_path, force)
    names = ["exposure", "time"]
    for m in traj.markers:
        names += [f"{m}_{c}" for c in ("X", "Y", "Z", "sX", "sY", "sZ")]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    for i, e in enumerate(traj.exposures):
        row = [e, repr(float(traj.times[i]))]
        for m in traj.markers:
            row += [_fmt(v) for v in traj.markers[m][i]] + [_fmt(v) for v in traj.sigma[m][i]]
        writer.writerow(row)
    meta = {"format": "photogram trajectories CSV", "file": Path(path).name,
            "length_unit": "m", "time_unit": "s", "axes": "project axes, Z up",
            "empty_cell": "not measured (coordinates) or not known (sigmas)",
            "columns": "exposure, time, then <point>_X, _Y, _Z, _sX, _sY, _sZ per point",
            "points": list(traj.markers), "source": traj.name,
            "source_length_unit": traj.length_unit}
    write_new_text(meta_path, json.dumps(meta, indent=2) + "\n", force)
    return write_new_text(path, buf.getvalue(), force)
