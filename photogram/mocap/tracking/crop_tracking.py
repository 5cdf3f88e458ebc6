"""Online crop tracking for image detectors: one detector call per frame.

The athlete is followed frame by frame with a square crop predicted from
the previous frames; the full image is searched only to acquire the
athlete (first frame) or to re-acquire it after a loss:

1. **predict** the crop of frame ``f``: a straight line (least squares)
   through the box centre and side of the last ``history`` good frames
   (constant velocity), evaluated at ``f``; the crop is a square of
   ``scale`` times the predicted side (1.5; 2 for wide views), as in steps
   3-4 of :mod:`photogram.mocap.tracking.athlete` (the paper's section
   4.1), resized to ``crop_size`` x ``crop_size`` pixels;
2. **detect** once on that crop; joints go back to full-image pixels by
   ``x = x0 + u s`` (``s`` = crop side / crop size,
   :func:`~photogram.mocap.tracking.athlete.crop_to_full`);
3. **accept** the detection if at least ``min_joint_fraction`` of the joints
   have a confidence of ``accept_confidence`` or more and the centre of
   their box lies inside the crop: the frame is *tracked*;
4. otherwise (no person, low confidence, a detection beside the crop) the
   detector runs on the **full image**: an accepted detection there
   *acquires* the athlete again (its box seeds the history anew); without
   one the frame is *lost*, the history is dropped and the next frame is
   searched on the full image.

A frame therefore costs one detector call, two in the frame where the crop
fails.

5. **sides** (``fix_sides``): a detector may exchange left and right (seen
   from behind, mediapipe labels a body as if it faced the camera). Over each
   run of found frames, every frame is kept or mirrored (its left/right
   pairs exchanged, ``Skeleton.swap_permutation``) so that consecutive frames
   are nearest: a two-state Viterbi path minimising the sum over frames of
   the median joint distance to the previous frame (in units of the box
   side), plus ``side_prior`` for every mirrored frame (between the two
   mirror-image paths of equal continuity, the one that agrees with the
   detector in more frames). The box of a frame is the box of its joints with a confidence above
``min_confidence`` of :class:`~photogram.mocap.tracking.athlete.TrackingSettings`
(its centre and its larger side). Nothing is smoothed afterwards: the
reconstruction (a DCT trajectory per window) smooths the joints.

The detector is a plain callable (``image -> (J, 3)`` joints or None,
with ``skeleton``); it is called on each crop or image alone and no state
is assumed to carry over between calls (mediapipe runs with
``static_image_mode=True``).
"""

from __future__ import annotations

import logging
import warnings
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from photogram.mocap.tracking.athlete import (TrackedCamera, TrackingSettings, crop_image,
                                              crop_to_full)
from photogram.mocap.tracking.detections import boxes_from_joints

__all__ = ["CropTrackingSettings", "CropTrackedCamera", "track_crops", "track_images",
           "predict_box",
           "accept_joints", "consistent_sides", "TRACKED", "ACQUIRED", "LOST", "STATUS_NAMES"]

log = logging.getLogger(__name__)

#: per-frame status of :class:`CropTrackedCamera`
TRACKED, ACQUIRED, LOST = 0, 1, 2
STATUS_NAMES = ("tracked", "acquired", "lost")


@dataclass
class CropTrackingSettings:
    """Parameters of the online crop tracking (module doc).

    ``history``: good frames the prediction is fitted to (the history is
    dropped at a loss); ``min_joint_fraction`` and ``accept_confidence``:
    the acceptance test; ``min_side``: smallest crop side (px);
    ``fix_sides`` and ``side_prior``: step 5.
    """

    history: int = 4
    min_joint_fraction: float = 0.25
    accept_confidence: float = 0.5
    min_side: float = 16.0
    fix_sides: bool = True
    side_prior: float = 1e-3


@dataclass
class CropTrackedCamera(TrackedCamera):
    """A :class:`TrackedCamera` with the per-frame ``status`` (TRACKED,
    ACQUIRED, LOST), ``mirrored`` (frames whose left and right were
    exchanged by step 5) and the detector calls on crops and on full images.
    (A copy cut to a frame range keeps the defaults: no status.)"""

    status: np.ndarray | None = None
    calls: dict = field(default_factory=dict)
    mirrored: np.ndarray | None = None

    def counts(self) -> dict:
        """Frames per status and detector calls."""
        st = np.zeros(0, int) if self.status is None else self.status
        out = {name: int(np.sum(st == code)) for code, name in enumerate(STATUS_NAMES)}
        out["mirrored"] = 0 if self.mirrored is None else int(np.sum(self.mirrored))
        out.update({f"calls_{k}": int(v) for k, v in self.calls.items()})
        return out


