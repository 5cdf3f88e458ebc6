"""The pure-numpy twin of the fused, point-ordered BAL linearization
(photogram/adjust/_numpy_point.py, dispatched by point_rows when the
compiled kernels are not active): the same cost, N_cc, g, W, Schur pieces
and step as the generic path (Problem.evaluate, then normal.assemble) on
generated and real BAL problems, also when its chunks split row groups;
the same numbers as the numba kernels where numba is installed; its
Jacobians are those of finite differences of the model; a full solve
reaches the generic path's final cost."""

import numpy as np
import pytest

import bal_real
from bal_checks import assert_same_normal_equations, check_gradient
from photogram.adjust import _numpy_point, kernels, point_rows, rcs_iterative, schur
from photogram.adjust.normal import assemble
from photogram.bundle.bal import bal_options, build_bal_problem, solve_bal
from photogram.simulation.bal_sphere import sphere_bal


@pytest.fixture
def numpy_path():
    """The compiled kernels off: the fused path runs the numpy twin."""
    before, rows = kernels.use_numba(), kernels.min_rows()
    kernels.use_numba(False)
    yield
    kernels.use_numba(before, min_rows=rows)


@pytest.fixture
def small_chunks(monkeypatch):
    """Chunks of 97 rows: every chunk boundary splits a row group."""
    monkeypatch.setattr(_numpy_point, "CHUNK", 97)


def _iterative(bal, **kw):
    problem = build_bal_problem(bal, behind="keep", **kw).problem
    problem.rcs["method"] = "iterative"
    return problem


def _generic(problem, state):
    rs, Js = problem.evaluate(state)
    return assemble(problem.structure, rs, Js, sparse=True)


def _assert_same_system(twin, ref, problem, state):
    assert_same_normal_equations(twin, ref, problem, state)
    assert twin.Wg is not None
    n_r = problem.layout.n_reduced
    x = np.random.default_rng(1).standard_normal(n_r)
    np.testing.assert_allclose(twin.wt_times_c(x), ref.wt_times_c(x), rtol=1e-10,
                               atol=1e-12 * np.abs(ref.wt_times_c(x)).max())
    y = np.random.default_rng(4).standard_normal((problem.layout.n_eliminated, 3))
    np.testing.assert_allclose(twin.w_times_e(y), ref.w_times_e(y), rtol=1e-10,
                               atol=1e-12 * np.abs(ref.w_times_e(y)).max())
    dx = np.random.default_rng(2).standard_normal(problem.layout.n_columns)
    assert twin.quadratic(dx) == pytest.approx(ref.quadratic(dx), rel=1e-10)


@pytest.mark.parametrize("n, obs, seed", [(12, 150, 3), (20, 80, 7)])
def test_twin_equals_the_generic_path(numpy_path, small_chunks, n, obs, seed):
    problem = _iterative(sphere_bal(n, obs_per_camera=obs, seed=seed).problem)
    state = problem.state
    twin = problem.linearize(state)
    od = problem.structure._point_plan.numpy_order
    assert len(od.chunks) > 1 and not np.isin([lo for lo, _ in od.chunks[1:]], od.gptr).all()
    _assert_same_system(twin, _generic(problem, state), problem, state)


