"""Bundle Adjustment in the Large: the reader, the engine problem, both
kernel paths (numpy and, where installed, numba), the covariance of a
gauge-free problem against a dense inverse, and convergence on the real
BAL problems to the Ceres figures of /work/shared/notes.md."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from photogram.adjust import kernels
from photogram.adjust.datum import check_datum, inner_constraints
from photogram.adjust.solver import SolverOptions, solve
from photogram.errors import GeometryError, InputError
from photogram.bundle.bal import (bal_cofactors, bal_from_state, bal_options, build_bal_problem,
                                  solve_bal)
from photogram.io.bal import (BALProblem, bal_cost, bal_residuals, behind_camera, read_bal,
                              write_bal)
from photogram.stats.covariance import cofactors

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bal"

PATHS = ["numpy"] + (["numba"] if kernels.HAVE_NUMBA else [])


@pytest.fixture(params=PATHS)
def kernel_path(request):
    """Run a test with the numpy path and, where numba is installed, with
    the compiled kernels."""
    before, rows = kernels.use_numba(), kernels.min_rows()
    kernels.use_numba(request.param == "numba", min_rows=0)   # also for small problems
    yield request.param
    kernels.use_numba(before, min_rows=rows)


def synthetic(n_cameras=6, n_points=80, noise=0.5, seed=0, perturb=True):
    """A small BAL problem: cameras on an arc looking at a cloud of points,
    BAL conventions (camera looks along -z, y up), f ~ 500, mild radial
    distortion; every point seen by 3-6 cameras."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1, 1, (n_points, 3)) * [1.0, 1.0, 0.5]
    cams = np.zeros((n_cameras, 9))
    for c in range(n_cameras):
        a = -0.4 + 0.8 * c / max(n_cameras - 1, 1)
        centre = np.array([6 * np.sin(a), 0.3 * rng.normal(), 6 * np.cos(a)])
        z = centre / np.linalg.norm(centre)            # camera +z points away from the scene
        x = np.cross([0.0, 1.0, 0.0], z)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        R = np.stack([x, y, z])
        cams[c, :3] = Rotation.from_matrix(R).as_rotvec()
        cams[c, 3:6] = -R @ centre
        cams[c, 6:9] = [500.0 * (1 + 0.05 * rng.normal()), -0.05, 0.01]
    cam_idx, pt_idx = [], []
    for p in range(n_points):
        k = rng.integers(3, min(6, n_cameras) + 1)
        for c in np.sort(rng.choice(n_cameras, k, replace=False)):
            cam_idx.append(c)
            pt_idx.append(p)
    truth = BALProblem(cams, pts, np.array(cam_idx), np.array(pt_idx),
                       np.zeros((len(cam_idx), 2)), "synthetic")
    xy = bal_residuals(truth) + rng.normal(0, noise, (len(cam_idx), 2))   # predicted + noise
    start = BALProblem(cams.copy(), pts.copy(), truth.camera, truth.point, xy, "synthetic")
    if perturb:
        start.points = pts + rng.normal(0, 0.02, pts.shape)
        start.cameras[:, :6] += rng.normal(0, 0.005, (n_cameras, 6))
        start.cameras[:, 6] *= 1.01
    return truth, start


def independent_cost(bal):
    """0.5 sum r^2 by scipy's rotations (independent of photogram)."""
    R = Rotation.from_rotvec(bal.cameras[bal.camera, :3])
    P = R.apply(bal.points[bal.point]) + bal.cameras[bal.camera, 3:6]
    p = -P[:, :2] / P[:, 2:]
    n2 = np.sum(p ** 2, axis=1)
    f, k1, k2 = bal.cameras[bal.camera, 6:9].T
    proj = (f * (1 + k1 * n2 + k2 * n2 ** 2))[:, None] * p
    return 0.5 * float(np.sum((proj - bal.xy) ** 2))


