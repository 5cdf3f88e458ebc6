"""Eccentricity of circular targets inside the adjustment
(photogram.geometry.circle, photogram.adjust.eccentric_blocks): analytic
Jacobians against central differences, the object-space pole against the
homography formula of photogram.measure.eccentricity, a bundle on exact
ellipse centres recovering the truth only with the correction, and the
project-file keys."""

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.adjust.eccentric_blocks import EccentricImagePointBlock
from photogram.adjust.solver import solve
from photogram.adjust.state import Layout, State
from photogram.geometry import matrix_to_opk, opk_to_matrix
from photogram.geometry.circle import ellipse_centre_offset, ellipse_centre_point
from photogram.simulation.network import frame_network, to_project


def _random(n=6, seed=3):
    rng = np.random.default_rng(seed)
    X = rng.normal(0, 0.3, (n, 3))
    normal = rng.normal(0, 1, (n, 3))
    R = opk_to_matrix(rng.uniform(-0.6, 0.6, (n, 3)))
    X0 = X + np.einsum("nji,j->ni", R, [0.0, 0.0, 1.5]) + rng.normal(0, 0.2, (n, 3))
    return X, normal, rng.uniform(0.005, 0.03, n), R, X0


def test_offset_jacobians_match_finite_differences():
    X, nv, r, R, X0 = _random()
    d0, J = ellipse_centre_offset(X, nv, r, R, X0, jacobians=True)
    h = 1e-7
    for key in ("X", "X0", "rotation"):
        num = np.zeros_like(J[key])
        for j in range(3):
            e = np.zeros(3)
            e[j] = h
            if key == "X":
                dp = ellipse_centre_offset(X + e, nv, r, R, X0)
                dm = ellipse_centre_offset(X - e, nv, r, R, X0)
            elif key == "X0":
                dp = ellipse_centre_offset(X, nv, r, R, X0 + e)
                dm = ellipse_centre_offset(X, nv, r, R, X0 - e)
            else:
                from photogram.geometry import small_rotation
                dp = ellipse_centre_offset(X, nv, r, small_rotation(e) @ R, X0)
                dm = ellipse_centre_offset(X, nv, r, small_rotation(-e) @ R, X0)
            num[:, :, j] = (dp - dm) / (2 * h)
        scale = np.abs(J[key]).max()
        assert scale > 1e-5                                   # not trivially zero
        assert np.abs(num - J[key]).max() <= 1e-6 * scale, key
    # delta lies in the target plane and vanishes for a fronto-parallel target
    assert np.allclose(np.einsum("ni,ni->n", d0, nv), 0, atol=1e-15)
    assert np.allclose(ellipse_centre_offset(X, R[:, 2], r, R, X0), 0, atol=1e-15)


def test_pole_projects_to_the_homography_ellipse_centre():
    """The projection of X_e equals the ellipse centre of the colleague's
    independent derivation (conic of the circle mapped by the homography)."""
    from photogram.measure.eccentricity import ellipse_centres
    from photogram.measure.render import PlaneCamera, look_at
    from photogram.geometry import camera_model
    Rcv, t = look_at((0.2, -0.7, 0.8), (0.4, 0.3, 0.0), up=(0, 1, 0))
    K = np.array([[900.0, 0, 399.5], [0, 900.0, 299.5], [0, 0, 1]])
    cam = PlaneCamera(K, Rcv, t, (800, 600))
    XY = np.random.default_rng(1).uniform(0, 0.8, (20, 2))
    radius = 0.03
    H = cam.homography()
    ec = ellipse_centres(H, XY, radius)
    R = np.diag([1.0, -1, -1]) @ Rcv
    X0 = -Rcv.T @ t
    X = np.column_stack([XY, np.zeros(len(XY))])
    Xe = ellipse_centre_point(X, [0, 0, 1], radius, np.broadcast_to(R, (20, 3, 3)),
                              np.broadcast_to(X0, (20, 3)))
    io = np.array([900.0, 900.0, 399.5, 299.5, 0, 0, 0, 0, 0])
    xy = camera_model("opencv").project(Xe, matrix_to_opk(R), X0, io)
    xy_centre = camera_model("opencv").project(X, matrix_to_opk(R), X0, io)
    assert np.abs(xy - ec).max() < 1e-9
    assert np.abs(ec - xy_centre).max() > 0.1              # the eccentricity is not tiny here


