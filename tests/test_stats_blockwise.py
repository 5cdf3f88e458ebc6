"""Blockwise statistics (issue 23, item 4): the cofactors, cross cofactors,
redundancy numbers and leverages computed point by point through the Schur
structure (photogram.stats.point_blocks, photogram.stats.leverage) against
the dense inverse of the whole normal matrix
(:func:`photogram.adjust.dense.dense_cofactors`), on small SIMULATED
networks: self-calibration with interior parameters, fixed control points,
weighted control points (sigmas), a free network (inner constraints), a
rig; and a memory bound that the former dense cross cofactors break."""

import tracemalloc

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.adjust.dense import dense_cofactors
from photogram.adjust.solver import solve
from photogram.bundle.statistics import orientation_covariance
from photogram.geometry import angle_increment_map
from photogram.simulation.network import frame_network, to_project
from photogram.stats.covariance import cofactors
from photogram.stats.reliability import leverages, redundancy_numbers

FREE_IO = ("c", "x0", "y0", "K1", "K2", "P1", "P2")


def _problem(datum, seed=0, n_stations=8, n_points=40):
    net = frame_network(sigma=0.3, seed=seed, n_stations=n_stations, n_points=n_points)
    prj = to_project(net, control=[0, 1, 2, 3, 4], free_interior=FREE_IO,
                     point_sigma=0.001 if datum == "weighted" else None,
                     perturb_points=0.002, perturb_stations=0.002,
                     rng=np.random.default_rng(seed))
    prj.adjustment.datum = datum
    built = build_problem(prj)
    solve(built.problem)
    return prj, built


def _dense(problem):
    """The dense cofactors of every column (zero for fixed ones) and the
    dense leverages per block."""
    from photogram.adjust.dense import dense_structure
    r, J, Q, _ = dense_cofactors(problem)
    st = dense_structure(problem)
    n = problem.layout.n_columns
    Qfull = np.zeros((n, n))
    Qfull[np.ix_(st.free, st.free)] = Q
    h = np.sum((J @ Q) * J, axis=1)
    return Qfull, h


def _rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - b)) / np.max(np.abs(b)))


def _pairs(A, B):
    """Every row of A against every row of B: (len(A) len(B), .) each."""
    return np.repeat(A, len(B), axis=0), np.tile(B, (len(A), 1))


@pytest.fixture(scope="module", params=["control", "weighted", "free"])
def case(request):
    prj, built = _problem(request.param)
    Qd, hd = _dense(built.problem)
    return request.param, prj, built, cofactors(built.problem), Qd, hd


def test_reduced_and_point_blocks_equal_the_dense_inverse(case):
    datum, _, built, cof, Qd, _ = case
    lay = built.problem.layout
    n_r = lay.n_reduced
    assert _rel(cof.Qcc, Qd[:n_r, :n_r]) < 1e-9
    pc = lay.point_cols
    assert _rel(cof.Qee, Qd[pc[:, :, None], pc[:, None, :]]) < 1e-9
    assert built.problem.layout.n_eliminated == len(pc)     # all points eliminated


def test_cross_blocks_equal_the_dense_inverse(case):
    _, _, built, cof, Qd, _ = case
    lay = built.problem.layout
    cols = np.vstack([lay.station_cols, np.concatenate(lay.camera_cols)[None, :6]])
    a, b = _pairs(lay.point_cols, cols)
    assert _rel(cof.block(a, b), Qd[a[:, :, None], b[:, None, :]]) < 1e-9
    assert _rel(cof.block(b, a), Qd[b[:, :, None], a[:, None, :]]) < 1e-9
    # permuted coordinates of the point and a mixed set of columns
    a2 = a[:, ::-1]
    b2 = np.concatenate([b[:, :2], np.roll(b[:, 2:], 7, axis=0)], axis=1)
    assert _rel(cof.block(a2, b2), Qd[a2[:, :, None], b2[:, None, :]]) < 1e-9


def test_cross_times_a_matrix_equals_the_dense_product(case):
    _, _, built, cof, Qd, _ = case
    lay = built.problem.layout
    n_r = lay.n_reduced
    Ne = np.random.default_rng(1).normal(size=(lay.n_eliminated, 3, 4))
    want = Qd[:n_r, n_r:] @ Ne.reshape(-1, 4)
    assert _rel(cof.ce_times(Ne), want) < 1e-9


def test_redundancy_numbers_equal_one_minus_the_dense_leverages(case):
    datum, _, built, cof, _, hd = case
    p = built.problem
    red = redundancy_numbers(p, cof)
    got = np.concatenate([r.ravel() for r in red])
    assert got.shape == hd.shape
    np.testing.assert_allclose(got, 1.0 - hd, rtol=0, atol=1e-10)
    assert abs(got.sum() - p.redundancy()) < 1e-8 * p.redundancy()


