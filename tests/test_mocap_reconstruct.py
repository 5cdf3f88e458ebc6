"""Energy, gradient, Gauss-Newton model, solvers and the reconstruction on a
small simulated run (SIMULATED data)."""

import numpy as np
import pytest

import photogram.mocap.reconstruction.reconstruct as R
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.evaluation.metrics import accuracy_3d, biomechanics
from photogram.mocap.reconstruction.solvers import _inv3, _pcg
from photogram.simulation.ski.simulate import simulate_session


@pytest.fixture(scope="module")
def sim():
    return simulate_session(seed=3, n_runs=1, frames_per_run=90)


@pytest.fixture(scope="module")
def batch(sim):
    s = R.ReconstructionSettings()
    windows, batches = R._batches(sim.observations[:60], sim.cameras.select_frames(
        np.arange(60)), SKI24, s, [])
    return batches[0]


def _start(sim, batch, idx, noise=0.02):
    ws, index, b = batch
    rng = np.random.default_rng(1)
    a = np.einsum("tk,wtjd->wjdk", b.B, sim.joints[index])
    return b, a + rng.normal(0, noise, a.shape)


def test_gradient_matches_central_differences(sim, batch):
    b, a = _start(sim, batch, None)
    L = np.full(len(SKI24.limbs), 0.3)
    rng = np.random.default_rng(2)
    for sigma2 in (100.0, 1e5):
        E, G = b.gradient(a, sigma2, L, 80.0, 1e4)
        assert np.allclose(E, b.energy(a, sigma2, L, 80.0, 1e4))
        V = rng.normal(0, 1e-6, a.shape)
        fd = b.energy(a + V, sigma2, L, 80.0, 1e4) - b.energy(a - V, sigma2, L, 80.0, 1e4)
        assert np.allclose(fd, 2 * np.sum(G * V, axis=(1, 2, 3)), rtol=1e-4, atol=1e-9)


def test_gauss_newton_model_matrix_free_equals_dense(sim, batch):
    b, a = _start(sim, batch, None)
    L = np.full(len(SKI24.limbs), 0.3)
    lin = b.linearize(a, 100.0, L, 80.0, 1e4)
    E, G = b.gradient(a, 100.0, L, 80.0, 1e4)
    assert np.allclose(lin.rhs, -G / 2, atol=1e-9 * np.abs(G).max())
    diag, off = lin.dense_blocks()
    nw, J, m = diag.shape[0], diag.shape[1], diag.shape[2]
    H = np.zeros((nw, J * m, J * m))
    for j in range(J):
        H[:, j * m:(j + 1) * m, j * m:(j + 1) * m] = diag[:, j]
    for k, (p, q) in enumerate(SKI24.limb_indices()):
        H[:, p * m:(p + 1) * m, q * m:(q + 1) * m] -= off[:, k]
        H[:, q * m:(q + 1) * m, p * m:(p + 1) * m] -= off[:, k]
    V = np.random.default_rng(3).normal(size=a.shape)
    Hv = np.einsum("wab,wb->wa", H, V.reshape(nw, -1)).reshape(V.shape)
    assert np.allclose(lin.matvec(V), Hv, rtol=1e-9, atol=1e-9 * np.abs(Hv).max())
    D = lin.block_diagonal()
    k = 7
    idx = [k, a.shape[-1] + k, 2 * a.shape[-1] + k]
    assert np.allclose(D[:, 4, :, :, k], H[:, 4 * m:5 * m, 4 * m:5 * m][:, idx][:, :, idx])
    damp = 1e-3 * np.ones_like(a)
    Dd = D.copy()
    for c in range(3):
        Dd[:, :, c, c] += damp[:, :, c]
    x, it = _pcg(lin, damp, _inv3(Dd), lin.rhs, tol=1e-12, max_iter=500)
    xd = np.linalg.solve(H + 1e-3 * np.eye(J * m), lin.rhs.reshape(nw, -1, 1))
    assert np.allclose(x.reshape(nw, -1), xd[..., 0], atol=1e-8 * np.abs(xd).max())


def test_reconstruction_from_the_centre_of_the_cameras(sim):
    rec = R.reconstruct(sim.observations, sim.cameras, SKI24, breaks=sim.breaks)
    acc = accuracy_3d(rec.joints, sim.joints, SKI24)
    assert acc["mpjpe"] < 0.025
    b = biomechanics(rec.joints, SKI24, 50.0)
    t = biomechanics(sim.joints, SKI24, 50.0)
    knee = np.nanmean(np.abs(np.concatenate([b[k] - t[k] for k in ("knee_flexion_r",
                                                                      "knee_flexion_l")])))
    assert knee < 3.0
    assert rec.stages[-1]["sigma2"] == R.DEFAULT_SIGMA2 == 400.0
    assert rec.stages[0]["sigma2"] == 1e6
    assert [st["sigma2"] for st in rec.stages] == [1e6, 1e5, 1e4, 1e3, 400.0]
    # estimated limb lengths are close to the truth and symmetric
    true = R.limb_lengths(sim.joints, SKI24)
    assert np.nanmax(np.abs(rec.limb_lengths - true)) < 0.03


def test_the_robust_scale_default_and_the_papers():
    """sigma^2 = 400 px^2 by default (docs/mocap.md section 10); the paper's
    100 px^2 is a setting (``[mocap.reconstruction] sigma2 = 100``), reached
    by one more continuation stage."""
    assert R.ReconstructionSettings().stages() == [1e6, 1e5, 1e4, 1e3, 400.0]
    paper = R.ReconstructionSettings(sigma2=R.PAPER_SIGMA2)
    assert R.PAPER_SIGMA2 == 100.0 and paper.stages() == [1e6, 1e5, 1e4, 1e3, 100.0]


def test_lbfgs_reaches_the_energy_of_gauss_newton(sim):
    obs, cams = sim.observations[:50], sim.cameras.select_frames(np.arange(50))
    gn = R.reconstruct(obs, cams, SKI24, R.ReconstructionSettings())
    lb = R.reconstruct(obs, cams, SKI24, R.ReconstructionSettings(solver="lbfgs"))
    assert lb.energy == pytest.approx(gn.energy, rel=2e-4)
    assert np.nanmax(np.abs(lb.joints - gn.joints)) < 0.02


def test_unobserved_joints_are_nan_and_given_lengths_are_used(sim):
    obs = sim.observations[:50].copy()
    obs[:, :, SKI24.index("r_pole")] = np.nan
    obs[20:, :, SKI24.index("l_pole")] = np.nan      # gone after frame 20
    lengths = dict(zip(SKI24.limbs, R.limb_lengths(sim.joints, SKI24)))
    rec = R.reconstruct(obs, sim.cameras.select_frames(np.arange(50)), SKI24,
                        R.ReconstructionSettings(limb_lengths=lengths))
    assert np.all(np.isnan(rec.joints[:, SKI24.index("r_pole")]))
    lp = rec.joints[:, SKI24.index("l_pole")]
    # seen until frame 19, a gap after (issue 22: no bridging by default);
    # with the linear trend of the pose basis (issue 22, item 3) the few
    # coefficients of the restricted basis follow the pole to its first
    # frame (measured 2-19 cm; without the trend the first frames were
    # 0.9-1.6 m off and failed the fit test)
    assert np.all(np.isfinite(lp[:20])) and np.all(np.isnan(lp[20:]))
    assert np.max(np.linalg.norm(lp[:20] - sim.joints[:20, SKI24.index("l_pole")],
                                 axis=-1)) < 0.25
    err = np.linalg.norm(rec.joints - sim.joints[:50], axis=-1)
    assert np.nanmean(err) < 0.03
