"""Metrics of appendix C: accuracy (PCK, MPJPE in 2D and 3D) and the
biomechanical quantities (centre of mass, speed, joint angles, lean,
fore/aft position). Definitions in docs/mocap.md, section "Metrics".

Every function takes joints of the SKI24 skeleton; other skeletons are
first mapped with :func:`ski_joints` (a joint a skeleton does not have is
NaN, and so is every quantity that needs it). Angles are in degrees,
lengths in the unit of the joints (m).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from photogram.mocap.body.anthropometry import segment_endpoints
from photogram.mocap.body.skeleton import BODY14, SKI24, Skeleton, mapping_to

__all__ = ["ski_joints", "centre_of_mass", "speed", "knee_flexion", "hip_flexion",
           "lean_angle", "fore_aft", "biomechanics", "mpjpe", "pck", "mpjpe_2d",
           "accuracy_3d", "bone_lengths", "segments", "median_residual", "gap_joints",
           "COM_JOINTS"]


def ski_joints(X: np.ndarray, skeleton: Skeleton) -> dict[str, np.ndarray]:
    """SKI24 name -> (F, 3) from joints (F, J, 3) of ``skeleton`` (NaN where
    the skeleton has no such joint; a mapped joint may be a mean)."""
    X = np.asarray(X, dtype=float)
    out = {n: np.full(X.shape[:-2] + X.shape[-1:], np.nan) for n in SKI24.joints}
    try:
        mapping = mapping_to(SKI24, skeleton)
    except Exception:
        return out
    for name, srcs in mapping.items():
        out[name] = np.mean(X[..., skeleton.indices(srcs), :], axis=-2)
    return out


def segments(n_frames: int, breaks=()) -> list[slice]:
    cuts = sorted({0, n_frames} | {int(b) for b in breaks if 0 < int(b) < n_frames})
    return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:])]


def _angle(u, v):
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.sum(u * v, -1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def centre_of_mass(J: dict) -> np.ndarray:
    """Whole-body CoM (F, 3) with de Leva's segments
    (:mod:`photogram.mocap.body.anthropometry`); a segment with a missing end
    point is left out and the others' masses renormalised (NaN only when
    the trunk is missing)."""
    acc, total = 0.0, 0.0
    trunk_ok = None
    for name, m, c, a, b in segment_endpoints(J):
        p = a + c * (b - a)
        ok = np.all(np.isfinite(p), axis=-1)
        if name == "trunk":
            trunk_ok = ok
        acc = acc + np.where(ok[..., None], m * p, 0.0)
        total = total + np.where(ok, m, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        com = acc / total[..., None]
    com[~trunk_ok] = np.nan
    return com


def speed(com: np.ndarray, fps: float, breaks=(), sigma: float = 1.5):
    """Velocity (F, 3) and speed (F,) of the CoM: Gaussian smoothing with
    ``sigma`` frames (per segment; the ends padded by point reflection, so
    that a uniform motion is not slowed down there), then central
    differences (one-sided at the ends) times ``fps``."""
    vel = np.full(com.shape, np.nan)
    for sl in segments(len(com), breaks):
        c = com[sl]
        if len(c) < 2:
            continue
        ok = np.all(np.isfinite(c), axis=1)
        if ok.sum() < 2:
            continue
        idx = np.arange(len(c))
        filled = np.stack([np.interp(idx, idx[ok], c[ok, k]) for k in range(3)], -1)
        if sigma > 0:       # pad by point reflection: straight motion stays straight
            n = int(4 * sigma) + 1
            padded = np.pad(filled, ((n, n), (0, 0)), mode="reflect", reflect_type="odd")
            sm = gaussian_filter1d(padded, sigma, axis=0, mode="nearest")[n:len(padded) - n]
        else:
            sm = filled
        v = np.gradient(sm, axis=0) * fps
        v[~ok] = np.nan
        vel[sl] = v
    return vel, np.linalg.norm(vel, axis=-1)


def knee_flexion(J: dict, side: str) -> np.ndarray:
    """180 deg minus the angle hip-knee-ankle (0: straight leg)."""
    return 180.0 - _angle(J[side + "_hip"] - J[side + "_knee"], J[side + "_ankle"] - J[side + "_knee"])


def hip_flexion(J: dict, side: str) -> np.ndarray:
    """180 deg minus the angle between the trunk (mid-hips to mid-shoulders)
    and the thigh (hip to knee): 0 standing straight, unsigned."""
    trunk = 0.5 * (J["r_shoulder"] + J["l_shoulder"]) - 0.5 * (J["r_hip"] + J["l_hip"])
    return 180.0 - _angle(trunk, J[side + "_knee"] - J[side + "_hip"])


def _travel_frame(J, vel, up):
    """Unit direction of travel (horizontal w.r.t. ``up``) and the left axis."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    body_fwd = np.cross(up, J["l_hip"] - J["r_hip"])          # forward from the hip axis
    d = np.where((np.linalg.norm(vel, axis=-1) >= 1.0)[..., None], vel, body_fwd)
    d = d - np.sum(d * up, -1, keepdims=True) * up
    with np.errstate(invalid="ignore", divide="ignore"):
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return d, np.cross(up, d), up


