"""Which joint-frames the detections determine, and why the others are gaps
(docs/mocap.md section 6, "Gaps").

A joint is located in 3D at a frame by the rays of at least two cameras. A
camera observes joint j at frame f when its detection there has finite
coordinates and a confidence above the reconstruction's ``min_confidence``
(and above 0) and, once the joints are reconstructed, the joint lies in
front of that camera (a ray does not meet a point behind its camera) and,
with ``max_error_px`` (``inlier_sigmas`` x sqrt(sigma2) of
``[mocap.reconstruction]``, 3 x 20 = 60 px by default), projects within
that distance of the detection: two cameras whose detections the solve
cannot both fit (one camera's depth left free beside a long occlusion, an
outlier the robust norm all but ignores) do not determine the joint.

A joint-frame observed by fewer than two cameras is a **gap**: the
reconstruction there is an extrapolation of the DCT trajectory (one camera
constrains two of the three coordinates; with a moving skier the
unconstrained depth was 35-56 m wrong in issue 22) and is never reported as
a coordinate. Reasons, per joint-frame:

======  ============  =================================================
code    reason        meaning
======  ============  =================================================
0       (determined)  observed by two cameras or more
1       no camera     no camera observes the joint at that frame
2       one camera    one camera only
3       behind        two cameras or more detect the joint, but the
                      reconstruction lies behind all of them but one at
                      most (wrong camera angles or positions)
4       cameras       two cameras or more detect the joint in front of
        disagree      them, but the reconstruction fits one at most (the
                      others' reprojection errors exceed ``max_error_px``)
5       not solved    two cameras or more, but the solve gave no finite
                      position (never seen: a diverged solve is an error)
======  ============  =================================================

``support_frames`` (``[mocap.reconstruction]``, default 0) bridges runs of
at most that many undetermined frames that have determined frames of the
same joint on both sides (inside one ``runs`` segment): the trajectory
interpolates there and is reported, and the bridged joint-frames are
counted apart. The default 0 reports only what two cameras see.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["REASONS", "GAP_REASONS", "DETERMINED", "NO_CAMERA", "ONE_CAMERA", "BEHIND",
           "DISAGREE", "NOT_SOLVED", "Gaps", "observing_cameras", "bridge_short_runs",
           "find_gaps"]

DETERMINED, NO_CAMERA, ONE_CAMERA, BEHIND, DISAGREE, NOT_SOLVED = 0, 1, 2, 3, 4, 5
#: reason code -> name (summary.json ``gaps.by_reason``)
REASONS = {DETERMINED: "determined", NO_CAMERA: "no camera", ONE_CAMERA: "one camera",
           BEHIND: "behind the cameras", DISAGREE: "cameras disagree",
           NOT_SOLVED: "not solved"}
GAP_REASONS = (NO_CAMERA, ONE_CAMERA, BEHIND, DISAGREE, NOT_SOLVED)


def observing_cameras(obs: np.ndarray, min_confidence: float = 0.0, cameras=None,
                      X: np.ndarray | None = None,
                      max_error_px: float | None = None) -> np.ndarray:
    """(F, C, J) True where camera c observes joint j at frame f.

    Parameters
    ----------
    obs : ndarray (F, C, J, 3)
        x, y (px), confidence; NaN or confidence 0: no detection.
    min_confidence : float
        A detection counts with a confidence above it (and above 0).
    cameras : MocapCameras, optional
        With ``X``: a detection of a joint that lies behind its camera does
        not count.
    X : ndarray (F, J, 3), optional
        Reconstructed joints (NaN: not checked).
    max_error_px : float, optional
        With ``cameras`` and ``X``: a detection farther than this from the
        projection of the joint (full camera model) does not count.
    """
    obs = np.asarray(obs, dtype=float)
    conf = np.nan_to_num(obs[..., 2], nan=0.0)
    seen = np.all(np.isfinite(obs[..., :2]), axis=-1) & (conf > max(float(min_confidence), 0.0))
    if cameras is not None and X is not None:
        with np.errstate(invalid="ignore"):
            behind = cameras.camera_points(np.asarray(X, float))[..., 2] >= 0   # looks along -z
        seen &= ~behind                                                           # NaN: False
        if max_error_px is not None:
            X = np.asarray(X, float)
            e = np.linalg.norm(cameras.project(X) - obs[..., :2], axis=-1)
            far = ~(e <= max_error_px) & np.all(np.isfinite(X), axis=-1)[:, None, :]
            seen &= ~far
    return seen


def bridge_short_runs(determined: np.ndarray, support_frames: int, breaks=()) -> np.ndarray:
    """``determined`` (F, J) with every run of at most ``support_frames``
    undetermined frames set True when the same joint is determined on both
    sides of it inside one segment (``breaks``: first frames of segments)."""
    out = np.array(determined, dtype=bool)
    h = int(support_frames)
    if h <= 0 or out.size == 0:
        return out
    F = out.shape[0]
    cuts = sorted({0, F} | {int(b) for b in breaks if 0 < int(b) < F})
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        seg = out[lo:hi]                            # a view: edited in place
        n = hi - lo
        # index of the last determined frame at or before t, and the first at or after
        idx = np.arange(n)[:, None]
        prev = np.maximum.accumulate(np.where(seg, idx, -1), axis=0)
        nxt = np.minimum.accumulate(np.where(seg, idx, n)[::-1], axis=0)[::-1]
        inside = (prev >= 0) & (nxt < n) & (nxt - prev - 1 <= h)
        seg |= inside
    return out


@dataclass
class Gaps:
    """The undetermined joint-frames of a reconstruction (module doc).

    ``reason`` (F, J) int: 0 determined (or bridged), 1 no camera, 2 one
    camera, 3 behind the cameras, 4 cameras disagree, 5 not solved;
    ``views`` (F, J) the cameras observing each joint-frame (in front of
    them and fitted); ``bridged`` (F, J) True where ``support_frames``
    bridged a short run.
    """

    reason: np.ndarray
    views: np.ndarray
    bridged: np.ndarray
    support_frames: int = 0
    max_error_px: float | None = None

    @property
    def mask(self) -> np.ndarray:
        """(F, J) True at a gap."""
        return self.reason != DETERMINED

    @property
    def total(self) -> int:
        return int(np.count_nonzero(self.mask))

    def summary(self, joint_names) -> dict:
        """summary.json ``gaps``: the rule, the count of gaps in all, by
        reason and per joint (joints without gaps left out), and the bridged
        joint-frames."""
        per_joint = np.count_nonzero(self.mask, axis=0)
        return {
            "rule": "a joint-frame is reported only where at least two cameras observe the "
                    "joint (confidence above min_confidence, the joint in front of the "
                    "camera and projected within max_error_px of the detection); the others "
                    "are gaps: empty in joints3d.csv, NaN in joints3d.trc, invalid (residual "
                    "-1) in joints3d.c3d",
            "max_error_px": self.max_error_px,
            "joint_frames": int(self.reason.size), "total": self.total,
            "by_reason": {REASONS[k]: int(np.count_nonzero(self.reason == k))
                          for k in GAP_REASONS},
            "per_joint": {str(n): int(c) for n, c in zip(joint_names, per_joint) if c},
            "support_frames": int(self.support_frames),
            "bridged": int(np.count_nonzero(self.bridged)),
        }

    def describe(self) -> str | None:
        """One line for the log and the project's warnings (None: no gap)."""
        if not self.total:
            return None
        n = self.reason.size
        by = ", ".join(f"{c} {REASONS[k]}" for k in GAP_REASONS
                       if (c := int(np.count_nonzero(self.reason == k))))
        return (f"{self.total} of {n} joint-frames ({100.0 * self.total / n:.1f} %) are gaps "
                f"({by}): fewer than two cameras observe them, so they are written empty, "
                f"not as coordinates (summary.json gaps)")