def box_centre_side(joints: np.ndarray, min_confidence: float) -> np.ndarray:
    """``(cx, cy, side)`` of the box of the joints (J, 3) above
    ``min_confidence`` (side: the larger of width and height); NaN without
    any."""
    b = boxes_from_joints(joints, min_confidence)
    return np.array([0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3]), max(b[2] - b[0], b[3] - b[1])])


def square(centre_side, scale: float, min_side: float = 1.0) -> np.ndarray:
    """The square crop box ``(x0, y0, x1, y1)`` of ``scale`` times the side."""
    cx, cy, side = (float(v) for v in centre_side)
    half = 0.5 * max(scale * side, min_side)
    return np.array([cx - half, cy - half, cx + half, cy + half])


def predict_box(frames, states, frame: int, scale: float, min_side: float = 1.0) -> np.ndarray:
    """The crop box of ``frame`` from the box centres and sides ``states``
    (n, 3) of the good ``frames`` (n,): least-squares straight lines
    (constant velocity) evaluated at ``frame``; one state: kept constant.
    The predicted side never drops below half the last measured side."""
    t = np.asarray(frames, float) - frame
    y = np.asarray(states, float).reshape(len(t), 3)
    if len(t) >= 2 and np.ptp(t) > 0:
        slope, value = np.polyfit(t, y, 1)
    else:
        value = y[-1]
    value = np.array(value, float)
    value[2] = max(value[2], 0.5 * y[-1, 2])
    return square(value, scale, min_side)


def accept_joints(joints, box, settings: CropTrackingSettings) -> bool:
    """The acceptance test (step 3): enough confident joints, and the
    centre of their box inside ``box`` (None: the full image)."""
    if joints is None:
        return False
    j = np.asarray(joints, float)
    conf = np.nan_to_num(j[:, 2])
    good = (conf >= settings.accept_confidence) & np.all(np.isfinite(j[:, :2]), axis=1)
    if good.sum() < max(1, int(np.ceil(settings.min_joint_fraction * len(j)))):
        return False
    if box is None:
        return True
    cx, cy = 0.5 * (j[good, :2].min(0) + j[good, :2].max(0))
    return bool(box[0] <= cx <= box[2] and box[1] <= cy <= box[3])


def _frame_distances(joints: np.ndarray, perm: np.ndarray, min_confidence: float):
    """Median joint distance of each frame to the previous one, as detected
    and with the frame mirrored, in units of the frame's box side:
    (F-1,), (F-1,) (0 where no joint is seen in both)."""
    a, b = joints[1:], joints[:-1]
    seen_b = np.nan_to_num(b[..., 2]) > min_confidence
    box = boxes_from_joints(a, min_confidence)
    side = np.fmax(box[:, 2] - box[:, 0], box[:, 3] - box[:, 1])
    side = np.where(np.isfinite(side) & (side > 0), side, 1.0)
    out = []
    for p in (np.arange(joints.shape[1]), perm):
        ok = seen_b & (np.nan_to_num(a[:, p, 2]) > min_confidence)
        d = np.where(ok, np.linalg.norm(a[:, p, :2] - b[..., :2], axis=-1), np.nan)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)        # nothing seen in both
            out.append(np.nan_to_num(np.nanmedian(d, axis=1)) / side)
    return out[0], out[1]


def consistent_sides(joints: np.ndarray, perm: np.ndarray, min_confidence: float = 0.1,
                     prior: float = 1e-3) -> np.ndarray:
    """Which frames of a run of detections (F, J, 3) to mirror (step 5 of
    the module doc): the two-state Viterbi path (kept / mirrored) of least
    total cost, the cost of a frame being its median joint distance to the
    previous frame (both as corrected) plus ``prior`` if it is mirrored."""
    F = len(joints)
    if F < 2 or np.all(perm == np.arange(len(perm))):
        return np.zeros(F, bool)
    same, cross = _frame_distances(joints, perm, min_confidence)
    cost = np.array([0.0, prior])                 # best path ending kept / mirrored
    back = np.zeros((F, 2), int)
    for f in range(1, F):
        stay, switch = same[f - 1], cross[f - 1]
        # to kept: from kept (same) or from mirrored (cross); to mirrored likewise
        k = (cost[0] + stay, cost[1] + switch)
        m = (cost[0] + switch, cost[1] + stay)
        back[f] = (int(np.argmin(k)), int(np.argmin(m)))
        cost = np.array([min(k), min(m) + prior])
    state = int(np.argmin(cost))
    out = np.zeros(F, bool)
    for f in range(F - 1, -1, -1):
        out[f] = bool(state)
        state = back[f, state]
    return out


