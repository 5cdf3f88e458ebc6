"""Orientation covariance propagated into intersected points: the analytic
sensitivity against finite differences of re-intersection."""

import copy

import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, solve
from photogram.simulation.designs import field_design
from photogram.stats.propagation import (
    STATION_PARAMETERS, orientation_sensitivity, propagate_orientation)


def intersected(project):
    built = build_problem(project, fix_interior=True, fix_stations=True)
    solve(built.problem, SolverOptions(tolerance=1e-15, max_iterations=30))
    return built


def field_points():
    prj, truth = field_design()
    # noise-free images: the Gauss-Newton sensitivity is then exact (with
    # residuals, second-order terms of size |r| make it differ by ~1e-4)
    prj.image_points.xy = truth["xy_true"].copy()
    prj.points.xyz = truth["points"]["xyz"].copy()          # start at the truth
    prj.points.kind[:] = "tie"
    prj.stations.position = truth["stations"]["X0"].copy()
    prj.stations.angles = truth["stations"]["angles"].copy()
    prj.adjustment.datum = "control"
    return prj


def _perturbed(prj, name, par, delta):
    """A copy of the project with one orientation parameter moved."""
    q = copy.deepcopy(prj)
    if name in q.cameras:
        q.cameras[name].parameters[par].value += delta
    else:
        i = q.stations.names.index(name)
        k = STATION_PARAMETERS.index(par)
        if k < 3:
            q.stations.position[i, k] += delta
        else:
            q.stations.angles[i, k - 3] += delta
    return q


def labels_of(prj):
    cams = list(prj.cameras)
    lab = [f"{c}.{p}" for c in cams for p in prj.cameras[c].parameters]
    lab += [f"{s}.{p}" for s in prj.stations.names for p in STATION_PARAMETERS]
    return lab


def test_sensitivity_matches_finite_differences():
    prj = field_points()
    built = intersected(prj)
    labels = labels_of(prj)
    S = orientation_sensitivity(built.problem, prj, built.camera_names, labels)
    base = built.problem.state.points.ravel()
    checks = ["S1.X0", "S2.Z0", "S3.omega", "S1.kappa", "K2.c", "K1.x0", "K3.K1"]
    for lab in checks:
        j = labels.index(lab)
        name, par = lab.split(".")
        h = {"X0": 1e-3, "Z0": 1e-3, "omega": 1e-6, "kappa": 1e-6, "c": 1e-3,
             "x0": 1e-3, "K1": 1e-12}[par]
        fd = [intersected(_perturbed(prj, name, par, sign * h)).problem.state.points.ravel()
              for sign in (1, -1)]
        num = (fd[0] - fd[1]) / (2 * h)
        assert np.allclose(S[:, j], num, rtol=1e-5, atol=1e-7 * np.abs(num).max()), lab


def test_propagated_covariance_is_symmetric_and_grows_with_orientation_noise():
    prj = field_points()
    built = intersected(prj)
    labels = labels_of(prj)
    S = orientation_sensitivity(built.problem, prj, built.camera_names, labels)
    sig = np.zeros(len(labels))
    for i, lab in enumerate(labels):
        sig[i] = 0.3 if lab.endswith(("X0", "Y0", "Z0")) else (
            5e-4 if lab.endswith(("omega", "phi", "kappa")) else 0.0)
    C = propagate_orientation(S, np.diag(sig ** 2))
    assert np.allclose(C, C.T)
    C2 = propagate_orientation(S, np.diag((2 * sig) ** 2))
    assert np.allclose(C2, 4 * C)
    assert np.all(np.diag(C) > 0)


def test_combine_covariance_blocks_union_override_and_fixed():
    """The union of labelled blocks: a later block overrides the shared
    parameters, a zero variance (held fixed there) is not copied."""
    from photogram.stats.propagation import combine_covariance_blocks
    a = np.array([[4.0, 1.0, 0.5], [1.0, 9.0, 0.0], [0.5, 0.0, 1.0]])
    b = np.array([[2.0, 0.3, 0.0], [0.3, 5.0, 0.0], [0.0, 0.0, 0.0]])
    labels, total = combine_covariance_blocks([["c", "x", "y"], ["x", "z", "c"]], [a, b])
    assert labels == ["c", "x", "y", "z"]
    i = {k: n for n, k in enumerate(labels)}
    assert total[i["x"], i["x"]] == 2.0 and total[i["z"], i["z"]] == 5.0    # b overrides
    assert total[i["x"], i["z"]] == total[i["z"], i["x"]] == 0.3
    assert total[i["c"], i["c"]] == 4.0       # fixed in b (variance 0): a's value kept
    assert total[i["c"], i["y"]] == 0.5 and total[i["y"], i["y"]] == 1.0
    assert total[i["c"], i["x"]] == 1.0       # only a holds the pair with c
    assert np.allclose(total, total.T)


def _line_views(prj, X_a, X_b, views, n=12):
    """Points along the image of the 3D line X_a-X_b in ``views``."""
    from photogram.lines import cameras_from_project
    cams = cameras_from_project(prj)
    t = np.linspace(0.0, 1.0, n)[:, None]
    X = X_a + t * (X_b - X_a)
    return {v: cams[v].project(X) for v in views}


def _line_direction(prj, pts):
    from photogram.lines import cameras_from_project, intersect_line_from_points
    res = intersect_line_from_points(pts, cameras_from_project(prj), 0.3)
    return res.line.direction, res.line.point


def test_line_direction_sensitivity_matches_finite_differences():
    """A 3D line intersected from points measured along its images, the
    images held fixed while the orientation moves: the analytic dd/dtheta
    against central differences of the re-intersected direction; exact with
    two views (two planes), within a few percent with three (the views'
    weights are approximated)."""
    from photogram.stats.propagation import line_direction_sensitivity
    prj = field_points()
    built = intersected(prj)
    labels = labels_of(prj)
    X = prj.points.xyz
    X_a, X_b = X[0], X[0] + 0.3 * (X[5] - X[0])
    names = list(prj.stations.names)
    for views, rtol in ((names[:2], 1e-4), (names[:3], 0.05)):
        pts = _line_views(prj, X_a, X_b, views)
        d, c = _line_direction(prj, pts)
        spec = [([names.index(v) for v in views], c, d, [12 / 0.3 ** 2] * len(views))]
        S = line_direction_sensitivity(built.problem, prj, built.camera_names, labels, spec)[0]
        assert (np.abs(d @ S) <= 1e-9 * np.abs(S).max(0) + 1e-300).all()   # dd across d
        for lab in ["S1.X0", "S2.Z0", "S1.omega", "S2.kappa", "K1.c", "K2.x0"]:
            j = labels.index(lab)
            name, par = lab.split(".")
            h = {"X0": 1e-3, "Z0": 1e-3, "omega": 1e-6, "kappa": 1e-6, "c": 1e-3,
                 "x0": 1e-3}[par]
            fd = []
            for sign in (1, -1):
                dq, _ = _line_direction(_perturbed(prj, name, par, sign * h), pts)
                fd.append(dq if dq @ d > 0 else -dq)
            num = (fd[0] - fd[1]) / (2 * h)
            scale = max(np.abs(num).max(), 1e-12)
            assert np.abs(S[:, j] - num).max() <= rtol * scale + 1e-9, (views, lab, S[:, j], num)
