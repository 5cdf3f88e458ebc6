"""photogram.rig.initial keeps its last OpenCV starts by their exact inputs
(issue 23 item 6): the same detections give the same start bit for bit,
as copies the caller may change; other detections are calibrated anew."""

import cv2
import numpy as np

from photogram.io.targets import parse_target
from photogram.rig import initial
from photogram.rig.initial import camera_intrinsics

TARGET = parse_target("chessboard:8x6:0.08")


def _frames(seed=0, n=6):
    P = TARGET.object_points()
    K = np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]])
    rng = np.random.default_rng(seed)
    frames = {}
    for f in range(n):
        xy, _ = cv2.projectPoints(P, rng.normal(0, 0.3, 3), np.array([-0.2, -0.15, 1.5 + f / 25]),
                                  K, np.array([-0.1, 0.02, 0, 0, 0]))
        frames[f] = (np.arange(len(P)), xy.reshape(-1, 2) + rng.normal(0, 0.1, (len(P), 2)))
    return frames, P


def test_the_same_detections_give_the_same_start_as_copies(monkeypatch):
    frames, P = _frames()
    calls = []
    real = cv2.calibrateCamera
    monkeypatch.setattr(cv2, "calibrateCamera", lambda *a, **k: calls.append(1) or real(*a, **k))
    initial._STARTS.clear()
    K1, d1, poses1, rms1 = camera_intrinsics(frames, P, (1280, 720), fix_k3=True)
    n = len(calls)
    assert n == 1 + len(initial.FOCAL_STARTS)
    K1_copy = K1.copy()
    K1[0, 0] = -1.0                                  # the caller's copy, not the kept one
    K2, d2, poses2, rms2 = camera_intrinsics(frames, P, (1280, 720), fix_k3=True)
    assert len(calls) == n                           # kept: no calibration
    assert np.array_equal(K2, K1_copy) and np.array_equal(d1, d2) and rms1 == rms2
    assert all(np.array_equal(poses1[f], poses2[f]) for f in poses1)
    # k3 free, or one corner moved by 1e-3 px (OpenCV gets float32: 6e-5 px steps
    # here; a smaller move that float32 rounds away is the same input): anew
    camera_intrinsics(frames, P, (1280, 720), fix_k3=False)
    assert len(calls) == 2 * n
    ids, xy = frames[3]
    xy = xy.copy()
    xy[0, 0] += 1e-3
    frames[3] = (ids, xy)
    camera_intrinsics(frames, P, (1280, 720), fix_k3=True)
    assert len(calls) == 3 * n


def test_the_kept_starts_are_bounded(monkeypatch):
    monkeypatch.setattr(initial, "_STARTS_SIZE", 2)
    initial._STARTS.clear()
    P = TARGET.object_points()
    for seed in range(4):
        frames, _ = _frames(seed, n=4)
        camera_intrinsics(frames, P, (1280, 720))
    assert len(initial._STARTS) == 2
