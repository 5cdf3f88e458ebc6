"""Integer frame offsets between the cameras from the tracked markers.

Cameras started by hand, or by a trigger that one of them missed, record
the same instants under frame numbers that differ by a constant: camera
``s`` started ``offset[s]`` frames late, frame ``t`` of the reference
camera (the first) is its frame ``t - offset[s]`` (the convention of
``truth/offsets.csv`` of the rendered videos). With the markers tracked in each camera on its own
(:func:`photogram.track.tracks2d.track_station`, which needs no
orientation), the right offset is the one at which the same marker in two
cameras satisfies the epipolar constraint of the given orientation: for
every candidate offset within ``max_offset`` the median symmetric epipolar
distance (:func:`photogram.track.rays.epipolar_distances`) over all
markers and frames seen in both is computed, and the smallest wins. The
jumper moves 10-25 px per frame, so one frame off costs pixels where the
right offset costs the orientation's error (the median ignores a few wrong
detections). The offset is *clear* when the next best costs at least
``clear_factor`` times as much and the best at most ``max_cost`` px; a
pair with fewer than ``min_pairs`` markers seen in both cameras gives no
offset.

The estimate needs a good orientation. A time offset moves every marker by
its image velocity, nearly a constant vector over a few frames, and so
does an orientation error: with the true views or the field bundle's
estimate the right offset costs 0.02-0.2 px against 2.4-6.5 px for the
next (the rendered sets), but angles 0.2 gon off make a wrong offset the
clear minimum at 1.3 px. Hence ``max_cost``: a best cost above it means
the orientation does not fit the markers at any offset, and
:func:`photogram.track.tracks.track_markers` refuses to guess (give the
offsets).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError
from photogram.track.rays import epipolar_distances

__all__ = ["SyncResult", "estimate_offsets"]


@dataclass
class SyncResult:
    """Offsets per station (reference 0; frames started late), the cost
    (median epipolar distance, px) per station and candidate offset, the pairs used at the
    chosen offset, and whether each choice is clear."""

    offsets: dict
    cost: dict = field(default_factory=dict)
    n_pairs: dict = field(default_factory=dict)
    clear: dict = field(default_factory=dict)

    def summary(self) -> str:
        """One line per station: offset, cost, the runner-up."""
        lines = []
        for s, off in self.offsets.items():
            c = self.cost.get(s)
            if not c:
                lines.append(f"{s}: offset {off} (reference)")
                continue
            ranked = sorted(c, key=c.get)
            nxt = ranked[1] if len(ranked) > 1 else None
            lines.append(f"{s}: offset {off}, median epipolar distance {c[off]:.2f} px"
                         + (f" (next {nxt}: {c[nxt]:.2f} px)" if nxt is not None else "")
                         + f", {self.n_pairs.get(s, 0)} marker pairs"
                         + ("" if self.clear.get(s, True) else " NOT CLEAR"))
        return "\n".join(lines)


def estimate_offsets(tracks: dict, cameras: dict, max_offset: int = 10,
                     min_pairs: int = 8, clear_factor: float = 2.0,
                     max_cost: float = 1.0) -> SyncResult:
    """Integer offset of every camera against the first (module doc).

    Parameters
    ----------
    tracks : dict station -> (F, M, 2)
        Marker positions per frame (px), NaN where not reliably tracked.
    cameras : dict station -> ViewCamera
        The orientation (estimated is fine: its error is a constant part of
        the cost).
    max_offset : int
        Offsets ``-max_offset..max_offset`` are tried.
    clear_factor, max_cost : float
        The choice is clear when the runner-up costs ``clear_factor`` times
        as much and the best costs at most ``max_cost`` px.

    Returns
    -------
    SyncResult

    Raises
    ------
    InputError
        A camera shares fewer than ``min_pairs`` tracked markers with the
        reference at every offset.
    """
    names = list(tracks)
    ref = names[0]
    A = np.asarray(tracks[ref], float)
    out = SyncResult({ref: 0})
    for s in names[1:]:
        B = np.asarray(tracks[s], float)
        costs, counts = {}, {}
        for d in range(-max_offset, max_offset + 1):
            t0, t1 = max(0, -d), min(len(A), len(B) - d)
            if t1 - t0 <= 0:
                continue
            a = A[t0:t1].reshape(-1, 2)
            b = B[t0 + d:t1 + d].reshape(-1, 2)
            both = np.isfinite(a).all(1) & np.isfinite(b).all(1)
            if both.sum() < min_pairs:
                continue
            dist = epipolar_distances(cameras[ref], cameras[s], a[both], b[both])
            costs[-d] = float(np.median(dist))
            counts[-d] = int(both.sum())
        if not costs:
            raise InputError(f"camera {s} and {ref} share fewer than {min_pairs} tracked "
                             f"markers at every offset within +-{max_offset} frames",
                             hint="check the seeds of both cameras, or give the offsets")
        ranked = sorted(costs, key=costs.get)
        best = ranked[0]
        out.offsets[s] = best
        out.cost[s] = costs
        out.n_pairs[s] = counts[best]
        out.clear[s] = costs[best] <= max_cost and (
            len(ranked) == 1 or costs[ranked[1]] >= clear_factor * costs[best])
    return out
