"""Online crop tracking (photogram.mocap.tracking.crop_tracking): one detector
call per frame on a predicted crop, the full image only to acquire or
re-acquire.

The fake detector sees "images" whose pixels hold their own full-image
coordinates (channel 0: x, channel 1: y, channel 2: the frame number, as
float32); a spy on the tracker's ``crop_image`` tells it the box of each
crop (the pixels cross-check it). It returns the known joints of a synthetic
moving person in the pixels of the crop it is given, or None when the person
is not in the crop, is hidden, or a frame is marked low-confidence, and it
counts its calls on full images and on crops. The tracker must map every
joint back to full-image pixels exactly.

The last test runs the real detector (mediapipe, the optional extra) on
Pose2Sim's real demo videos when both are present.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
import pytest

from photogram.mocap.body.skeleton import COCO17
from photogram.mocap.tracking.athlete import TrackingSettings, track_images_smoothed
from photogram.mocap.tracking.crop_tracking import (ACQUIRED, LOST, TRACKED, track_images,
                                                    CropTrackingSettings, accept_joints,
                                                    predict_box, track_crops)

H, W = 360, 480
SIZE = 128          # crop size: never the size of a full image


def person(f, speed=(6.0, 1.5), height0=150.0, growth=0.8, start=(100.0, 180.0)):
    """17 joints (x, y) of a synthetic person at frame f: a vertical figure
    moving at constant velocity and growing (walking towards the camera)."""
    h = height0 + growth * f
    cx, cy = start[0] + speed[0] * f, start[1] + speed[1] * f
    k = np.arange(17)
    x = cx + 0.25 * h * np.sin(0.9 * k + 0.05 * f)
    y = cy - 0.5 * h + h * k / 16.0
    return np.stack([x, y], -1)


class Frames:
    """Re-iterable coordinate images (module doc)."""

    def __init__(self, n):
        self.n = n

    def __iter__(self):
        yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
        for f in range(self.n):
            yield np.stack([xx, yy, np.full_like(xx, f)], -1)


class FakeDetector:
    """Known joints in the pixels of the image it is given (module doc).

    The crop box comes from a spy on the tracker's ``crop_image`` (the
    coordinates held by the pixels are quantised to 1/32 px by OpenCV's
    bilinear warp, so they only cross-check the box, to 0.1 px)."""

    skeleton = COCO17

    def __init__(self, truth, hidden=(), weak=(), noise=0.0, seed=0, mirror=()):
        self.truth = truth
        self.hidden, self.weak, self.mirror = set(hidden), set(weak), set(mirror)
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.full, self.crops = [], []       # frames of the calls
        self.box = None                      # set by the spy

    def __call__(self, image):
        img = np.asarray(image, float)
        f = int(round(img[..., 2].max()))
        if img.shape[:2] == (H, W):
            self.full.append(f)
            x0, y0, s = 0.0, 0.0, 1.0
        else:
            self.crops.append(f)
            x0, y0 = float(self.box[0]), float(self.box[1])
            s = (float(self.box[2]) - x0) / img.shape[1]
            u = v = img.shape[0] // 2                       # the crop is that box
            if 0 <= x0 + s * u < W - 1 and 0 <= y0 + s * v < H - 1:
                assert abs(img[v, u, 0] - (x0 + s * u)) < 0.1
                assert abs(img[v, u, 1] - (y0 + s * v)) < 0.1
        if f in self.hidden:
            return None
        xy = self.truth(f)
        if self.noise:
            xy = xy + self.rng.normal(0, self.noise, xy.shape)
        if f in self.mirror:                               # left and right exchanged
            xy = xy[COCO17.swap_permutation()]
        uv = np.stack([(xy[:, 0] - x0) / s, (xy[:, 1] - y0) / s], -1)
        centre = uv.mean(0)
        if not (0 <= centre[0] <= img.shape[1] and 0 <= centre[1] <= img.shape[0]):
            return None                                    # the person is not in this view
        conf = np.full(17, 0.2 if f in self.weak else 0.9)
        return np.concatenate([uv, conf[:, None]], 1)


@pytest.fixture
def spy(monkeypatch):
    """Make FakeDetector(...) instances learn the box of every crop."""
    from photogram.mocap.tracking import athlete, crop_tracking
    detectors = []

    def crop_image(image, box, size):
        for d in detectors:
            d.box = np.array(box, float)
        return athlete_crop(image, box, size)

    athlete_crop = athlete.crop_image
    monkeypatch.setattr(crop_tracking, "crop_image", crop_image)
    monkeypatch.setattr(athlete, "crop_image", crop_image)

    def make(*args, **kw):
        d = FakeDetector(*args, **kw)
        detectors.append(d)
        return d
    return make


SETTINGS = TrackingSettings(crop_size=SIZE)


def test_a_smoothly_moving_person_costs_one_call_per_frame_and_maps_back_exactly(spy):
    F = 40
    det = spy(person)
    t = track_crops(Frames(F), det, "cam", SETTINGS)
    assert det.full == [0] and det.crops == list(range(1, F))
    assert t.status[0] == ACQUIRED and np.all(t.status[1:] == TRACKED)
    assert t.counts() == {"tracked": F - 1, "acquired": 1, "lost": 0, "mirrored": 0,
                          "calls_crop": F - 1, "calls_full": 1}
    truth = np.array([person(f) for f in range(F)])
    assert np.allclose(t.joints[..., :2], truth, atol=1e-3)
    assert np.all(t.joints[..., 2] == 0.9) and np.all(t.person == -1)
    # the crops follow: square, 1.5 x the person's box side, around it
    side = t.boxes[:, 2] - t.boxes[:, 0]
    assert np.allclose(side, t.boxes[:, 3] - t.boxes[:, 1])
    box_side = np.max(t.detected[:, 2:] - t.detected[:, :2], axis=1)
    assert np.allclose(side[5:] / box_side[5:], 1.5, rtol=0.02)


def test_a_loss_costs_full_images_until_the_athlete_is_found_again(spy):
    F = 40
    hidden = range(20, 25)
    det = spy(person, hidden=hidden)
    t = track_crops(Frames(F), det, "cam", SETTINGS)
    # frame 20: the crop fails, then the full image; 21-24 full image only;
    # 25 re-acquired on the full image; then crops again
    assert det.full == [0, 20, 21, 22, 23, 24, 25]
    assert det.crops == list(range(1, 21)) + list(range(26, F))
    assert np.all(t.status[20:25] == LOST) and t.status[25] == ACQUIRED
    assert np.all(t.status[26:] == TRACKED)
    assert np.all(np.isnan(t.joints[20:25, :, :2])) and np.all(t.joints[20:25, :, 2] == 0)
    assert np.all(t.person[20:25] == -2)
    found = t.status != LOST
    truth = np.array([person(f) for f in range(F)])
    assert np.allclose(t.joints[found, :, :2], truth[found], atol=1e-3)


def test_low_confidence_in_the_crop_re_acquires_on_the_full_image(spy):
    F = 20
    det = spy(person, weak=[8])
    t = track_crops(Frames(F), det, "cam", SETTINGS)
    assert det.full == [0, 8, 9] and t.status[8] == LOST and t.status[9] == ACQUIRED
    assert t.counts()["calls_crop"] == F - 1 - 1      # frames 1..8 and 10..19


def test_a_jump_out_of_the_crop_is_re_acquired_in_the_same_frame(spy):
    def jumping(f):
        return person(f) + (np.array([220.0, 40.0]) if f >= 15 else 0.0)
    det = spy(jumping)
    t = track_crops(Frames(30), det, "cam", SETTINGS)
    assert det.full == [0, 15] and 15 in det.crops
    assert t.status[15] == ACQUIRED and np.all(np.delete(t.status, [0, 15]) == TRACKED)
    truth = np.array([jumping(f) for f in range(30)])
    assert np.allclose(t.joints[..., :2], truth, atol=1e-3)


def test_harsher_fast_noisy_person_is_kept_without_re_acquisitions(spy):
    """Not tuned on: 3 px joint noise and 3x the speed (18 px/frame)."""
    def fast(f):
        return person(f, speed=(9.0, 3.0), start=(60.0, 160.0), growth=0.3)
    F = 30
    det = spy(fast, noise=3.0, seed=1)
    t = track_crops(Frames(F), det, "cam", SETTINGS)
    assert det.full == [0] and np.all(t.status[1:] == TRACKED)
    truth = np.array([fast(f) for f in range(F)])
    err = np.linalg.norm(t.joints[..., :2] - truth, axis=-1)
    assert np.sqrt(np.mean(err ** 2)) < 3.0 * np.sqrt(2) * 1.1


def test_track_images_uses_the_crop_tracking_and_the_smoothed_flow_stays(spy):
    F = 16
    det = spy(person)
    t = track_images(Frames(F), det, "cam", SETTINGS)
    assert len(det.full) == 1 and len(det.crops) == F - 1
    det3 = spy(person)
    t3 = track_images_smoothed(Frames(F), det3, "cam", SETTINGS)
    assert len(det3.full) == F and len(det3.crops) == 2 * F        # three calls per frame
    assert np.allclose(t.joints, t3.joints, atol=1e-3)


def body(f):
    """COCO-17 joints of a person facing the camera and walking right:
    nose on top, every left/right pair 0.15-0.2 of the height apart."""
    h = 150.0 + 0.5 * f
    cx, cy = 100.0 + 5.0 * f, 180.0
    out = np.zeros((17, 2))
    out[0] = cx, cy - 0.45 * h
    for k, (right, left) in enumerate(COCO17.pairs):
        y = cy - 0.45 * h + (k + 1) * 0.9 * h / len(COCO17.pairs)
        half = (0.075 + 0.025 * (k % 2)) * h
        out[COCO17.index(right)] = cx - half, y
        out[COCO17.index(left)] = cx + half, y
    return out


def test_frames_with_left_and_right_exchanged_are_mirrored_back(spy):
    F = 40
    truth = np.array([body(f) for f in range(F)])
    for mirror in (range(12, 25), range(0, 6), [30]):     # the middle, the start, one frame
        det = spy(body, mirror=mirror)
        t = track_crops(Frames(F), det, "cam", SETTINGS)
        assert np.flatnonzero(t.mirrored).tolist() == list(mirror)
        assert np.allclose(t.joints[..., :2], truth, atol=1e-3)
        assert len(det.full) == 1                          # no re-acquisition
    # runs are decided apart: a loss between them, the detector mirrored in
    # most frames of the second: its labels win there
    det = spy(body, hidden=[10], mirror=range(11, 30))
    t = track_crops(Frames(F), det, "cam", SETTINGS)
    assert np.flatnonzero(t.mirrored).tolist() == list(range(30, 40))
    perm = COCO17.swap_permutation()
    assert np.allclose(t.joints[11:, :, :2], truth[11:, perm], atol=1e-3)
    off = spy(body, mirror=range(12, 25))
    t = track_crops(Frames(F), off, "cam", SETTINGS, crop=CropTrackingSettings(fix_sides=False))
    assert not t.mirrored.any() and np.allclose(t.joints[12:25, :, :2], truth[12:25, perm])


def test_harsher_noisy_mirrored_frames_are_mirrored_back(spy):
    """Not tuned on: 4 px joint noise, three mirrored stretches."""
    F = 50
    mirror = list(range(5, 9)) + list(range(20, 31)) + [44]
    det = spy(body, mirror=mirror, noise=4.0, seed=3)
    t = track_crops(Frames(F), det, "cam", SETTINGS)
    assert np.flatnonzero(t.mirrored).tolist() == mirror


def test_prediction_is_exact_for_constant_velocity_and_acceptance():
    frames = [3, 4, 6]
    states = [(10.0 + 2 * f, 50.0 - f, 40.0 + 0.5 * f) for f in frames]
    box = predict_box(frames, states, 8, 1.5)
    cx, cy, side = 26.0, 42.0, 1.5 * 44.0
    assert np.allclose(box, [cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2])
    assert np.allclose(predict_box([5], [(1.0, 2.0, 10.0)], 9, 2.0), [-9, -8, 11, 12])
    cs = CropTrackingSettings()
    j = np.zeros((17, 3))
    j[:, 0], j[:, 1], j[:, 2] = 50, 50, 0.9
    assert accept_joints(j, (0, 0, 100, 100), cs) and accept_joints(j, None, cs)
    assert not accept_joints(j, (60, 0, 100, 100), cs)             # beside the crop
    j[4:, 2] = 0.3                                                 # 4 of 17 confident
    assert not accept_joints(j, None, cs) and not accept_joints(None, None, cs)
    j[:5, 2] = 0.6                                                 # 5 of 17 >= 25 %
    assert accept_joints(j, None, cs)


# --------------------------------------------------------------------------
# real detector, real videos
# --------------------------------------------------------------------------
ROOT = Path(__file__).resolve().parents[1]
PROJECT = ROOT / "projects" / "pose2sim-demo" / "mediapipe.prj"
DATA = (PROJECT.parent / "../../../shared/data/pose2sim-demo").resolve()


def test_mediapipe_on_the_real_demo_videos_is_within_5_cm_of_pose2sim(caplog):
    pytest.importorskip("mediapipe")
    if not (DATA / "videos").is_dir():
        pytest.skip("Pose2Sim's demo videos are absent")
    from photogram.io.trc import read_trc
    from photogram.mocap.pipeline import run_mocap
    from photogram.mocap.sources.mediapipe import POSE2SIM_MARKERS
    from photogram.project.reader import read_project
    caplog.set_level(logging.INFO, logger="photogram.mocap.tracking.crop_tracking")
    c0 = time.process_time()
    result = run_mocap(read_project(PROJECT))
    cpu = time.process_time() - c0
    n = sum(len(t.joints) for t in result.tracked if t is not None)
    print(f"mediapipe on the demo: {n / cpu:.1f} camera-frames per CPU second "
          f"(tracking and reconstruction)")
    trc = read_trc(DATA / "pose2sim-triangulation-Balancing_for_IK.trc", rotate_to_z_up=True)
    X = result.reconstruction.joints
    sk = result.skeleton
    assert sk.name == "mediapipe33" and len(result.frames) == len(trc.frames) == 100
    d = np.array([np.linalg.norm(X[:, sk.index(j)] - trc.markers[m], axis=-1)
                  for m, j in POSE2SIM_MARKERS.items()])
    assert np.all(np.isfinite(d))
    assert np.median(d) <= 0.05
    # every camera keeps the athlete: one detector call per frame but for a
    # few re-acquisitions, no frame lost (the tracker's log line per camera)
    counts = [r.args for r in caplog.records if r.name.endswith("crop_tracking")]
    assert sorted(c[0] for c in counts) == ["cam_01", "cam_02", "cam_03", "cam_04"]
    for camera, frames, tracked, acquired, lost, calls_crop, calls_full, _ in counts:
        assert frames == 100 and lost == 0 and acquired <= 5
        assert calls_crop + calls_full <= frames + 5


def test_mediapipe_uses_only_its_packaged_model_files(monkeypatch, tmp_path):
    """The two model files of model_complexity 1 come with the package; a
    package without them is refused (mediapipe would download them)."""
    mp = pytest.importorskip("mediapipe")
    from photogram.errors import InputError
    from photogram.mocap.sources.mediapipe import MODEL_FILES, MediapipeDetector
    root = Path(mp.__file__).parent
    assert all((root / f).is_file() for f in MODEL_FILES)
    monkeypatch.setattr(mp, "__file__", str(tmp_path / "mediapipe" / "__init__.py"))
    with pytest.raises(InputError, match="would be downloaded") as exc:
        MediapipeDetector()
    assert "\n" not in exc.value.one_line()
