"""Checks of a motion-capture run that would otherwise end with exit 0 and a
wrong result: detections that cannot locate any joint in 3D, camera angles
that look like the wrong unit (issue 16, item 10).

* :func:`check_coverage`: a joint is located in 3D only where at least two
  cameras see it in the same frame with a confidence above the
  reconstruction's ``min_confidence`` (0 by default: any non-zero
  confidence). A run where no joint of any frame is seen so is refused
  (detections from one camera only, every confidence 0, cameras that never
  see the athlete at the same time); joints and cameras that never
  contribute are named in a warning.
* :func:`check_angle_unit`: the angles of the stations table and of
  ``camera_frames`` in the project's ``angle_unit``. Radians never exceed
  2 pi in magnitude, so ``rad`` with a larger angle (typically degrees) is
  refused; ``deg`` or ``gon`` with every angle within 2 pi (typically
  radians) is a warning: cameras whose axes all lie within 6 deg of the
  vertical are possible, if unusual for motion capture.
* :func:`check_energy`: a reconstruction whose energy is not finite (NaN
  or infinite) in any stage has no result to write: refused
  (:class:`~photogram.errors.GeometryError`, exit 2, no results folder).
* :func:`check_fit`: after the reconstruction, a camera whose median
  reprojection error exceeds 5 % of its image width (96 px of 1920) does not
  fit the joints: a warning naming it (wrong angles, unit, position, or
  frame numbering).
* :func:`check_bias`: a camera whose median residual vector (x, y) is
  longer than half its median reprojection error and than 2 px has a static
  bias (noise alone leaves a vector near zero): a warning naming it and
  the vector (principal point, rotation, a shifted image, or a frame
  offset while the athlete crosses the image steadily).
* :func:`check_outliers`: a camera whose median reprojection error is more
  than :data:`OUTLIER_FACTOR` (2.5) times the median of the other cameras'
  medians and at least :data:`OUTLIER_MIN_PX` (5 px) above it stands out:
  a warning naming it (its calibration, synchronisation or detections
  differ from the others').
"""

from __future__ import annotations

import math

import numpy as np

from photogram.errors import GeometryError, InputError

__all__ = ["check_coverage", "check_angle_unit", "check_energy", "check_fit", "check_bias",
           "TWO_PI",
           "POOR_FIT", "BIAS_SHARE", "check_outliers", "outlier_cameras", "OUTLIER_FACTOR",
           "OUTLIER_MIN_PX"]

TWO_PI = 2 * math.pi
#: a camera whose median reprojection error exceeds this fraction of its image width
POOR_FIT = 0.05
#: a median residual vector longer than this share of the median error is a static bias
BIAS_SHARE = 0.5
#: a camera whose median error exceeds this many times the other cameras' median ...
OUTLIER_FACTOR = 2.5
#: ... and is at least this many px above it stands out
OUTLIER_MIN_PX = 5.0


def _names(items, limit: int = 8) -> str:
    items = list(items)
    text = ", ".join(items[:limit])
    return text + (f" and {len(items) - limit} more" if len(items) > limit else "")


