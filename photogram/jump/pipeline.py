"""The ski-jump intersection step (ski-jump paper, section 4, step 3 and
appendix C): with the interior and exterior orientation held fixed, the
jumper points of every exposure are intersected by the one engine, the ski
lines by :mod:`photogram.lines`, the left/right labels of the skis checked
over the three views, and the stick model derived with propagated sigmas.

Moving points are read with an ``exposure`` column (a point ``P1`` at
exposure ``007`` is ``P1@007``, a ski line ``L1@007``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.datum import check_datum
from photogram.adjust.solver import SolverOptions, solve
from photogram.errors import InputError
from photogram.jump.exposures import exposure_order as _exposure_order
from photogram.jump.exposures import split_id
from photogram.jump.plausibility import plausibility_warnings
from photogram.jump.stick import stick_model
from photogram.lines import cameras_from_project, intersect_line_from_points
from photogram.lines.skis import check_ski_labels, swap_labels
from photogram.stats.covariance import cofactors, point_covariances
from photogram.stats.propagation import orientation_sensitivity, propagate_orientation
from photogram.stats.geometry import problem_intersection_angles, weak_angle_warning


@dataclass
class JumpResult:
    """Everything the intersect step estimates."""

    exposures: list                 # exposure ids, in time order
    times: np.ndarray               # s
    P: np.ndarray                   # (n, 4, 3) jumper points
    cov_P: np.ndarray               # (n, 12, 12)
    lines: dict                     # (exposure, ski) -> LineIntersection
    ski_checks: dict                # exposure -> SkiCheck
    model: object                   # StickModel
    project: object                 # the project with the estimated points
    point_sigma: np.ndarray = None  # (n_points, 3) of every point of the project
    summary: dict = field(default_factory=dict)
    residuals: dict = None          # column -> array, one row per image point (residuals.csv)
    height: tuple = None            # (H, sigma_H) (n,) above the landing profile, if given


def intersect_points(project, orientation=None):
    """Intersect every point of the project with fixed orientation.

    Returns
    -------
    project : Project with the estimated coordinates
    cov : (n_points, 3, 3) covariance from the image sigmas, plus the
        orientation's contribution when ``orientation = (labels, matrix)``
    joint : (3 n_points, 3 n_points) or None, the orientation part (points
        of different exposures are correlated through it)
    summary : dict (status, iterations, sigma0, redundancy)
    """
    from photogram.bundle import approximate_if_needed, residual_columns
    from photogram.stats.reliability import redundancy_numbers
    summary = {"warnings": []}
    project = approximate_if_needed(project, summary)
    built = build_problem(project, fix_interior=True, fix_stations=True)
    check_datum(built.problem, built.present)
    s = solve(built.problem, SolverOptions(max_iterations=project.adjustment.max_iterations,
                                           tolerance=project.adjustment.tolerance))
    cof = cofactors(built.problem)
    cov = point_covariances(cof)                  # a-priori image sigmas (sigma0 = 1)
    joint = None
    if orientation is not None:
        labels, matrix = orientation
        S = orientation_sensitivity(built.problem, project, built.camera_names, labels)
        joint = propagate_orientation(S, matrix)
        # for the lines' propagation (intersect_jump takes it out)
        summary["orientation_sensitivity"] = (built.problem, S, built.camera_names, labels,
                                              matrix)
        n = len(project.points)
        idx = np.arange(n)
        cov = cov + joint.reshape(n, 3, n, 3)[idx, :, idx, :]
    out = _copy_with_points(project, built.problem.state.points)
    # one row per image observation (residuals.csv; the COLMAP export takes its tracks)
    summary["residuals"] = residual_columns(built.problem,
                                            redundancy_numbers(built.problem, cof))
    weak = weak_angle_warning(project.points.ids, problem_intersection_angles(built.problem))
    if weak:
        summary["warnings"].append(weak)
    summary.update({"status": s.status, "iterations": s.iterations, "sigma0": s.sigma0,
                    "redundancy": s.redundancy, "message": s.message})
    return out, cov, joint, summary


def _copy_with_points(project, xyz):
    import copy
    out = copy.deepcopy(project)
    out.points.xyz = np.asarray(xyz, dtype=float).copy()
    return out


def _lines_by_exposure(project):
    """``{exposure: {station: {ski: xy (k, 2)}}}`` from the image lines, and
    the same of their sigmas ``(k,)`` (the table's sigma column where given,
    else ``[adjustment] sigma_image`` of the station)."""
    il = project.image_lines
    names = project.stations.names
    out: dict = {}
    sig: dict = {}
    default = _station_sigmas(project)
    sigma = np.asarray(il.sigma, float) if len(il.sigma) == len(il) else np.full(len(il), np.nan)
    for lab in dict.fromkeys(il.line.tolist()):
        ski, exposure = split_id(lab)
        rows = il.line == lab
        for s in np.unique(il.station[rows]):
            m = rows & (il.station == s)
            name = names[int(s)]
            out.setdefault(exposure, {}).setdefault(name, {})[ski] = il.xy[m]
            # a point's own sigma (the table's sigma column), else the station's
            sig.setdefault(exposure, {}).setdefault(name, {})[ski] = np.where(
                np.isfinite(sigma[m]) & (sigma[m] > 0), sigma[m], default[name])
    return out, sig


def _with_line_orientation(stash, project, cfg, exposures, pidx, cov_P, cov_d, c, d,
                           line_views):
    """The stick model's input covariance (n, 18, 18) per exposure with the
    orientation's covariance propagated into the ski directions as well as
    into the points, and their correlations within the exposure:
    ``C = C_image + S C_theta S^T`` with ``S`` the sensitivities (18, q) of
    P1..P4 (:func:`photogram.stats.propagation.orientation_sensitivity`) and
    of d1, d2 (:func:`photogram.stats.propagation.line_direction_sensitivity`);
    ``cov_P`` already holds the points' part."""
    from photogram.stats.propagation import line_direction_sensitivity
    problem, S, camera_names, labels, matrix = stash
    n = len(exposures)
    keys = sorted(line_views)
    spec = [(line_views[k][0], c[k], d[k], line_views[k][1]) for k in keys]
    S_lines = line_direction_sensitivity(problem, project, camera_names, labels, spec)
    q = len(labels)
    S_all = np.zeros((n, 18, q))
    for (e, j), Sd in zip(keys, S_lines):
        S_all[e, 12 + 3 * j:15 + 3 * j] = Sd
    S3 = S.reshape(-1, 3, q)
    for k, name in enumerate(cfg.points):
        for e, exposure in enumerate(exposures):
            i = pidx.get(f"{name}@{exposure}")
            if i is not None:
                S_all[e, 3 * k:3 * k + 3] = S3[i]
    C = np.zeros((n, 18, 18))
    C[:, :12, :12] = cov_P
    for j in range(2):
        C[:, 12 + 3 * j:15 + 3 * j, 12 + 3 * j:15 + 3 * j] = cov_d[:, j]
    orient = S_all @ matrix @ np.swapaxes(S_all, 1, 2)
    C[:, 12:, 12:] += orient[:, 12:, 12:]
    C[:, :12, 12:] += orient[:, :12, 12:]
    C[:, 12:, :12] += orient[:, 12:, :12]
    return 0.5 * (C + np.swapaxes(C, 1, 2))


