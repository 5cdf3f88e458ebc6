"""Residual blocks: analytic Jacobians against central finite differences,
and the Schur solution against a dense solve of the full normal equations."""

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.adjust.normal import assemble
from photogram.adjust.residual_blocks import (
    DistanceBlock, InteriorPriorBlock, PointPriorBlock, StationPriorBlock, VerticalBlock)
from photogram.adjust.schur import solve as schur_solve
from photogram.adjust.state import Layout, State
from photogram.geometry import opk_to_matrix
from photogram.simulation.network import frame_network, to_project

rng = np.random.default_rng(7)
N_PTS, N_ST = 6, 3


def small_state():
    pts = rng.normal(0, 1, (N_PTS, 3)) + [0, 0, 5]
    R = opk_to_matrix(rng.uniform(-1, 1, (N_ST, 3)))
    X0 = rng.normal(0, 1, (N_ST, 3))
    return State(pts, R, X0, [rng.normal(1, 0.1, 4)])


def layout():
    free = {"camera": [np.ones(4, bool)], "station": np.ones((N_ST, 6), bool),
            "point": np.ones((N_PTS, 3), bool)}
    return Layout([4], N_ST, N_PTS, np.ones(N_PTS, bool), free)


def blocks(lay):
    return [
        PointPriorBlock([0, 2], rng.normal(0, 1, (2, 3)), np.full((2, 3), 0.1), lay),
        StationPriorBlock([0, 1, 2], rng.normal(0, 1, (3, 3)), rng.uniform(-1, 1, (3, 3)),
                          np.full((3, 6), 0.1), lay),
        InteriorPriorBlock([0, 0], [1, 3], [1.0, 2.0], [0.5, 0.5], lay),
        DistanceBlock([0, 1], [3, 4], [1.0, 2.0], [0.01, 0.01], lay),
        VerticalBlock([1, 5], [2, 3], [0.01, 0.01], lay),
    ]


@pytest.mark.parametrize("k", range(5), ids=["point prior", "station prior", "interior prior",
                                             "distance", "vertical"])
def test_block_jacobians_match_finite_differences(k):
    lay = layout()
    state = small_state()
    blk = blocks(lay)[k]
    e0, J = blk.evaluate(state)
    h = 1e-6
    for slot, (Js, cols) in enumerate(zip(J, blk.slot_cols)):
        for j in range(cols.shape[1]):
            fd = np.zeros_like(e0)
            # perturb column cols[:, j] row by row (each row its own column)
            for sign in (1, -1):
                dx = np.zeros(lay.n_columns)
                dx[np.unique(cols[:, j])] = sign * h
                e, _ = blk.evaluate(state.updated(lay, dx))
                fd += sign * e / (2 * h)
            # a column shared by several rows moves them all: compare only
            # rows whose column is not shared within this slot
            uniq = np.array([np.sum(cols[:, j] == c) == 1 for c in cols[:, j]])
            err = np.abs(fd[uniq] - Js[uniq, :, j])
            assert err.max() <= 1e-6 * max(1.0, np.abs(Js[:, :, j]).max()), (slot, j)


def test_schur_solution_equals_dense_solution():
    net = frame_network(n_stations=5, n_points=25, sigma=0.3, seed=2)
    prj = to_project(net, control=[0, 1, 2], free_interior=("c", "x0", "y0", "K1"),
                     perturb_points=0.01, perturb_stations=0.01, rng=rng)
    from photogram.project.model import DistanceConstraint
    prj.distances.append(DistanceConstraint(prj.points.ids[5], prj.points.ids[6], 0.2, 0.001))
    p = build_problem(prj).problem
    rs, Js = p.evaluate(p.state)
    system = assemble(p.structure, rs, Js)
    dx, _ = schur_solve(system, p.layout)
    # dense J, N, g from the same blocks
    n = p.layout.n_columns
    rows = []
    for blk, J in zip(p.blocks, Js):
        m = len(blk) * blk.dim
        D = np.zeros((m, n))
        for Jj, cols in zip(J, blk.slot_cols):
            r_idx = np.arange(m).reshape(len(blk), blk.dim)
            np.add.at(D, (r_idx[:, :, None], np.broadcast_to(cols[:, None, :], Jj.shape)), Jj)
        rows.append(D)
    Jd = np.vstack(rows)
    r = np.concatenate([x.ravel() for x in rs])
    N = Jd.T @ Jd
    g = Jd.T @ r
    free = p.layout.free
    expect = np.zeros(n)
    expect[free] = np.linalg.solve(N[np.ix_(free, free)], -g[free])
    np.testing.assert_allclose(dx, expect, rtol=1e-7, atol=1e-10 * np.abs(expect).max())