def lean_angle(J: dict, com: np.ndarray, vel: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Signed angle (deg) between ``up`` and the line from the mid-ankles to
    the CoM, in the plane perpendicular to the direction of travel (the
    CoM velocity, or the body's forward direction below 1 m/s); positive
    when leaning to the left of the direction of travel."""
    d, left, up = _travel_frame(J, vel, up)
    p = com - 0.5 * (J["r_ankle"] + J["l_ankle"])
    return np.degrees(np.arctan2(np.sum(p * left, -1), np.sum(p * up, -1)))


def fore_aft(J: dict, com: np.ndarray, outside_leg: str = "extended"):
    """Fore/aft angle (deg) and distance of the CoM over the outside ski.

    The outside leg is, per frame, the leg with the larger included knee
    angle (smaller knee flexion: the extended leg) with ``outside_leg =
    "extended"`` (default), or the more flexed one with ``"flexed"``. With
    ``s`` the unit axis of that ski (tail to tip; heel to toes without skis)
    and ``d = CoM - ankle``: distance ``d . s`` (positive: CoM ahead of the
    ankle), angle ``atan2(d . s, |d - (d . s) s|)``.

    Returns angle (F,), distance (F,), side (F,) array of "r"/"l" ("" if
    unknown).
    """
    kr, kl = knee_flexion(J, "r"), knee_flexion(J, "l")
    right = kr <= kl if outside_leg == "extended" else kr >= kl
    side = np.where(np.isfinite(kr) & np.isfinite(kl), np.where(right, "r", "l"), "")
    out_a, out_d = np.full(len(com), np.nan), np.full(len(com), np.nan)
    for s in ("r", "l"):
        axis = J[s + "_ski_tip"] - J[s + "_ski_tail"]
        alt = J[s + "_toes"] - J[s + "_heel"]
        axis = np.where(np.all(np.isfinite(axis), -1, keepdims=True), axis, alt)
        with np.errstate(invalid="ignore", divide="ignore"):
            axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        d = com - J[s + "_ankle"]
        along = np.sum(d * axis, -1)
        perp = np.linalg.norm(d - along[..., None] * axis, axis=-1)
        m = side == s
        out_d[m] = along[m]
        out_a[m] = np.degrees(np.arctan2(along, perp))[m]
    return out_a, out_d, side


#: the SKI24 joints of the centre of mass (de Leva's segments, section 3)
COM_JOINTS = ("head", "neck", "r_shoulder", "l_shoulder", "r_elbow", "l_elbow", "r_hand",
              "l_hand", "r_hip", "l_hip", "r_knee", "l_knee", "r_ankle", "l_ankle", "r_heel",
              "l_heel", "r_toes", "l_toes")
#: the joints (besides the CoM's) each quantity depends on
_DEPENDS = {"knee_flexion_r": ("r_hip", "r_knee", "r_ankle"),
            "knee_flexion_l": ("l_hip", "l_knee", "l_ankle"),
            "hip_flexion_r": ("r_shoulder", "l_shoulder", "r_hip", "l_hip", "r_knee"),
            "hip_flexion_l": ("r_shoulder", "l_shoulder", "r_hip", "l_hip", "l_knee"),
            "fore_aft": ("r_hip", "l_hip", "r_knee", "l_knee", "r_ankle", "l_ankle",
                         "r_ski_tip", "l_ski_tip", "r_ski_tail", "l_ski_tail")}


def gap_joints(gaps: np.ndarray, skeleton: Skeleton) -> dict[str, np.ndarray]:
    """SKI24 name -> (F,) True where a joint of ``skeleton`` that it is
    mapped from is a gap (``gaps`` (F, J) of ``skeleton``); joints the
    skeleton does not have are never gaps (they are missing throughout)."""
    gaps = np.asarray(gaps, bool)
    out = {n: np.zeros(len(gaps), bool) for n in SKI24.joints}
    try:
        mapping = mapping_to(SKI24, skeleton)
    except Exception:
        return out
    for name, srcs in mapping.items():
        out[name] = np.any(gaps[:, skeleton.indices(srcs)], axis=1)
    return out


def biomechanics(X: np.ndarray, skeleton: Skeleton, fps: float, breaks=(),
                 up=(0.0, 0.0, 1.0), outside_leg: str = "extended",
                 gaps: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """All per-frame quantities as columns (name -> (F,) array).

    ``gaps`` (F, J), optional: the joint-frames the data do not determine
    (:mod:`photogram.mocap.reconstruction.observability`). A quantity is
    NaN at a frame where a joint it depends on is a gap: the CoM (and the
    speed, lean and fore/aft position from it) where any joint of
    :data:`COM_JOINTS` is, rather than leaving that segment out as for a
    joint the skeleton does not have.
    """
    J = ski_joints(X, skeleton)
    com = centre_of_mass(J)
    hole = None
    if gaps is not None:
        hole = gap_joints(gaps, skeleton)
        com[np.any([hole[n] for n in COM_JOINTS], axis=0)] = np.nan
    vel, spd = speed(com, fps, breaks)
    ang, dist, side = fore_aft(J, com, outside_leg)
    out = {"com_x": com[:, 0], "com_y": com[:, 1], "com_z": com[:, 2], "speed": spd,
           "knee_flexion_r": knee_flexion(J, "r"), "knee_flexion_l": knee_flexion(J, "l"),
           "hip_flexion_r": hip_flexion(J, "r"), "hip_flexion_l": hip_flexion(J, "l"),
           "lean": lean_angle(J, com, vel, up), "outside": side,
           "fore_aft_angle": ang, "fore_aft_distance": dist}
    if hole is not None:
        for key, names in _DEPENDS.items():
            bad = np.any([hole[n] for n in names], axis=0)
            for k in ((key,) if key in out else ("fore_aft_angle", "fore_aft_distance",
                                                   "outside")):
                out[k] = np.where(bad, "" if k == "outside" else np.nan, out[k])
    return out


# --------------------------------------------------------------------------
# accuracy against a reference
# --------------------------------------------------------------------------
def mpjpe(X: np.ndarray, T: np.ndarray, joints=None) -> float:
    """Mean Euclidean distance over frames and joints (NaN-aware)."""
    if joints is not None:
        X, T = X[:, joints], T[:, joints]
    return float(np.nanmean(np.linalg.norm(X - T, axis=-1)))


def _hip_centred(X, skeleton: Skeleton):
    J = ski_joints(X, skeleton)
    return X - (0.5 * (J["r_hip"] + J["l_hip"]))[:, None, :]


def accuracy_3d(X: np.ndarray, T: np.ndarray, skeleton: Skeleton) -> dict[str, float]:
    """Global, hip-centred and normalised MPJPE, all joints and the 14 body
    joints. Normalised: hip-centred with X scaled per frame by
    ``s = <X, T> / <X, X>`` (least squares)."""
    Xh, Th = _hip_centred(X, skeleton), _hip_centred(T, skeleton)
    ok = np.isfinite(Xh) & np.isfinite(Th)
    num = np.sum(np.where(ok, Xh * Th, 0.0), axis=(1, 2))
    den = np.sum(np.where(ok, Xh * Xh, 0.0), axis=(1, 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        Xn = Xh * (num / den)[:, None, None]
    body = [skeleton.index(j) for j in BODY14 if j in skeleton.joints] \
        if skeleton.name == "ski24" else None
    out = {}
    for tag, sel in (("", None), ("_body", body)):
        if tag and sel is None:
            continue
        out["mpjpe" + tag] = mpjpe(X, T, sel)
        out["mpjpe_hip" + tag] = mpjpe(Xh, Th, sel)
        out["mpjpe_normalized" + tag] = mpjpe(Xn, Th, sel)
    return out


def pck(pred: np.ndarray, truth: np.ndarray, skeleton: Skeleton, factor: float = 1.0):
    """Fraction of 2D joints (F, C, J, 2) within ``factor`` times the true
    head-neck distance of their image (NaN predictions count as wrong)."""
    J = {n: truth[..., k, :] for k, n in enumerate(skeleton.joints)}
    if skeleton.name != "ski24":
        J = ski_joints(truth, skeleton)
    radius = factor * np.linalg.norm(J["head"] - J["neck"], axis=-1)      # (F, C)
    valid = np.all(np.isfinite(truth), -1) & np.isfinite(radius)[..., None]
    err = np.linalg.norm(pred - truth, axis=-1)
    hit = np.where(np.isfinite(err), err <= radius[..., None], False)
    return float(np.sum(hit & valid) / max(np.sum(valid), 1))


def mpjpe_2d(pred: np.ndarray, truth: np.ndarray, image_width) -> dict[str, float]:
    """2D MPJPE in px and in normalised image coordinates (the image width
    maps to [-1, 1]: distances times ``2 / width``); ``image_width`` per
    camera (C,)."""
    err = np.linalg.norm(pred - truth, axis=-1)                           # (F, C, J)
    norm = err * (2.0 / np.asarray(image_width, float))[None, :, None]
    return {"mpjpe_2d_px": float(np.nanmean(err)), "mpjpe_2d_normalized": float(np.nanmean(norm))}


def bone_lengths(X: np.ndarray, skeleton: Skeleton, limbs=None) -> dict[str, tuple]:
    """Per limb ``"a-b": (mean, std, coefficient of variation)`` over frames."""
    out = {}
    for a, b in (limbs or skeleton.limbs):
        if a not in skeleton.joints or b not in skeleton.joints:
            continue
        d = np.linalg.norm(X[:, skeleton.index(a)] - X[:, skeleton.index(b)], axis=-1)
        d = d[np.isfinite(d)]
        if len(d) < 2:
            continue
        m, s = float(np.mean(d)), float(np.std(d, ddof=1))
        out[f"{a}-{b}"] = (m, s, s / m if m > 0 else np.nan)
    return out


def median_residual(projected: np.ndarray, detected: np.ndarray, use: np.ndarray) -> np.ndarray:
    """Per camera the median reprojection residual vector (C, 2), px.

    Parameters
    ----------
    projected, detected : ndarray (F, C, J, 2)
        Projections of the reconstructed joints and the detections.
    use : ndarray (F, C, J) of bool
        The detections counted (the reprojection statistics' selection).

    Returns
    -------
    ndarray (C, 2)
        Medians of ``detected - projected`` in x and y separately, over all
        frames and joints used (NaN: none). Noise gives about zero (the
        median of n symmetric residuals is within ~1.25 sigma / sqrt(n));
        a static bias of the camera (principal point, rotation, a shifted
        image) shows as a vector of about the error's size.
    """
    r = np.asarray(detected, float) - np.asarray(projected, float)
    ok = np.asarray(use, bool) & np.all(np.isfinite(r), -1)
    out = np.full((r.shape[1], 2), np.nan)
    for c in range(r.shape[1]):
        rc = r[:, c][ok[:, c]]
        if len(rc):
            out[c] = np.median(rc, axis=0)
    return out
