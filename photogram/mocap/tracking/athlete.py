"""Athlete tracking in each camera (section 4.1 of the paper).

For an image detector (a 2D pose network run by photogram) ``track_images``
follows the athlete online, one detector call per frame on a predicted
crop (:mod:`.crop_tracking`); ``track_images_smoothed`` is the offline flow
with square crops along smoothed boxes:

1. **detect** on the full image; the box of the confident joints (or of a
   person detector) is the detection of the frame;
2. **clean**: a detection whose centre leaves the last good box is replaced
   (treated as missing) and the last good box kept;
3. **smooth**: Gaussian smoothing of the box centre (sigma 10 frames) and
   side (sigma 50 frames), normalised over the frames with a detection;
   the crop is a square of ``scale`` times the side (1.5; 2 for wide
   views), resized to ``crop_size`` x ``crop_size`` (500) pixels;
4. **crop and detect** again; joints are mapped back to full-image
   coordinates ``x = x0 + u s`` (``s`` = crop side / crop size);
5. **refine**: the centre becomes the median of the detected joints,
   smoothed again (sigma 5), and the crops of step 4 are taken once more.

For detection sources (joints already in full-image coordinates: OpenPose,
CSV) steps 1-3 select the athlete and give the boxes; nothing is cropped.
With several people in a view the main person is the best *sequence*
(:func:`photogram.mocap.tracking.reacquire.follow_person`): candidates are
linked into tracklets, and the chain of tracklets of the largest total
quality (confidence; near the image centre for a pan-tilt camera, whose
centre the pipeline sets as ``image_centre``) is the athlete; a loss is
bridged by a gate that grows with the frames lost, and a tracklet found
anywhere else in the image re-acquires the track if it is worth more than
:data:`~photogram.mocap.tracking.reacquire.REACQUIRE_COST` frames. The
frames are reported as tracked, acquired (the first frame and every
re-acquisition) or lost (``status`` of :class:`TrackedCamera`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from photogram.mocap.tracking.detections import CameraDetections, boxes_from_joints

__all__ = ["TrackingSettings", "TrackedCamera", "gaussian_smooth", "select_person",
           "clean_boxes", "smooth_boxes", "track_detections",
           "track_images_smoothed",
           "crop_image", "crop_to_full"]


@dataclass
class TrackingSettings:
    scale: float = 1.5
    wide_scale: float = 2.0
    sigma_centre: float = 10.0
    sigma_side: float = 50.0
    sigma_refine: float = 5.0
    crop_size: int = 500
    min_confidence: float = 0.1
    # the multi-view choice (photogram.mocap.tracking.multiview)
    multiview: bool = True
    association_px: float = 40.0
    association_confidence: float = 0.3
    gate: float = 0.5
    # the image centre (px) of a pan-tilt camera following the athlete (set
    # per camera by the pipeline, not a project key): the main-person choice
    # prefers candidates near it (photogram.mocap.tracking.reacquire)
    image_centre: tuple | None = None


@dataclass
class TrackedCamera:
    """The athlete in one camera: ``joints`` (F, J, 3) (NaN, 0 where
    missing), ``detected`` (F, 4) raw boxes, ``boxes`` (F, 4) smoothed crop
    boxes, ``person`` (F,) chosen candidate's person id (-2: none),
    ``status`` (F,) tracked / acquired / lost (codes of
    :mod:`photogram.mocap.tracking.reacquire`; None: not tracked frame by
    frame)."""

    camera: str
    joints: np.ndarray
    detected: np.ndarray
    boxes: np.ndarray
    person: np.ndarray
    status: np.ndarray | None = None


def gaussian_smooth(values: np.ndarray, valid: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian smoothing along axis 0 normalised over the valid frames
    (missing frames are filled from their neighbours; NaN if none within
    reach)."""
    v = np.where(valid.reshape((-1,) + (1,) * (values.ndim - 1)), values, 0.0)
    w = valid.astype(float)
    num = gaussian_filter1d(v, sigma, axis=0, mode="nearest", truncate=4.0)
    den = gaussian_filter1d(w, sigma, axis=0, mode="nearest", truncate=4.0)
    den = den.reshape((-1,) + (1,) * (values.ndim - 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 1e-9, num / den, np.nan)


def _centre(box):
    return 0.5 * (box[..., :2] + box[..., 2:])


def _inside(point, box):
    return bool(box[0] <= point[0] <= box[2] and box[1] <= point[1] <= box[3])


def select_person(det: CameraDetections, min_confidence: float = 0.1, gate: float = 0.5,
                  image_centre=None) -> np.ndarray:
    """Row of ``det`` chosen in every frame (-1: none): the athlete's track
    of :func:`photogram.mocap.tracking.reacquire.follow_person`."""
    from photogram.mocap.tracking.reacquire import follow_person
    return follow_person(det, min_confidence, gate, image_centre).rows


def clean_boxes(boxes: np.ndarray, growth: float = 0.05) -> np.ndarray:
    """Valid-frame mask after replacing detections whose centre leaves the
    last good box (boxes (F, 4), NaN: no detection), grown about its centre
    by ``growth`` times its size per frame since it was good: a detection
    that jumped is replaced, one found again after a loss is kept."""
    valid = np.all(np.isfinite(boxes), axis=1)
    last, last_f = None, 0
    for f in np.flatnonzero(valid):
        if last is not None:
            c, half = _centre(last), 0.5 * (last[2:] - last[:2])
            half = half * (1.0 + growth * (f - last_f - 1))
            if not _inside(_centre(boxes[f]), np.r_[c - half, c + half]):
                valid[f] = False
                continue
        last, last_f = boxes[f], f
    return valid


def smooth_boxes(boxes: np.ndarray, valid: np.ndarray, settings: TrackingSettings,
                 scale: float, sigma_centre: float | None = None) -> np.ndarray:
    """Square crop boxes (F, 4): smoothed centre and side times ``scale``."""
    centre = _centre(boxes)
    side = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1])
    c = gaussian_smooth(centre, valid, settings.sigma_centre if sigma_centre is None
                        else sigma_centre)
    s = gaussian_smooth(side, valid, settings.sigma_side) * scale
    return np.concatenate([c - 0.5 * s[:, None], c + 0.5 * s[:, None]], axis=1)


