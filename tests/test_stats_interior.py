"""The sensitivity of a fixed-interior orientation to its interior
parameters, against finite differences of re-adjustment."""

import copy

import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, solve
from photogram.simulation.designs import field_design
from photogram.stats.interior import interior_sensitivity


def oriented(project):
    built = build_problem(project, fix_interior=True)
    solve(built.problem, SolverOptions(tolerance=1e-15, max_iterations=30))
    return built


def test_station_sensitivity_to_interior_matches_finite_differences():
    prj, truth = field_design()
    prj.image_points.xy = truth["xy_true"].copy()       # exact sensitivity without residuals
    prj.points.xyz = truth["points"]["xyz"].copy()
    prj.stations.position = truth["stations"]["X0"].copy()
    prj.stations.angles = truth["stations"]["angles"].copy()
    built = oriented(prj)
    labels = ["K1.c", "K3.c", "K2.x0", "K1.K1"]
    D, _ = interior_sensitivity(built.problem, built.camera_names, prj, labels)
    for j, lab in enumerate(labels):
        cam, par = lab.split(".")
        h = {"c": 0.01, "x0": 0.01, "K1": 1e-10}[par]
        X0 = []
        for sign in (1, -1):
            q = copy.deepcopy(prj)
            q.cameras[cam].parameters[par].value += sign * h
            X0.append(oriented(q).problem.state.X0.ravel())
        fd = (X0[0] - X0[1]) / (2 * h)
        got = D.reshape(-1, 6, len(labels))[:, :3, j].ravel()
        assert np.allclose(got, fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max()), lab