def test_leverages_of_chosen_rows_equal_the_dense_ones(case):
    _, _, built, cof, _, hd = case
    p = built.problem
    k = [b.name for b in p.blocks].index("image points")
    rows = np.array([0, 5, 17, 3, 5])
    start = sum(len(b) * b.dim for b in p.blocks[:k])
    want = hd[start:start + len(p.blocks[k]) * 2].reshape(-1, 2)[rows]
    np.testing.assert_allclose(leverages(p, cof, k, rows), want, rtol=0, atol=1e-10)


def test_joint_covariance_of_chosen_points_equals_the_dense_inverse(case):
    _, _, built, cof, Qd, _ = case
    pts = np.array([7, 2, 30, 0, 11])          # 0: a control point (fixed unless weighted)
    cols = built.problem.layout.point_cols[pts].ravel()
    got = cof.joint_points(pts)
    assert got.shape == (15, 15)
    assert _rel(got, Qd[np.ix_(cols, cols)]) < 1e-9
    assert np.abs(got[:3, 6:9]).max() > 1e-3 * np.abs(got[:3, :3]).max()   # cross blocks


def test_orientation_covariance_equals_the_dense_transformation(case):
    _, prj, built, cof, Qd, _ = case
    p = built.problem
    labels, cov = orientation_covariance(cof, p, prj, built.camera_names, 2.0)
    lay = p.layout
    io = np.concatenate(lay.camera_cols)
    cols = np.concatenate([io, lay.station_cols.ravel()])
    T = np.eye(len(cols))
    _, E = angle_increment_map(p.state.R)
    for s in range(len(E)):
        i = len(io) + 6 * s + 3
        T[i:i + 3, i:i + 3] = E[s]
    want = 2.0 * T @ Qd[np.ix_(cols, cols)] @ T.T
    assert len(labels) == len(cols)
    assert _rel(cov, want) < 1e-9


def test_rig_cross_cofactors_follow_the_composition():
    from test_rig_blocks import _rig_project
    from photogram.stats.rig_covariance import with_rig_cofactors
    prj, _, _, _ = _rig_project(rigs=True)
    built = build_problem(prj)
    p = built.problem
    solve(p)
    cof = cofactors(p)
    with_rig_cofactors(cof, p)
    lay = p.layout
    a, b = _pairs(lay.point_cols[::7], lay.station_cols[lay.derived[0]])
    Ne = np.random.default_rng(2).normal(size=(lay.n_eliminated, 3, 2))
    got, got_times = cof.block(a, b), cof.ce_times(Ne)
    Qec = cof.Qec                    # the dense (3 n_e, n_r) cross cofactors, propagated
    n_r = lay.n_reduced
    want = Qec[(a - n_r)[:, :, None], b[:, None, :]]
    assert np.abs(want).max() > 0
    assert _rel(got, want) < 1e-9
    assert _rel(got_times, Qec.T @ Ne.reshape(-1, 2)) < 1e-9


@pytest.mark.slow
def test_statistics_never_form_the_dense_cross_cofactors():
    """The former cross cofactors were a (3 n_e, n_r) array (175 MB here);
    the blockwise statistics need less than half of it and about what one
    linearization of the solve needs (traced numpy allocations)."""
    from photogram.simulation.network import wall_network
    net = wall_network(n_stations=150, n_points=8000, rays=4, seed=3)
    prj = to_project(net, control=range(10), free_interior=("c", "K1"),
                     perturb_points=0.01, perturb_stations=0.001,
                     rng=np.random.default_rng(3), sigma_image=0.5)
    prj.adjustment.datum = "control"
    built = build_problem(prj)
    p = built.problem
    solve(p)
    lay = p.layout
    dense_bytes = 3 * lay.n_eliminated * lay.n_reduced * 8

    def traced(f):
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            out = f()
            return out, tracemalloc.get_traced_memory()[1] - base
        finally:
            tracemalloc.stop()

    _, solve_peak = traced(lambda: p.linearize(p.state))
    red, peak = traced(lambda: redundancy_numbers(p, cofactors(p)))
    assert abs(sum(float(r.sum()) for r in red) - p.redundancy()) < 1e-6 * p.redundancy()
    assert peak < 0.5 * dense_bytes, (peak, dense_bytes)
    assert peak < 2.0 * solve_peak, (peak, solve_peak)
    print(f"statistics {peak / 1e6:.0f} MB, linearize {solve_peak / 1e6:.0f} MB, "
          f"dense cross cofactors {dense_bytes / 1e6:.0f} MB")