def find_gaps(obs: np.ndarray, min_confidence: float = 0.0, support_frames: int = 0,
              breaks=(), cameras=None, X: np.ndarray | None = None,
              max_error_px: float | None = None) -> Gaps:
    """The gaps of a reconstruction (module doc).

    Parameters
    ----------
    obs : ndarray (F, C, J, 3)
        The detections the reconstruction used.
    min_confidence, support_frames : as in ``[mocap.reconstruction]``
    breaks : first frames of independent segments (never bridged across)
    cameras, X : optional
        The cameras and the reconstructed joints (F, J, 3): a joint behind a
        camera does not count for it, and a joint-frame the solve left
        without a finite position is a gap (reason 5 if two cameras see it).
    max_error_px : float, optional
        With ``cameras`` and ``X``: a detection counts only within this
        reprojection error (px) of the joint.
    """
    detected = np.count_nonzero(observing_cameras(obs, min_confidence), axis=1)
    front = views = detected
    if cameras is not None and X is not None:
        front = np.count_nonzero(observing_cameras(obs, min_confidence, cameras, X), axis=1)
        views = front if max_error_px is None else np.count_nonzero(
            observing_cameras(obs, min_confidence, cameras, X, max_error_px), axis=1)
    enough = views >= 2
    determined = bridge_short_runs(enough, support_frames, breaks)
    # why, where not determined: the first test that leaves fewer than two cameras
    why = np.select([detected == 0, detected == 1, front < 2],
                    [NO_CAMERA, ONE_CAMERA, BEHIND], DISAGREE)
    reason = np.where(determined, DETERMINED, why)
    if X is not None:
        unsolved = determined & ~np.all(np.isfinite(np.asarray(X, float)), axis=-1)
        reason[unsolved] = np.where(enough[unsolved], NOT_SOLVED, why[unsolved])
        determined &= ~unsolved
    return Gaps(reason=reason.astype(np.int8), views=views, bridged=determined & ~enough,
                support_frames=int(support_frames),
                max_error_px=None if max_error_px is None else float(max_error_px))
