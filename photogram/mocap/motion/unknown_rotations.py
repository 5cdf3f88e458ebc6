"""``rotation = "estimate"`` in a motion-capture project: the measured
rotation differences, their check, and the comparison with true rotations.

The differences come either from a table (``rotation_differences`` in
``[mocap]``, written by an earlier run as ``rotation_differences.csv``) or
from the camera images (``[mocap.images]``: a video file or a folder of
images per camera), measured by :mod:`photogram.mocap.motion.homography` outside
the tracked athlete's box. A camera whose pairs mostly failed (too few
background features) is reported: a warning in the log and summary.json,
and its differences get weight 0 (its rotations are then estimated without
E_rot, from the athlete alone), never silently used.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from photogram.errors import GeometryError
from photogram.geometry.rotations import rodrigues_to_matrix

__all__ = ["measure_differences", "rotation_errors", "lagged_arrays"]

log = logging.getLogger(__name__)


def _cache_key(path, c, cameras, frame_range, boxes, settings) -> str:
    """What the measurement of one camera depends on: the images (path,
    size and modification time of the file or of every file in the folder),
    the frames, the interior orientation, the boxes and the settings."""
    import dataclasses
    import hashlib
    p = Path(path)
    files = sorted(p.iterdir()) if p.is_dir() else [p]
    h = hashlib.sha256()
    for f in files:
        st = f.stat()
        h.update(f"{f.name}:{st.st_size}:{st.st_mtime_ns};".encode())
    lo, hi = frame_range
    h.update(np.ascontiguousarray(cameras._io_rows(c, hi - lo)).tobytes())
    if boxes is not None:
        h.update(np.ascontiguousarray(np.nan_to_num(boxes, nan=-1.0)).tobytes())
    h.update(repr((str(p.resolve()), lo, hi, cameras.models[c],
                   dataclasses.asdict(settings))).encode())
    return h.hexdigest()


_LAGGED = ("first", "second", "dR", "inliers", "matches", "ok")


def _load_cached(file: Path, key: str):
    from photogram.mocap.motion.homography import LaggedDifferences, RotationDifferences
    try:
        with np.load(file, allow_pickle=False) as z:
            if str(z["key"]) != key:
                return None
            lagged = (LaggedDifferences(*(z["lagged_" + k] for k in _LAGGED))
                      if bool(z["has_lagged"]) else None)
            return RotationDifferences(dR=z["dR"], inliers=z["inliers"], matches=z["matches"],
                                       ok=z["ok"], seconds=float(z["seconds"]),
                                       frames=int(z["frames"]), lagged=lagged)
    except (OSError, KeyError, ValueError):
        return None


def _save_cached(file: Path, key: str, rd) -> None:
    import io as _io

    from photogram.project.atomic import atomic_write_bytes
    buf = _io.BytesIO()
    lagged = {} if rd.lagged is None else {
        "lagged_" + k: np.asarray(getattr(rd.lagged, k)) for k in _LAGGED}
    np.savez(buf, key=np.array(key), dR=rd.dR, inliers=rd.inliers, matches=rd.matches,
             ok=rd.ok, seconds=np.array(rd.seconds), frames=np.array(rd.frames),
             has_lagged=np.array(rd.lagged is not None), **lagged)
    file.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(file, buf.getvalue())


def _from_images(ms, cameras, tracked, frame_range, settings, cache=None):
    import itertools

    from photogram.mocap.motion.homography import rotation_differences
    from photogram.mocap.motion.video import read_frames
    from photogram.project.safe_names import safe_names
    lo, hi = frame_range
    out = {}
    # one file per camera, its name made safe (a camera may be called "../../x")
    files = {} if cache is None else {
        name: Path(cache) / f"{stem}.npz"
        for name, stem in zip(cameras.names, safe_names(cameras.names, default="camera"))}
    for c, name in enumerate(cameras.names):
        path = ms.images.get(name) if ms.images else None
        if path is None:
            continue
        t0 = time.perf_counter()
        boxes = None
        if tracked[c] is not None:
            boxes = np.asarray(tracked[c].boxes, float)
        key = _cache_key(path, c, cameras, frame_range, boxes, settings)
        cached = None if cache is None else _load_cached(files[name], key)
        if cached is not None:
            out[name] = cached
            log.info("camera %s: rotation differences of an interrupted run reused (%s)",
                     name, cache)
            continue
        frames = iter(read_frames(path, frames=range(lo, hi)))
        first = next(frames, None)
        if first is None:
            continue
        width = cameras.image_size[c][0]
        scale = first.shape[1] / width if np.isfinite(width) else 1.0
        io = cameras._io_rows(c, hi - lo)
        rd = rotation_differences(itertools.chain([first], frames), cameras.models[c], io,
                                  image_scale=scale, boxes=boxes, settings=settings)
        out[name] = rd
        if cache is not None:
            _save_cached(files[name], key, rd)
        log.info("camera %s: %d frame pairs, %d failed, median %d inliers, %.1f s", name,
                 len(rd.ok), int(np.sum(~rd.ok)), int(np.median(rd.inliers)) if len(rd.ok)
                 else 0, time.perf_counter() - t0)
    return out


def measure_differences(ms, cameras, tracked, frame_range, first_frame: int, warnings: list,
                        breaks=(), cache=None):
    """Rotation differences (F-1, C, 3, 3) (filtered: median 3, Gaussian 3; pairs
    with few inliers for their camera left out),
    weights (F-1, C) and the per-camera measurements (for the results
    folder) of the frames ``frame_range`` (start, stop; indices into the
    detections, whose first frame number is ``first_frame``). A table must
    hold exactly the pairs of these frames. With ``cache`` (a folder) every
    camera's measurement from images is saved there as soon as it is done
    and reused by a later run with the same images and settings: an
    interrupted run resumes with the next camera. The lagged pairs of the
    measurements (``RotationDifferences.lagged``, from the table's
    ``to_frame`` rows or the images) are in the per-camera measurements as
    measured (unfiltered); :func:`lagged_arrays` gathers them."""
    from photogram.mocap.motion.homography import HomographySettings
    from photogram.mocap.motion.rotation_series import (check_rotation_differences,
                                                        confident_pairs,
                                                        filter_rotation_differences,
                                                        read_rotation_differences)
    settings = HomographySettings(**ms.homography)
    lo, hi = frame_range
    F, C = hi - lo, cameras.n_cameras
    if ms.rotation_differences is not None:
        per = read_rotation_differences(ms.rotation_differences, cameras.names, F,
                                        first_frame=first_frame + lo)
    else:
        per = _from_images(ms, cameras, tracked, frame_range, settings, cache)
    dR = np.broadcast_to(np.eye(3), (max(F - 1, 0), C, 3, 3)).copy()
    weights = np.zeros((max(F - 1, 0), C))
    for c, name in enumerate(cameras.names):
        rd = per.get(name)
        if rd is None:
            warnings.append(f"camera {name}: no images and no rotation differences; its "
                            f"rotations are estimated from the athlete alone (no E_rot)")
            continue
        try:
            log.info(check_rotation_differences(rd, name, settings))
        except GeometryError as exc:
            warnings.append(exc.one_line() + "; its rotations are estimated from the athlete "
                            "alone (no E_rot)")
            log.warning(warnings[-1])
            continue
        ok = confident_pairs(rd, settings.min_inlier_fraction)
        dR[:, c] = filter_rotation_differences(rd.dR, ok, settings.median, settings.sigma,
                                               breaks)
        weights[:, c] = np.all(np.isfinite(dR[:, c]), axis=(1, 2))
        dR[~np.all(np.isfinite(dR), axis=(2, 3))] = np.eye(3)
    return dR, weights, per


def lagged_arrays(per_camera: dict, names, homography: dict) -> tuple:
    """The confident lagged pairs of all cameras, for the solver.

    Parameters
    ----------
    per_camera : dict
        ``{camera: RotationDifferences}`` (as returned by
        :func:`measure_differences`); cameras without lagged pairs, or missing,
        contribute none.
    names : sequence of str
        The cameras in solver order (the camera index).
    homography : dict
        ``[mocap.homography]`` (``min_inlier_fraction``, ``max_failed``,
        ``min_inliers``).

    Returns
    -------
    camera, first, second : (M,) int
        Camera index and the frames (0 = the first frame of the measured
        range) of each pair, ``R(second) = dR R(first)``.
    dR : (M, 3, 3)

    Notes
    -----
    A pair is kept when it is ``ok``, finite and has at least
    ``min_inlier_fraction`` times the median inliers of the camera's ok
    consecutive pairs (the rule of
    :func:`~photogram.mocap.motion.rotation_series.confident_pairs`); a
    camera whose consecutive pairs failed the check (more than
    ``max_failed`` failed: its differences get weight 0) gives none.
    """
    from photogram.mocap.motion.homography import HomographySettings
    st = HomographySettings(**homography)
    parts = []
    for c, name in enumerate(names):
        rd = per_camera.get(name)
        lg = None if rd is None else rd.lagged
        if lg is None or not len(lg.ok) or (rd.pairs and rd.failed > st.max_failed * rd.pairs):
            continue
        keep = np.asarray(lg.ok, bool) & np.all(np.isfinite(lg.dR), axis=(1, 2))
        ok = np.asarray(rd.ok, bool) & np.all(np.isfinite(rd.dR), axis=(1, 2))
        if st.min_inlier_fraction > 0 and ok.any():
            median = np.median(np.asarray(rd.inliers, float)[ok])
            keep &= np.asarray(lg.inliers, float) >= st.min_inlier_fraction * median
        idx = np.flatnonzero(keep)
        parts.append((np.full(len(idx), c), np.asarray(lg.first)[idx],
                      np.asarray(lg.second)[idx], np.asarray(lg.dR, float)[idx]))
    if not parts:
        z = np.zeros(0, int)
        return z, z.copy(), z.copy(), np.zeros((0, 3, 3))
    cam, first, second, dR = (np.concatenate(v) for v in zip(*parts))
    return cam.astype(int), first.astype(int), second.astype(int), dR


def rotation_errors(R, R_true, names) -> dict:
    """Per camera the median and 95th percentile of the angle (deg) between
    estimated and true rotations (F, C, 3, 3)."""
    E = np.einsum("fcab,fcdb->fcad", R, R_true)
    ang = np.degrees(np.arccos(np.clip((np.trace(E, axis1=2, axis2=3) - 1) / 2, -1, 1)))
    out = {n: {"median_deg": float(np.median(ang[:, c])),
               "p95_deg": float(np.percentile(ang[:, c], 95)),
               "max_deg": float(ang[:, c].max())} for c, n in enumerate(names)}
    out["all"] = {"median_deg": float(np.median(ang)),
                  "p95_deg": float(np.percentile(ang, 95))}
    return out


def differences_from_vectors(rvec_deg: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors in degrees."""
    r = np.radians(np.asarray(rvec_deg, float))
    return rodrigues_to_matrix(r.reshape(-1, 3)).reshape(r.shape[:-1] + (3, 3))