# ---------------------------------------------------------------- reader
@pytest.mark.parametrize("suffix", [".txt", ".txt.bz2"])
def test_reader_round_trip_and_initial_cost(tmp_path, suffix):
    _, start = synthetic()
    path = tmp_path / f"problem-6-80-pre{suffix}"
    write_bal(path, start)
    if suffix.endswith(".bz2"):
        assert path.read_bytes()[:3] == b"BZh"
    bal = read_bal(path)
    assert (bal.n_cameras, bal.n_points, bal.n_observations) == (6, 80, len(start.camera))
    assert bal.name == "problem-6-80-pre"
    np.testing.assert_array_equal(bal.camera, start.camera)
    np.testing.assert_array_equal(bal.point, start.point)
    np.testing.assert_array_equal(bal.cameras, start.cameras)
    np.testing.assert_array_equal(bal.points, start.points)
    np.testing.assert_array_equal(bal.xy, start.xy)
    assert bal_cost(bal) == pytest.approx(independent_cost(bal), rel=1e-12)
    assert not behind_camera(bal).any()


def test_reader_errors(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_bal(tmp_path / "missing.txt")
    bad = tmp_path / "bad.txt"
    bad.write_text("2 1 3\n0 0 1.0 2.0\n")
    with pytest.raises(InputError, match="truncated"):
        read_bal(bad)
    bad.write_text("1 1 1\n3 0 1.0 2.0\n" + "0\n" * 12)
    with pytest.raises(InputError, match="outside the header counts"):
        read_bal(bad)


def test_engine_problem_has_ceres_cost_and_maps_back():
    _, start = synthetic()
    built = build_bal_problem(start)
    p = built.problem
    assert p.cost(p.state) == pytest.approx(bal_cost(start), rel=1e-12)
    assert len(p.state.io) == start.n_cameras              # one camera per station
    back = bal_from_state(built.bal, p.state)
    np.testing.assert_allclose(back.cameras, start.cameras, rtol=1e-12, atol=1e-12)


def test_behind_camera_observations_are_dropped_or_kept():
    _, start = synthetic()
    start.points[5] = [0.0, 0.0, 50.0]          # far behind every camera
    behind = behind_camera(start)
    assert behind.sum() == np.count_nonzero(start.point == 5)
    dropped = build_bal_problem(start, behind="drop", datum="fixed")
    np.testing.assert_array_equal(dropped.dropped, np.flatnonzero(behind))
    assert dropped.bal.n_observations == start.n_observations - behind.sum()
    kept = build_bal_problem(start, behind="keep", datum="fixed")
    assert kept.bal.n_observations == start.n_observations
    assert kept.problem.cost(kept.problem.state) == pytest.approx(bal_cost(start), rel=1e-12)


def test_datum_check_accepts_the_declared_gauge_only():
    _, start = synthetic()
    built = build_bal_problem(start)                          # gauge free (Ceres' way)
    check_datum(built.problem, built.present)
    with pytest.raises(GeometryError, match="datum defect 7"):
        check_datum(built.problem, {**built.present, "gauge": False})
    fixed = build_bal_problem(start, datum="fixed")
    check_datum(fixed.problem, {**fixed.present, "gauge": False})


# ---------------------------------------------------------------- solving
def test_gauge_free_trust_region_reaches_the_noise_level(kernel_path):
    truth, start = synthetic(noise=0.5, seed=3)
    built = build_bal_problem(start)
    s = solve_bal(built, bal_options(function_tolerance=1e-10))
    assert s.status == "converged"
    n = start.n_observations
    redundancy = 2 * n - (9 * start.n_cameras + 3 * start.n_points - 7)
    # chi-square: 2 cost / (0.5 px)^2 ~ redundancy
    assert 2 * s.final_cost / 0.25 / redundancy == pytest.approx(1.0, abs=0.15)
    # the same minimum in the other datums
    for datum in ("fixed", "inner"):
        other = build_bal_problem(start, datum=datum)
        so = solve(other.problem, SolverOptions(damping="trust_region", tolerance=1e-12,
                                                max_iterations=200))
        assert so.final_cost == pytest.approx(s.final_cost, rel=1e-8)


def test_kernel_paths_agree():
    """The compiled kernels give the numpy path's normal equations,
    Schur complement, step and cofactors."""
    if not kernels.HAVE_NUMBA:
        pytest.skip("numba is not installed")
    _, start = synthetic(seed=5)
    before, rows = kernels.use_numba(), kernels.min_rows()
    out = {}
    try:
        for flag in (False, True):
            kernels.use_numba(flag, min_rows=0)
            built = build_bal_problem(start, datum="fixed")
            p = built.problem
            rs, Js = p.evaluate(p.state)
            system = p.linearize(p.state)
            dx, _ = p.solve_linear(system, 1e-3)
            cof = cofactors(p)
            out[flag] = (rs[0], *Js[0], system.Ncc, system.A, system.g, system.WT, dx,
                         cof.Qcc, cof.Qee)
    finally:
        kernels.use_numba(before, min_rows=rows)
    for a, b in zip(out[False], out[True]):
        scale = max(np.abs(a).max(), 1e-300)
        assert np.abs(a - b).max() <= 1e-9 * scale


# ---------------------------------------------------------------- covariance
def dense_normal(problem):
    """J^T J of the whitened problem, dense."""
    rs, Js = problem.evaluate(problem.state)
    n = problem.layout.n_columns
    rows = []
    for blk, J in zip(problem.blocks, Js):
        m = len(blk) * blk.dim
        D = np.zeros((m, n))
        r_idx = np.arange(m).reshape(len(blk), blk.dim)
        for Jj, cols in zip(J, blk.slot_cols):
            np.add.at(D, (r_idx[:, :, None], np.broadcast_to(cols[:, None, :], Jj.shape)), Jj)
        rows.append(D)
    J = np.vstack(rows)
    return J.T @ J


@pytest.mark.parametrize("datum", ["gauge", "fixed"])
def test_covariance_equals_dense_inverse(kernel_path, datum):
    """Cameras (Qcc), per-point 3x3 blocks (Qee) and the cross cofactors
    (Qec, as cofactors.block computes them for residual rows) of a small
    BAL-like problem equal the inverse of the dense normal matrix: for the
    gauge-free problem bordered by the minimum-trace inner constraints, for
    the fixed datum with the fixed columns removed."""
    _, start = synthetic(n_cameras=5, n_points=40, seed=11)
    built = build_bal_problem(start, datum=datum)
    p = built.problem
    solve(p, bal_options())
    lay = p.layout
    N = dense_normal(p)
    if datum == "gauge":
        cof = bal_cofactors(p, points=np.arange(start.n_points))
        G = inner_constraints(lay, p.state)
        K = np.block([[N, G], [G.T, np.zeros((G.shape[1], G.shape[1]))]])
        Q = np.linalg.inv(K)[:lay.n_columns, :lay.n_columns]
    else:
        cof = cofactors(p)
        free = lay.free
        Q = np.zeros_like(N)
        Q[np.ix_(free, free)] = np.linalg.inv(N[np.ix_(free, free)])
    if datum == "gauge":
        # every point of this network is well determined: the default datum
        # points are all points
        np.testing.assert_allclose(bal_cofactors(p).Qcc, cof.Qcc, rtol=1e-9, atol=1e-12)
    n_r = lay.n_reduced
    scale = np.abs(Q).max()
    np.testing.assert_allclose(cof.Qcc, Q[:n_r, :n_r], rtol=0, atol=1e-8 * scale)
    pc = lay.point_cols
    np.testing.assert_allclose(cof.Qee, Q[pc[:, :, None], pc[:, None, :]], rtol=0, atol=1e-8 * scale)
    blk = p.blocks[0]
    cols_pt, cols_st = blk.slot_cols[0], blk.slot_cols[1]
    np.testing.assert_allclose(cof.block(cols_pt, cols_st), Q[cols_pt[:, :, None], cols_st[:, None, :]],
                               rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(cof.block(cols_st, cols_pt), Q[cols_st[:, :, None], cols_pt[:, None, :]],
                               rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(cof.Qec, Q[n_r:, :n_r], rtol=0, atol=1e-8 * scale)


# ---------------------------------------------------------------- real problems
# Ceres (pycolmap 4.2.1, DENSE_SCHUR, one thread, Ceres' default
# tolerances) on the same observations (behind-camera ones dropped):
# /work/shared/notes.md
REAL = {
    "problem-49-7776-pre": (49, 7776, 31843, 31, 850912.4606808, 850802.0903412, 13308.48),
    "problem-21-11315-pre": (21, 11315, 36455, 0, 4413239.3144322, 4413239.3144322, 30378.65),
    "problem-16-22106-pre": (16, 22106, 83718, 0, 4185659.5182497, 4185659.5182497, 18033.90),
}


@pytest.mark.skipif(not DATA.is_dir(), reason="BAL data not available")
@pytest.mark.parametrize("name", sorted(REAL))
def test_real_bal_problem_reaches_the_ceres_cost(name):
    """(Read, built and solved once per session by tests/bal_real.py, with
    solve_bal's defaults, for this test and tests/test_adjust_rcs_sparse.py.)"""
    import bal_real
    n_c, n_p, n_o, n_behind, cost0, cost0_front, ceres = REAL[name]
    bal = bal_real.read(name)
    assert (bal.n_cameras, bal.n_points, bal.n_observations) == (n_c, n_p, n_o)
    assert int(behind_camera(bal).sum()) == n_behind
    assert bal_cost(bal) == pytest.approx(cost0, rel=1e-9)
    run = bal_real.solved(name)
    built, p, s = run.built, run.built.problem, run.summary
    assert run.dropped == n_behind
    assert run.cost_before == pytest.approx(cost0_front, rel=1e-9)
    assert s.status == "converged"
    assert abs(s.final_cost - ceres) <= 1e-4 * ceres
    assert bal_cost(bal_from_state(built.bal, p.state)) == pytest.approx(s.final_cost, rel=1e-9)


def test_indexed_evaluation_equals_the_generic_model(kernel_path):
    """The engine's indexed BAL path (compiled or component-wise numpy)
    equals the model's generic rotation-matrix path."""
    from photogram.geometry import camera_model
    _, start = synthetic(seed=2)
    p = build_bal_problem(start).problem
    blk = p.blocks[0]
    st = p.state
    io = np.stack(st.io)
    m = camera_model("bal")
    # the engine's path: the block passes the compiled kernel when it is in use
    r, (JX, JS, JI) = blk.evaluate(st)
    r_ref, jac = m.residuals_rotation(blk.xy, st.points[blk.point], st.R[blk.station],
                                      st.X0[blk.station], io[blk.camera])
    np.testing.assert_allclose(r, r_ref, rtol=0, atol=1e-9)
    for J, ref in ((JX, jac["X"]), (JS, np.concatenate([jac["X0"], jac["rotation"]], axis=2)),
                   (JI, jac["io"])):
        np.testing.assert_allclose(J, ref, rtol=1e-10, atol=1e-10 * np.abs(ref).max())
    r_only, none = blk.evaluate(st, jacobians=False)
    assert none is None
    np.testing.assert_array_equal(r_only, r)
    # the model alone (no kernel given): its numpy rows, the same values
    r_np, _ = m.residuals_indexed(blk.xy, st.points, st.R, st.X0, io, blk.point,
                                  blk.station, blk.camera)
    np.testing.assert_allclose(r_np, r, rtol=0, atol=1e-9)
