"""The fused, point-ordered linearization of BAL problems
(photogram/adjust/point_rows.py, kernels in _numba_point.py): the same
normal equations, cost and Schur pieces as the generic path; its gradient
is the finite-difference gradient of its cost; it steps aside where it
does not apply; the buffer of W_o^T is reused only when no live system
holds it."""

import gc

import numpy as np
import pytest
from bal_checks import assert_same_normal_equations, check_gradient

from photogram.adjust import kernels, point_rows, rcs_iterative, schur
from photogram.adjust.normal import assemble
from photogram.adjust.solver import SolverOptions, rcs_method
from photogram.bundle.bal import bal_options, build_bal_problem, solve_bal
from photogram.simulation.bal_sphere import sphere_bal

pytestmark = pytest.mark.skipif(not kernels.HAVE_NUMBA, reason="numba not installed")


@pytest.fixture
def numba_small():
    """The compiled kernels also for these small problems."""
    before, rows = kernels.use_numba(), kernels.min_rows()
    kernels.use_numba(True, min_rows=0)
    yield
    kernels.use_numba(before, min_rows=rows)


def _problem(n=12, obs=150, seed=3):
    problem = build_bal_problem(sphere_bal(n, obs_per_camera=obs, seed=seed).problem,
                                behind="keep").problem
    problem.rcs["method"] = "iterative"
    return problem


def _generic(problem, state):
    rs, Js = problem.evaluate(state)
    return assemble(problem.structure, rs, Js, sparse=True)


def test_fused_normal_equations_equal_the_generic_ones(numba_small):
    problem = _problem()
    state = problem.state
    fused = problem.linearize(state)
    ref = _generic(problem, state)
    assert_same_normal_equations(fused, ref, problem, state)
    x = np.random.default_rng(1).standard_normal(problem.layout.n_reduced)
    np.testing.assert_allclose(fused.wt_times_c(x), ref.wt_times_c(x), rtol=1e-10, atol=1e-10)
    dx = np.random.default_rng(2).standard_normal(problem.layout.n_columns)
    assert fused.quadratic(dx) == pytest.approx(ref.quadratic(dx), rel=1e-10)


def test_fused_schur_pieces_equal_the_generic_ones(numba_small):
    problem = _problem()
    fused = problem.linearize(problem.state)
    Ncc, A = schur.damped(fused, problem.layout, 0.1)
    Ainv = schur.invert_point_blocks(A)
    coupling, rhs = fused.schur_parts(Ncc, Ainv)
    op = rcs_iterative.SchurOperator(fused, Ncc, Ainv)
    n_e = problem.layout.n_eliminated
    g_e = fused.g[problem.layout.n_reduced:].reshape(n_e, 3)
    np.testing.assert_allclose(rhs, op.w_times_e(np.einsum("nij,nj->ni", Ainv, g_e)),
                               rtol=1e-10, atol=1e-10 * np.abs(rhs).max())
    x = np.random.default_rng(0).standard_normal(problem.layout.n_reduced)
    np.testing.assert_allclose(rcs_iterative.schur_jacobi(op, coupling)(x),
                               rcs_iterative.schur_jacobi(op)(x), rtol=1e-8, atol=1e-12)
    # the operator is the dense reduced camera system's product
    S, _ = schur.reduced_camera_system(_generic(problem, problem.state), Ainv, Ncc.toarray())
    np.testing.assert_allclose(op(x), S @ x, rtol=1e-9, atol=1e-9 * np.abs(S @ x).max())


def test_fused_gradient_is_the_finite_difference_gradient_of_the_cost(numba_small):
    problem = _problem(n=8, obs=60, seed=5)
    system = problem.linearize(problem.state)
    check_gradient(problem, system, np.random.default_rng(3))


def test_fused_path_steps_aside(numba_small):
    problem = _problem()
    assert point_rows.plan(problem) is not None
    problem.rcs["method"] = "dense"
    assert point_rows.plan(problem) is None            # only with the iterative RCS
    problem.rcs["method"] = "iterative"
    problem.active[0][3] = False                       # a rejected observation
    assert point_rows.plan(problem) is None
    assert not isinstance(problem.linearize(problem.state), point_rows.PointSystem)
    problem.active[0][3] = True
    problem.variance["image"] = 4.0                    # weights other than 1
    assert point_rows.plan(problem) is None
    problem.variance["image"] = 1.0
    kernels.use_numba(False)
    assert point_rows.plan(problem) is not None        # pure-numpy path: the numpy twin
    assert problem.linearize(problem.state).Wg is not None
    kernels.use_numba(True)
    assert point_rows.plan(problem) is not None
    assert problem.linearize(problem.state).Wg is None  # the compiled kernels


