"""The two-level preconditioner of the iterative reduced-camera-system
solve (photogram/adjust/rcs_coarse.py): Schur-Jacobi plus a coarse
correction on clusters of cameras. Checked against the RCS formed
densely from the implicit operator: ``S P`` and ``S_c = P^T S P`` exact,
the preconditioner symmetric positive definite, PCG reaching the dense
solve in fewer steps than Schur-Jacobi, full solves reaching the same
cost; the numba kernel against its numpy twin."""

from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from photogram.adjust import kernels, rcs_coarse, rcs_iterative, schur
from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, cg_preconditioner, rcs_method
from photogram.bundle.bal import bal_options, build_bal_problem, solve_bal
from photogram.simulation.bal_sphere import sphere_bal
from photogram.simulation.network import to_project, wall_network

PATHS = ["numpy"] + (["numba"] if kernels.HAVE_NUMBA else [])


@pytest.fixture(params=PATHS)
def kernel_path(request):
    """Both kernel paths (numba where installed: then the fused
    point-ordered BAL path), also for small problems."""
    before, rows = kernels.use_numba(), kernels.min_rows()
    kernels.use_numba(request.param == "numba", min_rows=0)
    yield request.param
    kernels.use_numba(before, min_rows=rows)


def _operator(n=40, obs=120, seed=3, damping=1e-3):
    """The Schur operator of a damped, linearized sphere problem (the
    path the solver itself takes), its dense RCS ``S`` and its
    Schur-Jacobi preconditioner (as the solver builds it)."""
    problem = build_bal_problem(sphere_bal(n, obs_per_camera=obs, seed=seed).problem,
                                behind="keep").problem
    problem.rcs["method"] = "iterative"
    system = problem.linearize(problem.state)
    if hasattr(system, "damped_inverse"):            # point_rows.PointSystem
        Ncc, Ainv = system.damped_inverse(problem.layout, damping)
        op = rcs_iterative.SchurOperator(system, Ncc, Ainv, ordered=True)
        parts = system.schur_parts(Ncc, Ainv, ordered=True)
        jacobi = rcs_iterative.schur_jacobi(op, None if parts is None else parts[0])
    else:
        Ncc, A = schur.damped(system, problem.layout, damping)
        op = rcs_iterative.SchurOperator(system, Ncc, schur.invert_point_blocks(A))
        jacobi = rcs_iterative.schur_jacobi(op)
    S = np.column_stack([op(e) for e in np.eye(op.n_r)])
    return problem, system, op, 0.5 * (S + S.T), jacobi


def test_cluster_groups_on_a_grid():
    """A 12 x 12 grid graph: every node in one cluster, every cluster
    connected, sizes between half the target and the target plus a merged
    remainder."""
    n = 12
    idx = np.arange(n * n).reshape(n, n)
    e = np.r_[np.c_[idx[:, :-1].ravel(), idx[:, 1:].ravel()],
              np.c_[idx[:-1].ravel(), idx[1:].ravel()]]
    C = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n * n, n * n))
    C = (C + C.T).tocsr()
    label = rcs_coarse.cluster_groups(C, 9)
    counts = np.bincount(label)
    assert label.min() == 0 and len(counts) == label.max() + 1
    assert counts.min() >= 9 // 2 and counts.max() <= 2 * 9
    assert 144 // 18 <= len(counts) <= 144 // 4
    for c in range(len(counts)):
        members = np.flatnonzero(label == c)
        sub = C[members][:, members]
        assert sp.csgraph.connected_components(sub, directed=False)[0] == 1


