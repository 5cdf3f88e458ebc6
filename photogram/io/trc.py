"""OpenSim marker files (.trc), as written by Pose2Sim and read by OpenSim.

Layout (tab separated, ``\\n`` line ends)::

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    <values of the line above>
    Frame#  Time  <marker 1>  ""  ""  <marker 2>  ""  ""  ...
    ""  ""  X1  Y1  Z1  X2  Y2  Z2  ...
    <frame>  <time>  <x y z of every marker>   (one line per frame)

A missing coordinate is written as ``NaN`` (as OpenSim's own TRC writer
does) and read back as NaN, as is an empty field: gaps are never
interpolated. Empty fields were written before: OpenSim 4.6's
``TimeSeriesTableVec3`` refuses a row whose *last* marker is empty (its
tokenizer drops trailing empty fields), NaN is read by it, by Pose2Sim and
by :func:`read_trc` alike.

Axes: OpenSim is Y-up. Our projects are Z-up, so with ``rotate_to_y_up``
(default) a project point ``(X, Y, Z)`` is written as

    (X_trc, Y_trc, Z_trc) = (Y, Z, X)

(a cyclic permutation, hence a proper rotation; Pose2Sim's ``zup2yup``), and
:func:`read_trc` with ``rotate_to_z_up`` turns it back, ``(X, Y, Z) =
(Z_trc, X_trc, Y_trc)``. Coordinates are written in ``units`` as given (no
scaling).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.atomic import atomic_write_text
from photogram.project.model import LENGTH_UNITS
from photogram.project.toml_writer import comment_string

__all__ = ["TrcData", "write_trc", "read_trc", "zup_to_yup", "yup_to_zup"]

HEADER_KEYS = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units",
               "OrigDataRate", "OrigDataStartFrame", "OrigNumFrames")


def zup_to_yup(xyz: np.ndarray) -> np.ndarray:
    """Z-up project coordinates (..., 3) to OpenSim's Y-up: ``(Y, Z, X)``."""
    xyz = np.asarray(xyz, dtype=float)
    return xyz[..., [1, 2, 0]]


def yup_to_zup(xyz: np.ndarray) -> np.ndarray:
    """OpenSim's Y-up coordinates (..., 3) back to Z-up: ``(Z, X, Y)``."""
    xyz = np.asarray(xyz, dtype=float)
    return xyz[..., [2, 0, 1]]


@dataclass
class TrcData:
    """Content of a .trc file.

    ``markers`` maps name -> (n, 3) coordinates (NaN where empty), in the
    file's axes unless read with ``rotate_to_z_up``.
    """

    frames: np.ndarray
    times: np.ndarray
    markers: dict[str, np.ndarray]
    units: str
    header: dict[str, str] = field(default_factory=dict)

    @property
    def data_rate(self) -> float:
        return float(self.header.get("DataRate", "nan"))


def _header_text(text) -> str:
    """A user string for the tab-separated header: as it is, or quoted with
    its tabs, line breaks and other control characters escaped."""
    text = str(text)
    if any(ord(c) < 0x20 or ord(c) == 0x7F or c in "\x85\u2028\u2029" for c in text):
        return comment_string(text)
    return text


def _fmt(x: float) -> str:
    return "NaN" if not np.isfinite(x) else repr(float(x))


