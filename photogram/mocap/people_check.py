"""The athlete across the cameras when the rotations are estimated
(``rotation = "estimate"``; docs/mocap.md section 5).

Without rotations the multi-view choice cannot run before the
reconstruction: the observations are the per-camera tracks
(:mod:`photogram.mocap.tracking.reacquire`: continuity, the image centre and
the image motion of a pan-tilt camera). Once the poses and rotations are
estimated, the multi-view choice runs once with the estimated cameras as a
check (:func:`photogram.mocap.stages.check_people`). If it takes another
person than the per-camera track in some camera-frames, the observations
become its choice (as with known rotations: inconsistent and ambiguous
camera-frames left out, undecided runs kept) and the poses and rotations
are estimated once more from them; the log, ``warnings`` and summary.json
(``people.mode``, ``people.first_pass``, ``tracking``: ``persons`` of the
second pass, ``persons_first_pass``) say so.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from photogram.mocap.body.skeleton import map_joints
from photogram.mocap.stages import check_people, choose_people
from photogram.mocap.tracking.athlete import TrackingSettings
from photogram.mocap.tracking.multiview import describe
from photogram.mocap.tracking.report import add_multiview

__all__ = ["check_estimated"]

log = logging.getLogger(__name__)


def check_estimated(project, source, cameras, tracked, obs_source, skeleton, rec, frames, lo,
                    breaks, sync_info, tracking_info, solve):
    """The check and, when it disagrees, the second pass (module doc).

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
    ms = project.mocap
    tracking = TrackingSettings(**ms.tracking)
    offsets = (sync_info or {}).get("applied")
    estimated = replace(cameras, R=rec.R)
    people, _ = check_people(source, estimated, tracked, len(frames), tracking, breaks,
                             offsets, lo)
    if people is None:
        return None, rec, None
    for line in describe(people["cameras"]):
        log.info("check with the estimated rotations: %s", line)
    other = {n: d["other_person"] for n, d in people["cameras"].items() if d.get("other_person")}
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