@pytest.mark.parametrize("model", ["brown", "opencv"])
def test_block_jacobians_match_finite_differences(model):
    rng = np.random.default_rng(5)
    n_p, n_s = 5, 3
    pts = rng.uniform(-0.3, 0.3, (n_p, 3))
    X0 = np.array([[0.2, -1.5, 1.2], [-1.2, 0.3, 1.0], [0.9, 0.9, 1.4]])
    from photogram.simulation.network import look_at as pg_look_at
    R = pg_look_at(X0, [0.0, 0.0, 0.0])
    io = (np.array([1000.0, 320, 240, -5e-8, 1e-13, 0, 2e-6, -1e-6, 1e-4, 2e-4])
          if model == "brown" else np.array([1000.0, 990, 320, 240, -0.1, 0.02, 1e-3, -1e-3, 0]))
    state = State(pts, R, X0, [io])
    p = len(io)
    free = {"camera": [np.ones(p, bool)], "station": np.ones((n_s, 6), bool),
            "point": np.ones((n_p, 3), bool)}
    lay = Layout([p], n_s, n_p, np.ones(n_p, bool), free)
    st = np.repeat(np.arange(n_s), n_p)
    pt = np.tile(np.arange(n_p), n_s)
    from photogram.geometry import camera_model
    cm = camera_model(model)
    xy = cm.project(pts[pt], matrix_to_opk(R[st]), X0[st], io) + rng.normal(0, 1, (len(st), 2))
    blk = EccentricImagePointBlock(cm, [0], np.zeros(len(st), int), st, pt, xy,
                                   np.ones(len(st)), lay, rng.uniform(0.01, 0.05, n_p)[pt],
                                   rng.normal(0, 1, (n_p, 3))[pt])
    e0, J = blk.evaluate(state)
    for slot, (Js, cols) in enumerate(zip(J, blk.slot_cols)):
        for j in range(cols.shape[1]):
            fd = np.zeros_like(e0)
            for c in np.unique(cols[:, j]):
                rows = cols[:, j] == c
                h = 1e-6 * max(1.0, abs(_value(state, lay, c)))
                for sign in (1, -1):
                    dx = np.zeros(lay.n_columns)
                    dx[c] = sign * h
                    e, _ = blk.evaluate(state.updated(lay, dx))
                    fd[rows] += sign * e[rows] / (2 * h)
            err = np.abs(fd - Js[:, :, j])
            assert err.max() <= 1e-5 * max(1.0, np.abs(Js[:, :, j]).max()), (slot, j)
    # the block's eccentricity is the shift of the prediction (in measured
    # coordinates; the brown residual is in corrected ones: the distortion's
    # derivative, a few per mille here, separates them)
    ecc = blk.eccentricity(state)
    e_plain, _ = EccentricImagePointBlock(cm, [0], np.zeros(len(st), int), st, pt, xy,
                                          np.ones(len(st)), lay, 0.0, [0, 0, 1]).evaluate(state)
    tol = 1e-9 if model == "opencv" else 0.02
    shift = np.abs(e0 - e_plain)
    assert np.all(np.linalg.norm(shift - np.abs(ecc), axis=1)
                  <= tol * np.linalg.norm(ecc, axis=1) + 1e-9)
    assert np.abs(ecc).max() > 0.01


def _value(state, lay, c):
    """Current value of column c (interior parameters only; 0 otherwise)."""
    for k, cols in enumerate(lay.camera_cols):
        if c in cols:
            return state.io[k][list(cols).index(c)]
    return 0.0