def write_trc(path: str | Path, times, markers: dict, units: str = "m",
              rotate_to_y_up: bool = True, *, data_rate: float | None = None,
              frames=None) -> Path:
    """Write markers as an OpenSim .trc file, atomically.

    Parameters
    ----------
    path : str or Path
    times : array_like (n,)
        Time of every frame in s (strictly increasing).
    markers : dict name -> array_like (n, 3)
        Coordinates in ``units`` (NaN: missing, written as ``NaN``).
    units : str
        Length unit of the coordinates (m, dm, cm, mm), written to the header.
    rotate_to_y_up : bool
        Turn Z-up coordinates into OpenSim's Y-up ``(Y, Z, X)`` (module doc).
    data_rate : float, optional
        Frames per second for DataRate/CameraRate (default: from the median
        time step).
    frames : array_like (n,) of int, optional
        Frame numbers (default: from the times and the rate, the first is 1).

    Returns
    -------
    Path
    """
    times = np.asarray(times, dtype=float)
    n = times.size
    if times.ndim != 1 or n == 0:
        raise InputError("write_trc needs a 1-D array of at least one time")
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise InputError("TRC times must be finite and strictly increasing")
    if units not in LENGTH_UNITS:
        raise InputError(f"unknown TRC units {units!r}", hint=f"use one of {', '.join(LENGTH_UNITS)}")
    if not markers:
        raise InputError("write_trc needs at least one marker")
    names, data = [], []
    for name, xyz in markers.items():
        # a user string (a point id, a joint): a tab or line break would
        # shift every column of the header, so it is quoted and escaped
        name = _header_text(name)
        if not name:
            raise InputError("a marker name is empty", file=path,
                             hint="give every marker (point, joint) a name")
        a = np.asarray(xyz, dtype=float)
        if a.shape != (n, 3):
            raise InputError(f"marker {name!r} has shape {a.shape}, expected ({n}, 3)")
        if name in names:
            raise InputError(f"marker name {name!r} given twice")
        names.append(name)
        data.append(zup_to_yup(a) if rotate_to_y_up else a)
    if data_rate is None:
        data_rate = 1.0 / float(np.median(np.diff(times))) if n > 1 else 1.0
    if not (np.isfinite(data_rate) and data_rate > 0):
        raise InputError(f"data_rate must be positive, got {data_rate}")
    if frames is None:
        frames = np.rint((times - times[0]) * data_rate).astype(int) + 1
    frames = np.asarray(frames)
    if frames.shape != (n,):
        raise InputError(f"frames has shape {frames.shape}, expected ({n},)")
    rate = f"{data_rate:.10g}"
    m = len(names)
    lines = [
        "\t".join(["PathFileType", "4", "(X/Y/Z)",
                   _header_text(Path(path).name)]),
        "\t".join(HEADER_KEYS),
        "\t".join([rate, rate, str(n), str(m), units, rate, str(int(frames[0])), str(n)]),
        "\t".join(["Frame#", "Time"] + [c for nm in names for c in (nm, "", "")]),
        "\t".join(["", ""] + [f"{a}{k}" for k in range(1, m + 1) for a in "XYZ"]),
    ]
    block = np.concatenate(data, axis=1)          # (n, 3m)
    for i in range(n):
        row = [str(int(frames[i])), repr(float(times[i]))] + [_fmt(x) for x in block[i]]
        lines.append("\t".join(row))
    return atomic_write_text(path, "\n".join(lines) + "\n")


def read_trc(path: str | Path, rotate_to_z_up: bool = False) -> TrcData:
    """Read an OpenSim .trc file (ours, Pose2Sim's, most mocap exports).

    Empty fields are NaN; blank lines are skipped; a data line shorter than
    the marker list is padded with NaN.

    Parameters
    ----------
    path : str or Path
    rotate_to_z_up : bool
        Turn the file's Y-up coordinates into Z-up ``(Z_trc, X_trc, Y_trc)``.

    Raises
    ------
    InputError
        Missing file, not a TRC file, bad numbers.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"cannot read TRC file: {exc.strerror}", file=path) from None
    raw = text.splitlines()
    lines = [(k + 1, ln) for k, ln in enumerate(raw) if ln.strip()]
    if len(lines) < 5 or not lines[0][1].startswith("PathFileType"):
        raise InputError("not a TRC file (no PathFileType header)", file=path, line=1)
    keys = [s.strip() for s in lines[1][1].split("\t")]
    vals = [s.strip() for s in lines[2][1].split("\t")]
    header = dict(zip(keys, vals))
    if "NumMarkers" not in header:
        raise InputError("TRC header has no NumMarkers", file=path, line=lines[1][0])
    lno, name_line = lines[3]
    if not name_line.startswith("Frame#"):
        raise InputError("expected the Frame#/Time line", file=path, line=lno)
    names = [s.strip() for s in name_line.split("\t")[2:] if s.strip()]
    try:
        m = int(header["NumMarkers"])
    except ValueError:
        raise InputError(f"NumMarkers is {header['NumMarkers']!r}", file=path,
                         line=lines[2][0]) from None
    if len(set(names)) != len(names):
        raise InputError("duplicate marker names in the TRC file", file=path, line=lno)
    if m != len(names):
        raise InputError(f"NumMarkers is {m} but {len(names)} marker names follow",
                         file=path, line=lno)
    body = lines[5:] if not _is_number(lines[4][1].split("\t")[0]) else lines[4:]
    n = len(body)
    frames = np.zeros(n, dtype=int)
    times = np.zeros(n)
    block = np.full((n, 3 * m), np.nan)
    for i, (lno, ln) in enumerate(body):
        fields = ln.split("\t")
        try:
            frames[i] = int(float(fields[0]))
            times[i] = float(fields[1])
            vals = [float(s) if s.strip() else np.nan for s in fields[2:2 + 3 * m]]
        except (ValueError, IndexError):
            raise InputError("bad number in TRC data", file=path, line=lno) from None
        block[i, :len(vals)] = vals
    markers = {}
    for k, name in enumerate(names):
        xyz = block[:, 3 * k:3 * k + 3].copy()
        markers[name] = yup_to_zup(xyz) if rotate_to_z_up else xyz
    return TrcData(frames=frames, times=times, markers=markers,
                   units=header.get("Units", ""), header=header)


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True
