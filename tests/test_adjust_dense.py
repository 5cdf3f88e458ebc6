"""The engine's dense path (photogram.adjust.dense) and the re-solve API
(block.set_observations, Problem.reset, merged_image_blocks): the dense
Jacobian is the engine's (analytic, checked against finite differences),
the dense and pointwise Gauss-Newton reach what the generic solver reaches,
and a problem re-solved with new observations equals a problem built with
them. Issue 17: Monte Carlo runs this path."""

import copy

import numpy as np
import pytest

from photogram.adjust.build import build_problem, merged_image_blocks
from photogram.adjust.dense import (dense_cofactors, dense_jacobian, gauss_newton,
                                    point_normals, pointwise_structure)
from photogram.adjust.residual_blocks import ImagePointBlock, VerticalBlock
from photogram.adjust.solver import SolverOptions, solve
from photogram.adjust.state import Layout, State
from photogram.geometry import camera_model
from photogram.project.model import Parameter
from photogram.simulation.network import frame_network, to_project

MODELS = ("brown", "opencv", "bal", "aicon")


def _project(model="brown", seed=2, perturb=0.0):
    rng = np.random.default_rng(seed)
    net = frame_network(n_stations=4, n_points=16, sigma=0.3, seed=seed)
    prj = to_project(net, control=range(6), point_sigma=0.001, sigma_image=0.3, name="d",
                     perturb_points=perturb, perturb_stations=perturb, rng=rng)
    prj.adjustment.datum = "weighted"
    if model != "brown":
        names = camera_model(model).parameter_names
        for cam in prj.cameras.values():
            v = cam.values()
            values = {"opencv": (v[0], v[0], v[1], v[2], 0, 0, 0, 0, 0),
                      "bal": (v[0], 0.0, 0.0),
                      "aicon": (v[0], v[1], v[2], 5e-8, 0, 0, 0, 0, 0, 0, 100.0)}[model]
            cam.model = model
            cam.parameters = {n: Parameter(float(x)) for n, x in zip(names, values)}
    return prj


