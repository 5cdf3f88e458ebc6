"""Comparisons of a motion-capture result (docs/mocap.md): reprojection
errors per camera, the accuracy against a truth joints table (``truth``)
and against a reference reconstruction (``reference_trc``, e.g. Pose2Sim's
triangulation: its points projected with the same cameras against the same
detections)."""

from __future__ import annotations

import numpy as np

from photogram.mocap.evaluation.metrics import (accuracy_3d, biomechanics, bone_lengths, mpjpe_2d,
                                                pck)
from photogram.mocap.files import read_joints
from photogram.mocap.reconstruction.cameras import MocapCameras

__all__ = ["reprojection_errors", "compare_truth", "compare_reference", "REFERENCE_CONFIDENCE",
           "ANGLES"]

#: detections used for the reprojection errors (Pose2Sim's likelihood threshold)
REFERENCE_CONFIDENCE = 0.3
ANGLES = ("knee_flexion_r", "knee_flexion_l", "hip_flexion_r", "hip_flexion_l", "lean",
          "fore_aft_angle")


def reprojection_errors(X, cameras: MocapCameras, obs, min_confidence=REFERENCE_CONFIDENCE,
                        joints=None) -> dict:
    """Per camera: median, mean and 90th percentile (px) of the distance
    between the projection of X (F, J, 3) and the detections (F, C, J, 3)
    with confidence >= ``min_confidence`` (optionally only ``joints``), and
    the median residual vector (detection minus projection, x and y:
    :func:`photogram.mocap.evaluation.metrics.median_residual`)."""
    proj = cameras.project(X)
    err = np.linalg.norm(proj - obs[..., :2], axis=-1)
    use = np.nan_to_num(obs[..., 2]) >= min_confidence
    if joints is not None:
        keep = np.zeros(obs.shape[2], bool)
        keep[list(joints)] = True
        use &= keep[None, None, :]
    from photogram.mocap.evaluation.metrics import median_residual
    vec = median_residual(proj, obs[..., :2], use)
    out = {}
    for c, name in enumerate(cameras.names):
        e = err[:, c][use[:, c] & np.isfinite(err[:, c])]
        out[name] = {"median_px": float(np.median(e)) if len(e) else None,
                     "median_dx_px": float(vec[c, 0]) if len(e) else None,
                     "median_dy_px": float(vec[c, 1]) if len(e) else None,
                     "mean_px": float(np.mean(e)) if len(e) else None,
                     "p90_px": float(np.percentile(e, 90)) if len(e) else None,
                     "n": int(len(e))}
    return out


def _aligned(frames_ref, X_ref, frames):
    out = np.full((len(frames),) + X_ref.shape[1:], np.nan)
    index = {int(f): i for i, f in enumerate(frames_ref)}
    for i, f in enumerate(frames):
        if int(f) in index:
            out[i] = X_ref[index[int(f)]]
    return out