def _exact_ellipse_centres(net, radius, normals, n_edge=72):
    """Centres of ellipses fitted to the projected edge of every circle (the
    camera's own model, lens distortion included): what a perfect
    measurement of an ellipse centre gives."""
    from photogram.geometry import camera_model
    from photogram.measure.ellipse import conic_centres, fit_ellipses
    model = camera_model(net.model_name)
    n = normals[net.point]
    a = np.cross(n, [0.0, 0.0, 1.0]) + np.cross(n, [1.0, 0.0, 0.0]) * 1e-3
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(n, a)
    t = np.linspace(0, 2 * np.pi, n_edge, endpoint=False)
    edge = (net.points[net.point][:, None, :]
            + radius * (np.cos(t)[None, :, None] * a[:, None]
                        + np.sin(t)[None, :, None] * b[:, None]))
    N = len(net.point)
    st = np.repeat(net.station, n_edge)
    xy = model.project(edge.reshape(-1, 3), matrix_to_opk(net.R[st]), net.X0[st],
                       net.io[net.station_camera[st]]).reshape(N, n_edge, 2)
    conics, _ = fit_ellipses(xy[:, :, 0], xy[:, :, 1], np.ones((N, n_edge)))
    return conic_centres(conics)


@pytest.mark.parametrize("model,distorted", [("opencv", False), ("brown", True),
                                             ("opencv", True)])
def test_bundle_on_exact_ellipse_centres_recovers_the_truth_only_with_the_correction(
        model, distorted):
    """Noise-free ellipse centres of tilted circles (3D field, one normal per
    target): the adjustment predicting ellipse centres returns the true
    camera and points -- exactly without lens distortion, up to the
    first-order treatment of the distortion with it (measured here: the
    distortion's curvature over a target moves the fitted centre by a few
    1e-4 px); predicting circle centres leaves a bias."""
    io = ((1420.0, 320.0, 240.0, -5e-8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) if model == "brown"
          else (1420.0, 1420.0, 320.0, 240.0, -0.1 if distorted else 0.0, 0.0, 0.0, 0.0, 0.0))
    free = ("c", "x0", "y0", "K1") if model == "brown" else ("fx", "fy", "cx", "cy", "k1")
    net = frame_network(n_stations=8, n_points=40, sigma=0.0, seed=4, model_name=model, io=io)
    rng = np.random.default_rng(8)
    normals = np.array([0.0, 0.0, 1.0]) + rng.normal(0, 0.3, (len(net.points), 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    radius = 0.03
    net.xy = _exact_ellipse_centres(net, radius, normals)
    ecc = np.linalg.norm(net.xy - net.xy_true, axis=1)
    print(f"{model}: eccentricity max {ecc.max():.3f} px, rms {np.sqrt((ecc ** 2).mean()):.3f} px")
    assert ecc.max() > 0.1
    out = {}
    for corrected in (False, True):
        prj = to_project(net, control=[0, 1, 2, 3], free_interior=free, sigma_image=0.1,
                         perturb_points=0.01, perturb_stations=0.01,
                         rng=np.random.default_rng(1))
        if corrected:
            from photogram.project.model import TargetSettings
            prj.targets = TargetSettings(ids=list(prj.points.ids),
                                         radius=np.full(len(net.points), radius), normals=normals)
        p = build_problem(prj).problem
        s = solve(p)
        assert s.status == "converged"
        res = np.concatenate([b.evaluate(p.state, False)[0].ravel() for b in p.blocks
                              if b.name == "image points"])
        out[corrected] = (np.abs(p.state.io[0] - net.io[0])[0],
                          np.abs(p.state.points - net.points).max(),
                          np.sqrt(np.mean(res ** 2)))
        print(f"{model} corrected={corrected}: |dc| {out[corrected][0]:.2e} px, "
              f"max point error {out[corrected][1] * 1e6:.2f} um, rms residual "
              f"{out[corrected][2]:.2e} px, {s.iterations} iterations")
    (c0, p0, r0), (c1, p1, r1) = out[False], out[True]
    if not distorted:                                 # exact
        assert c1 < 1e-5 and p1 < 1e-8 and r1 < 5e-8
    else:                                             # the distortion's first order
        assert c1 < 0.1 and p1 < 1e-5 and r1 < 1e-3
    assert c0 > 10 * c1 and p0 > 10 * p1 and r0 > 10 * r1
