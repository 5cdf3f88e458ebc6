"""Stages of ``photogram mocap`` between the detections and the
reconstruction (docs/mocap.md): the synchronisation of the cameras
(``offsets``), the multi-view choice of the athlete among the candidates
of every camera (with estimated rotations: its check after the
reconstruction and a second pass), the gaps (joint-frames fewer than two
cameras observe) and the zero-lag post-filter of the joints."""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np

from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.mocap.reconstruction.reconstruct import Reconstruction
from photogram.mocap.tracking.athlete import TrackingSettings

__all__ = ["shift_candidates", "people_candidates", "choose_people", "check_people",
           "check_estimated", "mark_gaps", "post_filter", "synchronise"]

log = logging.getLogger(__name__)


def shift_candidates(det, rows, k: int):
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


def people_candidates(source, cameras: MocapCameras, tracked, tracking: TrackingSettings,
                      n_frames: int, offsets=None, skip: int = 0):
    """Per camera all candidates (CameraDetections; image detectors: the
    tracked person) and the rows of the per-camera track (F,), renumbered
    by ``skip`` (the first frame used; image detectors' ``tracked`` start
    there already) plus the whole frames of ``offsets``."""
    from photogram.mocap.tracking.athlete import select_person
    from photogram.mocap.tracking.multiview import tracked_candidates
    candidates, per_camera = [], []
    for name, t in zip(cameras.names, tracked):
        if t is None:
            candidates.append(None)
            per_camera.append(None)
            continue
        k = int(np.floor((offsets or {}).get(name, 0.0)))
        try:
            det = source.detections(name)
            c = cameras.index(name)     # pan-tilt cameras: as the per-camera track
            rows = select_person(det, tracking.min_confidence, tracking.gate,
                                 0.5 * cameras.image_size[c] if cameras.n_frames else None)
            k += int(skip)
        except NotImplementedError:                 # image detectors: the tracked person
            det, rows = tracked_candidates(t, source.skeleton)
        if k:
            det, rows = shift_candidates(det, np.asarray(rows), k)
        candidates.append(det)
        per_camera.append(rows[:n_frames])
    return candidates, per_camera


def check_people(source, cameras: MocapCameras, tracked, n_frames: int,
                 tracking: TrackingSettings, breaks=(), offsets=None, skip: int = 0):
    """With estimated rotations (``rotation = "estimate"``): the multi-view
    choice (docs/mocap.md section 5) run once after the reconstruction with
    the estimated cameras, as a *check* of the per-camera tracks that gave
    the observations (which it does not change): the report of
    :meth:`~photogram.mocap.tracking.multiview.Association.report` per
    camera (``other_person``: frames where it would take another candidate
    than the per-camera track; ``unconfirmed_runs``: [first, last] runs of
    the per-camera track it does not confirm,
    :func:`~photogram.mocap.tracking.confirm.unconfirmed_runs`, counted from
    the first reconstructed frame) and the warnings (None: not run)."""
    if not tracking.multiview or sum(t is not None for t in tracked) < 2:
        return None, []
    from photogram.mocap.tracking.multiview import associate, settings_from_tracking
    candidates, per_camera = people_candidates(source, cameras, tracked, tracking, n_frames,
                                               offsets, skip)
    assoc = associate(candidates, cameras, n_frames, settings_from_tracking(tracking),
                      breaks=breaks)
    report = assoc.report(cameras.names, per_camera)
    from photogram.mocap.tracking.confirm import unconfirmed_runs
    for c, name in enumerate(cameras.names):
        if per_camera[c] is not None:
            runs = unconfirmed_runs(per_camera[c], assoc.status[:, c])
            if runs:
                report[name]["unconfirmed_runs"] = [[int(a), int(b)] for a, b, *_ in runs]
    notes = [f"camera {name}: with the estimated rotations the multi-view check takes another "
             f"person than the per-camera track in {d['other_person']} frames and finds "
             f"{d['per_camera_left_out']} more of its frames inconsistent or ambiguous; the "
             f"reconstruction used the per-camera track (docs/mocap.md section 5)"
             for name, d in report.items() if d.get("other_person")]
    return {"mode": "check with the estimated rotations", "cameras": report,
            "undecided_runs": [[lo, hi - 1] for lo, hi in assoc.undecided_runs],
            "settings": vars(assoc.settings).copy()}, notes