@pytest.mark.parametrize("size", [4, 9])
def test_two_level_is_spd_and_its_coarse_operator_exact(kernel_path, size):
    _, _, op, S, jacobi = _operator()
    tl = rcs_coarse.two_level(op, jacobi, size)
    assert tl.pat.n_clusters >= 3
    P = tl.pat.P.toarray()
    # every reduced column in exactly one aggregate
    np.testing.assert_array_equal(P.sum(axis=1), np.ones(op.n_r))
    scale = np.abs(S).max()
    np.testing.assert_allclose(tl.SP.toarray(), S @ P, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(tl.Sc, P.T @ S @ P, rtol=0, atol=1e-10 * scale)
    J = np.column_stack([jacobi(e) for e in np.eye(op.n_r)])
    I = np.eye(op.n_r)
    for floor in (0.0, None):        # every coarse mode; the default floor
        tl = rcs_coarse.two_level(op, jacobi, size, floor=floor)
        M = np.column_stack([tl(e) for e in np.eye(op.n_r)])
        assert np.abs(M - M.T).max() <= 1e-10 * np.abs(M).max()
        assert np.linalg.eigvalsh(0.5 * (M + M.T)).min() > 0.0
        # the formula of the module docstring, densely: Q = P C P^T with
        # C = S_c^-1 (floor 0) or its inverse on the kept modes
        C = np.column_stack([tl.coarse(e) for e in np.eye(tl.pat.n_c)])
        if floor == 0.0:
            assert tl.n_dropped == 0
            np.testing.assert_allclose(C, np.linalg.inv(tl.Sc), rtol=1e-6,
                                       atol=1e-8 * np.abs(C).max())
        else:
            np.testing.assert_allclose(C @ tl.Sc @ C, C, rtol=1e-6, atol=1e-8 * np.abs(C).max())
        Q = P @ C @ P.T
        ref = Q + (I - Q @ S) @ J @ (I - S @ Q)
        np.testing.assert_allclose(M, ref, rtol=0, atol=1e-8 * np.abs(ref).max())
    # the smoother is the Schur-Jacobi inverse: the diagonal blocks of S
    for cols in op.system.structure.group_cols:
        np.testing.assert_allclose(np.linalg.inv(J[np.ix_(cols, cols)]), S[np.ix_(cols, cols)],
                                   rtol=1e-6, atol=1e-6 * np.abs(S[np.ix_(cols, cols)]).max())


def test_pcg_reaches_the_dense_solution_in_fewer_steps(kernel_path):
    _, _, op, S, jacobi = _operator(n=150, obs=60, seed=1)
    b = np.random.default_rng(0).standard_normal(op.n_r)
    exact = np.linalg.solve(S, b)
    x_j, it_j = rcs_iterative.pcg(op, b, jacobi, tolerance=1e-8, max_iterations=5000)
    steps = {}
    for floor in (0.0, None):
        two = rcs_coarse.two_level(op, jacobi, 16, floor=floor)
        x_t, steps[floor] = rcs_iterative.pcg(op, b, two, tolerance=1e-8, max_iterations=5000)
        assert np.abs(x_t - exact).max() <= 1e-5 * np.abs(exact).max()
        # the residual test is taken in the Schur-Jacobi norm (the same rule)
        r = b - op(x_t)
        assert r @ jacobi(r) <= 1e-16 * (b @ jacobi(b))
    assert np.abs(x_j - exact).max() <= 1e-5 * np.abs(exact).max()
    assert steps[0.0] <= 0.6 * it_j and steps[None] <= 0.8 * it_j, (steps, it_j)


def test_step_through_schur_solve_equals_the_dense_step(kernel_path):
    problem, system, _, _, _ = _operator(n=30, obs=100, seed=2)
    dense = problem.linearize(problem.state)
    dx_i, fact = schur.solve(system, problem.layout, 1e-3, method="iterative",
                             cg_tolerance=1e-12, cg_max_iterations=5000,
                             cg_preconditioner="two_level", coarse_cluster_size=6)
    problem.rcs["method"] = "dense"
    dense = problem.linearize(problem.state)
    dx_d, _ = schur.solve(dense, problem.layout, 1e-3)
    assert fact is None
    assert np.max(np.abs(dx_i - dx_d)) <= 1e-7 * np.max(np.abs(dx_d))


def test_full_solve_same_final_cost_and_reported(kernel_path):
    sb = sphere_bal(60, obs_per_camera=100, seed=4)
    out = {}
    for kind in ("schur_jacobi", "two_level", "adaptive"):
        built = build_bal_problem(sb.problem, behind="keep")
        s = solve_bal(built, bal_options(linear_solver="iterative", cg_preconditioner=kind,
                                         coarse_cluster_size=8))
        assert s.status == "converged" and s.cg_preconditioner == kind
        assert built.problem.rcs["cg_preconditioner"] == "schur_jacobi"   # restored
        out[kind] = s.final_cost
    assert out["two_level"] == pytest.approx(out["schur_jacobi"], rel=1e-6)
    assert out["adaptive"] == pytest.approx(out["schur_jacobi"], rel=1e-6)
    dense = solve_bal(build_bal_problem(sb.problem, behind="keep"),
                      bal_options(linear_solver="dense"))
    assert dense.cg_preconditioner == ""
    assert out["two_level"] == pytest.approx(dense.final_cost, rel=1e-6)


def test_automatic_choice_and_validation(kernel_path, monkeypatch):
    from photogram.adjust import solver
    small = build_bal_problem(sphere_bal(12, obs_per_camera=60, seed=3).problem,
                              behind="keep").problem
    opt = SolverOptions()
    assert opt.cg_preconditioner == "auto"
    assert cg_preconditioner(small, opt, "dense") == ""
    assert cg_preconditioner(small, opt, "iterative") == "schur_jacobi"   # 12 < threshold
    monkeypatch.setattr(solver, "TWO_LEVEL_MIN_GROUPS", 12)
    # measured to pay with the compiled kernels only
    assert cg_preconditioner(small, opt, "iterative") == (
        "adaptive" if kernel_path == "numba" else "schur_jacobi")
    assert cg_preconditioner(small, SolverOptions(cg_preconditioner="adaptive"),
                             "iterative") == "adaptive"
    assert cg_preconditioner(small, SolverOptions(cg_preconditioner="two_level"),
                             "iterative") == "two_level"
    assert cg_preconditioner(small, SolverOptions(cg_preconditioner="schur_jacobi"),
                             "iterative") == "schur_jacobi"
    with pytest.raises(ValueError):
        cg_preconditioner(small, SolverOptions(cg_preconditioner="cluster_jacobi"), "iterative")
    # a common interior orientation: row groups share columns, no two-level
    net = wall_network(n_stations=8, n_points=150, rays=5, seed=2)
    prj = to_project(net, control=range(10), perturb_points=0.02, perturb_stations=0.002,
                     free_interior=("c", "x0", "y0", "K1"), rng=np.random.default_rng(2))
    prj.adjustment.datum = "control"
    shared = build_problem(prj).problem
    assert not rcs_coarse.applicable(shared.structure)
    assert rcs_method(shared, SolverOptions(linear_solver="iterative")) == "iterative"
    assert cg_preconditioner(shared, opt, "iterative") == "schur_jacobi"
    for kind in ("two_level", "adaptive"):
        with pytest.raises(ValueError):
            cg_preconditioner(shared, SolverOptions(cg_preconditioner=kind), "iterative")
    gc = np.array([[0, 1], [2, 3]])
    assert rcs_coarse.applicable(SimpleNamespace(group_cols=gc, n_r=4, n_e_rows=5))
    assert not rcs_coarse.applicable(SimpleNamespace(group_cols=np.array([[0, 1], [1, 2]]),
                                                     n_r=3, n_e_rows=5))


@pytest.mark.skipif(not kernels.HAVE_NUMBA, reason="numba is not installed")
def test_numba_and_numpy_twins_agree():
    before, rows = kernels.use_numba(), kernels.min_rows()
    kernels.use_numba(True, min_rows=0)
    try:
        _, _, op, _, jacobi = _operator(n=50, obs=100, seed=5)
        a = rcs_coarse.two_level(op, jacobi, 8, compiled=False)
        b = rcs_coarse.two_level(op, jacobi, 8, compiled=True)
    finally:
        kernels.use_numba(before, min_rows=rows)
    # the block pattern found by the compiled pass and by the numpy plan
    st = op.system.structure
    pl = op.point
    args = (st.group_cols, st.n_r, pl.group, pl.ptr, 8)
    pn, pc = rcs_coarse._Pattern(*args), rcs_coarse._Pattern(*args, compiled=True)
    np.testing.assert_array_equal(pn.cluster, pc.cluster)
    np.testing.assert_array_equal(pn.bg, pc.bg)
    np.testing.assert_array_equal(pn.bc, pc.bc)
    A, B = a.SP.toarray(), b.SP.toarray()
    assert np.abs(A - B).max() <= 1e-12 * np.abs(A).max()
    r = np.random.default_rng(1).standard_normal(op.n_r)
    np.testing.assert_allclose(b(r), a(r), rtol=1e-9, atol=1e-12 * np.abs(a(r)).max())


def test_fused_coarse_pass_equals_the_separate_passes(kernel_path):
    """The Schur-Jacobi blocks, the reduced right-hand side and the
    coarse coupling blocks ``W A^-1 W^T P`` of the fused pass (numba:
    one stream over ``W_o^T``) equal those of the separate passes, and
    the coupling equals ``S P`` formed from the dense RCS."""
    _, system, op, S, jacobi = _operator(n=50, obs=100, seed=5)
    if not hasattr(system, "schur_parts"):
        pytest.skip("not the point-ordered path")
    pat = rcs_coarse.pattern_of(op, 8)
    blocks, rhs = system.schur_parts(op.Ncc, op.Ainv_o, ordered=True)
    fb, frhs, coupling = system.schur_parts(op.Ncc, op.Ainv_o, ordered=True, coarse=pat)
    assert np.abs(fb - blocks).max() <= 1e-12 * np.abs(blocks).max()
    assert np.abs(frhs - rhs).max() <= 1e-12 * np.abs(rhs).max()
    separate = rcs_coarse.two_level(op, jacobi, 8)
    fused = rcs_coarse.two_level(op, jacobi, 8, coupling=coupling)
    A, B = separate.SP.toarray(), fused.SP.toarray()
    assert np.abs(A - B).max() <= 1e-12 * np.abs(A).max()
    SP = S @ pat.P.toarray()
    assert np.abs(B - SP).max() <= 1e-9 * np.abs(SP).max()
    r = np.random.default_rng(2).standard_normal(op.n_r)
    np.testing.assert_allclose(fused(r), separate(r), rtol=1e-9,
                               atol=1e-12 * np.abs(separate(r)).max())


def test_adaptive_switches_on_after_a_long_solve(kernel_path):
    """``"adaptive"``: Schur-Jacobi while the previous solve on the
    structure took at most ``ADAPTIVE_STEPS`` CG steps, two-level after
    one that took more; the recorded count is the one PCG returned."""
    problem, system, op, _, _ = _operator(n=40, obs=100, seed=6)
    assert rcs_coarse.resolve(op, "adaptive") == "schur_jacobi"          # no solve yet
    assert rcs_coarse.resolve(op, "two_level") == "two_level"
    apply = rcs_coarse.preconditioner(op, "adaptive", 8)
    assert not isinstance(apply, rcs_coarse.TwoLevel)
    rcs_coarse.record(op, rcs_coarse.ADAPTIVE_STEPS)
    assert rcs_coarse.resolve(op, "adaptive") == "schur_jacobi"
    rcs_coarse.record(op, rcs_coarse.ADAPTIVE_STEPS + 1)
    assert isinstance(rcs_coarse.preconditioner(op, "adaptive", 8), rcs_coarse.TwoLevel)
    # through schur.solve: the count of the last solve is recorded
    schur.solve(system, problem.layout, 1e-3, method="iterative",
                cg_tolerance=1e-12, cg_max_iterations=5000,
                cg_preconditioner="schur_jacobi", coarse_cluster_size=8)
    owner = op.point if op.point is not None else system.structure
    assert owner._last_cg_steps > rcs_coarse.ADAPTIVE_STEPS
