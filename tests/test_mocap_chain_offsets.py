"""The chain's offsets fitted over the whole run
(photogram.mocap.reconstruction.chain_offsets; issue 22). SIMULATED data."""

import numpy as np
import pytest

from photogram.geometry.aiming import look_at
from photogram.geometry.rotations import matrix_to_rodrigues, rodrigues_to_matrix
from photogram.mocap.reconstruction.bootstrap import chain_rotations
from photogram.mocap.motion.rotation_series import difference_noise
from photogram.mocap.reconstruction.chain_offsets import (OffsetTrack,
                                                          interpolate_offsets,
                                                          observation_jacobians, offset_knots,
                                                          refine_chain_offsets)

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _angle_deg(A, B):
    return np.degrees(np.linalg.norm(matrix_to_rodrigues(np.swapaxes(A, -1, -2) @ B), axis=-1))


def test_observation_jacobians_match_finite_differences():
    rng = np.random.default_rng(1)
    N = 7
    R = rodrigues_to_matrix(rng.normal(0, 0.3, (N, 3)) + [np.pi, 0, 0])
    v = rng.normal(0, 1, (N, 3))
    v = np.einsum("nba,nb->na", R, np.column_stack([v[:, :2], -np.abs(v[:, 2]) - 20]))
    t_obs = rng.normal(0, 0.01, (N, 2))
    scale = rng.uniform(1500, 4000, (N, 2))
    r, Jd, Jt, front = observation_jacobians(R, v, t_obs, scale)
    assert front.all()
    h = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        rp = observation_jacobians(R, v + e, t_obs, scale)[0]
        rm = observation_jacobians(R, v - e, t_obs, scale)[0]
        np.testing.assert_allclose(Jd[:, :, k], (rp - rm) / (2 * h), rtol=1e-5, atol=1e-6)
        Rp = R @ rodrigues_to_matrix(e)
        Rm = R @ rodrigues_to_matrix(-e)
        rp = observation_jacobians(Rp, v, t_obs, scale)[0]
        rm = observation_jacobians(Rm, v, t_obs, scale)[0]
        np.testing.assert_allclose(Jt[:, :, k], (rp - rm) / (2 * h), rtol=1e-5, atol=1e-4)


def test_offset_knots_cover_every_frame_of_every_segment():
    frames, cams, knot, alpha = offset_knots(45, [0, 2], breaks=(20,), knot_frames=10,
                                             n_cameras=3)
    assert (knot[:, 1] == -1).all()                      # camera 1 not refined
    for c in (0, 2):
        kf = frames[cams == c]
        assert {0, 19, 20, 44} <= set(kf.tolist())       # segment ends are knots
        t = np.arange(45)
        f0, f1 = frames[knot[:, c, 0]], frames[knot[:, c, 1]]
        assert np.all((f0 <= t) & (t <= f1))
        assert np.all(f1 - f0 <= 10)
        assert np.all((f0 < 20) == (f1 < 20))              # no knot pair crosses the break
        np.testing.assert_allclose(alpha[:, c], (t - f0) / np.maximum(f1 - f0, 1))


def test_interpolate_offsets_is_geodesic_between_knots():
    frames, cams, knot, alpha = offset_knots(11, [0], knot_frames=10, n_cameras=1)
    O = rodrigues_to_matrix(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.2]]))
    out = interpolate_offsets(OffsetTrack(frames, cams, O, knot, alpha))
    np.testing.assert_allclose(out[0, 0], O[0], atol=1e-12)
    np.testing.assert_allclose(out[10, 0], O[1], atol=1e-12)
    np.testing.assert_allclose(matrix_to_rodrigues(out[5, 0]), [0, 0, 0.1], atol=1e-12)


def test_difference_noise_recovers_the_simulated_error():
    rng = np.random.default_rng(3)
    sigma = np.radians(0.03)
    motion = np.column_stack([np.linspace(0.001, 0.01, 2000), np.zeros(2000), np.zeros(2000)])
    dR = rodrigues_to_matrix(motion + rng.normal(0, sigma, (2000, 3)))
    ok = rng.uniform(size=2000) > 0.05
    est = difference_noise(dR, ok)
    assert abs(est / sigma - 1) < 0.1
    assert np.isnan(difference_noise(dR[:3], np.array([True, False, True])))


def _scene(seed=5, F=150, C=4, J=12):
    """An athlete (J points within 1 m) crossing 60 m in front of C cameras
    that follow it; the true rotations R (F, C, 3, 3) and joints X (F, J, 3)."""
    rng = np.random.default_rng(seed)
    X0 = np.array([[0.0, -40, 1.5], [30, -45, 1.5], [60, -40, 1.5], [30, 30, 1.5]])[:C]
    path = np.column_stack([np.linspace(0, 60, F), 3 * np.sin(np.linspace(0, 3, F)),
                            np.ones(F)])
    body = rng.normal(0, 0.4, (J, 3))
    X = path[:, None] + body[None]
    R = np.stack([look_at(X0, path[f]) for f in range(F)])
    return X0, X, R


