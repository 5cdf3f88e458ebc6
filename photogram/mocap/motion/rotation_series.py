"""Filtering, evaluation, checks and files of frame-to-frame camera rotations.

The rotation differences of :mod:`photogram.mocap.motion.homography` (estimated
from SIMULATED or real images) are filtered as in the paper (median filter
of 7 pairs and Gaussian smoothing with sigma 3 of the rotation vectors, per
axis, failed pairs interpolated first), compared with the truth
(simulation), checked (a camera whose images show too little static
background is reported), and written to / read from CSV files.
"""

from __future__ import annotations

import csv
import io as _io
import os
import re
import tempfile
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d, median_filter

from photogram.errors import GeometryError, InputError
from photogram.geometry import matrix_to_rodrigues, rodrigues_to_matrix
from photogram.mocap.motion.homography import (HomographySettings, LaggedDifferences,
                                               RotationDifferences)
from photogram.project.atomic import give_file_mode

__all__ = ["confident_pairs", "difference_noise", "filter_rotation_differences",
           "rotation_difference_errors",
           "check_rotation_differences", "write_rotation_differences",
           "read_rotation_differences"]


def confident_pairs(rd, fraction: float = 0.3) -> np.ndarray:
    """(F-1,) bool: the pairs of ``rd`` (a
    :class:`~photogram.mocap.motion.homography.RotationDifferences`) that
    are ``ok`` and have at least ``fraction`` times the median inliers of
    the camera's ok pairs. A homography fitted to few background points is
    often wrong (0.5-3 deg); left to the filter's interpolation, it does not
    enter the chain of differences (a random walk that keeps every error)."""
    ok = np.asarray(rd.ok, bool) & np.all(np.isfinite(rd.dR), axis=(1, 2))
    inliers = np.asarray(rd.inliers, float)
    if fraction <= 0 or not ok.any():
        return ok
    return ok & (inliers >= fraction * np.median(inliers[ok]))


def filter_rotation_differences(dR, ok, median: int = 7, sigma: float = 3.0,
                                breaks=()) -> np.ndarray:
    """Outlier removal and smoothing of rotation differences (the paper's).

    The rotation vectors of ``dR`` (F-1, 3, 3) are filled at the failed
    pairs (``ok`` False or not finite) by linear interpolation from the
    neighbouring good pairs (constant beyond the ends), then median filtered
    (``median`` pairs) and Gaussian smoothed (``sigma`` pairs), per axis.
    ``breaks`` are frames that start a new segment (a new run): segments are
    filtered separately and the pair that crosses a break is returned as it
    is (NaN if it failed).

    Returns
    -------
    ndarray (F-1, 3, 3)

    Raises
    ------
    GeometryError
        No pair of a segment has a usable estimate.
    """
    dR = np.asarray(dR, dtype=float)
    ok = np.asarray(ok, bool) & np.all(np.isfinite(dR), axis=(1, 2))
    n = len(dR)
    out = dR.copy()
    edges = sorted({int(b) - 1 for b in breaks if 0 < int(b) <= n})   # crossing pairs
    start = 0
    for stop in edges + [n]:
        seg = np.arange(start, stop)
        if len(seg):
            good = ok[seg]
            if not good.any():
                raise GeometryError(f"no usable rotation difference in frame pairs "
                                    f"{start}..{stop - 1}",
                                    hint="the images show too little static background")
            r = np.zeros((len(seg), 3))
            r[good] = matrix_to_rodrigues(dR[seg][good])
            idx = np.arange(len(seg))
            for k in range(3):
                r[:, k] = np.interp(idx, idx[good], r[good, k])
                if median > 1:
                    r[:, k] = median_filter(r[:, k], size=median, mode="nearest")
                if sigma > 0:
                    r[:, k] = gaussian_filter1d(r[:, k], sigma, mode="nearest")
            out[seg] = rodrigues_to_matrix(r)
        start = stop + 1
    return out


