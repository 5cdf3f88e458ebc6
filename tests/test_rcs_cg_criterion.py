"""Ceres' truncated-Newton stopping test for the CG of the iterative
reduced-camera-system solve (``SolverOptions.cg_criterion="model"``,
photogram/adjust/rcs_iterative.py): CG stops at the first step i where
i (Q_i - Q_{i-1}) / Q_i < eta, Q(x) = x^T S x - 2 b^T x."""

import numpy as np
import pytest

from photogram.adjust import rcs_iterative, schur
from photogram.adjust.solver import SolverOptions
from photogram.bundle.bal import bal_options, build_bal_problem, solve_bal
from photogram.simulation.bal_sphere import sphere_bal


def _operator(damping=1e-4):
    problem = build_bal_problem(sphere_bal(40, obs_per_camera=150, seed=7).problem,
                                behind="keep").problem
    problem.rcs["method"] = "iterative"
    system = problem.linearize(problem.state)
    Ncc, A = schur.damped(system, problem.layout, damping)
    op = rcs_iterative.SchurOperator(system, Ncc, schur.invert_point_blocks(A))
    b = np.random.default_rng(1).standard_normal(op.n_r)
    return op, b


@pytest.mark.parametrize("eta", [0.1, 0.01])
def test_model_criterion_stops_at_the_first_small_zeta(eta):
    op, b = _operator()
    precond = rcs_iterative.schur_jacobi(op)

    def Q(x):
        return float(x @ op(x) - 2.0 * b @ x)

    x, it = rcs_iterative.pcg(op, b, precond, tolerance=eta, max_iterations=1000,
                              criterion="model")
    assert 1 < it < 1000
    xs = [np.zeros_like(b)] + [rcs_iterative.pcg(op, b, precond, tolerance=0.0,
                                                 max_iterations=k)[0] for k in range(1, it)]
    xs.append(x)
    zeta = [k * (Q(xs[k]) - Q(xs[k - 1])) / Q(xs[k]) for k in range(1, it + 1)]
    assert zeta[-1] < eta
    assert all(z >= eta for z in zeta[:-1])


def test_model_criterion_option_reaches_the_same_minimum():
    sb = sphere_bal(12, obs_per_camera=150, seed=4)
    costs = {}
    for crit in ("residual", "model"):
        built = build_bal_problem(sb.problem, behind="keep")
        s = solve_bal(built, bal_options(linear_solver="iterative", cg_criterion=crit))
        assert s.status == "converged"
        costs[crit] = s.final_cost
    assert costs["model"] == pytest.approx(costs["residual"], rel=1e-6)
    assert SolverOptions().cg_criterion == "residual"
    op, b = _operator()
    with pytest.raises(ValueError):
        rcs_iterative.pcg(op, b, rcs_iterative.schur_jacobi(op), criterion="energy")