def chain_differences(per_camera: dict, names, homography: dict, n_frames: int,
                      breaks=()) -> np.ndarray:
    """(F-1, C, 3, 3): every camera's measured differences with failed and
    unconfident pairs interpolated and the median filter applied, but not
    smoothed (``sigma`` 0; identity for cameras without): the chain of
    :mod:`photogram.mocap.reconstruction.chain_offsets`. Smoothing keeps
    the sum of steady pans but shifts the chain where the pan speed changes
    (by about ``sigma^2 / 2`` times the angular acceleration: 0.39 deg on
    the simulated ski-ptz run, against a drift of 0.16 deg of the raw
    chain), and the offsets' prior trusts the chain."""
    from photogram.mocap.motion.homography import HomographySettings
    from photogram.mocap.motion.rotation_series import (confident_pairs,
                                                        filter_rotation_differences)
    st = HomographySettings(**homography)
    out = np.broadcast_to(np.eye(3), (max(n_frames - 1, 0), len(names), 3, 3)).copy()
    for c, name in enumerate(names):
        rd = per_camera.get(name)
        if rd is None or not len(rd.dR):
            continue
        try:
            out[:, c] = filter_rotation_differences(rd.dR, confident_pairs(
                rd, st.min_inlier_fraction), st.median, 0.0, breaks)
        except GeometryError:
            continue
    out[~np.all(np.isfinite(out), axis=(2, 3))] = np.eye(3)
    return out


def difference_sigmas(per_camera: dict, names, homography: dict) -> np.ndarray:
    """(C,) error per pair and axis (rad) of every camera's raw measured
    differences (``per_camera`` as returned by :func:`measure_differences`;
    the confident pairs of ``[mocap.homography]``): the prior of the chain's
    random walk in :mod:`photogram.mocap.reconstruction.chain_offsets`. NaN
    for a camera without differences."""
    from photogram.mocap.motion.homography import HomographySettings
    from photogram.mocap.motion.rotation_series import confident_pairs
    from photogram.mocap.motion.rotation_series import difference_noise
    fraction = HomographySettings(**homography).min_inlier_fraction
    out = np.full(len(names), np.nan)
    for c, name in enumerate(names):
        rd = per_camera.get(name)
        if rd is not None and len(rd.dR):
            out[c] = difference_noise(rd.dR, confident_pairs(rd, fraction))
    return out
