"""A pan-tilt camera that looks away from the athlete (issue 22, the
harsh simulator's C4): during the loss only a bystander, standing still,
drifts across the image off its centre; the per-camera track must not
bridge the loss with it (docs/mocap.md section 5, step 4 of
:mod:`photogram.mocap.tracking.reacquire`). Constructed case: the truth is
who each row is."""

import numpy as np

from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.tracking.detections import CameraDetections
from photogram.mocap.tracking.reacquire import follow_person

IMAGE_CENTRE = (960.0, 540.0)


SHAPE = np.random.default_rng(7).random((SKI24.n_joints, 2)) - 0.5     # a fixed figure


def _person(rng, centre, size):
    """(J, 3) joints of the figure of ``size`` px about ``centre``, 2 px noise."""
    xy = np.asarray(centre) + size * SHAPE + rng.normal(0, 2.0, SHAPE.shape)
    return np.c_[xy, np.full(len(SHAPE), 0.8)]


def _scene(seed=0):
    """Athlete near the centre in frames 0-39 and 180-239, lost (out of the
    image) in 40-179; a bystander seen in 100-130 only, drifting 12 px per
    frame from the lower left towards the centre (still 0.5 half diagonals
    off it at the end), as a camera panning past a person standing still."""
    rng = np.random.default_rng(seed)
    frames, joints, person = [], [], []
    for f in range(240):
        if f < 40 or f >= 180:
            frames.append(f)
            joints.append(_person(rng, (960 + 20 * np.sin(f / 9), 560), 300))
            person.append(0)
        if 100 <= f <= 130:
            frames.append(f)
            joints.append(_person(rng, (300 + 11 * (f - 100), 880 - 4 * (f - 100)), 260))
            person.append(1)
    return CameraDetections.from_joints("C4", SKI24, frames, np.array(joints), 240,
                                        person=np.array(person))


def test_the_loss_of_a_pan_tilt_camera_is_not_bridged_by_a_drifting_bystander():
    det = _scene()
    track = follow_person(det, image_centre=IMAGE_CENTRE)
    chosen = np.where(track.rows >= 0, det.person[np.maximum(track.rows, 0)], -1)
    assert np.all(chosen[100:131] != 1), np.flatnonzero(chosen == 1)
    assert np.all(chosen[:40] == 0) and np.all(chosen[180:] == 0)      # the athlete kept
    # a fixed camera (no image centre): nothing says the bystander is not the athlete
    fixed = follow_person(det)
    assert np.all(fixed.rows[:40] >= 0) and np.all(fixed.rows[180:] >= 0)


def test_an_off_centre_athlete_after_a_short_gap_is_still_followed():
    """An athlete off the centre of a lagging pan-tilt camera, missed by the
    detector for 3 frames, is taken again (only a long loss is not bridged
    by a person drifting off the centre)."""
    rng = np.random.default_rng(1)
    frames = [f for f in range(120) if not 60 <= f < 63]
    joints = np.array([_person(rng, (400 - 2 * (f % 7), 850), 280) for f in frames])
    det = CameraDetections.from_joints("C6", SKI24, frames, joints, 120)
    track = follow_person(det, image_centre=IMAGE_CENTRE)
    assert np.sum(track.rows >= 0) == len(frames)
