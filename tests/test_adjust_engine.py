"""The adjustment engine on synthetic networks with known truth."""

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.adjust.datum import check_datum
from photogram.adjust.solver import SolverOptions, solve
from photogram.errors import GeometryError
from photogram.init.helmert import helmert
from photogram.simulation.network import frame_network, to_project

FREE_IO = ("c", "x0", "y0", "K1")


def project_of(net, datum, seed=1, **kw):
    prj = to_project(net, control=[0, 1, 2, 3, 4], free_interior=FREE_IO, perturb_points=0.01,
                     perturb_stations=0.01, point_sigma=1e-4, rng=np.random.default_rng(seed), **kw)
    prj.adjustment.datum = datum
    return prj


@pytest.mark.parametrize("datum", ["control", "weighted", "free"])
def test_noise_free_network_recovers_truth(datum):
    net = frame_network(sigma=0.0)
    built = build_problem(project_of(net, datum))
    approx = built.problem.state.points.copy()
    check_datum(built.problem, built.present)
    s = solve(built.problem, SolverOptions(tolerance=1e-14, max_iterations=30))
    st = built.problem.state
    assert s.status == "converged"
    np.testing.assert_allclose(st.io[0][:4], net.io[0][:4], rtol=1e-8, atol=1e-14)
    if datum == "free":
        # the shape is exact; the datum is the minimum-trace one
        h = helmert(st.points, net.points)
        assert np.abs(h.residuals).max() < 1e-9
        # inner constraints: the translation part keeps the centroid of the
        # approximate points (sum of all point corrections is zero)
        np.testing.assert_allclose((st.points - approx).sum(axis=0), 0.0, atol=1e-9)
    else:
        np.testing.assert_allclose(st.points, net.points, atol=1e-9)
        np.testing.assert_allclose(st.X0, net.X0, atol=1e-8)


def test_redundancy_counts_observations_unknowns_and_conditions():
    net = frame_network(sigma=0.3)
    for datum, conditions in (("control", 0), ("free", 7)):
        built = build_problem(project_of(net, datum))
        p = built.problem
        n_obs = 2 * len(net.station)
        free_pts = len(net.points) - (5 if datum == "control" else 0)
        n_unknowns = 3 * free_pts + 6 * len(net.X0) + len(FREE_IO)
        assert p.redundancy() == n_obs - n_unknowns + conditions


def test_sigma0_is_near_one_with_correct_a_priori_sigma():
    net = frame_network(sigma=0.3, n_stations=12, n_points=80, seed=3)
    built = build_problem(project_of(net, "control"))
    s = solve(built.problem)
    # chi-square with ~1500 degrees of freedom: 5 sigma band is about +-0.09
    assert abs(s.sigma0 - 1.0) < 0.09


def test_datum_defect_is_reported_before_iterating():
    net = frame_network(sigma=0.3)
    prj = project_of(net, "control")
    prj.points.kind[:] = "tie"
    built = build_problem(prj)
    with pytest.raises(GeometryError, match="datum defect 7: no control, no distance, no inner constraints"):
        check_datum(built.problem, built.present)


def test_two_control_points_leave_one_rotation():
    net = frame_network(sigma=0.3)
    prj = project_of(net, "control")
    prj.points.kind[2:] = "tie"
    built = build_problem(prj)
    with pytest.raises(GeometryError, match="datum defect 1"):
        check_datum(built.problem, built.present)


def test_free_network_with_distance_uses_six_conditions_and_gets_scale():
    net = frame_network(sigma=0.0)
    from photogram.project.model import DistanceConstraint
    prj = project_of(net, "free")
    a, b = 0, 7
    true = float(np.linalg.norm(net.points[a] - net.points[b]))
    prj.distances.append(DistanceConstraint(prj.points.ids[a], prj.points.ids[b], true, 1e-5))
    built = build_problem(prj)
    assert built.problem.G.shape[1] == 6
    check_datum(built.problem, built.present)
    solve(built.problem, SolverOptions(tolerance=1e-14))
    st = built.problem.state
    h = helmert(st.points, net.points)
    assert abs(h.scale - 1) < 1e-9
    assert np.abs(h.residuals).max() < 1e-9


def test_weighted_station_priors_alone_define_the_datum():
    """Appendix D.2: approximate exterior orientations as weighted
    observations give the datum without any control point."""
    net = frame_network(sigma=0.3, seed=8)
    prj = project_of(net, "control")
    prj.points.kind[:] = "tie"
    prj.stations.position = net.X0.copy()
    prj.stations.angles = net.angles.copy()
    prj.stations.position_sigma[:] = 0.001
    prj.stations.angle_sigma[:] = 0.001
    built = build_problem(prj)
    check_datum(built.problem, built.present)
    s = solve(built.problem)
    assert s.status == "converged"
    err = built.problem.state.points - net.points
    assert np.sqrt(np.mean(err ** 2)) < 0.002


def test_robust_huber_downweights_a_blunder():
    from photogram.stats.robust import robust_reweighting
    net = frame_network(sigma=0.3, seed=9)
    net.xy[10] += [12.0, -9.0]     # a 50-sigma blunder
    clean = frame_network(sigma=0.3, seed=9)
    b_clean = build_problem(project_of(clean, "control"))
    solve(b_clean.problem)
    b = build_problem(project_of(net, "control"))
    solve(b.problem)
    ls_err = np.abs(b.problem.state.points - b_clean.problem.state.points).max()
    info = robust_reweighting(b.problem, "huber")
    rob_err = np.abs(b.problem.state.points - b_clean.problem.state.points).max()
    k = next(i for i, blk in enumerate(b.problem.blocks) if blk.name == "image points")
    assert b.problem.robust_weight[k][10, 0] < 0.05
    assert rob_err < ls_err / 3
    assert info["downweighted"] >= 1
