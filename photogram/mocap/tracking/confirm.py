"""Runs of a per-camera track that the other cameras do not confirm
(docs/mocap.md section 5, "Estimated rotations"; issue 22).

With estimated rotations the observations are the per-camera tracks
(:mod:`photogram.mocap.tracking.reacquire`); the multi-view check
(:mod:`photogram.mocap.tracking.multiview`, run with the estimated cameras)
may keep the per-camera person, take another one (``other_person``) or
leave the camera out of the frame as *inconsistent*: no candidate of the
camera, the per-camera person included, fits the other cameras. The last
case says that the per-camera track followed somebody the other cameras do
not see there, yet it changed nothing before: a bystander taken while the
athlete was occluded (two frames of a crossing), or a bystander standing
still that a camera took after a loss (27 frames), stayed in the
observations.

A single inconsistent frame inside a run of the athlete is noise (a swap,
an outlier, a rotation off for a moment): the unit judged is the **run**, the
frames of the per-camera track between two losses of :data:`RUN_GAP` + 1
(two) frames or more (one missing frame is a dropout of the detector and
does not cut it). A run in which
the check finds the per-camera person inconsistent in at least
:data:`UNCONFIRMED_SHARE` (a third) of the frames it judged (used,
inconsistent or ambiguous; undecided frames are not judged) is
*unconfirmed*: its camera-frames are left out of the observations.

The third (SIMULATED harsh setting, estimate mode, first-pass check): the
athlete's runs are inconsistent in at most 12-18 % of their frames (seeds
22, 23, 26: ``C4`` after its whip pan, where its estimated rotation is
off), the bystander runs in 44 % (seed 22 ``C6``: the coach at the image
edge of a long lens, where the estimated cameras fit it within 24-39 px
in 5 of 9 frames), 78 % and 100 %. Half, the first choice, missed seed
22's ``C6``; the third was set after measuring it, and checked on seeds
24, 25 and 27 (docs/mocap.md section 5).
"""

from __future__ import annotations

import numpy as np

from photogram.mocap.tracking.multiview import AMBIGUOUS, INCONSISTENT, USED

__all__ = ["UNCONFIRMED_SHARE", "RUN_GAP", "track_runs", "unconfirmed_runs"]

#: share of a run's judged frames found inconsistent that leaves it out
UNCONFIRMED_SHARE = 1.0 / 3.0
#: missing frames a run of the per-camera track bridges
RUN_GAP = 1


def track_runs(rows, max_gap: int = RUN_GAP) -> list:
    """(first, last) frames of the runs of a per-camera track ``rows`` (F,)
    (-1: lost): frames with a row, gaps of at most ``max_gap`` frames
    joined."""
    found = np.flatnonzero(np.asarray(rows) >= 0)
    if not len(found):
        return []
    cut = np.flatnonzero(np.diff(found) > max_gap + 1)
    firsts = np.r_[found[0], found[cut + 1]]
    lasts = np.r_[found[cut], found[-1]]
    return [(int(a), int(b)) for a, b in zip(firsts, lasts)]


def unconfirmed_runs(rows, status, share: float = UNCONFIRMED_SHARE) -> list:
    """The runs of one camera's per-camera track that the multi-view check
    does not confirm (module doc).

    Parameters
    ----------
    rows : (F,) int
        The per-camera track's row per frame (-1: lost).
    status : (F,) int
        The check's status of the camera per frame
        (:data:`~photogram.mocap.tracking.multiview.USED`, ``INCONSISTENT``,
        ``AMBIGUOUS``, ``NO_CANDIDATE``, ``UNDECIDED``).
    share : float
        Share of the judged frames found inconsistent that leaves a run out.

    Returns
    -------
    list of (first, last, inconsistent, judged)
    """
    rows = np.asarray(rows)
    status = np.asarray(status)
    out = []
    for a, b in track_runs(rows):
        mine = rows[a:b + 1] >= 0
        st = status[a:b + 1][mine]
        judged = int(np.sum((st == USED) | (st == INCONSISTENT) | (st == AMBIGUOUS)))
        bad = int(np.sum(st == INCONSISTENT))
        if judged and bad >= share * judged:
            out.append((a, b, bad, judged))
    return out