def choose_people(source, cameras: MocapCameras, tracked, obs, tracking: TrackingSettings,
                   first: int = 0, runs=(), offsets=None, skip: int = 0):
    """The athlete's joints chosen by multi-view consistency (docs/mocap.md
    section 5; :mod:`photogram.mocap.tracking.multiview`): the observations
    and the per-camera report (None: not run). ``offsets`` (camera ->
    frames, applied to ``obs`` already): the candidates are renumbered by
    the whole frames, the chosen joints shifted by the rest; ``skip``: the
    first frame of ``obs`` in the source's frames. Also returns
    the source's person id of every observation (F, C) (-2: none, -1:
    unknown; None: not run)."""
    if not tracking.multiview or sum(t is not None for t in tracked) < 2:
        return obs, None, None
    from photogram.mocap.tracking.multiview import associate, describe, settings_from_tracking
    candidates, per_camera = people_candidates(source, cameras, tracked, tracking,
                                               obs.shape[0], offsets, skip)
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
    person = np.full(assoc.rows.shape, -2)
    for c, det in enumerate(candidates):
        take = assoc.rows[:, c] >= 0
        if det is not None and take.any():
            person[take, c] = det.person[assoc.rows[take, c]]
    for lo, hi in assoc.undecided_runs:     # mostly inconsistent: the cameras are wrong,
        chosen[lo:hi] = obs[lo:hi]          # the per-camera choice is kept
        for c, t in enumerate(tracked):
            person[lo:hi, c] = -2 if t is None else np.asarray(t.person)[lo:hi]
        log.info("frames %d..%d: the cameras are mostly inconsistent with each other (%g px); "
                 "the per-camera choice of the athlete is kept", first + lo, first + hi - 1,
                 tracking.association_px)
    people = {"cameras": report,
              "undecided_runs": [[first + lo, first + hi - 1] for lo, hi in assoc.undecided_runs],
              "seed_frames": [first + f for f in assoc.seeds], "sizes": assoc.sizes,
              "settings": vars(assoc.settings).copy()}
    return chosen, people, person


def mark_gaps(rec: Reconstruction, obs, cameras: MocapCameras, skeleton, settings, breaks,
              warnings: list) -> Reconstruction:
    """The reconstruction with its gaps NaN and described
    (:mod:`photogram.mocap.reconstruction.observability`; ``settings``: the
    reconstruction's ``min_confidence``, ``support_frames`` and
    ``inlier_px``). The known-
    rotation solve marks them itself; the estimated rotations' are found
    here with the estimated cameras. A warning (log and ``warnings``) says
    how many joint-frames are gaps and why."""
    if rec.gaps is None:
        from photogram.mocap.reconstruction.observability import find_gaps
        gaps = find_gaps(obs, settings.min_confidence, settings.support_frames, breaks,
                         cameras, rec.joints, max_error_px=settings.inlier_px)
        X = np.array(rec.joints, dtype=float)
        X[gaps.mask] = np.nan
        rec = replace(rec, joints=X, gaps=gaps)
    note = rec.gaps.describe()
    if note:
        per_joint = rec.gaps.summary(skeleton.joints)["per_joint"]
        worst = sorted(per_joint.items(), key=lambda kv: -kv[1])[:5]
        log.warning("warning: %s", note)
        log.info("gaps per joint (most): %s", ", ".join(f"{n} {c}" for n, c in worst))
        warnings.append(note)
    return rec


def post_filter(rec: Reconstruction, ms, breaks, warnings: list):
    """The zero-lag filter of ``[mocap.filter]`` (default Butterworth, order
    4, 6 Hz: :mod:`photogram.mocap.reconstruction.filtering`) on the joints,
    before any metric, over every contiguous run of finite values on its own:
    gaps stay NaN and are never bridged; the unfiltered joints stay in
    ``rec.unfiltered``."""
    from photogram.mocap.reconstruction.filtering import FilterSettings, filter_joints
    X, report = filter_joints(rec.joints, ms.fps, FilterSettings(**ms.filter), breaks)
    if report.get("note"):
        log.warning("warning: filter: %s", report["note"])
        warnings.append("filter: " + report["note"])
    if report["type"] == "none":
        return rec, report
    return replace(rec, joints=X, unfiltered=rec.joints), report


def synchronise(obs, cameras: MocapCameras, ms):
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