def test_buffer_reused_only_when_free(numba_small):
    problem = _problem()
    first = problem.linearize(problem.state)
    second = problem.linearize(problem.state)
    assert first.WTp is not second.WTp                 # both alive: two buffers
    kept = first.WTp.copy()
    del first
    gc.collect()
    third = problem.linearize(problem.state)
    assert third.WTp is not second.WTp                 # the free buffer, not the live one
    np.testing.assert_array_equal(third.WTp, kept)
    assert len(problem.structure._point_plan.buffers) == 2


def test_fused_solve_matches_dense_solve_and_auto_switch(numba_small):
    sb = sphere_bal(12, obs_per_camera=150, seed=4)
    costs = {}
    for method in ("dense", "iterative"):
        built = build_bal_problem(sb.problem, behind="keep")
        s = solve_bal(built, bal_options(linear_solver=method))
        assert s.status == "converged"
        costs[method] = s.final_cost
    assert costs["iterative"] == pytest.approx(costs["dense"], rel=1e-6)
    # "auto": 500 reduced columns with the fused path (numba or its numpy
    # twin), 1500 without it (numba; 4000 on the generic numpy path)
    mid = _problem(n=60, obs=30)                       # 540 reduced columns
    assert rcs_method(mid, SolverOptions()) == "iterative"
    kernels.use_numba(False)
    assert rcs_method(mid, SolverOptions()) == "iterative"
    mid.variance["image"] = 4.0                        # weights other than 1: no fused path
    assert rcs_method(mid, SolverOptions()) == "dense"
    kernels.use_numba(True)
    assert rcs_method(mid, SolverOptions()) == "dense"


def test_point_seen_twice_by_one_camera(numba_small):
    """Two rows of one (point, camera): the Schur-Jacobi blocks merge them
    (generic pass); the fused system still gives the dense step."""
    from photogram.io.bal import BALProblem
    bal = sphere_bal(12, obs_per_camera=150, seed=3).problem
    extra = np.arange(0, bal.n_observations, 97)
    twice = BALProblem(bal.cameras, bal.points, np.r_[bal.camera, bal.camera[extra]],
                       np.r_[bal.point, bal.point[extra]], np.r_[bal.xy, bal.xy[extra] + 0.3])
    problem = build_bal_problem(twice, behind="keep").problem
    problem.rcs["method"] = "iterative"
    fused = problem.linearize(problem.state)
    assert isinstance(fused, point_rows.PointSystem) and not fused.plan.unique
    assert fused.schur_parts(*schur.damped(fused, problem.layout, 0.1)) is None
    dense_sys = _generic(problem, problem.state)
    problem.rcs["method"] = "dense"
    dense = problem.linearize(problem.state)
    dx_d, _ = schur.solve(dense, problem.layout, 1e-3)
    dx_i, _ = schur.solve(fused, problem.layout, 1e-3, method="iterative", cg_tolerance=1e-12,
                          cg_max_iterations=5000)
    assert np.max(np.abs(dx_i - dx_d)) <= 1e-7 * np.max(np.abs(dx_d))
    Ncc, A = schur.damped(fused, problem.layout, 0.1)
    Ainv = schur.invert_point_blocks(A)
    S, _ = schur.reduced_camera_system(dense_sys, Ainv, Ncc.toarray())
    op = rcs_iterative.SchurOperator(fused, Ncc, Ainv)
    x = np.random.default_rng(0).standard_normal(len(S))
    block = np.zeros_like(S)
    for cols in problem.structure.group_cols:
        block[np.ix_(cols, cols)] = S[np.ix_(cols, cols)]
    np.testing.assert_allclose(rcs_iterative.schur_jacobi(op)(x), np.linalg.solve(block, x),
                               rtol=1e-8)
