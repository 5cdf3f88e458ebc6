"""Covariance, redundancy numbers, data snooping and variance components
against known truth."""

import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.solver import solve
from photogram.simulation.network import frame_network, observe, to_project
from photogram.stats.covariance import (
    camera_covariances, cofactors, point_covariances, station_covariances)
from photogram.stats.reliability import data_snooping, redundancy_numbers
from photogram.stats.variance import estimate_variance_components

FREE_IO = ("c", "x0", "y0", "K1")


def solved(net, seed=0, datum="control"):
    prj = to_project(net, control=[0, 1, 2, 3, 4], free_interior=FREE_IO,
                     rng=np.random.default_rng(seed))
    prj.adjustment.datum = datum
    b = build_problem(prj)
    solve(b.problem)
    return b.problem


def test_covariance_matches_monte_carlo():
    truth = frame_network(sigma=0.0, n_stations=8, n_points=40, seed=5)
    p = solved(truth)
    cof = cofactors(p)
    pred_pt = np.sqrt(np.diagonal(point_covariances(cof), axis1=1, axis2=2))
    pred_c = np.sqrt(camera_covariances(cof)[0][0, 0])   # a-priori sigma 0.3 px is in the weights
    pred_st = np.sqrt(np.diagonal(station_covariances(cof, p.state.R), axis1=1, axis2=2))
    rng = np.random.default_rng(11)
    errs_pt, errs_c, errs_st = [], [], []
    for _ in range(60):
        net = frame_network(sigma=0.0, n_stations=8, n_points=40, seed=5)
        net.xy = net.xy_true + rng.normal(0, 0.3, net.xy.shape)
        q = solved(net)
        errs_pt.append(q.state.points - truth.points)
        errs_c.append(q.state.io[0][0] - truth.io[0][0])
        errs_st.append(q.state.X0 - truth.X0)
    mc_pt = np.std(errs_pt, axis=0)
    free = np.arange(5, 40)
    ratio = mc_pt[free] / pred_pt[free]
    # 60 runs: the sample sigma scatters by ~9 %; averaged over 105 coordinates
    assert 0.85 < ratio.mean() < 1.15
    assert 0.7 < np.std(errs_c) / pred_c < 1.3
    ratio_st = np.std(errs_st, axis=0) / pred_st[:, :3]
    assert 0.8 < ratio_st.mean() < 1.2
    assert np.all(pred_pt[:5] == 0)   # fixed control


def test_redundancy_numbers_sum_to_redundancy():
    net = frame_network(sigma=0.3, seed=2)
    for datum in ("control", "free"):
        p = solved(net, datum=datum)
        red = redundancy_numbers(p)
        total = sum(float(r.sum()) for r in red)
        assert abs(total - p.redundancy()) < 1e-6 * p.redundancy()
        assert all(np.all((r >= -1e-9) & (r <= 1 + 1e-9)) for r in red)


def test_data_snooping_finds_planted_blunders_and_nothing_else():
    net = frame_network(sigma=0.3, n_stations=10, n_points=60, seed=4)
    rng = np.random.default_rng(3)
    bad = rng.choice(len(net.xy), 5, replace=False)
    net.xy[bad, rng.integers(0, 2, 5)] += rng.choice([-1, 1], 5) * 15 * 0.3   # 15 sigma
    p = solved(net)
    res = data_snooping(p, alpha=0.001)
    found = {r["row"] for r in res.rejected}
    assert set(bad.tolist()) <= found
    # false alarms: about alpha per tested coordinate (2 per image point)
    expected = 0.001 * 2 * len(net.xy)
    assert len(found - set(bad.tolist())) <= max(5, 3 * expected)
    assert res.critical_value > 3.2


def test_variance_components_recover_two_noise_levels():
    base = frame_network(sigma=0.0, n_stations=8, n_points=60, seed=6)
    # two cameras: stations 0-3 camera 0 (0.3 px), 4-7 camera 1 (0.9 px)
    cam = (np.arange(8) >= 4).astype(int)
    io = np.vstack([base.io[0], base.io[0]])
    net = observe("brown", io, cam, base.R, base.X0, base.points, (640, 480), sigma=0.0)
    rng = np.random.default_rng(9)
    noise = np.where((cam[net.station] == 0)[:, None], 0.3, 0.9)
    net.xy = net.xy_true + rng.normal(0, 1, net.xy.shape) * noise
    prj = to_project(net, control=[0, 1, 2, 3, 4], free_interior=FREE_IO, sigma_image=0.5,
                     rng=np.random.default_rng(0))
    b = build_problem(prj)
    solve(b.problem)
    hist = estimate_variance_components(b.problem)
    v = b.problem.variance
    s1 = np.sqrt(v["image K1"]) * 0.5
    s2 = np.sqrt(v["image K2"]) * 0.5
    assert abs(s1 - 0.3) < 0.03 and abs(s2 - 0.9) < 0.08
    assert len(hist) >= 2
