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
from photogram.simulation.network import frame_network, observe, to_project


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
