"""What the tracking did, per camera (summary.json ``tracking``, one log
line per camera; docs/mocap.md section 5, "Reported").

Counted over the reconstructed frames: frames where the per-camera track
found the athlete (``tracked``, re-acquisitions included) and where it did
not (``lost``, with the runs of lost frames), the frames where it was
acquired again after a loss or found elsewhere in the image
(``reacquired``), the frames where the multi-view stage took another person
than the per-camera track (``other_person``) or left the camera out; and,
when the source gives person ids, the frames of every source person among
the observations the reconstruction uses (``persons``).
"""

from __future__ import annotations

import numpy as np

from photogram.mocap.tracking.reacquire import ACQUIRED, LOST

__all__ = ["tracking_report", "add_multiview", "describe_tracking", "runs_of"]


def runs_of(mask: np.ndarray) -> list:
    """(first, last) index pairs of the runs of True in ``mask``."""
    m = np.asarray(mask, bool)
    if not m.any():
        return []
    edges = np.diff(np.r_[0, m.astype(int), 0])
    return list(zip(np.flatnonzero(edges == 1).tolist(),
                    (np.flatnonzero(edges == -1) - 1).tolist()))


def _status(t) -> np.ndarray:
    """A camera's per-frame status; without one, found frames are tracked."""
    if getattr(t, "status", None) is not None:
        return np.asarray(t.status, int)
    found = (np.nan_to_num(np.asarray(t.joints)[..., 2]) > 0).any(-1)
    out = np.where(found, 0, LOST)
    out[found & ~np.r_[False, found[:-1]]] = ACQUIRED
    return out


def tracking_report(tracked, frames, names, person=None, people=None) -> dict:
    """Per camera the counts of the module doc.

    Parameters
    ----------
    tracked : list of TrackedCamera or None
        Per camera, cut to the reconstructed frames.
    frames : (F,) array_like
        Their frame numbers.
    names : list of str
    person : (F, C) array_like, optional
        The source's person id of every observation (-2: none, -1: unknown).
    people : dict, optional
        ``cameras`` of the multi-view report
        (:meth:`photogram.mocap.tracking.multiview.Association.report`).
    """
    frames = np.asarray(frames)
    out = {}
    for c, name in enumerate(names):
        t = tracked[c]
        if t is None:
            continue
        st = _status(t)[:len(frames)]
        found = st != LOST
        lost_runs = runs_of(~found)
        acquired = np.flatnonzero(st == ACQUIRED)
        first_found = int(np.argmax(found)) if found.any() else -1
        re = acquired[acquired != first_found]
        d = {"frames": int(len(st)), "tracked": int(found.sum()), "lost": int((~found).sum()),
             "lost_runs": [[int(frames[a]), int(frames[b])] for a, b in lost_runs],
             "longest_loss": max((b - a + 1 for a, b in lost_runs), default=0),
             "reacquired": int(len(re)), "reacquired_frames": [int(frames[f]) for f in re]}
        if person is not None:
            p = np.asarray(person)[:len(frames), c]
            ids, n = np.unique(p[p >= 0], return_counts=True)
            if len(ids):
                d["persons"] = {str(int(i)): int(k) for i, k in zip(ids, n)}
        out[name] = d
    return add_multiview(out, people)


def add_multiview(report: dict, people) -> dict:
    """The multi-view stage's counts (``people``: its report's ``cameras``)
    added to a :func:`tracking_report` (in place; returned)."""
    for name, d in report.items():
        mv = (people or {}).get(name)
        if mv is not None:
            d["other_person"] = int(mv.get("other_person", 0))
            d["multiview_left_out"] = int(mv.get("per_camera_left_out", 0))
            d["multiview_gained"] = int(mv.get("gained", 0))
    return report


def describe_tracking(report: dict) -> list[str]:
    """One log line per camera of :func:`tracking_report`."""
    out = []
    for name, d in report.items():
        runs = len(d["lost_runs"])
        line = (f"camera {name}: athlete tracked in {d['tracked']} of {d['frames']} frames, "
                f"lost in {d['lost']} ({runs} run{'' if runs == 1 else 's'}, longest "
                f"{d['longest_loss']}), re-acquired {d['reacquired']} "
                f"time{'' if d['reacquired'] == 1 else 's'}")
        if d["reacquired_frames"]:
            shown = d["reacquired_frames"][:10]
            line += " (frames " + ", ".join(map(str, shown)) + (
                ", ..." if len(d["reacquired_frames"]) > 10 else "") + ")"
        if "other_person" in d:
            line += (f"; the multi-view choice took another person in {d['other_person']} "
                     f"frames and left out {d['multiview_left_out']} tracked frames")
        if "persons" in d:
            line += "; source persons observed (id: frames): " + ", ".join(
                f"{k}: {v}" for k, v in d["persons"].items())
        out.append(line)
    return out
