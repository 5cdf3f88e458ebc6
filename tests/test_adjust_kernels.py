"""The engine's two kernel paths (numpy, and numba where installed) on a
self-calibration network with every kind of row (image points of
eliminated and of coupled points, a distance, control priors, a subset of
free interior parameters), and Ceres' trust-region strategy against the
default Levenberg-Marquardt one."""

import numpy as np
import pytest

from photogram.adjust import kernels
from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, solve
from photogram.project.model import DistanceConstraint
from photogram.simulation.network import frame_network, to_project
from photogram.stats.covariance import cofactors

FREE_IO = ("c", "x0", "y0", "K1")


def network_problem(datum="weighted"):
    net = frame_network(n_stations=6, n_points=40, sigma=0.3, seed=4)
    prj = to_project(net, control=[0, 1, 2, 3], free_interior=FREE_IO, perturb_points=0.01,
                     perturb_stations=0.01, point_sigma=1e-3, rng=np.random.default_rng(4))
    prj.distances.append(DistanceConstraint(prj.points.ids[5], prj.points.ids[6], 0.2, 0.001))
    prj.adjustment.datum = datum
    return build_problem(prj).problem


def results(p):
    system = p.linearize(p.state)
    dx, _ = p.solve_linear(system, 1e-3)
    cof = cofactors(p)
    blk = p.blocks[0]
    return (system.Ncc, system.A, system.g, system.WT, dx, cof.Qcc, cof.Qee,
            cof.block(blk.slot_cols[0], blk.slot_cols[1]))


@pytest.mark.skipif(not kernels.HAVE_NUMBA, reason="numba is not installed")
@pytest.mark.parametrize("datum", ["weighted", "free"])
def test_numba_and_numpy_paths_agree(datum):
    before, rows = kernels.use_numba(), kernels.min_rows()
    try:
        kernels.use_numba(False)
        ref = results(network_problem(datum))
        kernels.use_numba(True, min_rows=0)
        fast = results(network_problem(datum))
    finally:
        kernels.use_numba(before, min_rows=rows)
    for a, b in zip(ref, fast):
        assert np.abs(a - b).max() <= 1e-9 * max(np.abs(a).max(), 1e-300)


def test_trust_region_reaches_the_lm_solution():
    p_lm = network_problem("weighted")
    s_lm = solve(p_lm, SolverOptions(tolerance=1e-12))
    p_tr = network_problem("weighted")
    s_tr = solve(p_tr, SolverOptions(damping="trust_region", function_tolerance=1e-12,
                                     max_iterations=200))
    assert s_tr.status == "converged"
    assert s_tr.successful_steps >= 1
    assert s_tr.final_cost == pytest.approx(s_lm.final_cost, rel=1e-9)
    np.testing.assert_allclose(p_tr.state.points, p_lm.state.points, atol=1e-7)
    np.testing.assert_allclose(p_tr.state.io[0], p_lm.state.io[0], rtol=1e-7)