def test_refine_recovers_offsets_that_the_windows_leave_open():
    """Start: every camera turned by a slowly varying 0.5-1 deg error and the
    athlete shifted with them (the mode that windows cannot see); the chain of
    measured differences (0.01 deg per pair) and 2 px detections give the
    offsets back to a small part of that."""
    X0, X, R_true = _scene()
    F, C, J = X.shape[0], len(X0), X.shape[1]
    rng = np.random.default_rng(7)
    sigma = np.radians(0.01)
    dR_true = R_true[1:] @ np.swapaxes(R_true[:-1], -1, -2)
    noise = rodrigues_to_matrix(rng.normal(0, sigma, (F - 1, C, 3)))
    Q = chain_rotations(noise @ dR_true)
    scale = np.full((F, C, 2), 3000.0)
    Xc = np.einsum("fcab,fcjb->fcja", R_true, X[:, None] - X0[None, :, None])
    t_obs = np.stack([-Xc[..., 0] / Xc[..., 2], Xc[..., 1] / Xc[..., 2]], -1)
    t_obs = t_obs + rng.normal(0, 2.0 / 3000, t_obs.shape)
    conf = np.ones((F, C, J))
    slow = np.radians(0.5) * np.stack([np.sin(np.linspace(0, 2, F) + k)
                                       for k in range(3 * C)], -1).reshape(F, C, 3)
    R_start = R_true @ rodrigues_to_matrix(slow + np.radians(0.5))
    X_start = X + np.array([0.3, -0.2, 0.1])
    before = np.median(_angle_deg(R_start, R_true))
    R, info = refine_chain_offsets(X_start, R_start, Q, t_obs, conf, scale, X0, range(C),
                                   sigma_pair=np.full(C, sigma), sigma2=400.0)
    after = np.median(_angle_deg(R, R_true))
    assert before > 0.5
    assert after < 0.2 and after < before / 5, (before, after, info)
    assert [st["sigma2"] for st in info["stages"]] == [40000.0, 4000.0, 400.0]


def test_refine_holds_cameras_that_are_not_refined():
    X0, X, R_true = _scene(F=40)
    F, C = X.shape[0], len(X0)
    Q = chain_rotations(R_true[1:] @ np.swapaxes(R_true[:-1], -1, -2))
    Xc = np.einsum("fcab,fcjb->fcja", R_true, X[:, None] - X0[None, :, None])
    t_obs = np.stack([-Xc[..., 0] / Xc[..., 2], Xc[..., 1] / Xc[..., 2]], -1)
    R_start = R_true @ rodrigues_to_matrix(np.full(3, np.radians(0.3)))
    R_start[:, 2:] = R_true[:, 2:]                     # held cameras: right
    R, _ = refine_chain_offsets(X, R_start, Q, t_obs, np.ones(X.shape[:1] + (C, X.shape[1])),
                                np.full((F, C, 2), 3000.0), X0, [0, 1])
    np.testing.assert_array_equal(R[:, 2:], R_start[:, 2:])
    assert np.median(_angle_deg(R_start[:, :2], R_true[:, :2])) > 0.5
    assert np.median(_angle_deg(R[:, :2], R_true[:, :2])) < 0.02


@pytest.mark.parametrize("knot_frames", [5, 25])
def test_refine_without_detections_keeps_the_start(knot_frames):
    X0, X, R_true = _scene(F=30)
    F, C, J = X.shape[0], len(X0), X.shape[1]
    Q = chain_rotations(R_true[1:] @ np.swapaxes(R_true[:-1], -1, -2))
    R, info = refine_chain_offsets(X, R_true, Q, np.full((F, C, J, 2), np.nan),
                                   np.zeros((F, C, J)), np.full((F, C, 2), 3000.0), X0,
                                   range(C), knot_frames=knot_frames)
    np.testing.assert_array_equal(R, R_true)
    assert info["iterations"] == 0


def test_correlation_inflation_of_white_and_smoothed_errors():
    """White errors: about 1; errors smoothed over frames (a moving average
    of m frames: 1 + 2 sum rho_k = m): about m."""
    from photogram.mocap.reconstruction.chain_links import correlation_inflation
    rng = np.random.default_rng(11)
    F, C, J = 400, 3, 8
    f, c, j = [a.ravel() for a in np.meshgrid(np.arange(F), np.arange(C), np.arange(J),
                                              indexing="ij")]
    white = rng.normal(0, 5, (F, C, J, 2))
    keep = np.ones(len(f), bool)
    assert abs(correlation_inflation(white.reshape(-1, 2), f, c, j, keep, (F, C, J), 20)
               - 1.0) < 0.15
    m = 5
    kernel = np.ones(m) / m
    smooth = np.apply_along_axis(lambda x: np.convolve(x, kernel, mode="same"), 0,
                                 rng.normal(0, 5, (F, C, J, 2)))
    got = correlation_inflation(smooth.reshape(-1, 2), f, c, j, keep, (F, C, J), 20)
    assert abs(got - m) < 0.6, got
    none = np.full((len(f), 2), np.nan)
    assert correlation_inflation(none, f, c, j, keep, (F, C, J), 20) == 1.0