def _mirror_runs(joints, status, perm, st, cs):
    """Step 5 over each run of found frames; the mirrored mask."""
    mirrored = np.zeros(len(joints), bool)
    found = np.flatnonzero(status != LOST)
    if not len(found):
        return mirrored
    runs = np.split(found, np.flatnonzero(np.diff(found) > 1) + 1)
    for run in runs:
        mirrored[run] = consistent_sides(joints[run], perm, st.min_confidence, cs.side_prior)
    joints[mirrored] = joints[mirrored][:, perm]
    return mirrored


def _as_joints(res, J: int):
    if res is None:
        return None
    out = np.asarray(res, float).reshape(J, 3)
    return out


def track_crops(images, detector, camera: str = "", settings: TrackingSettings | None = None,
                wide: bool = False, crop: CropTrackingSettings | None = None
                ) -> CropTrackedCamera:
    """Follow the athlete through ``images`` (an iterable of RGB arrays,
    read once) with ``detector`` (module doc).

    Returns
    -------
    CropTrackedCamera
        ``joints`` (F, J, 3) in full-image pixels (NaN, 0 where lost),
        ``detected`` (F, 4) the box of the accepted joints, ``boxes`` (F, 4)
        the crop tried (the square around the detection for acquired
        frames; NaN where lost without a prediction), ``person`` -1 where
        found, -2 where lost, ``status`` and ``calls``.
    """
    st = settings or TrackingSettings()
    cs = crop or CropTrackingSettings()
    J = detector.skeleton.n_joints
    scale = st.wide_scale if wide else st.scale
    size = int(st.crop_size)
    history: deque = deque(maxlen=max(1, int(cs.history)))
    joints, boxes, status = [], [], []
    calls = {"crop": 0, "full": 0}
    for f, image in enumerate(images):
        found, box, code = None, np.full(4, np.nan), LOST
        if history:
            fr = [h[0] for h in history]
            box = predict_box(fr, [h[1] for h in history], f, scale, cs.min_side)
            res = _as_joints(detector(crop_image(image, box, size)), J)
            calls["crop"] += 1
            if res is not None:
                res = crop_to_full(res, box, size)
                if accept_joints(res, box, cs):
                    found, code = res, TRACKED
        if found is None:
            res = _as_joints(detector(image), J)
            calls["full"] += 1
            if accept_joints(res, None, cs):
                found, code = res, ACQUIRED
        if found is None:
            history.clear()
            found = np.full((J, 3), np.nan)
            found[:, 2] = 0.0
        else:
            found[:, 2] = np.nan_to_num(found[:, 2])
            state = box_centre_side(found, st.min_confidence)
            if np.all(np.isfinite(state)):
                history.append((f, state))
                if code == ACQUIRED:
                    box = square(state, scale, cs.min_side)
        joints.append(found)
        boxes.append(box)
        status.append(code)
    F = len(joints)
    joints = np.array(joints).reshape(F, J, 3)
    status = np.array(status, int)
    mirrored = np.zeros(F, bool)
    if cs.fix_sides:                                              # step 5
        mirrored = _mirror_runs(joints, status, detector.skeleton.swap_permutation(), st, cs)
    result = CropTrackedCamera(camera, joints, boxes_from_joints(joints, st.min_confidence),
                               np.array(boxes).reshape(F, 4),
                               np.where(status == LOST, -2, -1), status, calls, mirrored)
    c = result.counts()
    log.info("camera %s: %d frames: %d tracked on the crop, %d acquired on the full image, "
             "%d lost; detector calls: %d on crops, %d on full images; %d frames mirrored",
             camera, F, c["tracked"], c["acquired"], c["lost"], calls["crop"], calls["full"],
             c["mirrored"])
    return result


def track_images(images, detector, camera: str = "", settings: TrackingSettings | None = None,
                 wide: bool = False) -> TrackedCamera:
    """An image detector on an image sequence: one call per frame on a crop
    predicted from the previous frames (:func:`track_crops`); the paper's
    three-call flow is :func:`photogram.mocap.tracking.athlete.track_images_smoothed`."""
    return track_crops(images, detector, camera, settings, wide)