def _station_sigmas(project):
    sig = project.adjustment.sigma_image
    cams = project.stations.camera
    return {n: (sig[c] if isinstance(sig, dict) else sig)
            for n, c in zip(project.stations.names, cams)}


def intersect_jump(project, orientation=None) -> JumpResult:
    """The whole intersect step for a project with exposures.

    Parameters
    ----------
    project : Project
        Cameras and stations with their (adjusted) orientation; jumper
        points and ski lines measured with an exposure column; settings in
        ``project.intersect``.
    orientation : (labels, matrix), optional
        Covariance of the orientation to propagate into the points
        (covariance.npz of calibrate/orient results).
    """
    cfg = project.intersect
    adjusted, cov, joint, summary = intersect_points(project, orientation)
    pidx = adjusted.points.index()
    moving = [split_id(i) for i in adjusted.points.ids if "@" in i]
    exposures, frames = _exposure_order([e for _, e in moving])
    if not exposures:
        raise InputError("no exposures: the image points table has no 'exposure' column",
                         file=project.sources.get("image_points"),
                         hint="add a column exposure with the frame number of every measurement")
    n = len(exposures)
    P = np.full((n, 4, 3), np.nan)
    cov_P = np.zeros((n, 12, 12))
    for k, name in enumerate(cfg.points):
        for e, exposure in enumerate(exposures):
            i = pidx.get(f"{name}@{exposure}")
            if i is not None:
                P[e, k] = adjusted.points.xyz[i]
                cov_P[e, 3 * k:3 * k + 3, 3 * k:3 * k + 3] = cov[i]
    if joint is not None:                                  # within-exposure correlations
        n_p = len(adjusted.points)
        J = joint.reshape(n_p, 3, n_p, 3)
        for e, exposure in enumerate(exposures):
            ids = [pidx.get(f"{nm}@{exposure}") for nm in cfg.points]
            for a, ia in enumerate(ids):
                for b, ib in enumerate(ids):
                    if ia is not None and ib is not None and a != b:
                        cov_P[e, 3 * a:3 * a + 3, 3 * b:3 * b + 3] = J[ia, :, ib, :]

    cameras = cameras_from_project(adjusted)
    sig = _station_sigmas(project)
    by_exposure, sig_by_exposure = _lines_by_exposure(project)
    checks, lines, line_views = {}, {}, {}
    names = list(project.stations.names)
    d = np.full((n, 2, 3), np.nan)
    c = np.full((n, 2, 3), np.nan)
    cov_d = np.zeros((n, 2, 3, 3))
    for e, exposure in enumerate(exposures):
        views = by_exposure.get(exposure)
        if not views:
            continue
        check = None
        complete = {st: v for st, v in views.items() if all(s in v for s in cfg.skis)}
        if len(complete) >= 3:
            check = check_ski_labels(complete, cameras, sig, labels=tuple(cfg.skis),
                                     exposure=exposure)
            checks[exposure] = check
            if check.status == "swapped":
                summary["warnings"].append(check.message)
                if cfg.swap_skis:
                    views = {**views, **swap_labels(complete, check)}
        for j, ski in enumerate(cfg.skis):
            pts = {st: v[ski] for st, v in views.items() if ski in v}
            if len(pts) < 2:       # e.g. flagged by photogram track: a gap, not an error
                summary["warnings"].append(
                    f"ski line {ski}@{exposure} is measured in {len(pts)} image(s): not "
                    f"intersected (the stick-model values that need it are empty)")
                continue
            sig_pts = {st: sig_by_exposure[exposure][st][ski] for st in pts}
            if check is not None and check.status == "swapped" and cfg.swap_skis:
                other = cfg.skis[1 - j]
                sig_pts.update({st: sig_by_exposure[exposure][st][other]
                                for st in check.swapped if st in pts})
            res = intersect_line_from_points(pts, cameras, sig_pts, label=f"{ski}@{exposure}")
            lines[(exposure, ski)] = res
            line_views[(e, j)] = ([names.index(st) for st in pts],
                                  [float(np.sum(1 / np.asarray(sig_pts[st]) ** 2)) for st in pts])
            d[e, j] = res.line.direction
            c[e, j] = res.line.point
            if res.line.covariance is not None:
                cov_d[e, j] = res.line.covariance_plucker[:3, :3]
    times = (frames - frames[0]) / cfg.fps
    stash = summary.pop("orientation_sensitivity", None)
    if stash is None:
        cov_in = dict(cov_points=cov_P, cov_dirs=cov_d)
    else:
        cov_in = dict(cov=_with_line_orientation(stash, project, cfg, exposures, pidx,
                                                 cov_P, cov_d, c, d, line_views))
    model = stick_model(P, d[:, 0], d[:, 1], fps=cfg.fps, times=times,
                        length_unit=project.units.length, ski_length=cfg.ski_length,
                        binding_fraction=cfg.binding_fraction, c1=c[:, 0], c2=c[:, 1],
                        forward="flight", **cov_in)
    height = None
    if cfg.landing_profile:                 # Z0 above the landing slope, besides world Z
        from photogram.jump.coach import read_landing_profile
        above = stick_model(P, d[:, 0], d[:, 1], fps=cfg.fps, times=times,
                            length_unit=project.units.length, ski_length=cfg.ski_length,
                            binding_fraction=cfg.binding_fraction, c1=c[:, 0], c2=c[:, 1],
                            forward="flight", ground=read_landing_profile(cfg.landing_profile),
                            **cov_in)
        sd = above.sigma
        height = (above.values["Z0"], sd["Z0"] if sd is not None else np.full(n, np.nan))
    summary["warnings"] += plausibility_warnings(model, project.units.length)
    summary["exposures"] = n
    summary["swapped_skis"] = {e: ch.swapped for e, ch in checks.items() if ch.status == "swapped"}
    summary["ski_checks"] = {e: ch.status for e, ch in checks.items()}
    point_sigma = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0, None))
    residuals = summary.pop("residuals", None)
    return JumpResult(exposures, times, P, cov_P, lines, checks, model, adjusted, point_sigma,
                      summary, residuals, height)
