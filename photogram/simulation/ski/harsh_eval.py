"""Truth comparisons of a pipeline run on a simulated session that the
pipeline's own summary cannot make (issue 22, ``benchmarks/ski_ptz.py``):
whose detections the reconstruction used (the athlete's or a bystander's),
and how many joint-frames seen by fewer than two cameras were reported as
valid. SIMULATED truth: :mod:`photogram.simulation.ski.harsh`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["people_of", "used_people", "undetermined_joint_frames"]


def people_of(sim) -> np.ndarray:
    """(P, F, C, J, 3) detections of every person of ``sim``, index 0 the
    athlete (a :class:`photogram.simulation.ski.simulate.SkiSimulation`
    without bystanders: the athlete only)."""
    people = getattr(sim, "people", None)
    return sim.observations[None] if people is None else people


def used_people(observations, frames, camera_names, sim, decimals: int = 1) -> dict:
    """Which person each joint observation used by a run belongs to.

    ``observations`` (F', C', J, 3) of a :class:`photogram.mocap.pipeline.MocapResult`
    (``frames`` (F',) its frame numbers, ``camera_names`` its cameras), a
    joint used where its confidence is > 0; it is matched to the person of
    ``sim`` whose detection of that joint in that camera frame has the same
    coordinates (as written with ``decimals`` decimals, within
    0.6 * 10^-decimals px).

    Returns
    -------
    dict
        ``joints_used``, ``athlete_joints``, ``bystander_joints`` (joint
        observations of any other person), ``unmatched_joints`` (of no
        person: moved by the pipeline, e.g. a sub-frame shift),
        ``bystander_frames`` (camera frames with at least one bystander
        joint used), ``camera_frames`` (camera frames with a joint used) and
        ``bystander_frames_per_camera``; ``athlete_frames_missed``: camera
        frames in which the athlete was detected but none of its joints used
        (lost by the tracking or the choice of the athlete).
    """
    people = people_of(sim)
    names = list(sim.cameras.names)
    tol = 0.6 * 10.0 ** -decimals
    obs = np.asarray(observations, float)
    used = np.nan_to_num(obs[..., 2]) > 0
    f = np.asarray(frames, int)
    owner = np.full(used.shape, -1)
    athlete_seen = np.zeros(used.shape[:2], bool)
    for c, name in enumerate(camera_names):
        mine = people[:, :, names.index(name)][:, f]                       # (P, F', J, 3)
        cand = np.round(mine[..., :2], decimals)
        same = np.all(np.abs(cand - obs[None, :, c, :, :2]) <= tol, axis=-1)
        same &= np.nan_to_num(mine[..., 2]) > 0
        athlete_seen[:, c] = np.any(np.nan_to_num(mine[0, ..., 2]) > 0, axis=-1)
        first = np.argmax(same, axis=0)
        owner[:, c] = np.where(same.any(0), first, -1)
    owner = np.where(used, owner, -2)
    by = owner >= 1
    per_cam = by.any(-1).sum(0)
    return {"joints_used": int(used.sum()), "athlete_joints": int(np.sum(owner == 0)),
            "bystander_joints": int(by.sum()), "unmatched_joints": int(np.sum(owner == -1)),
            "bystander_frames": int(by.any(-1).sum()), "camera_frames": int(used.any(-1).sum()),
            "athlete_frames_missed": int(np.sum(athlete_seen & ~np.any(owner == 0, axis=-1))),
            "bystander_frames_per_camera": {n: int(v) for n, v in zip(camera_names, per_cam)}}


def undetermined_joint_frames(observations, joints) -> dict:
    """Joint-frames observed (confidence > 0) by fewer than two cameras in
    ``observations`` (F, C, J, 3), and how many of them the run reported as
    valid (finite coordinates in ``joints`` (F, J, 3))."""
    seen = np.sum(np.nan_to_num(np.asarray(observations)[..., 2]) > 0, axis=1)     # (F, J)
    valid = np.all(np.isfinite(joints), -1)
    under = seen < 2
    return {"joint_frames": int(seen.size), "undetermined": int(under.sum()),
            "undetermined_valid": int(np.sum(under & valid)),
            "unseen_valid": int(np.sum((seen == 0) & valid))}