def test_twin_schur_pieces_and_step_equal_the_generic_ones(numpy_path, small_chunks):
    problem = _iterative(sphere_bal(12, obs_per_camera=150, seed=3).problem)
    lay = problem.layout
    twin = problem.linearize(problem.state)
    ref = _generic(problem, problem.state)
    Ncc, A = schur.damped(ref, lay, 0.1)
    Ainv = schur.invert_point_blocks(A)
    Ncc_t, Ainv_o = twin.damped_inverse(lay, 0.1)
    np.testing.assert_allclose(Ncc_t.toarray(), Ncc.toarray(), rtol=0,
                               atol=1e-12 * np.abs(Ncc.toarray()).max())
    np.testing.assert_allclose(Ainv_o, Ainv[twin.plan.point], rtol=1e-10,
                               atol=1e-12 * np.abs(Ainv).max())
    coupling, rhs = twin.schur_parts(Ncc, Ainv)
    op_ref = rcs_iterative.SchurOperator(ref, Ncc, Ainv)
    g_e = ref.g[lay.n_reduced:].reshape(-1, 3)
    np.testing.assert_allclose(rhs, op_ref.w_times_e(np.einsum("nij,nj->ni", Ainv, g_e)),
                               rtol=1e-10, atol=1e-10 * np.abs(rhs).max())
    x = np.random.default_rng(0).standard_normal(lay.n_reduced)
    op = rcs_iterative.SchurOperator(twin, Ncc, Ainv)
    np.testing.assert_allclose(rcs_iterative.schur_jacobi(op, coupling)(x),
                               rcs_iterative.schur_jacobi(op_ref)(x), rtol=1e-8, atol=1e-12)
    S, _ = schur.reduced_camera_system(ref, Ainv, Ncc.toarray())
    np.testing.assert_allclose(op(x), S @ x, rtol=1e-9, atol=1e-9 * np.abs(S @ x).max())
    # the damped step (CG to 1e-12) equals the generic path's and the dense one
    kw = dict(method="iterative", cg_tolerance=1e-12, cg_max_iterations=5000)
    dx_t, _ = schur.solve(twin, lay, 1e-3, **kw)
    dx_g, _ = schur.solve(ref, lay, 1e-3, **kw)
    problem.rcs["method"] = "dense"
    dx_d, _ = schur.solve(problem.linearize(problem.state), lay, 1e-3)
    assert np.max(np.abs(dx_t - dx_g)) <= 1e-8 * np.max(np.abs(dx_g))
    assert np.max(np.abs(dx_t - dx_d)) <= 1e-7 * np.max(np.abs(dx_d))


def test_twin_jacobians_are_finite_differences_of_the_model(numpy_path):
    """``g = J^T r`` is the gradient of the twin's cost and ``dx^T N dx``
    is ``|J dx|^2`` with ``J dx`` from central differences of the
    residuals, in random directions over all columns (camera, station,
    rotation, interior, points)."""
    problem = _iterative(sphere_bal(8, obs_per_camera=60, seed=5).problem)
    lay, state = problem.layout, problem.state
    system = problem.linearize(state)
    assert system.Wg is not None
    rng = np.random.default_rng(3)
    check_gradient(problem, system, rng)
    # scale of each column: a step that moves the image by about a pixel
    scale = 1.0 / np.sqrt(np.maximum(np.r_[system.Ncc.diagonal(),
                                           np.einsum("nii->ni", system.A).ravel()], 1e-300))
    for k in range(3):
        dx = scale * rng.standard_normal(lay.n_columns) * 1e-4
        rp = problem.evaluate(state.updated(lay, dx), jacobians=False)[0][0]
        rm = problem.evaluate(state.updated(lay, -dx), jacobians=False)[0][0]
        Jdx = (rp - rm) / 2.0                           # r = observed - computed: -J dx
        assert system.quadratic(dx) == pytest.approx(float(np.sum(Jdx * Jdx)), rel=1e-6)


@pytest.mark.skipif(not kernels.HAVE_NUMBA, reason="numba not installed")
def test_twin_equals_the_numba_kernels(small_chunks):
    before, rows = kernels.use_numba(), kernels.min_rows()
    try:
        problem = _iterative(sphere_bal(12, obs_per_camera=150, seed=3).problem)
        kernels.use_numba(True, min_rows=0)
        nb = problem.linearize(problem.state)
        cost_nb = problem.cost(problem.state)
        kernels.use_numba(False)
        tw = problem.linearize(problem.state)
        cost_tw = problem.cost(problem.state)
    finally:
        kernels.use_numba(before, min_rows=rows)
    assert nb.Wg is None and tw.Wg is not None and nb.plan is tw.plan
    assert cost_tw == pytest.approx(cost_nb, rel=1e-12) and tw.cost == pytest.approx(nb.cost,
                                                                                    rel=1e-12)
    np.testing.assert_allclose(tw.WTp, nb.WTp, rtol=0, atol=1e-12 * np.abs(nb.WTp).max())
    np.testing.assert_allclose(tw.A_o, nb.A_o, rtol=1e-12, atol=1e-12 * np.abs(nb.A_o).max())
    np.testing.assert_allclose(tw.g_o, nb.g_o, rtol=0, atol=1e-11 * np.abs(nb.g_o).max())
    np.testing.assert_allclose(tw.g, nb.g, rtol=0, atol=1e-11 * np.abs(nb.g).max())
    np.testing.assert_allclose(tw.Ncc.toarray(), nb.Ncc.toarray(), rtol=0,
                               atol=1e-12 * np.abs(nb.Ncc.toarray()).max())
    lay = problem.layout
    Ncc, Ainv_t = tw.damped_inverse(lay, 0.1)
    _, Ainv_n = nb.damped_inverse(lay, 0.1)
    np.testing.assert_allclose(Ainv_t, Ainv_n, rtol=1e-10, atol=1e-12 * np.abs(Ainv_n).max())
    x = np.random.default_rng(0).standard_normal(lay.n_reduced)
    np.testing.assert_allclose(tw.schur_matvec(Ainv_n, x), nb.schur_matvec(Ainv_n, x),
                               rtol=1e-10, atol=1e-12 * np.abs(nb.schur_matvec(Ainv_n, x)).max())
    np.testing.assert_allclose(tw.back_o(x), nb.back_o(x), rtol=1e-10,
                               atol=1e-12 * np.abs(nb.back_o(x)).max())
    for a, b in zip(tw.schur_parts(Ncc, Ainv_n, ordered=True),
                    nb.schur_parts(Ncc, Ainv_n, ordered=True)):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10 * np.abs(b).max())