def check_coverage(obs: np.ndarray, camera_names, joint_names, frames, min_confidence: float,
                   file=None) -> list[str]:
    """Refuse detections that determine no joint; warn about joints and
    cameras that never count.

    Parameters
    ----------
    obs : ndarray (F, C, J, 3)
        x, y, confidence (x NaN: not detected).
    camera_names, joint_names : sequence of str
    frames : ndarray (F,)
        Frame numbers (for the message).
    min_confidence : float
        The reconstruction's threshold: a detection counts with a confidence
        above it (and above 0).
    file : str or Path, optional
        The file the detections come from (for the error).

    Returns
    -------
    list of str
        Warnings (joints never seen by two cameras at once, cameras with no
        detection that counts).

    Raises
    ------
    InputError
        No joint in any frame is seen by two cameras at once.
    """
    conf = np.nan_to_num(obs[..., 2], nan=0.0)
    seen = (conf > max(float(min_confidence), 0.0)) & np.all(np.isfinite(obs[..., :2]), -1)
    per_camera = seen.sum(axis=(0, 2))                     # (C,)
    pairs = seen.sum(axis=1) >= 2                          # (F, J)
    span = f"frames {int(frames[0])}..{int(frames[-1])}" if len(frames) else "no frames"
    threshold = "> 0" if min_confidence <= 0 else f"> {min_confidence:g} (min_confidence)"
    if not pairs.any():
        with_det = [c for c, n in zip(camera_names, per_camera) if n]
        if not with_det:
            what = (f"no detection of cameras {_names(camera_names)} in {span} has a "
                    f"confidence {threshold}")
            hint = "check the confidence column (0 means not detected) and min_confidence"
        elif len(with_det) == 1:
            others = [c for c in camera_names if c != with_det[0]]
            what = (f"only camera {with_det[0]} has detections with confidence {threshold} in "
                    f"{span} (none from {_names(others) or 'any other camera'}); a joint "
                    f"needs two cameras at once to be located in 3D")
            hint = "give the detections of at least two cameras"
        else:
            what = (f"no joint is seen by two cameras in the same frame with confidence "
                    f"{threshold} in {span} (detections that count: " + ", ".join(
                        f"{c} {n}" for c, n in zip(camera_names, per_camera)) + ")")
            hint = "check that the cameras' frames are synchronised and numbered alike"
        raise InputError("nothing to reconstruct: " + what, file=file, hint=hint)
    warnings = []
    never = [j for j, ok in zip(joint_names, pairs.any(axis=0)) if not ok]
    if never:
        warnings.append(f"{len(never)} joint(s) never seen by two cameras at once with "
                        f"confidence {threshold} ({_names(never)}): their positions come "
                        f"from the limb prior only, not from measurements")
    blind = [c for c, n in zip(camera_names, per_camera) if n == 0]
    if blind:
        warnings.append(f"camera(s) {_names(blind)} have no detection with confidence "
                        f"{threshold}: they do not contribute")
    return warnings


def check_angle_unit(values, unit: str, what: str, file=None, records=None) -> str | None:
    """Refuse or warn when angles look like another unit than ``unit``.

    Parameters
    ----------
    values : array_like (N, 3)
        omega, phi, kappa as written in the file (in ``unit``).
    unit : str
        The project's angle unit (rad, deg, gon).
    what : str
        The table, for the messages (e.g. "camera_frames").
    file : str or Path, optional
    records : array_like of int, optional
        The line of each row in ``file``.

    Returns
    -------
    str or None
        A warning (deg or gon that look like radians).

    Raises
    ------
    InputError
        ``unit`` is rad and an angle exceeds 2 pi in magnitude.
    """
    v = np.abs(np.asarray(values, float).reshape(-1, 3))
    v = np.where(np.isfinite(v), v, 0.0)
    if v.size == 0:
        return None
    largest = float(v.max())
    if unit == "rad" and largest > TWO_PI + 1e-9:
        row = int(np.argmax(v.max(axis=1)))
        line = None if records is None or len(records) <= row else int(records[row])
        guess = "degrees" if largest <= 360 + 1e-9 else "gon or degrees"
        raise InputError(f"an angle of {what} is {largest:g} but angle_unit is rad (radians "
                         f"never exceed 2 pi = 6.283): the angles look like {guess}",
                         file=file, line=line,
                         hint='set angle_unit = "deg" (or "gon") in [project] if that is '
                              'their unit, or give the angles in radians')
    if unit in ("deg", "gon") and 0 < largest <= TWO_PI + 1e-9:
        return (f"every angle of {what} is within 2 pi ({largest:g} {unit} at most) although "
                f"angle_unit is {unit}: they look like radians (if so, set angle_unit = "
                f"\"rad\" in [project]; omega and phi that small mean cameras looking "
                f"straight down, unusual for motion capture)")
    return None


def check_energy(stages, energy, file=None) -> None:
    """Refuse a reconstruction whose energy is not finite.

    Parameters
    ----------
    stages : list of dict
        The stages of the reconstruction (``Reconstruction.stages``); those
        with an ``energy`` are checked, in order.
    energy : float
        The energy reported (the last stage's).
    file : str or Path, optional
        The project (for the error).

    Raises
    ------
    GeometryError
        An energy is NaN or infinite: the solve diverged or was given
        non-finite input, and its joints are no result.
    """
    checked = [(k, st) for k, st in enumerate(stages) if "energy" in st]
    for k, st in checked + [(None, {"energy": energy})]:
        e = st.get("energy")
        if e is not None and not math.isfinite(float(e)):
            where = "the reconstruction" if k is None else (
                f"stage {k + 1} of {len(stages)} of the reconstruction"
                + (f" (sigma2 {st['sigma2']:g} px^2)" if "sigma2" in st else ""))
            raise GeometryError(
                f"the energy of {where} is {float(e)} (not finite): the solve diverged and "
                f"its joints are no result; nothing was written", file=file,
                hint="check the cameras (positions, rotations, interior orientation) and the "
                     "detections for non-finite or absurd values")
    return None