def track_detections(det: CameraDetections, settings: TrackingSettings | None = None,
                     wide: bool = False) -> TrackedCamera:
    """Select the athlete among full-image detections and smooth its boxes."""
    st = settings or TrackingSettings()
    F, J = det.n_frames, det.skeleton.n_joints
    from photogram.mocap.tracking.reacquire import follow_person
    track = follow_person(det, st.min_confidence, st.gate, st.image_centre)
    rows = track.rows
    joints = np.full((F, J, 3), np.nan)
    joints[..., 2] = 0.0
    person = np.full(F, -2)
    have = rows >= 0
    joints[have] = det.joints[rows[have]]
    person[have] = det.person[rows[have]]
    detected = boxes_from_joints(joints, st.min_confidence)
    valid = clean_boxes(detected)
    boxes = smooth_boxes(detected, valid, st, st.wide_scale if wide else st.scale)
    return TrackedCamera(det.camera, joints, detected, boxes, person, track.status)


# --------------------------------------------------------------------------
# crops for image detectors
# --------------------------------------------------------------------------
def crop_image(image: np.ndarray, box, size: int) -> np.ndarray:
    """The square ``box`` (x0, y0, x1, y1) of ``image`` resized to size x size
    (outside the image: black)."""
    import cv2
    x0, y0, x1, _ = (float(v) for v in box)
    s = (x1 - x0) / size
    M = np.array([[1.0 / s, 0.0, -x0 / s], [0.0, 1.0 / s, -y0 / s]])
    return cv2.warpAffine(np.ascontiguousarray(image), M, (size, size),
                          flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


def crop_to_full(joints: np.ndarray, box, size: int) -> np.ndarray:
    """Joints (J, 3) in crop pixels back to full-image pixels."""
    out = np.array(joints, dtype=float, copy=True)
    s = (float(box[2]) - float(box[0])) / size
    out[:, 0] = box[0] + out[:, 0] * s
    out[:, 1] = box[1] + out[:, 1] * s
    return out


def _run(images, detector, boxes, J, size):
    out = np.full((len(boxes), J, 3), np.nan)
    out[..., 2] = 0.0
    for f, image in enumerate(images):
        if f >= len(boxes):
            break
        if not np.all(np.isfinite(boxes[f])):
            continue
        res = detector(crop_image(image, boxes[f], size))
        if res is not None:
            out[f] = crop_to_full(res, boxes[f], size)
    return out


def track_images_smoothed(images, detector, camera: str = "",
                          settings: TrackingSettings | None = None,
                          wide: bool = False) -> TrackedCamera:
    """Steps 1-5 of the module doc with an image detector on a re-iterable
    image sequence (three detector calls per frame)."""
    st = settings or TrackingSettings()
    J = detector.skeleton.n_joints
    full = []
    for image in images:                                   # step 1
        res = detector(image)
        full.append(np.full((J, 3), np.nan) if res is None else np.asarray(res, float))
    F = len(full)
    first = np.array(full).reshape(F, J, 3)
    first[..., 2] = np.nan_to_num(first[..., 2])
    detected = boxes_from_joints(first, st.min_confidence)
    valid = clean_boxes(detected)                          # step 2
    scale = st.wide_scale if wide else st.scale
    boxes = smooth_boxes(detected, valid, st, scale)       # step 3
    joints = _run(images, detector, boxes, J, st.crop_size)  # step 4
    conf = np.nan_to_num(joints[..., 2]) > st.min_confidence
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)         # frames without joints
        med = np.stack([np.nanmedian(np.where(conf, joints[..., k], np.nan), axis=1)
                        for k in range(2)], -1) if F else np.zeros((0, 2))
    ok = np.all(np.isfinite(med), axis=1)                  # step 5
    if ok.any():
        centre = gaussian_smooth(med, ok, st.sigma_refine)
        side = (boxes[:, 2] - boxes[:, 0])
        boxes = np.concatenate([centre - 0.5 * side[:, None], centre + 0.5 * side[:, None]], 1)
        joints = _run(images, detector, boxes, J, st.crop_size)
    return TrackedCamera(camera, joints, detected, boxes, np.full(F, -1))
