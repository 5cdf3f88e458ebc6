"""The motion-capture pipeline of ``photogram mocap``: cameras, detections,
tracking, reconstruction, metrics, and the comparisons with a truth or a
reference reconstruction.

Steps (docs/mocap.md): read the cameras (``[cameras]``/``[stations]`` or a
Pose2Sim calibration; rotations per frame from ``camera_frames``); open the
source and track the athlete in every camera; map the detections onto the
reconstruction skeleton (``skeleton`` of ``[mocap]``; default: the source's,
a generic skeleton); cut the frame range; reconstruct
(:mod:`photogram.mocap.reconstruction.reconstruct`; a non-finite energy is
an error); mark the joint-frames fewer than two cameras observe as gaps
(:mod:`photogram.mocap.reconstruction.observability`); post-filter the joints
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
from photogram.mocap.comparisons import (REFERENCE_CONFIDENCE, compare_reference, compare_truth,
                                         reprojection_errors)
from photogram.mocap.evaluation.metrics import biomechanics, bone_lengths
from photogram.mocap.files import cameras_from_project, read_camera_frames, read_limb_lengths
from photogram.mocap.reconstruction.blas import one_blas_thread
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.mocap.reconstruction.reconstruct import (Reconstruction, ReconstructionSettings,
                                                        reconstruct)
from photogram.mocap.sources import open_source
from photogram.mocap.stages import (check_estimated, choose_people, mark_gaps, post_filter,
                                    synchronise)
from photogram.mocap.tracking.athlete import TrackingSettings

__all__ = ["MocapResult", "run_mocap", "reprojection_errors", "REFERENCE_CONFIDENCE"]

log = logging.getLogger(__name__)


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

def _observations(project, cameras: MocapCameras, allow_plugin: bool = False):
    ms = project.mocap
    source = open_source(ms, cameras.names, project.folder, allow_plugin=allow_plugin)
    tracking = TrackingSettings(**ms.tracking)
    # pan-tilt cameras (rotations per frame, known or estimated) follow the
    # athlete: the per-camera choice prefers candidates near the image centre
    pan_tilt = ms.camera_frames is not None or ms.rotation == "estimate"
    tracked = []
    for c, name in enumerate(cameras.names):
        if name not in source.cameras:
            tracked.append(None)
            continue
        t0 = time.perf_counter()
        st = replace(tracking, image_centre=tuple(0.5 * cameras.image_size[c])) if (
            pan_tilt) else tracking
        tracked.append(source.track(name, st, wide=name in ms.source.wide))
        log.debug("camera %s: %d frames of detections, tracking %.1f s (frames tracked, "
                  "lost and re-acquired: below)", name, len(tracked[-1].joints),
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


@one_blas_thread
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
        obs, cameras, sync_info = synchronise(obs, cameras, ms)
        if estimate and sync_info["applied"]:
            note = ("offsets applied to the detections and the zoom only: the rotation "
                    "differences, the athlete boxes they are measured outside and "
                    "truth_rotations keep every camera's own frame numbers")
            log.warning("warning: %s", note)
            project.warnings.append(note)
    obs, people, person = (obs, None, None) if estimate else choose_people(
        source, cameras, tracked, obs, TrackingSettings(**ms.tracking), first, ms.runs,
        (sync_info or {}).get("applied"))
    if person is None:          # the per-camera track gives the observations
        person = np.full((F, len(tracked)), -2)
        for c, t in enumerate(tracked):
            if t is not None:
                person[:len(t.person), c] = np.asarray(t.person)[:F]
    skeleton = source.skeleton
    obs_source = obs                    # in the source's skeleton
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
    tracked = [None if t is None else type(t)(
        t.camera, t.joints[lo:hi], t.detected[lo:hi], t.boxes[lo:hi], t.person[lo:hi],
        None if t.status is None else t.status[lo:hi]) for t in tracked]
    from photogram.mocap.tracking.report import describe_tracking, tracking_report
    tracking_info = tracking_report(tracked, frames, cameras.names, person[lo:hi],
                                    (people or {}).get("cameras"))
    for line in describe_tracking(tracking_info):
        log.info("%s", line)
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
        from photogram.mocap.motion.unknown_rotations import (chain_differences,
                                                              difference_sigmas,
                                                              lagged_arrays,
                                                              measure_differences)
        from photogram.mocap.reconstruction.estimate import (estimate_poses_and_rotations,
                                                             estimate_settings)
        t1 = time.perf_counter()
        from photogram.project.output_policy import PARTIAL
        dR, weights, per_camera = measure_differences(
            ms, cameras, tracked, (lo, hi), first, project.warnings, breaks,
            cache=project.output_folder() / PARTIAL / "rotation_differences")
        timings["rotation_differences_s"] = time.perf_counter() - t1
        settings = estimate_settings(**rs)
        sig = difference_sigmas(per_camera, cameras.names, ms.homography)
        lagged = lagged_arrays(per_camera, cameras.names, ms.homography)
        chain = chain_differences(per_camera, cameras.names, ms.homography, hi - lo, breaks)
        rec = estimate_poses_and_rotations(obs, cameras, skeleton, dR, weights, settings, breaks,
                                           sig, lagged, chain)
        checked, rec, people = check_estimated(           # the multi-view check
            project, source, cameras, tracked, obs_source[lo:hi], skeleton, rec, frames, lo,
            breaks, sync_info, tracking_info,
            lambda o: estimate_poses_and_rotations(o, cameras, skeleton, dR, weights, settings,
                                                   breaks, sig, lagged, chain))
        obs = obs if checked is None else checked
        cameras = replace(cameras, R=rec.R)
        rotation_info = {"differences": per_camera, "weights": weights}
    else:
        settings = ReconstructionSettings(**rs)
        rec = reconstruct(obs, cameras, skeleton, settings, breaks)
    log.info("reconstruction: %d frames, %d windows, %s, energy %.6g, %d iterations, %.1f s",
             len(frames), rec.n_windows, rec.solver, rec.energy, rec.iterations, rec.seconds)
    from photogram.mocap.evaluation.checks import check_energy
    check_energy(rec.stages, rec.energy, file=project.path)
    timings["reconstruction_s"] = rec.seconds
    rec = mark_gaps(rec, obs, cameras, skeleton, settings, breaks, project.warnings)
    rec, filter_report = post_filter(rec, ms, breaks, project.warnings)
    bio = biomechanics(rec.joints, skeleton, ms.fps, breaks, ms.up, ms.outside_leg,
                       gaps=rec.gaps.mask)
    result = MocapResult(
        skeleton=skeleton, fps=ms.fps, frames=frames, cameras=cameras, observations=obs,
        tracked=tracked, reconstruction=rec, biomechanics=bio,
        reprojection=reprojection_errors(rec.joints, cameras, obs),
        bones=bone_lengths(rec.joints, skeleton), breaks=breaks,
        info={"source": source.describe(), "timings": timings, "rotation": ms.rotation,
              "filter": filter_report, "tracking": tracking_info, **rotation_info,
              **({"sync": sync_info} if sync_info else {}),
              **({"people": people} if people else {})})
    from photogram.mocap.evaluation.checks import check_fit
    from photogram.mocap.evaluation.checks import check_bias, check_outliers
    for note in (check_fit(result.reprojection, cameras.image_size[:, 0])
                 + check_bias(result.reprojection) + check_outliers(result.reprojection)):
        log.warning("warning: %s", note)
        project.warnings.append(note)
    true_cameras = None if estimate else cameras       # the truth's 2D projections
    if estimate and ms.truth_rotations is not None:
        from photogram.mocap.motion.unknown_rotations import rotation_errors
        truth = read_camera_frames(ms.truth_rotations, cameras, project, first,
                                   lo + len(frames)).select_frames(np.arange(lo, hi))
        true_cameras = replace(cameras, R=truth.rotations(len(frames)))
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
        compare_truth(result, ms, true_cameras)
    if ms.reference_trc is not None:
        compare_reference(result, ms)
    return result