def test_twin_full_solve_reaches_the_generic_final_cost(numpy_path, monkeypatch):
    sb = sphere_bal(12, obs_per_camera=150, seed=4)
    opts = bal_options(linear_solver="iterative")
    built = build_bal_problem(sb.problem, behind="keep")
    twin = solve_bal(built, opts)
    monkeypatch.setattr(point_rows, "plan", lambda problem, method=None: None)
    generic = solve_bal(build_bal_problem(sb.problem, behind="keep"), opts)
    assert twin.status == generic.status == "converged"
    assert twin.final_cost == pytest.approx(generic.final_cost, rel=1e-8)
    # and the noise level: 2 cost / sigma^2 is chi^2 with the redundancy as
    # degrees of freedom (0.5 px noise; within 5 of its standard deviations)
    r = built.problem.redundancy()
    assert abs(2 * twin.final_cost / 0.5 ** 2 - r) < 5 * np.sqrt(2 * r)


def test_twin_equals_the_generic_path_on_real_bal(numpy_path):
    """problem-49-7776 (Ladybug; 31 observations behind their camera kept
    so that every observation is active, as the fused path requires)."""
    name = "problem-49-7776-pre"
    if not (bal_real.DATA / f"{name}.txt.bz2").exists():
        pytest.skip(f"{bal_real.DATA / name}.txt.bz2 not found")
    problem = _iterative(bal_real.read(name))
    state = problem.state
    twin = problem.linearize(state)
    _assert_same_system(twin, _generic(problem, state), problem, state)
    lay = problem.layout
    ref = _generic(problem, state)
    kw = dict(method="iterative", cg_tolerance=1e-10, cg_max_iterations=5000)
    dx_t, _ = schur.solve(twin, lay, 1e-2, **kw)
    dx_g, _ = schur.solve(ref, lay, 1e-2, **kw)
    assert np.max(np.abs(dx_t - dx_g)) <= 1e-6 * np.max(np.abs(dx_g))


def test_twin_point_seen_twice_by_one_camera(numpy_path, small_chunks):
    """Two rows of one (point, camera): the generic Schur-Jacobi pass
    merges them; the twin's step is still the dense one."""
    from photogram.io.bal import BALProblem
    bal = sphere_bal(12, obs_per_camera=150, seed=3).problem
    extra = np.arange(0, bal.n_observations, 97)
    twice = BALProblem(bal.cameras, bal.points, np.r_[bal.camera, bal.camera[extra]],
                       np.r_[bal.point, bal.point[extra]], np.r_[bal.xy, bal.xy[extra] + 0.3])
    problem = _iterative(twice)
    twin = problem.linearize(problem.state)
    assert twin.Wg is not None and not twin.plan.unique
    _assert_same_system(twin, _generic(problem, problem.state), problem, problem.state)
    problem.rcs["method"] = "dense"
    dx_d, _ = schur.solve(problem.linearize(problem.state), problem.layout, 1e-3)
    dx_t, _ = schur.solve(twin, problem.layout, 1e-3, method="iterative", cg_tolerance=1e-12,
                          cg_max_iterations=5000)
    assert np.max(np.abs(dx_t - dx_d)) <= 1e-7 * np.max(np.abs(dx_d))
