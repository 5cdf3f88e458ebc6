"""The true world a Monte-Carlo simulation draws its observations from.

``truth = "adjusted"`` (default): the adjusted solution of the adjustment
project (interior orientation as that project has it, stations and points
as ``photogram orient``/``calibrate`` estimate them) and, for the intersect
step, the jumper points and ski lines intersected with that orientation
from the measured images.

``truth = "simulation"``: the simulation's true values in the ``truth/``
folder beside each project (``cameras.csv``, ``stations.csv``,
``points.csv``; for the intersect step ``jumper_points.csv`` and
``skis.csv``), as projects/generate.py and ``photogram simulate`` write them.

Either way the exact observations are computed from the truth: image points
by projection, reference coordinates and constraints as their true values,
and the points measured along the skis as the images of the true ski line
points nearest to their rays.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pandas as pd

from photogram.errors import GeometryError, InputError
from photogram.geometry import matrix_to_opk
from photogram.project.tables import angle_to_rad

__all__ = ["adjusted_truth", "adjusted_result", "simulation_truth", "read_truth_table",
           "line_observations"]


def read_truth_table(path: Path, required=()):
    """A truth CSV (comment lines with #) with every column as text."""
    if not Path(path).is_file():
        raise InputError("truth table not found", file=path,
                         hint='use truth = "adjusted", or write the truth/ folder '
                              "(photogram simulate does)")
    frame = pd.read_csv(path, comment="#", dtype=str, skipinitialspace=True)
    missing = [c for c in required if c not in frame.columns]
    if missing:
        raise InputError(f"truth table has no column(s) {', '.join(missing)}", file=path)
    return frame


def adjusted_result(project, *, fix_interior: bool):
    """The adjustment command's result for the adjustment step (its project
    is the truth world; its sigmas are what the command reports)."""
    from photogram.bundle import adjust
    result = adjust(project, fix_interior=fix_interior)
    if result.summary["status"] != "converged":
        raise GeometryError(f"montecarlo: the adjustment of {project.path} did not converge "
                            f"({result.summary['message']})",
                            hint="the adjusted solution is the truth of the simulation")
    return result


def adjusted_truth(project, *, fix_interior: bool):
    """The adjusted project of the adjustment step (the truth world)."""
    return adjusted_result(project, fix_interior=fix_interior).project


def simulation_truth(project):
    """A copy of ``project`` holding the values of its ``truth/`` folder."""
    folder = project.folder / "truth"
    out = copy.deepcopy(project)
    cams = read_truth_table(folder / "cameras.csv", ["camera"])
    for _, row in cams.iterrows():
        name = str(row["camera"])
        if name not in out.cameras:
            continue
        for p, par in out.cameras[name].parameters.items():
            if p in row and isinstance(row[p], str):
                par.value = float(row[p])
    stations = read_truth_table(folder / "stations.csv",
                                ["station", "X0", "Y0", "Z0", "omega", "phi", "kappa"])
    index = out.stations.index()
    unit = project.units.angle
    for _, row in stations.iterrows():
        i = index.get(str(row["station"]))
        if i is None:
            continue
        out.stations.position[i] = [float(row[c]) for c in ("X0", "Y0", "Z0")]
        out.stations.angles[i] = [angle_to_rad(row[c], unit) for c in ("omega", "phi", "kappa")]
    points = read_truth_table(folder / "points.csv", ["id", "X", "Y", "Z"])
    pidx = out.points.index()
    xyz = np.full((len(out.points), 3), np.nan)
    for _, row in points.iterrows():
        i = pidx.get(str(row["id"]))
        if i is not None:
            xyz[i] = [float(row[c]) for c in "XYZ"]
    seen = np.bincount(out.image_points.point, minlength=len(out.points)) > 0
    coupled = {p for d in out.distances for p in (d.point_a, d.point_b)}
    coupled |= {p for v in out.verticals for p in (v.top, v.bottom)}
    need = seen | np.array([i in coupled for i in out.points.ids], dtype=bool)
    need |= np.asarray(out.points.kind, dtype=object) == "control"
    missing = [out.points.ids[i] for i in np.flatnonzero(need & ~np.all(np.isfinite(xyz), 1))]
    if missing:
        raise InputError(f"truth/points.csv has no coordinates for {', '.join(missing[:5])}",
                         file=folder / "points.csv")
    keep = np.all(np.isfinite(xyz), 1)
    out.points.xyz = np.where(keep[:, None], xyz, out.points.xyz)
    bad = [n for n, ok in zip(out.stations.names,
                              np.all(np.isfinite(out.stations.position), 1)) if not ok]
    if bad:
        raise InputError(f"truth/stations.csv has no values for {', '.join(bad)}",
                         file=folder / "stations.csv")
    return out


def simulation_jump_truth(project, exposures, point_names, skis):
    """True jumper points (E, 4, 3) and ski lines (point, direction) of the
    intersect project from its ``truth/`` folder."""
    folder = project.folder / "truth"
    pts = read_truth_table(folder / "jumper_points.csv", ["exposure", "point", "X", "Y", "Z"])
    P = np.full((len(exposures), 4, 3), np.nan)
    e_index = {e: i for i, e in enumerate(exposures)}
    k_index = {n: i for i, n in enumerate(point_names)}
    for _, row in pts.iterrows():
        e, k = e_index.get(str(row["exposure"])), k_index.get(str(row["point"]))
        if e is not None and k is not None:
            P[e, k] = [float(row[c]) for c in "XYZ"]
    sk = read_truth_table(folder / "skis.csv", ["exposure", "line", "X_tail", "Y_tail", "Z_tail",
                                                "X_tip", "Y_tip", "Z_tip"])
    LP = np.full((len(exposures), 2, 3), np.nan)
    LD = np.full((len(exposures), 2, 3), np.nan)
    j_index = {n: i for i, n in enumerate(skis)}
    for _, row in sk.iterrows():
        e, j = e_index.get(str(row["exposure"])), j_index.get(str(row["line"]))
        if e is None or j is None:
            continue
        a = np.array([float(row[c]) for c in ("X_tail", "Y_tail", "Z_tail")])
        b = np.array([float(row[c]) for c in ("X_tip", "Y_tip", "Z_tip")])
        LP[e, j] = 0.5 * (a + b)
        LD[e, j] = (b - a) / np.linalg.norm(b - a)
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(LP))):
        raise InputError("the truth of the jump misses exposures, points or skis",
                         file=folder, hint="check jumper_points.csv and skis.csv")
    return P, LP, LD


