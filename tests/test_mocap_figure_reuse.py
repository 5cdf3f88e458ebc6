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

KEYS = ("knee_flexion_r", "knee_flexion_l", "hip_flexion_r", "hip_flexion_l", "lean",
        "fore_aft_angle", "speed")


def _result(seed, frames, skeleton=SKI24, truth=True, blank=()):
    """A stand-in for a mocap result: smooth random joints and series (the
    figures read nothing else); the frames in ``blank`` all gaps."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 50.0
    X = rng.normal(0, 0.4, (1, skeleton.n_joints, 3)) + 0.01 * np.cumsum(
        rng.normal(0, 1, (frames, skeleton.n_joints, 3)), axis=0)
    X[list(blank)] = np.nan

    def series():
        return {k: 20 * np.sin(t * rng.uniform(1, 5) + rng.uniform(0, 6)) + rng.uniform(-30, 30)
                for k in KEYS}
    return SimpleNamespace(times=t, frames=np.arange(frames) + 100 * seed, skeleton=skeleton,
                           biomechanics=series(), truth_biomechanics=series() if truth else None,
                           reconstruction=SimpleNamespace(joints=X))


def _draw(result, path):
    with matplotlib.style.context("default"):
        outputs._plot_series(result, path / "angles.png")
        outputs._plot_skeletons(result, path / "skeletons.png")
    return [hashlib.sha256((path / n).read_bytes()).hexdigest()
            for n in ("angles.png", "skeletons.png")]


@pytest.mark.parametrize("first, second", [
    (dict(seed=1, frames=30), dict(seed=2, frames=75)),
    (dict(seed=3, frames=40, blank=(0, 1, 2, 3, 4, 5)), dict(seed=4, frames=40, blank=range(6))),
    (dict(seed=5, frames=20, skeleton=COCO17, truth=False),
     dict(seed=6, frames=50, skeleton=COCO17, truth=False)),
])
def test_a_kept_figure_draws_what_a_new_one_draws(tmp_path, first, second):
    a, b = _result(**first), _result(**second)
    outputs._REUSED.clear()
    new_b = _draw(b, tmp_path)                       # built for b
    outputs._REUSED.clear()
    new_a = _draw(a, tmp_path)
    assert new_a != new_b                            # the data show
    assert len(outputs._REUSED) == 2                 # kept: a's figures
    assert _draw(b, tmp_path) == new_b               # a's figures given b's data
    assert _draw(a, tmp_path) == new_a