def check_estimated(project, source, cameras, tracked, obs_source, skeleton, rec, frames, lo,
                    breaks, sync_info, tracking_info, solve):
    """With estimated rotations: the multi-view check and, when it takes
    another person than the per-camera track, the second pass.

    Without rotations the multi-view choice cannot run before the
    reconstruction: the observations are the per-camera tracks
    (:mod:`photogram.mocap.tracking.reacquire`). Once the poses and
    rotations are estimated, :func:`check_people` runs with the estimated
    cameras. If it takes another person than the per-camera track in some
    camera-frames, the observations become its choice (as with known
    rotations: inconsistent and ambiguous camera-frames left out, undecided
    runs kept) and ``solve`` estimates the poses and rotations once more;
    the log, ``warnings`` and summary.json (``people.mode``,
    ``people.first_pass``, ``tracking``: ``persons`` of the second pass,
    ``persons_first_pass``) say so. If it takes nobody else but does not
    confirm runs of a per-camera track
    (:mod:`photogram.mocap.tracking.confirm`), their camera-frames are left
    out and ``solve`` runs once more (``unconfirmed_runs`` per camera in
    ``people.cameras`` and ``tracking``).

    Parameters
    ----------
    cameras : MocapCameras
        The cameras of the reconstructed frames, rotations unknown.
    obs_source : (F, C, J, 3)
        The observations in the source's skeleton (reconstructed frames).
    skeleton : Skeleton
        The reconstruction's skeleton.
    rec : Reconstruction
        The first estimate (``rec.R`` the estimated rotations).
    frames : (F,) frame numbers; ``lo`` the first one's index in the source.
    solve : callable
        ``observations -> Reconstruction`` (the estimate of the pipeline).

    Returns
    -------
    observations (in ``skeleton``) or None (unchanged), the reconstruction,
    the people entry of summary.json (None: not run).
    """
    from photogram.mocap.body.skeleton import map_joints
    from photogram.mocap.tracking.multiview import describe
    from photogram.mocap.tracking.report import add_multiview
    tracking = TrackingSettings(**project.mocap.tracking)
    offsets = (sync_info or {}).get("applied")
    estimated = replace(cameras, R=rec.R)
    people, _ = check_people(source, estimated, tracked, len(frames), tracking, breaks,
                             offsets, lo)
    if people is None:
        return None, rec, None
    for line in describe(people["cameras"]):
        log.info("check with the estimated rotations: %s", line)
    other = {n: d["other_person"] for n, d in people["cameras"].items() if d.get("other_person")}
    unconfirmed = {n: d["unconfirmed_runs"] for n, d in people["cameras"].items()
                   if d.get("unconfirmed_runs")}
    for n, runs in unconfirmed.items():       # reported as frame numbers
        people["cameras"][n]["unconfirmed_runs"] = [[int(frames[a]), int(frames[b])]
                                                    for a, b in runs]
    if not other and unconfirmed:
        return _leave_out_unconfirmed(project, source.skeleton, cameras, tracked, obs_source,
                                      skeleton, people, unconfirmed, tracking_info, solve,
                                      int(frames[0]))
    if not other:
        add_multiview(tracking_info, people["cameras"])
        return None, rec, people
    chosen, second, person = choose_people(source, estimated, tracked, obs_source, tracking,
                                           int(frames[0]), [int(frames[0]) + b for b in breaks],
                                           offsets, lo)
    if source.skeleton.name != skeleton.name:
        chosen = map_joints(chosen, source.skeleton, skeleton)
    for name, n in other.items():
        note = (f"camera {name}: with the estimated rotations the multi-view check took another "
                f"person than the per-camera track in {n} frames; the poses and rotations were "
                f"estimated again from the multi-view choice (docs/mocap.md section 5)")
        log.warning("warning: %s", note)
        project.warnings.append(note)
    rec = solve(chosen)
    second["mode"] = "chosen with the estimated rotations (second pass)"
    second["first_pass"] = people["cameras"]
    add_multiview(tracking_info, second["cameras"])
    for c, name in enumerate(cameras.names):
        if name in tracking_info:
            p = person[:, c]
            ids, k = np.unique(p[p >= 0], return_counts=True)
            before = tracking_info[name].pop("persons", None)
            if before is not None:
                tracking_info[name]["persons_first_pass"] = before
            if len(ids):
                tracking_info[name]["persons"] = {str(int(i)): int(v) for i, v in zip(ids, k)}
    return chosen, rec, second


def _leave_out_unconfirmed(project, source_skeleton, cameras, tracked, obs_source, skeleton,
                           people, unconfirmed, tracking_info, solve, first=0):
    """The second pass of :func:`check_estimated` when the check takes no
    other person but finds runs of per-camera tracks that the other cameras
    do not confirm (:mod:`photogram.mocap.tracking.confirm`): their
    camera-frames are left out of the observations and the poses and
    rotations estimated once more."""
    from photogram.mocap.body.skeleton import map_joints
    from photogram.mocap.tracking.report import add_multiview
    chosen = np.array(obs_source, float, copy=True)
    for name, runs in unconfirmed.items():
        c = cameras.index(name)
        n = 0
        for a, b in runs:
            chosen[a:b + 1, c] = (np.nan, np.nan, 0.0)
            n += b - a + 1
        note = (f"camera {name}: with the estimated rotations the multi-view check finds the "
                f"per-camera track inconsistent with the other cameras in at least a third of "
                f"the frames of {', '.join(f'{first + a}..{first + b}' for a, b in runs)}; "
                f"these {n} frame(s) were left out and the poses and rotations estimated again "
                f"(docs/mocap.md section 5)")
        log.warning("warning: %s", note)
        project.warnings.append(note)
        if name in tracking_info:
            tracking_info[name]["unconfirmed_runs"] = [[first + a, first + b] for a, b in runs]
            before = tracking_info[name].pop("persons", None)
            if before is not None:
                tracking_info[name]["persons_first_pass"] = before
                p = np.asarray(tracked[c].person)[:len(chosen)].copy()
                for a, b in runs:
                    p[a:b + 1] = -2
                ids, k = np.unique(p[p >= 0], return_counts=True)
                tracking_info[name]["persons"] = {str(int(i)): int(v) for i, v in zip(ids, k)}
    if source_skeleton.name != skeleton.name:
        chosen = map_joints(chosen, source_skeleton, skeleton)
    rec = solve(chosen)
    people["mode"] = "check with the estimated rotations; unconfirmed runs left out (second pass)"
    add_multiview(tracking_info, people["cameras"])
    return chosen, rec, people
