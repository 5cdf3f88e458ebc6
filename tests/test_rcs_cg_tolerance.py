"""The CG forcing tolerance of the iterative reduced-camera-system solve
(default 0.1, Ceres' eta): pcg stops once the preconditioned residual has
fallen below the tolerance, and a looser tolerance takes fewer steps."""

import numpy as np
import pytest

from photogram.adjust import rcs_iterative, schur
from photogram.adjust.solver import SolverOptions
from photogram.bundle.bal import build_bal_problem
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


def test_default_is_ceres_eta():
    assert SolverOptions().cg_tolerance == 0.1


@pytest.mark.parametrize("tol", [0.1, 1e-2, 1e-4])
def test_pcg_meets_its_tolerance(tol):
    op, b = _operator()
    precond = rcs_iterative.schur_jacobi(op)
    x, it = rcs_iterative.pcg(op, b, precond, tolerance=tol, max_iterations=1000)
    assert 0 < it < 1000
    r = b - op(x)
    assert np.sqrt(r @ precond(r)) <= tol * np.sqrt(b @ precond(b)) * (1 + 1e-9)


def test_looser_tolerance_takes_fewer_steps_and_a_coarser_solution():
    op, b = _operator()
    precond = rcs_iterative.schur_jacobi(op)
    exact, _ = rcs_iterative.pcg(op, b, precond, tolerance=1e-10, max_iterations=2000)
    out = {t: rcs_iterative.pcg(op, b, precond, tolerance=t) for t in (0.1, 1e-2)}
    assert out[0.1][1] < out[1e-2][1]
    err = {t: np.linalg.norm(x - exact) for t, (x, _) in out.items()}
    assert err[1e-2] < err[0.1]
