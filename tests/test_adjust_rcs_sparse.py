"""The iterative solve of the reduced camera system (RCS,
photogram/adjust/rcs_iterative.py): conjugate gradients on the implicit
Schur complement with the Schur-Jacobi preconditioner give the dense
step; the automatic choice follows SolverOptions as documented; the real
BAL problems reach the dense path's final cost."""

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from photogram.adjust import kernels, rcs_iterative, schur
from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, rcs_method
from photogram.bundle.bal import bal_options, build_bal_problem, solve_bal
from photogram.io.bal import behind_camera
from photogram.simulation.bal_sphere import project_bal, sphere_bal
from photogram.simulation.network import to_project, wall_network

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bal"
PATHS = ["numpy"] + (["numba"] if kernels.HAVE_NUMBA else [])


@pytest.fixture(params=PATHS)
def kernel_path(request):
    """Both kernel paths (numba where installed), also for small problems."""
    before, rows = kernels.use_numba(), kernels.min_rows()
    kernels.use_numba(request.param == "numba", min_rows=0)
    yield request.param
    kernels.use_numba(before, min_rows=rows)


def _sphere(n=12, obs=120, seed=3, datum="gauge"):
    return build_bal_problem(sphere_bal(n, obs_per_camera=obs, seed=seed).problem,
                             behind="keep", datum=datum).problem


def _steps(problem, damping, tol=1e-12):
    """The dense and the iterative step of the same normal equations."""
    dense = problem.linearize(problem.state)
    problem.rcs["method"] = "iterative"
    try:
        sparse = problem.linearize(problem.state)
    finally:
        problem.rcs["method"] = "dense"
    assert sp.issparse(sparse.Ncc) and not sp.issparse(dense.Ncc)
    np.testing.assert_allclose(sparse.Ncc.toarray(), dense.Ncc, rtol=0, atol=1e-9 * np.abs(
        dense.Ncc).max())
    dx_d, _ = schur.solve(dense, problem.layout, damping, problem.G)
    dx_i, fact = schur.solve(sparse, problem.layout, damping, problem.G, method="iterative",
                             cg_tolerance=tol, cg_max_iterations=5000)
    assert fact is None
    return dx_d, dx_i


def test_generator_observations_are_the_projection_plus_noise():
    sb = sphere_bal(20, obs_per_camera=100, noise=0.0, seed=5)
    bal = sb.problem
    xy = project_bal(sb.true_cameras, sb.true_points, bal.camera, bal.point)
    np.testing.assert_allclose(bal.xy, xy, atol=1e-9)
    k = np.bincount(bal.point, minlength=bal.n_points)
    assert k.min() >= 3 and k.max() <= 10
    assert not behind_camera(bal).any()
    # each (camera, point) once; ordered by camera
    assert len(np.unique(bal.camera * bal.n_points + bal.point)) == bal.n_observations
    assert np.all(np.diff(bal.camera) >= 0)


@pytest.mark.parametrize("damping", [1e-4, 1.0])
def test_iterative_step_equals_dense_step_gauge_free(kernel_path, damping):
    dx_d, dx_i = _steps(_sphere(), damping)
    assert np.max(np.abs(dx_i - dx_d)) <= 1e-7 * np.max(np.abs(dx_d))


def test_iterative_step_equals_dense_step_fixed_datum_undamped(kernel_path):
    problem = _sphere(datum="fixed")
    dx_d, dx_i = _steps(problem, 0.0)
    assert np.max(np.abs(dx_i - dx_d)) <= 1e-6 * np.max(np.abs(dx_d))
    assert np.all(dx_i[~problem.layout.free] == 0.0)


def test_iterative_step_shared_interior_and_control(kernel_path):
    """A wall network (one camera's interior shared by all stations: row
    groups overlap in the interior columns; control points; Brown model)."""
    net = wall_network(n_stations=8, n_points=150, rays=5, seed=2)
    prj = to_project(net, control=range(10), perturb_points=0.02, perturb_stations=0.002,
                     free_interior=("c", "x0", "y0", "K1"), rng=np.random.default_rng(2))
    prj.adjustment.datum = "control"
    problem = build_problem(prj).problem
    dx_d, dx_i = _steps(problem, 1e-3)
    assert np.max(np.abs(dx_i - dx_d)) <= 1e-6 * np.max(np.abs(dx_d))