def rotation_difference_errors(dR, R_true) -> dict:
    """Errors of rotation differences against the truth, degrees.

    The error rotation ``dR[t] dR_true[t]^T`` (``dR_true = R(t+1) R(t)^T``)
    as a rotation vector in the camera frame (x right, y up, z backwards:
    x is tilt, y pan, z roll). Returns ``{"x": {"median", "p95"}, "y": ...,
    "z": ..., "angle": ..., "n": pairs}`` over the finite pairs (median and
    95th percentile of the absolute components and of the angle).
    """
    dR = np.asarray(dR, float)
    R_true = np.asarray(R_true, float)
    true = R_true[1:] @ np.swapaxes(R_true[:-1], -1, -2)
    good = np.all(np.isfinite(dR), axis=(1, 2))
    e = np.degrees(matrix_to_rodrigues(dR[good] @ np.swapaxes(true[good], -1, -2)))
    out = {"n": int(good.sum())}
    cols = {"x": np.abs(e[:, 0]), "y": np.abs(e[:, 1]), "z": np.abs(e[:, 2]),
            "angle": np.linalg.norm(e, axis=1)}
    for key, v in cols.items():
        out[key] = ({"median": float(np.median(v)), "p95": float(np.percentile(v, 95))}
                    if len(v) else {"median": np.nan, "p95": np.nan})
    return out


def check_rotation_differences(rd: RotationDifferences, camera_name: str,
                               settings: HomographySettings | None = None) -> str:
    """One line about a camera's estimates; raises when too many pairs failed.

    Returns
    -------
    str
        ``"camera C1: 278 frame pairs, 0 failed, median 412 background inliers"``.

    Raises
    ------
    GeometryError
        More than ``settings.max_failed`` of the pairs have fewer than
        ``settings.min_inliers`` inliers: the camera's rotations cannot be
        estimated from its images.
    """
    st = settings or HomographySettings()
    med = rd.median_inliers
    if rd.pairs and rd.failed > st.max_failed * rd.pairs:
        raise GeometryError(
            f"camera {camera_name}: {rd.failed} of {rd.pairs} frame pairs have fewer than "
            f"{st.min_inliers} background inliers (median {med:.0f}); its rotations cannot "
            f"be estimated from the images",
            hint="the view shows too little static texture outside the athlete (sky, "
                 "uniform snow); give this camera's rotations in camera_frames or check "
                 "the athlete boxes")
    return (f"camera {camera_name}: {rd.pairs} frame pairs, {rd.failed} failed, median "
            f"{med:.0f} background inliers")


# --------------------------------------------------------------------------
_COLUMNS = ["frame", "camera", "rx", "ry", "rz", "inliers", "matches", "ok"]


