"""Window seams (issue 22, item 3): the pose basis with a linear trend, the
centre of mass continuous across window overlaps and at the ends of a run,
the speed computed from it, and the windows' disagreement reported.

The data are SIMULATED (photogram.simulation.ski.simulate). Before the fix
a truncated DCT bent every window's ends flat (a skier at 16 m/s): with the
part-2 count of 11 DCT terms (200 frames, known rotations) the CoM's
frame-to-frame motion was 26 cm off the truth's at the end of the run and
0.68 cm per frame in the overlaps, the speed error 0.45 m/s on average and
9.4 m/s at the ends; now 5.5 cm, 0.28 cm, 0.026 and 0.45 m/s."""

import numpy as np
import pytest

import photogram  # noqa: F401
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.evaluation.metrics import biomechanics, centre_of_mass
from photogram.mocap.reconstruction.dct import dct_basis, plan_windows, trend_basis
from photogram.mocap.reconstruction.reconstruct import ReconstructionSettings, reconstruct
from photogram.simulation.ski.simulate import simulate_session


def test_trend_basis_is_orthonormal_and_holds_a_straight_run_exactly():
    T, K = 50, 11
    B = trend_basis(T, K)
    assert B.shape == (T, K + 1)
    assert np.allclose(B.T @ B, np.eye(K + 1), atol=1e-12)
    assert np.allclose(B[:, 0], 1 / np.sqrt(T))             # the constant stays column 0
    run = 0.33 * np.arange(T) + 4.0                          # 16.5 m/s at 50 fps
    assert np.max(np.abs(run - B @ (B.T @ run))) < 1e-12
    D = dct_basis(T, K)                                      # the plain DCT bends its ends
    assert np.max(np.abs(run - D @ (D.T @ run))) > 0.1
    # the DCT terms are still spanned
    assert np.allclose(B @ (B.T @ D), D, atol=1e-12)
    assert trend_basis(3, 5).shape == (3, 3) and np.allclose(trend_basis(3, 5), dct_basis(3, 3))


def _com(X):
    return centre_of_mass({n: X[:, k] for k, n in enumerate(SKI24.joints)})


@pytest.fixture(scope="module")
def run_11():
    """One run of 200 frames, known rotations, 11 DCT terms per window."""
    sim = simulate_session(seed=8, n_runs=1, frames_per_run=200)
    s = ReconstructionSettings(n_dct=11)
    return sim, s, reconstruct(sim.observations, sim.cameras, SKI24, s)


def test_com_is_continuous_across_window_overlaps_and_at_the_ends(run_11):
    sim, s, rec = run_11
    F = len(sim.joints)
    jump = np.linalg.norm(np.diff(_com(rec.joints), axis=0) - np.diff(_com(sim.joints), axis=0),
                          axis=1)                    # the motion between frames minus the truth's
    cover = np.zeros(F, int)
    for w in plan_windows(F, s.window, s.overlap, s.coefficients):
        cover[w.start:w.stop] += 1
    seam = (cover[:-1] > 1) | (cover[1:] > 1)
    assert seam.sum() >= 30
    assert np.mean(jump[seam]) < 0.004                       # m per frame (before: 0.0068)
    assert np.max(jump) < 0.08                               # (before: 0.25 at the last frame)
    b = biomechanics(rec.joints, SKI24, sim.fps)
    t = biomechanics(sim.joints, SKI24, sim.fps)
    assert np.nanmean(np.abs(b["speed"] - t["speed"])) < 0.06     # m/s (before: 0.45)
    assert np.nanmax(np.abs(b["speed"] - t["speed"])) < 1.0       # (before: 9.4 m/s at the ends)


def test_windows_disagreement_is_reported(run_11):
    sim, s, rec = run_11
    d = rec.stages[-1]["seam_disagreement_m"]
    assert 0 < d["median"] <= d["p95"] <= d["max"] < 0.1
    assert rec.stages[-1]["linear_trend"] is True and rec.stages[-1]["coefficients"] == 11