def compare_truth(result, ms, true_cameras: MocapCameras | None) -> None:
    """Accuracy against ``truth`` (a joints table): 3D errors, errors of the
    biomechanical quantities, and 2D errors (docs/mocap.md section 7).

    The 2D metrics: ``*_detections`` compare the detections with the truth
    projected through ``true_cameras`` (the cameras that took the images:
    with known rotations the project's cameras; with ``rotation =
    "estimate"`` the project's centres and zoom with the rotations of
    ``truth_rotations``); ``true_cameras`` None (rotations estimated, no
    ``truth_rotations``) leaves them out rather than compare the detections
    with the truth seen through estimated cameras. ``*_reprojected`` compare
    the reconstruction with the truth, both projected through
    ``result.cameras`` (the estimated rotations when estimated: the 3D error
    as the reconstruction's cameras see it). With estimated rotations
    ``accuracy["cameras_2d"]`` says which cameras each used.
    """
    sk = result.skeleton
    frames_t, T = read_joints(ms.truth, sk)
    T = _aligned(frames_t, T, result.frames)
    X = result.reconstruction.joints
    acc = accuracy_3d(X, T, sk)
    tb = biomechanics(T, sk, result.fps, result.breaks, ms.up, ms.outside_leg)
    com = np.stack([result.biomechanics[k] for k in ("com_x", "com_y", "com_z")], -1)
    com_t = np.stack([tb[k] for k in ("com_x", "com_y", "com_z")], -1)
    acc["com_error"] = float(np.nanmean(np.linalg.norm(com - com_t, axis=-1)))
    acc["speed_mae"] = float(np.nanmean(np.abs(result.biomechanics["speed"] - tb["speed"])))
    for k in ANGLES + ("fore_aft_distance",):
        acc[k + "_mae"] = float(np.nanmean(np.abs(result.biomechanics[k] - tb[k])))
    knees = np.concatenate([np.abs(result.biomechanics[k] - tb[k]) for k in
                            ("knee_flexion_r", "knee_flexion_l")])
    acc["knee_flexion_mae"] = float(np.nanmean(knees))
    width = np.where(np.isfinite(result.cameras.image_size[:, 0]),
                     result.cameras.image_size[:, 0], 1.0)
    det = np.where((np.nan_to_num(result.observations[..., 2]) > 0)[..., None],
                   result.observations[..., :2], np.nan)
    pairs = [("reprojected", result.cameras.project(X), result.cameras.project(T))]
    if true_cameras is not None:
        pairs.insert(0, ("detections", det, true_cameras.project(T)))
    for tag, pred, truth_2d in pairs:
        acc[f"pck_{tag}"] = pck(pred, truth_2d, sk)
        for k, v in mpjpe_2d(pred, truth_2d, width).items():
            acc[f"{k}_{tag}"] = v
    if ms.rotation == "estimate":
        acc["cameras_2d"] = {
            "detections": "not computed: no truth_rotations (the detections are compared "
                          "with the truth seen through the true cameras only)"
            if true_cameras is None else
            "true: the project's centres and zoom with the rotations of truth_rotations",
            "reprojected": "estimated: the reconstruction and the truth both projected "
                           "through the estimated cameras"}
    result.truth, result.truth_biomechanics, result.accuracy = T, tb, acc


def compare_reference(result, ms) -> None:
    """Reprojection errors and bone-length CV of a reference TRC (Z-up
    world: read with ``rotate_to_z_up``), over the joints both have."""
    from photogram.io.trc import read_trc
    sk = result.skeleton
    trc = read_trc(ms.reference_trc, rotate_to_z_up=True)
    common = [j for j in sk.joints if j in trc.markers]
    if not common:
        raise ms.error(("reference_trc",), f"the reference TRC has no marker named like a "
                       f"joint of skeleton {sk.name}",
                       hint="the markers must carry the skeleton's joint names")
    n = min(len(trc.frames), len(result.frames))
    R = np.full(result.reconstruction.joints.shape, np.nan)
    for j in common:
        R[:n, sk.index(j)] = trc.markers[j][:n]
    if trc.units and trc.units != "m":
        from photogram.project.model import LENGTH_UNITS
        R *= LENGTH_UNITS.get(trc.units, 1.0)
    idx = [sk.index(j) for j in common]
    limbs = [(a, b) for a, b in sk.limbs if a in common and b in common]
    ours = result.reconstruction.joints.copy()
    ours[n:] = np.nan
    mine = reprojection_errors(ours, result.cameras, result.observations, joints=idx)
    theirs = reprojection_errors(R, result.cameras, result.observations, joints=idx)
    cv_ours = bone_lengths(ours, sk, limbs)
    cv_ref = bone_lengths(R, sk, limbs)
    result.reference = {
        "file": str(ms.reference_trc), "frames": n, "joints": common,
        "alignment": "row i of the TRC is frame i of the detections",
        "confidence_threshold": REFERENCE_CONFIDENCE,
        "reprojection": {c: {"ours_median_px": mine[c]["median_px"],
                             "reference_median_px": theirs[c]["median_px"],
                             "ours_median_vector_px": [mine[c]["median_dx_px"],
                                                       mine[c]["median_dy_px"]],
                             "reference_median_vector_px": [theirs[c]["median_dx_px"],
                                                            theirs[c]["median_dy_px"]],
                             "n": mine[c]["n"]} for c in result.cameras.names},
        "bone_cv": {k: {"ours": cv_ours[k][2], "reference": cv_ref.get(k, (0, 0, np.nan))[2],
                        "ours_mean_m": cv_ours[k][0],
                        "reference_mean_m": cv_ref.get(k, (np.nan,))[0]}
                    for k in cv_ours},
        "bone_cv_mean": {"ours": float(np.nanmean([v[2] for v in cv_ours.values()])),
                         "reference": float(np.nanmean([v[2] for v in cv_ref.values()]))},
        "mpjpe_to_reference": float(np.nanmean(np.linalg.norm(ours[:, idx] - R[:, idx],
                                                              axis=-1))),
    }