def test_schur_jacobi_blocks_are_the_diagonal_blocks_of_the_rcs(kernel_path):
    problem = _sphere(n=10, obs=80)
    problem.rcs["method"] = "iterative"
    system = problem.linearize(problem.state)
    problem.rcs["method"] = "dense"
    Ncc, A = schur.damped(system, problem.layout, 0.1)
    Ainv = schur.invert_point_blocks(A)
    S, _ = schur.reduced_camera_system(system, Ainv, Ncc.toarray())
    op = rcs_iterative.SchurOperator(system, Ncc, Ainv)
    x = np.random.default_rng(0).standard_normal(len(S))
    np.testing.assert_allclose(op(x), S @ x, rtol=1e-9, atol=1e-9 * np.abs(S @ x).max())
    apply = rcs_iterative.schur_jacobi(op)
    block = np.zeros_like(S)
    for cols in system.structure.group_cols:       # one station (9 columns) per group
        block[np.ix_(cols, cols)] = S[np.ix_(cols, cols)]
    np.testing.assert_allclose(apply(x), np.linalg.solve(block, x), rtol=1e-8)


def test_automatic_choice(kernel_path):
    small = _sphere(n=12)                          # 108 reduced columns
    opt = SolverOptions()
    assert opt.linear_solver == "auto" and opt.iterative_min_columns is None
    assert rcs_method(small, opt) == "dense"
    assert rcs_method(small, SolverOptions(iterative_min_columns=100)) == "iterative"
    assert rcs_method(small, SolverOptions(linear_solver="iterative")) == "iterative"
    mid = _sphere(n=170, obs=30)                   # 1530 reduced columns
    # the fused BAL path (numba or its numpy twin, point_rows): from 500 on
    assert rcs_method(mid, opt) == "iterative"
    # the generic paths (weights other than 1 leave the fused one): 1500
    # columns with the numba kernels, 4000 without
    mid.variance["image"] = 4.0
    assert rcs_method(mid, opt) == ("iterative" if kernel_path == "numba" else "dense")
    big = _sphere(n=450, obs=12)                   # 4050 reduced columns
    assert rcs_method(big, opt) == "iterative"
    assert rcs_method(big, SolverOptions(linear_solver="dense")) == "dense"
    inner = _sphere(n=450, obs=12, datum="inner")  # datum conditions: dense only
    assert rcs_method(inner, opt) == "dense"
    with pytest.raises(ValueError):
        rcs_method(inner, SolverOptions(linear_solver="iterative"))
    with pytest.raises(ValueError):
        rcs_method(small, SolverOptions(linear_solver="sparse"))


def test_solve_reports_the_method_and_restores_the_problem(kernel_path):
    sb = sphere_bal(12, obs_per_camera=150, seed=4)
    costs = {}
    for method in ("dense", "iterative"):
        built = build_bal_problem(sb.problem, behind="keep")
        s = solve_bal(built, bal_options(linear_solver=method))
        assert s.linear_solver == method and s.status == "converged"
        assert built.problem.rcs["method"] == "dense"
        costs[method] = s.final_cost
    assert costs["iterative"] == pytest.approx(costs["dense"], rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("key", ["21-11315", "16-22106"])
def test_real_bal_same_final_cost(key):
    """The iterative RCS solve (forced; these problems are below the
    automatic switch) reaches the dense path's final cost on real data."""
    import bal_real
    path = DATA / f"problem-{key}-pre.txt.bz2"
    if not path.exists():
        pytest.skip(f"{path} not found")
    # the dense solve: solve_bal's default (tests/bal_real.py, shared with
    # tests/test_bal.py), the automatic choice for these sizes
    dense = bal_real.solved(f"problem-{key}-pre").summary
    assert dense.linear_solver == "dense"
    built = build_bal_problem(bal_real.read(f"problem-{key}-pre"))
    iterative = solve_bal(built, bal_options(linear_solver="iterative"))
    assert iterative.linear_solver == "iterative"
    assert iterative.final_cost == pytest.approx(dense.final_cost, rel=1e-5)