def write_rotation_differences(path, per_camera: dict, first_frame: int = 0,
                               comment: str = "") -> Path:
    """Write rotation differences of several cameras as CSV, atomically.

    One row per camera and pair: ``frame`` (t; the difference maps frame t
    to t+1, numbered from ``first_frame``), ``camera``, ``rx, ry, rz`` (the
    rotation vector of ``dR``, photogrammetric, degrees; empty if the pair
    failed), ``inliers``, ``matches``, ``ok`` (1/0). When some camera has
    lagged pairs (``RotationDifferences.lagged``, frames t and t+k, k > 1) a
    ninth column ``to_frame`` follows: ``frame + 1`` on the consecutive
    rows, the pair's second frame on the lagged rows (after the camera's
    consecutive rows); without lagged pairs the file has the eight columns
    only. ``comment`` lines go first, each prefixed with ``# `` (the reader
    skips them).
    """
    path = Path(path)
    buf = _io.StringIO()
    for text in comment.splitlines():
        buf.write(f"# {text}\n")
    w = csv.writer(buf, lineterminator="\n")
    lagged = any(rd.lagged is not None and len(rd.lagged.ok) for rd in per_camera.values())
    w.writerow(_COLUMNS + ["to_frame"] if lagged else _COLUMNS)
    for name, rd in per_camera.items():
        steps = np.arange(len(rd.dR))
        rows = [(steps, steps + 1, rd.dR, rd.inliers, rd.matches, rd.ok)]
        lg = rd.lagged
        if lg is not None and len(lg.ok):
            rows.append((lg.first, lg.second, lg.dR, lg.inliers, lg.matches, lg.ok))
        for first, second, dR, inl, nm, ok in rows:
            r = _degrees(dR)
            for i in range(len(dR)):
                vals = ["" if not np.isfinite(v) else f"{v:.9f}" for v in r[i]]
                row = [first_frame + int(first[i]), name, *vals, int(inl[i]), int(nm[i]),
                       int(bool(ok[i]))]
                w.writerow(row + [first_frame + int(second[i])] if lagged else row)
    if not path.parent.is_dir():
        raise InputError("the folder does not exist", file=path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    give_file_mode(tmp, path, fd=fd)    # mkstemp's 0600 -> the umask's mode
    try:
        with os.fdopen(fd, "w", newline="") as handle:
            handle.write(buf.getvalue())
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise
    return path


def _degrees(dR) -> np.ndarray:
    """(n, 3) rotation vectors (deg) of (n, 3, 3) matrices, NaN where not finite."""
    dR = np.asarray(dR, float).reshape(-1, 3, 3)
    good = np.all(np.isfinite(dR), axis=(1, 2))
    r = np.full((len(dR), 3), np.nan)
    if good.any():
        r[good] = np.degrees(matrix_to_rodrigues(dR[good]))
    return r


def _integer(text: str) -> int:
    """An integer cell: digits with an optional sign (not '1_0', not '1e3')."""
    text = text.strip()
    if not re.fullmatch(r"[+-]?[0-9]+", text):
        raise ValueError(text)
    return int(text)


def read_rotation_differences(path, camera_names, n_frames: int,
                              first_frame: int = 0) -> dict:
    """Read :func:`write_rotation_differences`'s CSV.

    Every camera of ``camera_names`` needs the ``n_frames - 1`` pairs
    ``first_frame .. first_frame + n_frames - 2``; other cameras are an error.
    With the ninth column ``to_frame``, a row whose ``to_frame`` is empty or
    ``frame + 1`` is such a consecutive pair, a row with ``to_frame >
    frame + 1`` a lagged pair (at most one per camera and frames).

    Returns
    -------
    dict
        ``{camera: RotationDifferences}`` (``seconds`` 0; ``lagged`` None
        for a camera without lagged rows).

    Raises
    ------
    InputError
        Missing file, missing columns, malformed row (``file:line``), unknown
        camera, frame or to_frame out of range, duplicate or missing pairs.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("no such file", file=path,
                         hint="estimate the rotation differences first")
    names = list(camera_names)
    P = n_frames - 1
    data = {c: (np.full((P, 3), np.nan), np.zeros(P, int), np.zeros(P, int),
                np.zeros(P, bool), np.zeros(P, bool)) for c in names}
    lagged = {c: {} for c in names}
    from photogram.project.text_input import read_text
    lines = read_text(path, "rotation differences table").splitlines()
    skip = 0
    while skip < len(lines) and lines[skip].lstrip().startswith("#"):
        skip += 1
    rows = csv.reader(lines[skip:])
    try:
        header = next(rows, None)
    except csv.Error:       # a cell over 128 KiB (csv.field_size_limit) in the header
        header = None
    header = None if header is None else [h.strip() for h in header]
    if header not in (_COLUMNS, _COLUMNS + ["to_frame"]):
        raise InputError("expected the columns " + ",".join(_COLUMNS) + "[,to_frame]",
                         file=path, line=skip + 1,
                         hint="the header names exactly these columns (to_frame optional)")
    columns = header
    first_line = {}
    from photogram.project.tables import csv_records
    numbers = list(range(skip + 1, len(lines) + 1))
    for line, row in enumerate(csv_records(rows, numbers, path), start=skip + 2):
        if not row or all(not c.strip() for c in row) or row[0].lstrip().startswith("#"):
            continue
        cam, t, t2, r, k_in, k_m, flag = _row(row, columns, data, names, first_frame,
                                              n_frames, path, line)
        if t2 > t + 1:
            key, store = (cam, t, t2), lagged[cam]
        else:
            key, store = (cam, t), None
        if key in first_line:
            what = f"frames {row[0]}-{row[8].strip()}" if store is not None else f"frame {row[0]}"
            raise InputError(f"duplicate {what} of camera {cam} (first on line "
                             f"{first_line[key]})", file=path, line=line,
                             hint="give each camera one row per frame pair")
        first_line[key] = line
        if store is not None:
            store[t, t2] = (r, k_in, k_m, bool(flag))
            continue
        rv, inl, nm, ok, seen = data[cam]
        rv[t], inl[t], nm[t], ok[t], seen[t] = r, k_in, k_m, bool(flag), True
    out = {}
    for cam, (rv, inl, nm, ok, seen) in data.items():
        if not seen.all():
            missing = np.flatnonzero(~seen)[:5] + first_frame
            raise InputError(f"camera {cam} lacks {np.count_nonzero(~seen)} frame pair(s)",
                             file=path, hint="first missing frames: "
                             + ", ".join(str(v) for v in missing))
        out[cam] = RotationDifferences(_matrices(rv), inl, nm, ok, 0.0, n_frames,
                                       _lagged(lagged[cam]))
    return out


def _matrices(rv) -> np.ndarray:
    """(n, 3, 3) rotations of (n, 3) rotation vectors in degrees, NaN rows NaN."""
    rv = np.asarray(rv, float).reshape(-1, 3)
    dR = np.full((len(rv), 3, 3), np.nan)
    good = np.all(np.isfinite(rv), axis=1)
    if good.any():
        dR[good] = rodrigues_to_matrix(np.radians(rv[good]))
    return dR


def _lagged(pairs: dict) -> LaggedDifferences | None:
    """LaggedDifferences of ``{(t, t2): (r, inliers, matches, ok)}``, sorted."""
    if not pairs:
        return None
    keys = sorted(pairs)
    vals = [pairs[k] for k in keys]
    return LaggedDifferences(np.array([k[0] for k in keys], int),
                             np.array([k[1] for k in keys], int),
                             _matrices([v[0] for v in vals]),
                             np.array([v[1] for v in vals], int),
                             np.array([v[2] for v in vals], int),
                             np.array([v[3] for v in vals], bool))


def _row(row, columns, data, names, first_frame, n_frames, path, line):
    """(camera, t, t2, r, inliers, matches, ok) of one record (0-based frames),
    InputError with ``file:line`` for a faulty one."""
    P = n_frames - 1
    if len(row) != len(columns):
        raise InputError(f"{len(row)} fields, expected {len(columns)}", file=path,
                         line=line, hint="one cell per column: " + ",".join(columns))
    cam = row[1].strip()
    if cam not in data:
        raise InputError(f"unknown camera {cam!r}", file=path, line=line,
                         hint="cameras: " + ", ".join(names))
    try:
        t = _integer(row[0]) - first_frame
        r = [float(v) if v.strip() else np.nan for v in row[2:5]]
        k_in, k_m, flag = _integer(row[5]), _integer(row[6]), _integer(row[7])
        t2 = (_integer(row[8]) - first_frame if len(row) > 8 and row[8].strip()
              else t + 1)
    except ValueError:
        raise InputError("malformed number in " + ",".join(row), file=path,
                         line=line, hint="frame, inliers, matches, ok and to_frame are "
                         "integers; rx, ry, rz numbers (deg) or empty") from None
    if not 0 <= t < P:
        raise InputError(f"frame {row[0]} outside {first_frame}.."
                         f"{first_frame + P - 1}", file=path, line=line,
                         hint="frame is the first frame of each pair of the detections")
    if not t < t2 <= P:
        raise InputError(f"to_frame {row[8].strip()} outside {first_frame + t + 1}.."
                         f"{first_frame + P}", file=path, line=line,
                         hint="to_frame is the pair's second frame: after frame, at most "
                         "the last frame of the detections")
    if np.any(np.abs(np.asarray(r)) > 360.0):          # inf included, NaN not
        raise InputError("a rotation difference of more than 360 deg", file=path,
                         line=line, hint="rx, ry, rz: the rotation vector from frame "
                         "to to_frame (the next frame), in degrees")
    if flag not in (0, 1) or (flag and not np.all(np.isfinite(r))):
        raise InputError("ok must be 0 or 1, and 1 needs rx, ry, rz", file=path,
                         line=line, hint="finite rx, ry, rz (deg) where ok is 1")
    return cam, t, t2, r, k_in, k_m, flag


def difference_noise(dR, ok) -> float:
    """The error per pair and axis of measured rotation differences (rad),
    robustly from consecutive usable pairs: ``1.4826 MAD(e(t+1) - e(t)) /
    sqrt(2)`` of their rotation vectors ``e``. The camera's own changes of
    angular speed count as error too (a conservative estimate); NaN without
    two consecutive usable pairs."""
    dR = np.asarray(dR, float)
    ok = np.asarray(ok, bool) & np.all(np.isfinite(dR), axis=(1, 2))
    both = ok[1:] & ok[:-1]
    if not both.any():
        return float("nan")
    e = np.zeros((len(dR), 3))
    e[ok] = matrix_to_rodrigues(dR[ok])
    de = (e[1:] - e[:-1])[both]
    mad = np.median(np.abs(de - np.median(de, axis=0)))
    return float(1.4826 * mad / np.sqrt(2.0))