def test_project_keys_of_the_offsets_are_read(tmp_path):
    from photogram.mocap.reconstruction.estimate import estimate_settings
    s = estimate_settings(chain_offsets=False, offset_knot_frames=20, chain_sigma_deg=0.02)
    assert (s.chain_offsets, s.offset_knot_frames, s.chain_sigma_deg) == (False, 20, 0.02)
    from photogram.project.reader_mocap import RECONSTRUCTION_KEYS
    assert {"chain_offsets", "offset_knot_frames", "chain_sigma_deg"} <= set(RECONSTRUCTION_KEYS)


def test_differences_over_many_frames_hold_the_chain_s_drift():
    """A noisy chain (0.05 deg per pair) drifts; differences measured over
    10 and 25 frames (0.01 deg) tie it together: the offsets come out closer
    to the truth than with the chain alone."""
    X0, X, R_true = _scene(seed=9, F=200)
    F, C, J = X.shape[0], len(X0), X.shape[1]
    rng = np.random.default_rng(21)
    sigma = np.radians(0.05)
    dR_true = R_true[1:] @ np.swapaxes(R_true[:-1], -1, -2)
    Q = chain_rotations(rodrigues_to_matrix(rng.normal(0, sigma, (F - 1, C, 3))) @ dR_true)
    Xc = np.einsum("fcab,fcjb->fcja", R_true, X[:, None] - X0[None, :, None])
    t_obs = np.stack([-Xc[..., 0] / Xc[..., 2], Xc[..., 1] / Xc[..., 2]], -1)
    t_obs = t_obs + rng.normal(0, 5.0 / 3000, t_obs.shape)
    scale = np.full((F, C, 2), 3000.0)
    a = np.concatenate([np.tile(np.arange(0, F - k), C) for k in (10, 25)])
    cam = np.concatenate([np.repeat(np.arange(C), F - k) for k in (10, 25)])
    b = a + np.concatenate([np.full(C * (F - k), k) for k in (10, 25)])
    true = R_true[b, cam] @ np.swapaxes(R_true[a, cam], -1, -2)
    lag_sigma = np.radians(0.01)
    M = rodrigues_to_matrix(rng.normal(0, lag_sigma, (len(a), 3))) @ true
    lagged = (cam, a, b, M, np.full(len(a), lag_sigma))
    args = (X, R_true, Q, t_obs, np.ones((F, C, J)), scale, X0, range(C))
    R0, _ = refine_chain_offsets(*args, sigma_pair=np.full(C, sigma))
    R1, info = refine_chain_offsets(*args, sigma_pair=np.full(C, sigma), lagged=lagged)
    e0 = np.median(_angle_deg(R0, R_true))
    e1 = np.median(_angle_deg(R1, R_true))
    assert e1 < 0.8 * e0, (e0, e1)        # 0.25 -> 0.18 deg
    # a lagged difference of a camera that is not refined is left out
    R2, _ = refine_chain_offsets(X, R_true, Q, t_obs, np.ones((F, C, J)), scale, X0, [0, 1],
                                 sigma_pair=np.full(C, sigma), lagged=lagged)
    np.testing.assert_array_equal(R2[:, 2:], R_true[:, 2:])


def test_lagged_links_across_a_run_break_are_left_out_and_noise_is_estimated():
    from photogram.mocap.reconstruction.chain_links import ChainLinks, lagged_noise
    F, C = 40, 1
    frames, cams, knot, alpha = offset_knots(F, [0], breaks=(20,), knot_frames=10, n_cameras=C)
    track = OffsetTrack(frames, cams, np.broadcast_to(np.eye(3), (len(frames), 3, 3)).copy(),
                        knot, alpha)
    Q = np.broadcast_to(np.eye(3), (F, C, 3, 3)).copy()
    a, b = np.array([0, 5, 15, 25]), np.array([10, 15, 25, 35])     # 15 -> 25 crosses
    links = ChainLinks(track, Q, np.full(C, 1e-3),
                       (np.zeros(4, int), a, b, np.broadcast_to(np.eye(3), (4, 3, 3)),
                        np.full(4, 1e-3)))
    assert sorted(links.lagged[1].tolist()) == [0, 5, 25]
    rng = np.random.default_rng(2)
    sig_pair, sig_lag = np.radians(0.03), np.radians(0.02)
    n = 3000
    a = rng.integers(0, 100, n)
    b = a + 10
    Qc = rodrigues_to_matrix(rng.normal(0, 1, (110, 1, 3)))
    walk = rng.normal(0, sig_pair * np.sqrt(10), (n, 3)) + rng.normal(0, sig_lag, (n, 3))
    dR = Qc[b, 0] @ rodrigues_to_matrix(walk) @ np.swapaxes(Qc[a, 0], -1, -2)
    # e = log((Q(b) Q(a)^T)^T dR): rotate the error into the frame of Q(a)
    est = lagged_noise(Qc, (np.zeros(n, int), a, b, dR), np.array([sig_pair]))
    assert abs(est[0] / sig_lag - 1) < 0.25, np.degrees(est)