def project_points(models, io, angles, X0, X, camera, station, point):
    """Exact image coordinates of observations: camera ``k`` of model
    ``models[k]`` with the interior orientation ``io[k, :n_k]`` (io padded
    to the largest model)."""
    xy = np.zeros((len(point), 2))
    cam = camera[station]
    for k, model in enumerate(models):
        rows = np.flatnonzero(cam == k)
        if len(rows):
            s, p = station[rows], point[rows]
            xy[rows] = model.project(X[p], angles[s], X0[s], io[k, :model.n_params])
    return xy


def line_observations(models, io, R, X0, station_camera, xy_measured, station, line_no, LP, LD):
    """Exact image coordinates along the true lines: the image of the point
    of line ``line_no`` nearest to the ray of each measured point."""
    from photogram.lines.views import ideal_coordinates
    cam = station_camera[station]
    C = np.zeros((len(station), 2))
    for k, model in enumerate(models):
        rows = np.flatnonzero(cam == k)
        if len(rows):
            C[rows] = ideal_coordinates(model.name, xy_measured[rows], io[k, :model.n_params])
    c = io[cam, 0]
    dc = np.stack([C[:, 0], -C[:, 1], -c], -1)
    ray = np.einsum("nji,nj->ni", R[station], dc)
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    P, D = LP[line_no], LD[line_no]
    w0 = P - X0[station]
    b = np.einsum("ni,ni->n", ray, D)
    d = np.einsum("ni,ni->n", w0, D)
    e = np.einsum("ni,ni->n", ray, w0)
    t = (b * e - d) / (1.0 - b * b)
    Y = P + t[:, None] * D
    return project_points(models, io, matrix_to_opk(R), X0, Y, station_camera, station,
                          np.arange(len(Y)))
