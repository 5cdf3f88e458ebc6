"""The figures of ``photogram mocap`` kept for the next results folder of
the same layout (photogram.mocap.outputs._reused, issue 23 item 6): a kept
figure given new data draws the same PNG, byte for byte, as a figure built
for that data."""

import hashlib
from types import SimpleNamespace

import matplotlib.style
import numpy as np
import pytest

from photogram.mocap import outputs
from photogram.mocap.body.skeleton import COCO17, SKI24

# `make test-fast` leaves this module out (5 s: sixteen figures drawn).
pytestmark = pytest.mark.slow

KEYS = ("knee_flexion_r", "knee_flexion_l", "hip_flexion_r", "hip_flexion_l", "lean",
        "fore_aft_angle", "speed", "com_x", "com_y")
FIGURES = ("angles", "skeletons", "trajectory", "reprojection")


def _result(seed, frames, skeleton=SKI24, truth=True, blank=(), cameras=4, reference=False):
    """A stand-in for a mocap result: smooth random joints and series,
    cameras projecting orthographically, noisy detections (the figures read
    nothing else); the frames in ``blank`` all gaps."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 50.0
    X = rng.normal(0, 0.4, (1, skeleton.n_joints, 3)) + 0.01 * np.cumsum(
        rng.normal(0, 1, (frames, skeleton.n_joints, 3)), axis=0)
    X[list(blank)] = np.nan

    def series():
        return {k: 20 * np.sin(t * rng.uniform(1, 5) + rng.uniform(0, 6)) + rng.uniform(-30, 30)
                for k in KEYS}
    names = [f"cam{c}" for c in range(cameras)]
    scale = rng.uniform(50, 150, cameras)

    def project(P):
        return scale[None, :, None, None] * P[:, None, :, :2]
    obs = project(X) + rng.normal(0, 3, (frames, cameras, skeleton.n_joints, 2))
    conf = rng.uniform(0, 1, obs.shape[:3] + (1,))
    ref = {"reprojection": {n: {"reference_median_px": v} for n, v in
                            zip(names, [None] + list(rng.uniform(1, 5, cameras - 1)))}}
    return SimpleNamespace(times=t, frames=np.arange(frames) + 100 * seed, skeleton=skeleton,
                           biomechanics=series(), truth_biomechanics=series() if truth else None,
                           reconstruction=SimpleNamespace(joints=X),
                           cameras=SimpleNamespace(names=names, project=project,
                                                   X0=rng.normal(0, 20, (cameras, 3))),
                           observations=np.concatenate([obs, conf], -1),
                           reference=ref if reference else None)


def _draw(result, path):
    with matplotlib.style.context("default"):
        outputs._plot_series(result, path / "angles.png")
        outputs._plot_skeletons(result, path / "skeletons.png")
        outputs._plot_trajectory(result, path / "trajectory.png")
        outputs._plot_reprojection(result, path / "reprojection.png")
    return [hashlib.sha256((path / f"{n}.png").read_bytes()).hexdigest() for n in FIGURES]


@pytest.mark.parametrize("first, second", [
    (dict(seed=1, frames=30, blank=range(4), reference=True),
     dict(seed=2, frames=75, blank=range(9), reference=True)),
    (dict(seed=5, frames=20, skeleton=COCO17, truth=False, cameras=2),
     dict(seed=6, frames=50, skeleton=COCO17, truth=False, cameras=2)),
])
def test_a_kept_figure_draws_what_a_new_one_draws(tmp_path, first, second):
    a, b = _result(**first), _result(**second)
    outputs._REUSED.clear()
    new_b = _draw(b, tmp_path)                           # built for b
    outputs._REUSED.clear()
    new_a = _draw(a, tmp_path)
    assert all(x != y for x, y in zip(new_a, new_b))     # the data show
    assert len(outputs._REUSED) == len(FIGURES)          # kept: a's figures
    assert _draw(b, tmp_path) == new_b                   # a's figures given b's data
