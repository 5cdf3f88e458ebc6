"""A Bundle Adjustment in the Large problem (:mod:`photogram.io.bal`, the
file format) as an engine problem: building it (one ``bal`` camera per
station, unit weights, gauge / fixed / inner datum), solving it with Ceres'
trust-region settings, mapping the solution back, and its cofactors in the
free-network datum.

In the engine (photogram's conventions, docs/camera-models.md) a BAL camera
is ``R = R(r)``, ``X0 = -R^T t`` (``Xc = R (X - X0) = P``) with the ``bal``
camera model (parameters f, k1, k2; :mod:`photogram.geometry.bal_model`)
and image coordinates **y down**: ``(x, y)`` becomes ``(x, -y)``. The cost is
unchanged. Every BAL camera has its own f, k1, k2, so the engine problem has
one camera (interior orientation) per station.

Observations whose point lies behind its camera at the start (P_z >= 0) are
dropped by default (``behind="drop"``), as the Ceres figure of COLMAP's
bundle adjuster treats them; ``behind="keep"`` keeps them (Ceres' own BAL
example).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import InputError
from photogram.geometry import matrix_to_rodrigues, rodrigues_to_matrix
from photogram.io.bal import BALProblem, behind_camera

__all__ = ["build_bal_problem", "BALBuilt", "bal_from_state", "engine_problem", "solve_bal",
           "bal_options", "bal_cofactors", "DATUMS"]


@dataclass
class BALBuilt:
    """An engine problem made from a BAL problem, and how to map back."""

    problem: object           # photogram.adjust.solver.Problem
    bal: BALProblem           # the observations actually used
    present: dict             # flags for datum messages
    dropped: np.ndarray       # observation indices (into the file) left out


def build_bal_problem(bal: BALProblem, behind: str = "drop", datum: str = "gauge") -> BALBuilt:
    """The engine problem of a BAL problem.

    Parameters
    ----------
    bal : BALProblem
    behind : "drop" or "keep"
        Observations behind their camera at the start: left out (as the
        COLMAP/Ceres figures of docs/benchmarks.md) or kept (Ceres' BAL
        example; their cost is computed as for any other).
    datum : "gauge", "fixed" or "inner"
        ``gauge`` (default, as Ceres' BAL example): nothing is fixed; the 7
        similarity motions stay free, the Levenberg-Marquardt damping of the
        trust region (``bal_options()``, :func:`solve_bal`) keeps every step
        regular, and the cost is that of the very problem Ceres minimizes
        (the datum check is told so: ``present["gauge"]``). ``fixed``: the
        exterior orientation of camera 0 and one centre coordinate of the
        camera farthest from it are fixed (7 parameters, a regular system
        for any solver strategy). ``inner``: the 7 minimum-trace inner
        constraints over all points (bordered system). The minimum cost is
        the same in every datum.
    """
    if behind not in ("drop", "keep"):
        raise InputError(f"behind must be 'drop' or 'keep', not {behind!r}")
    dropped = np.zeros(0, dtype=int)
    if behind == "drop":
        mask = behind_camera(bal)
        if mask.any():
            dropped = np.flatnonzero(mask)
            bal = bal.subset(~mask)
    problem, present = engine_problem(bal, datum=datum)
    return BALBuilt(problem, bal, present, dropped)


def bal_from_state(bal: BALProblem, state) -> BALProblem:
    """A copy of ``bal`` with cameras and points of an engine state."""
    out = bal.copy()
    R = state.R
    out.cameras[:, :3] = matrix_to_rodrigues(R)
    out.cameras[:, 3:6] = -np.einsum("nij,nj->ni", R, state.X0)
    out.cameras[:, 6:9] = np.stack(state.io)
    out.points = state.points.copy()
    return out


DATUMS = ("gauge", "fixed", "inner")


def engine_problem(bal: BALProblem, datum: str = "gauge"):
    """The engine :class:`~photogram.adjust.solver.Problem` of ``bal`` (all
    observations as given) and the datum flags for
    :func:`~photogram.adjust.datum.check_datum`.

    One camera (f, k1, k2, model ``bal``) per station; every parameter free
    except points without observations; unit weights (sigma 1 px), so the
    engine's cost is Ceres' ``0.5 sum r^2``. Observations are ordered by
    camera (contiguous row groups for the reduced camera system).
    """
    from photogram.adjust.datum import inner_constraints
    from photogram.adjust.residual_blocks import ImagePointBlock
    from photogram.adjust.solver import Problem
    from photogram.adjust.state import Layout, State
    from photogram.geometry import camera_model

    if datum not in DATUMS:
        raise InputError(f"unknown BAL datum {datum!r}", hint="use " + ", ".join(DATUMS))
    n_c, n_p = bal.n_cameras, bal.n_points
    order = np.lexsort((bal.point, bal.camera))
    cam, pt, xy = bal.camera[order], bal.point[order], bal.xy[order]
    seen = np.bincount(pt, minlength=n_p) > 0
    free = {"camera": [np.ones(3, dtype=bool) for _ in range(n_c)],
            "station": np.ones((n_c, 6), dtype=bool),
            "point": np.repeat(seen[:, None], 3, axis=1)}
    R = rodrigues_to_matrix(bal.cameras[:, :3])
    X0 = -np.einsum("nji,nj->ni", R, bal.cameras[:, 3:6])
    if datum == "fixed":
        free["station"][0] = False
    if datum == "fixed" and n_c > 1:
        # the scale: one centre coordinate of the camera farthest from
        # camera 0, along its largest offset
        far = 1 + int(np.argmax(np.linalg.norm(X0[1:] - X0[0], axis=1)))
        free["station"][far, int(np.argmax(np.abs(X0[far] - X0[0])))] = False
    layout = Layout([3] * n_c, n_c, n_p, np.zeros(n_p, dtype=bool), free)
    state = State(bal.points.astype(float).copy(), R, X0,
                  [bal.cameras[c, 6:9].astype(float).copy() for c in range(n_c)])
    blk = ImagePointBlock(camera_model("bal"), np.arange(n_c), cam, cam, pt,
                          xy * np.array([1.0, -1.0]), np.ones(len(cam)), layout)
    blk.rows = order
    blk.group = "image"
    G = inner_constraints(layout, state) if datum == "inner" else None
    problem = Problem(state, layout, [blk], G=G, point_labels=range(n_p))
    present = {"control": False, "distance": False, "inner": G is not None,
               "gauge": datum == "gauge"}
    return problem, present


def bal_options(**kw):
    """Solver options of the BAL mode: Ceres' Levenberg-Marquardt trust
    region with Ceres' default tolerances (function 1e-6, parameter 1e-8,
    gradient 1e-10), at most 100 iterations."""
    from photogram.adjust.solver import SolverOptions
    base = dict(damping="trust_region", max_iterations=100, function_tolerance=1e-6)
    base.update(kw)
    return SolverOptions(**base)


def solve_bal(built: BALBuilt, options=None):
    """Minimize a BAL problem (in place); returns the engine's Summary."""
    from photogram.adjust.solver import solve
    return solve(built.problem, options or bal_options())