def check_fit(reprojection: dict, image_width) -> list[str]:
    """Warnings for cameras whose median reprojection error (px) exceeds
    :data:`POOR_FIT` of their image width (``reprojection``: per camera a
    dict with ``median_px``, as :func:`photogram.mocap.pipeline.reprojection_errors`;
    ``image_width``: per camera, NaN if unknown)."""
    poor = []
    for (name, r), width in zip(reprojection.items(), image_width):
        med = r.get("median_px")
        if med is not None and np.isfinite(width) and med > POOR_FIT * width:
            poor.append(f"{name} {med:.0f} px ({100 * med / width:.0f} %)")
    if not poor:
        return []
    return [f"median reprojection error above {100 * POOR_FIT:g} % of the image width: "
            f"{_names(poor)}; the reconstruction does not fit these cameras' detections "
            f"(camera angles in the wrong unit, wrong positions or rotations, or frames "
            f"numbered differently?)"]


def check_bias(reprojection: dict, min_px: float = 2.0) -> list[str]:
    """Warnings for cameras whose median residual vector (``median_dx_px``,
    ``median_dy_px`` of ``reprojection``, as
    :func:`photogram.mocap.pipeline.reprojection_errors`) is longer than
    :data:`BIAS_SHARE` of their median reprojection error and than
    ``min_px``."""
    biased = []
    for name, r in reprojection.items():
        dx, dy, med = r.get("median_dx_px"), r.get("median_dy_px"), r.get("median_px")
        if dx is None or dy is None or med is None:
            continue
        norm = math.hypot(dx, dy)
        if norm > max(BIAS_SHARE * med, min_px):
            biased.append(f"{name} ({dx:+.1f}, {dy:+.1f}) px of median error {med:.1f} px")
    if not biased:
        return []
    return [f"static bias of the detections against the reconstruction (median residual "
            f"vector): {_names(biased)}; not random error: the camera's calibration "
            f"(principal point, rotation) or image is offset, or its frames are (an athlete "
            f"moving steadily across the image; offsets = \"report\" in [mocap] measures "
            f"that)"]


def outlier_cameras(medians: dict) -> dict:
    """The cameras whose median reprojection error stands out.

    Parameters
    ----------
    medians : dict
        Camera name -> median reprojection error (px; None or NaN: unknown).

    Returns
    -------
    dict
        Camera name -> ``(median, others)`` for every camera whose median
        exceeds ``OUTLIER_FACTOR`` times ``others``, the median of the other
        cameras' medians, and ``others + OUTLIER_MIN_PX``; needs at least
        two other cameras with a median.
    """
    known = {n: float(m) for n, m in medians.items() if m is not None and np.isfinite(m)}
    out = {}
    for name, med in known.items():
        rest = [m for n, m in known.items() if n != name]
        if len(rest) < 2:
            continue
        others = float(np.median(rest))
        if med > OUTLIER_FACTOR * others and med > others + OUTLIER_MIN_PX:
            out[name] = (med, others)
    return out


def check_outliers(reprojection: dict) -> list[str]:
    """Warnings for the cameras of :func:`outlier_cameras` (``reprojection``:
    per camera a dict with ``median_px``)."""
    flagged = outlier_cameras({n: r.get("median_px") for n, r in reprojection.items()})
    if not flagged:
        return []
    names = [f"{n} {m:.1f} px (others {o:.1f} px)" for n, (m, o) in flagged.items()]
    return [f"camera residuals stand out (median reprojection error above "
            f"{OUTLIER_FACTOR:g} x the other cameras' median and {OUTLIER_MIN_PX:g} px above "
            f"it): {_names(names)}; its calibration, synchronisation or detections do not "
            f"agree with the other cameras'"]