@pytest.mark.parametrize("model", MODELS)
def test_dense_jacobian_is_the_engines_and_matches_finite_differences(model):
    p = build_problem(_project(model)).problem
    st = p.state
    r, J, Jall = dense_jacobian(p, st, all_columns=True)
    J = J.copy()
    rs, _ = p.evaluate(st, jacobians=False)
    np.testing.assert_allclose(r, np.concatenate([x.ravel() for x in rs]), rtol=1e-13, atol=0)
    free = np.flatnonzero(p.layout.free)
    np.testing.assert_array_equal(J, Jall[:, free])
    h = 1e-6
    for col in list(free[:: max(1, len(free) // 25)]) + list(p.layout.camera_cols[0]):
        dx = np.zeros(p.layout.n_columns)
        dx[col] = h
        rp = dense_jacobian(p, st.updated(p.layout, dx), residuals_only=True)
        rm = dense_jacobian(p, st.updated(p.layout, -dx), residuals_only=True)
        fd = (rp - rm) / (2 * h)
        scale = max(1.0, np.abs(Jall[:, col]).max())
        assert np.abs(fd - Jall[:, col]).max() <= 2e-5 * scale, col


def test_dense_gauss_newton_reaches_the_generic_solution():
    prj = _project(perturb=0.01)
    a = build_problem(prj).problem
    solve(a, SolverOptions(tolerance=1e-12))
    b = merged_image_blocks(build_problem(prj).problem)
    it = gauss_newton(b, tolerance=1e-10)
    assert it < 10
    np.testing.assert_allclose(b.state.points, a.state.points, atol=1e-8)
    np.testing.assert_allclose(b.state.X0, a.state.X0, atol=1e-8)
    # cofactors of the dense path = the engine's (photogram.stats)
    from photogram.stats.covariance import cofactors, station_covariances
    _, _, Q, _ = dense_cofactors(b)
    S = station_covariances(cofactors(a), a.state.R)
    st = b.layout.station_cols[:, :3]
    col = {c: i for i, c in enumerate(np.flatnonzero(b.layout.free))}
    sig = np.sqrt(np.diag(Q))[[col[c] for c in st.ravel()]].reshape(-1, 3)
    np.testing.assert_allclose(sig, np.sqrt(np.diagonal(S, axis1=1, axis2=2))[:, :3], rtol=1e-6)


def test_resolving_with_new_observations_equals_a_new_build():
    prj = _project()
    p = merged_image_blocks(build_problem(prj).problem)
    start = p.state.copy()
    rng = np.random.default_rng(5)
    new = copy.deepcopy(prj)
    new.image_points.xy = prj.image_points.xy + rng.normal(0, 0.3, prj.image_points.xy.shape)
    ctrl = np.asarray(prj.points.kind) == "control"
    new.points.xyz[ctrl] += rng.normal(0, 0.001, (ctrl.sum(), 3))
    q = build_problem(new).problem
    solve(q, SolverOptions(tolerance=1e-12))
    # the same structure, new values
    obs = p.observations()
    for k, b in enumerate(p.blocks):
        if isinstance(b, ImagePointBlock):
            obs[k] = new.image_points.xy[b.rows]
        elif b.observed == "xyz":
            obs[k] = new.points.xyz[b.point]
    p.set_observations(obs)
    p.reset(start)
    gauss_newton(p, tolerance=1e-10)
    np.testing.assert_allclose(p.state.points, q.state.points, atol=1e-8)
    np.testing.assert_allclose(p.state.X0, q.state.X0, atol=1e-8)
    with pytest.raises(ValueError):
        p.blocks[0].set_observations(np.zeros((3, 2)))


@pytest.mark.parametrize("model", MODELS)
def test_pointwise_path_equals_the_generic_intersection(model):
    """Orientation fixed (photogram intersect): point by point 3x3."""
    prj = _project(model, perturb=0.01)
    a = build_problem(prj, fix_interior=True, fix_stations=True).problem
    solve(a, SolverOptions(tolerance=1e-12))
    b = build_problem(prj, fix_interior=True, fix_stations=True).problem
    assert pointwise_structure(b).ok
    gauss_newton(b, tolerance=1e-12)
    seen = np.unique(np.concatenate([blk.point for blk in b.blocks
                                     if isinstance(blk, ImagePointBlock)]))
    points, A, g = point_normals(b, b.state)
    assert np.abs(g).max() < 1e-6 * np.abs(A).max()
    assert b.cost(b.state) <= a.cost(a.state) * (1 + 1e-12)
    if model != "bal":      # bal's cameras here misfit the brown simulation by far: the
        # generic LM stops on the cost tolerance before the points settle to 1e-8
        np.testing.assert_allclose(b.state.points[seen], a.state.points[seen], atol=1e-8)
    from photogram.stats.covariance import cofactors, point_covariances
    cov = point_covariances(cofactors(a))
    np.testing.assert_allclose(np.linalg.inv(A), cov[points], rtol=1e-6, atol=1e-14)


def test_vertical_block_observed_slopes_and_jacobian():
    rng = np.random.default_rng(3)
    free = {"camera": [np.ones(0, bool)], "station": np.ones((0, 6), bool),
            "point": np.ones((4, 3), bool)}
    lay = Layout([0], 0, 4, np.ones(4, bool), free)
    st = State(rng.normal(0, 1, (4, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3)),
               [np.zeros(0)])
    st.points[[0, 2], 2] += 3.0
    blk = VerticalBlock([0, 2], [1, 3], [0.01, 0.01], lay)
    e0, J0 = blk.evaluate(st)
    blk.set_observations(np.array([[0.1, -0.2], [0.0, 0.3]]))
    e1, J1 = blk.evaluate(st)
    np.testing.assert_allclose(e0 - e1, [[0.1, -0.2], [0.0, 0.3]], atol=1e-15)
    for a, b in zip(J0, J1):
        np.testing.assert_array_equal(a, b)
    h = 1e-6
    for q in range(3):
        dx = np.zeros(lay.n_columns)
        dx[lay.point_cols[0, q]] = h
        ep, _ = blk.evaluate(st.updated(lay, dx))
        em, _ = blk.evaluate(st.updated(lay, -dx))
        np.testing.assert_allclose((ep - em)[0] / (2 * h), J1[0][0, :, q], rtol=1e-6, atol=1e-9)


def test_brown_correction_kept_while_observations_and_interior_stay():
    """The cached correction gives the same residuals and Jacobians as a
    fresh evaluation, and follows new observations and interior values."""
    p = build_problem(_project(perturb=0.01), fix_interior=True).problem
    blk = next(b for b in p.blocks if isinstance(b, ImagePointBlock))
    e1, J1 = blk.evaluate(p.state)
    e2, J2 = blk.evaluate(p.state)
    e3, J3 = blk.evaluate(p.state, True, fixed_io=True)
    np.testing.assert_array_equal(e1, e2)
    np.testing.assert_array_equal(e1, e3)
    for a, b in zip(J1, J2):
        np.testing.assert_array_equal(a, b)
    assert J3[2] is None
    np.testing.assert_array_equal(J1[0], J3[0])
    fresh = ImagePointBlock(blk.model, blk.cameras, blk.camera, blk.station, blk.point,
                            blk.xy + 0.5, blk.sigma[:, 0], p.layout)
    blk.set_observations(blk.xy + 0.5)
    np.testing.assert_array_equal(blk.evaluate(p.state)[0], fresh.evaluate(p.state)[0])
    st = p.state.copy()
    st.io[0] = st.io[0] * (1 + 1e-3)
    np.testing.assert_array_equal(blk.evaluate(st)[0], fresh.evaluate(st)[0])


@pytest.mark.parametrize("model", MODELS)
def test_points_only_is_evaluate_with_the_orientation_held(model):
    """ImagePointBlock.points_only (the intersection's residuals as a
    function of the points alone) gives exactly evaluate's residuals and
    point Jacobian at any points, and its Jacobian matches finite
    differences."""
    prj = _project(model, perturb=0.01)
    p = build_problem(prj, fix_interior=True, fix_stations=True).problem
    blk = next(b for b in p.blocks if isinstance(b, ImagePointBlock))
    f = blk.points_only(p.state)
    rng = np.random.default_rng(5)
    for _ in range(3):
        pts = p.state.points + rng.normal(0, 0.01, p.state.points.shape)
        e, JX = f(pts)
        st = State(pts, p.state.R, p.state.X0, p.state.io)
        e_ref, Js = blk.evaluate(st, True, fixed_io=True, fixed_stations=True)
        np.testing.assert_array_equal(e, e_ref)
        np.testing.assert_array_equal(JX, Js[0])
    h = 1e-6
    for q in range(3):
        dp = np.zeros_like(pts)
        dp[:, q] = h
        fd = (f(pts + dp)[0] - f(pts - dp)[0]) / (2 * h)
        own = JX[:, :, q]
        np.testing.assert_allclose(fd, own, rtol=1e-5, atol=1e-6 * np.abs(own).max())


def test_point_normals_of_equal_views_equal_the_sum_per_observation():
    """The batched product for points seen in equally many rows equals the
    sum of the per-observation normal equations (reduceat) to rounding."""
    rng = np.random.default_rng(4)
    net = frame_network(n_stations=4, n_points=16, sigma=0.3, seed=4)
    prj = to_project(net, control=[], point_sigma=0.001, sigma_image=0.3, name="d",
                     perturb_points=0.01, perturb_stations=0.0, rng=rng)
    p = build_problem(prj, fix_interior=True, fix_stations=True).problem
    ps = pointwise_structure(p)
    assert ps.ok and ps.views > 1 and len(p.blocks) == 1      # the batched path
    points, A, g = point_normals(p, p.state)
    blk = next(b for b in p.blocks if isinstance(b, ImagePointBlock))
    e, Js = blk.evaluate(p.state, True, fixed_io=True, fixed_stations=True)
    w = p.weights(p.blocks.index(blk))
    J = Js[0] * w[:, :, None]
    r = e * w
    A_ref = np.zeros((len(p.state.points), 3, 3))
    g_ref = np.zeros((len(p.state.points), 3))
    np.add.at(A_ref, blk.point, np.swapaxes(J, 1, 2) @ J)
    np.add.at(g_ref, blk.point, np.einsum("nki,nk->ni", J, r))
    np.testing.assert_allclose(A, A_ref[points], rtol=1e-12, atol=1e-12 * np.abs(A).max())
    np.testing.assert_allclose(g, g_ref[points], rtol=1e-10, atol=1e-12 * np.abs(g).max())