def bal_cofactors(problem, datum="inner", points=None):
    """Cofactors (a-priori sigma0 = 1) of a solved, gauge-free BAL problem:
    cameras ``cof.Qcc`` (f k1 k2 per camera, then X0 and the rotation
    increment per station), points ``cof.Qee`` (3x3 each), and the cross
    cofactors on request (``cof.block``).

    Computed in a regular datum first (``datum="fixed"``: camera 0's
    exterior orientation and one centre coordinate of the camera farthest
    from it, as ``build_bal_problem(datum="fixed")``; a Cholesky of the
    reduced camera system), then, for ``datum="inner"`` (default), moved by
    an S-transformation to the minimum-trace datum over ``points`` (the
    free-network covariance). The default ``points`` are the determined
    ones: those whose trace in the fixed datum is at most 100 times the
    median (BAL problems contain a few points at nearly infinite distance,
    with variances 10^12 times the others, which would otherwise pull the
    datum onto themselves).
    """
    from photogram.adjust.datum import similarity_motions
    from photogram.adjust.solver import Problem
    from photogram.adjust.state import Layout
    from photogram.stats.covariance import cofactors, s_transform

    if datum not in ("inner", "fixed"):
        raise InputError(f"unknown covariance datum {datum!r}", hint="use 'inner' or 'fixed'")
    lay, state = problem.layout, problem.state
    n_s = len(state.X0)
    free = {"camera": [lay.free[c] for c in lay.camera_cols],
            "station": lay.free[lay.station_cols].copy(),
            "point": lay.free[lay.point_cols]}
    free["station"][0] = False
    if n_s > 1:
        far = 1 + int(np.argmax(np.linalg.norm(state.X0[1:] - state.X0[0], axis=1)))
        free["station"][far, int(np.argmax(np.abs(state.X0[far] - state.X0[0])))] = False
    fixed_lay = Layout([len(c) for c in lay.camera_cols], n_s, len(state.points),
                       lay.reduced_points, free)
    twin = Problem(state, fixed_lay, problem.blocks, point_labels=problem.point_labels)
    twin.variance, twin.active, twin.robust_weight = (problem.variance, problem.active,
                                                      problem.robust_weight)
    twin.coordinate_active = problem.coordinate_active
    cof = cofactors(twin)
    if datum == "fixed":
        return cof
    if points is None:
        tr = np.trace(cof.Qee, axis1=1, axis2=2)
        points = np.flatnonzero(lay.free[lay.point_cols].all(axis=1) & (tr <= 100 * np.median(tr)))
    T = similarity_motions(lay, state)
    Tp = np.zeros_like(T)
    cols = lay.point_cols[np.asarray(points)].ravel()
    Tp[cols] = T[cols]
    Tp[~lay.free] = 0.0
    QTp = cof.factorization.solve(Tp)
    return s_transform(cof, T, Tp, QTp, layout=lay)
