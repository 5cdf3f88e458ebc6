"""The motion-capture pipeline of ``photogram mocap``: cameras, detections,
tracking, reconstruction, metrics, and the comparisons with a truth or a
reference reconstruction.

Steps (docs/mocap.md): read the cameras (``[cameras]``/``[stations]`` or a
Pose2Sim calibration; rotations per frame from ``camera_frames``); open the
source and track the athlete in every camera; map the detections onto the
reconstruction skeleton (``skeleton`` of ``[mocap]``; default: the source's,
a generic skeleton); cut the frame range; reconstruct
(:mod:`photogram.mocap.reconstruction.reconstruct`); post-filter the joints
(``[mocap.filter]``, :mod:`photogram.mocap.reconstruction.filtering`);
compute the per-frame quantities (:mod:`photogram.mocap.evaluation.metrics`),
the reprojection errors per camera and the bone-length variation; compare
with ``truth`` (a joints table) and with ``reference_trc`` (e.g. Pose2Sim's
triangulation: its points projected with the same cameras against the same
detections).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import Skeleton, get_skeleton, map_joints
from photogram.mocap.evaluation.metrics import (accuracy_3d, biomechanics, bone_lengths, mpjpe_2d,
                                                pck)
from photogram.mocap.files import (cameras_from_project, read_camera_frames, read_joints,
                                   read_limb_lengths)
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.mocap.reconstruction.reconstruct import (Reconstruction, ReconstructionSettings,
                                                        reconstruct)
from photogram.mocap.sources import open_source
from photogram.mocap.tracking.athlete import TrackingSettings

__all__ = ["MocapResult", "run_mocap", "reprojection_errors", "REFERENCE_CONFIDENCE"]

log = logging.getLogger(__name__)

#: detections used for the reprojection errors (Pose2Sim's likelihood threshold)
REFERENCE_CONFIDENCE = 0.3
_ANGLES = ("knee_flexion_r", "knee_flexion_l", "hip_flexion_r", "hip_flexion_l", "lean",
           "fore_aft_angle")


@dataclass
class MocapResult:
    """Everything ``photogram mocap`` writes."""

    skeleton: Skeleton
    fps: float
    frames: np.ndarray              # (F,) frame numbers (as in the detections)
    cameras: MocapCameras
    observations: np.ndarray        # (F, C, J, 3)
    tracked: list
    reconstruction: Reconstruction
    biomechanics: dict
    reprojection: dict
    bones: dict
    breaks: list
    truth: np.ndarray | None = None
    truth_biomechanics: dict | None = None
    accuracy: dict | None = None
    reference: dict | None = None
    info: dict = field(default_factory=dict)

    @property
    def times(self) -> np.ndarray:
        return (self.frames - self.frames[0]) / self.fps


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


def _observations(project, cameras: MocapCameras, allow_plugin: bool = False):
    ms = project.mocap
    source = open_source(ms, cameras.names, project.folder, allow_plugin=allow_plugin)
    tracking = TrackingSettings(**ms.tracking)
    tracked = []
    for name in cameras.names:
        if name not in source.cameras:
            tracked.append(None)
            continue
        t0 = time.perf_counter()
        tracked.append(source.track(name, tracking, wide=name in ms.source.wide))
        log.debug("camera %s: %d frames tracked (%.1f s)", name, len(tracked[-1].joints),
                 time.perf_counter() - t0)
    F = max((len(t.joints) for t in tracked if t is not None), default=0)
    if F == 0:
        raise InputError("the source has no detections", file=project.path)
    J = source.skeleton.n_joints
    obs = np.full((F, len(cameras.names), J, 3), np.nan)
    obs[..., 2] = 0.0
    for c, t in enumerate(tracked):
        if t is not None:
            obs[:len(t.joints), c] = t.joints
    return source, tracked, obs


def _shift_candidates(det, rows, k: int):
    """A camera's candidates and its per-frame choice ``rows`` renumbered
    as if the camera had started ``k`` frames later (its frame f + k is
    frame f; the synchronisation offset's whole frames)."""
    from dataclasses import replace as _replace
    frames = det.frames - k
    keep = (frames >= 0) & (frames < det.n_frames)
    new_index = np.cumsum(keep) - 1
    det = _replace(det, frames=frames[keep], joints=det.joints[keep], boxes=det.boxes[keep],
                   person=det.person[keep])
    out = np.full(len(rows), -1)
    src = np.arange(len(rows)) + k
    ok = (src >= 0) & (src < len(rows))
    old = np.where(ok, rows[np.clip(src, 0, len(rows) - 1)], -1)
    take = ok & (old >= 0)
    take[take] &= keep[old[take]]
    out[take] = new_index[old[take]]
    return det, out


def _choose_people(source, cameras: MocapCameras, tracked, obs, tracking: TrackingSettings,
                   first: int = 0, runs=(), offsets=None):
    """The athlete's joints chosen by multi-view consistency (docs/mocap.md
    section 5; :mod:`photogram.mocap.tracking.multiview`): the observations
    and the per-camera report (None: not run). ``offsets`` (camera ->
    frames, applied to ``obs`` already): the candidates are renumbered by
    the whole frames, the chosen joints shifted by the rest."""
    if not tracking.multiview or sum(t is not None for t in tracked) < 2:
        return obs, None
    from photogram.mocap.tracking.athlete import select_person
    from photogram.mocap.tracking.multiview import (associate, describe,
                                                    settings_from_tracking,
                                                    tracked_candidates)
    candidates, per_camera = [], []
    for name, t in zip(cameras.names, tracked):
        if t is None:
            candidates.append(None)
            per_camera.append(None)
            continue
        try:
            det = source.detections(name)
            rows = select_person(det, tracking.min_confidence)
        except NotImplementedError:                 # image detectors: the tracked person
            det, rows = tracked_candidates(t, source.skeleton)
        k = int(np.floor((offsets or {}).get(name, 0.0)))
        if k:
            det, rows = _shift_candidates(det, np.asarray(rows), k)
        candidates.append(det)
        per_camera.append(rows[:obs.shape[0]])
    assoc = associate(candidates, cameras, obs.shape[0], settings_from_tracking(tracking),
                      breaks=[r - first for r in runs])
    report = assoc.report(cameras.names, per_camera)
    for line in describe(report):
        log.info("%s", line)
    chosen = assoc.joints(candidates)
    for name, o in (offsets or {}).items():           # the fraction of a frame
        if o - np.floor(o) > 1e-9:
            from photogram.mocap.evaluation.sync_shift import shift_observations
            c = cameras.index(name)
            chosen[:, c] = shift_observations(chosen[:, c], o - np.floor(o))
    for lo, hi in assoc.undecided_runs:     # mostly inconsistent: the cameras are wrong,
        chosen[lo:hi] = obs[lo:hi]          # the per-camera choice is kept
        log.info("frames %d..%d: the cameras are mostly inconsistent with each other (%g px); "
                 "the per-camera choice of the athlete is kept", first + lo, first + hi - 1,
                 tracking.association_px)
    people = {"cameras": report,
              "undecided_runs": [[first + lo, first + hi - 1] for lo, hi in assoc.undecided_runs],
              "seed_frames": [first + f for f in assoc.seeds], "sizes": assoc.sizes,
              "settings": vars(assoc.settings).copy()}
    return chosen, people


def run_mocap(project, *, allow_plugin: bool = False) -> MocapResult:
    """Run the whole pipeline on a project read by
    :func:`photogram.project.read_project` (with a ``[mocap]`` section);
    ``allow_plugin``: the user's opt-in to import a ``plugin`` network
    (``--allow-plugin``)."""
    ms = project.mocap
    timings = {}
    t0 = time.perf_counter()
    cameras = cameras_from_project(project)
    source, tracked, obs = _observations(project, cameras, allow_plugin)
    timings["tracking_s"] = time.perf_counter() - t0
    first = int(getattr(source, "first_frame", 0))
    F = obs.shape[0]
    estimate = ms.rotation == "estimate"
    if ms.camera_frames is not None:
        cameras = read_camera_frames(ms.camera_frames, cameras, project, first, F,
                                     rotations=not estimate)
    # synchronisation first: the multi-view choice of the athlete compares
    # the cameras frame by frame
    sync_info = None
    if ms.offsets is not None:
        obs, cameras, sync_info = _synchronise(obs, cameras, ms)
    obs, people = (obs, None) if estimate else _choose_people(
        source, cameras, tracked, obs, TrackingSettings(**ms.tracking), first, ms.runs,
        (sync_info or {}).get("applied"))
    skeleton = source.skeleton
    if ms.skeleton is not None:
        try:
            target = get_skeleton(ms.skeleton)
        except InputError as exc:
            raise ms.error(("skeleton",), exc.what, hint=exc.hint) from None
        if target.name != skeleton.name:
            try:
                obs = map_joints(obs, skeleton, target)
            except InputError as exc:
                raise ms.error(("skeleton",), exc.what, hint=exc.hint) from None
            skeleton = target
    frames = first + np.arange(F)
    lo, hi = 0, F
    if ms.frames is not None:
        lo, hi = max(ms.frames[0] - first, 0), min(ms.frames[1] - first + 1, F)
        if hi <= lo:
            raise ms.error(("frames",), f"frames {list(ms.frames)} select nothing of frames "
                           f"{first}..{first + F - 1}")
    obs, frames = obs[lo:hi], frames[lo:hi]
    cameras = cameras.select_frames(np.arange(lo, hi)) if cameras.n_frames else cameras
    tracked = [None if t is None else type(t)(t.camera, t.joints[lo:hi], t.detected[lo:hi],
                                                t.boxes[lo:hi], t.person[lo:hi])
               for t in tracked]
    breaks = [r - frames[0] for r in ms.runs if frames[0] < r <= frames[-1]]
    rs = dict(ms.reconstruction)
    from photogram.mocap.evaluation.checks import check_coverage
    for note in check_coverage(obs, cameras.names, skeleton.joints, frames,
                               rs.get("min_confidence", 0.0),
                               file=ms.source.path or project.path):
        log.warning("warning: %s", note)
        project.warnings.append(note)
    if ms.limb_lengths is not None:
        rs["limb_lengths"] = read_limb_lengths(ms.limb_lengths, skeleton)
    from photogram.project.model import LENGTH_UNITS
    rs.setdefault("limb_unit", 0.01 / LENGTH_UNITS[project.units.length])   # 1 cm
    rs["fps"] = ms.fps
    rotation_info = {}
    if estimate:
        from photogram.mocap.motion.unknown_rotations import measure_differences
        from photogram.mocap.reconstruction.estimate import (estimate_poses_and_rotations,
                                                             estimate_settings)
        t1 = time.perf_counter()
        from photogram.project.output_policy import PARTIAL
        dR, weights, per_camera = measure_differences(
            ms, cameras, tracked, (lo, hi), first, project.warnings, breaks,
            cache=project.output_folder() / PARTIAL / "rotation_differences")
        timings["rotation_differences_s"] = time.perf_counter() - t1
        rec = estimate_poses_and_rotations(obs, cameras, skeleton, dR, weights,
                                           estimate_settings(**rs), breaks)
        cameras = replace(cameras, R=rec.R)
        rotation_info = {"differences": per_camera, "weights": weights}
    else:
        rec = reconstruct(obs, cameras, skeleton, ReconstructionSettings(**rs), breaks)
    log.info("reconstruction: %d frames, %d windows, %s, energy %.6g, %d iterations, %.1f s",
             len(frames), rec.n_windows, rec.solver, rec.energy, rec.iterations, rec.seconds)
    timings["reconstruction_s"] = rec.seconds
    rec, filter_report = _post_filter(rec, ms, breaks, project.warnings)
    bio = biomechanics(rec.joints, skeleton, ms.fps, breaks, ms.up, ms.outside_leg)
    result = MocapResult(
        skeleton=skeleton, fps=ms.fps, frames=frames, cameras=cameras, observations=obs,
        tracked=tracked, reconstruction=rec, biomechanics=bio,
        reprojection=reprojection_errors(rec.joints, cameras, obs),
        bones=bone_lengths(rec.joints, skeleton), breaks=breaks,
        info={"source": source.describe(), "timings": timings, "rotation": ms.rotation,
              "filter": filter_report, **rotation_info,
              **({"sync": sync_info} if sync_info else {}),
              **({"people": people} if people else {})})
    from photogram.mocap.evaluation.checks import check_fit
    from photogram.mocap.evaluation.checks import check_bias
    for note in (check_fit(result.reprojection, cameras.image_size[:, 0])
                 + check_bias(result.reprojection)):
        log.warning("warning: %s", note)
        project.warnings.append(note)
    if estimate and ms.truth_rotations is not None:
        from photogram.mocap.motion.unknown_rotations import rotation_errors
        truth = read_camera_frames(ms.truth_rotations, cameras, project, first,
                                   lo + len(frames)).select_frames(np.arange(lo, hi))
        result.info["rotation_errors"] = rotation_errors(rec.R, truth.rotations(len(frames)),
                                                         cameras.names)
        result.info["rotation_errors_bootstrap"] = rotation_errors(
            rec.R_bootstrap, truth.rotations(len(frames)), cameras.names)["all"]
        from photogram.mocap.motion.rotation_series import rotation_difference_errors
        Rt = truth.rotations(len(frames))
        result.info["difference_errors_deg"] = {
            name: rotation_difference_errors(rd.dR, Rt[:, cameras.index(name)])
            for name, rd in rotation_info["differences"].items()}
    if ms.truth is not None:
        _compare_truth(result, ms)
    if ms.reference_trc is not None:
        _compare_reference(result, ms)
    return result


def _post_filter(rec: Reconstruction, ms, breaks, warnings: list):
    """The zero-lag filter of ``[mocap.filter]`` (default Butterworth, order
    4, 6 Hz: :mod:`photogram.mocap.reconstruction.filtering`) on the joints,
    before any metric; the unfiltered joints stay in ``rec.unfiltered``."""
    from photogram.mocap.reconstruction.filtering import FilterSettings, filter_joints
    X, report = filter_joints(rec.joints, ms.fps, FilterSettings(**ms.filter), breaks)
    if report.get("note"):
        log.warning("warning: filter: %s", report["note"])
        warnings.append("filter: " + report["note"])
    if report["type"] == "none":
        return rec, report
    return replace(rec, joints=X, unfiltered=rec.joints), report


def _synchronise(obs, cameras: MocapCameras, ms):
    """``offsets`` of [mocap] (docs/mocap.md, "Synchronisation"): estimate
    ("estimate", "report") and apply ("estimate", a table) the cameras'
    frame offsets; returns the detections, cameras and summary entry."""
    from photogram.mocap.evaluation.sync import apply_offsets, estimate_offsets
    F = obs.shape[0]
    info = {"mode": ms.offsets if isinstance(ms.offsets, str) else "given"}
    if isinstance(ms.offsets, dict):
        applied = {}
        for name, o in ms.offsets.items():
            if name not in cameras.names:
                raise ms.error(("offsets", name), f"offsets names camera {name!r}, which the "
                               f"project does not have",
                               hint="cameras: " + ", ".join(cameras.names))
            if abs(o) >= F:
                raise ms.error(("offsets", name), f"offset {o:g} of camera {name} is not "
                               f"shorter than the sequence ({F} frames)",
                               hint=f"give an offset between -{F - 1} and {F - 1} frames")
            applied[name] = o
    else:
        t0 = time.perf_counter()
        est = estimate_offsets(obs, cameras, ms.fps)
        for line in est.lines():
            log.info(line)
        info["estimate"] = est.as_dict()
        info["seconds"] = time.perf_counter() - t0
        applied = {}
        if ms.offsets == "estimate":
            for n, o, s in zip(est.names, est.offsets, est.sigma):
                if np.isfinite(o):     # within max(2 sigma, 0.1) of an integer: that integer
                    o = float(np.rint(o)) if abs(o - np.rint(o)) <= max(2 * s, 0.1) else float(o)
                    if o != 0:
                        applied[n] = o
    if applied:
        obs, cameras = apply_offsets(obs, cameras,
                                     {cameras.index(n): o for n, o in applied.items()})
        log.info("synchronisation: offsets applied (frames): " + ", ".join(
            f"{n} {o:+.3g}" for n, o in applied.items()))
    info["applied"] = applied
    return obs, cameras, info


# --------------------------------------------------------------------------
def _aligned(frames_ref, X_ref, frames):
    out = np.full((len(frames),) + X_ref.shape[1:], np.nan)
    index = {int(f): i for i, f in enumerate(frames_ref)}
    for i, f in enumerate(frames):
        if int(f) in index:
            out[i] = X_ref[index[int(f)]]
    return out


def _compare_truth(result: MocapResult, ms) -> None:
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
    for k in _ANGLES + ("fore_aft_distance",):
        acc[k + "_mae"] = float(np.nanmean(np.abs(result.biomechanics[k] - tb[k])))
    knees = np.concatenate([np.abs(result.biomechanics[k] - tb[k]) for k in
                            ("knee_flexion_r", "knee_flexion_l")])
    acc["knee_flexion_mae"] = float(np.nanmean(knees))
    truth_2d = result.cameras.project(T)
    width = np.where(np.isfinite(result.cameras.image_size[:, 0]),
                     result.cameras.image_size[:, 0], 1.0)
    det = np.where((np.nan_to_num(result.observations[..., 2]) > 0)[..., None],
                   result.observations[..., :2], np.nan)
    reproj = result.cameras.project(X)
    for tag, pred in (("detections", det), ("reprojected", reproj)):
        acc[f"pck_{tag}"] = pck(pred, truth_2d, sk)
        for k, v in mpjpe_2d(pred, truth_2d, width).items():
            acc[f"{k}_{tag}"] = v
    result.truth, result.truth_biomechanics, result.accuracy = T, tb, acc


def _compare_reference(result: MocapResult, ms) -> None:
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
