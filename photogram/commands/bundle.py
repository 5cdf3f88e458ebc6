"""`photogram calibrate` and `photogram orient`: configurations of the one
engine, from a project file to a results folder.

read project -> approximate values (chain) -> build problem -> datum check
-> solve -> robust reweighting / data snooping / variance components ->
statistics -> results folder (summary.json, cameras.toml, stations.csv,
points.csv, residuals.csv, log.txt).
"""

from __future__ import annotations

import copy
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.datum import check_datum, check_datum_condition
from photogram.adjust.solver import SolverOptions, solve
from photogram.errors import GeometryError
from photogram.geometry import matrix_to_opk
from photogram.stats.covariance import (
    camera_covariances, cofactors, high_correlations, point_covariances, station_covariances)
from photogram.stats.reliability import data_snooping, normalized_residuals, redundancy_numbers
from photogram.stats.robust import robust_reweighting
from photogram.stats.variance import estimate_variance_components

log = logging.getLogger("photogram")


@dataclass
class BundleResult:
    """Everything a command produces, before it is written."""

    project: object                     # Project with the estimated values
    summary: dict
    camera_sigma: dict
    station_sigma: np.ndarray           # (n_s, 6), angles in radians
    point_sigma: np.ndarray             # (n_p, 3)
    residuals: dict                     # column -> array
    covariances: dict = field(default_factory=dict)
    point_extra: dict = field(default_factory=dict)   # further points.csv columns


def _options(adj):
    return SolverOptions(max_iterations=adj.max_iterations, tolerance=adj.tolerance,
                         damping=adj.damping)


def _needs_approximations(project):
    st, pts = project.stations, project.points
    seen = np.zeros(len(pts), dtype=bool)
    seen[project.image_points.point] = True
    return (not np.all(np.isfinite(st.position)) or not np.all(np.isfinite(st.angles))
            or not np.all(np.isfinite(pts.xyz[seen])))


def approximate_if_needed(project, summary):
    """Run the approximation chain when some station or observed point has
    no approximate value; record its report in the summary."""
    if not _needs_approximations(project):
        return project
    from photogram.init.chain import approximate
    project, report = approximate(project)
    summary["approximation"] = report.to_dict() if hasattr(report, "to_dict") else dict(report)
    return project


def adjust(project, *, fix_interior=False) -> BundleResult:
    """Adjust ``project`` with the settings of its ``[adjustment]`` table.

    Parameters
    ----------
    project : Project
    fix_interior : bool
        Hold all interior orientation fixed (``photogram orient``).

    Raises
    ------
    GeometryError
        Also for a numerical failure of linear algebra (a singular or
        non-finite system from absurd approximate values, e.g. angles in
        the wrong unit): one line, not an internal error.
    """
    try:
        return _adjust(project, fix_interior)
    except np.linalg.LinAlgError as exc:
        raise GeometryError(f"the adjustment of {project.name} met a singular or non-finite "
                            f"system (numpy: {exc}); the approximate values or the units "
                            f"are probably wrong",
                            file=project.path,
                            hint="check angle_unit, length_unit and image_unit in [project] "
                                 "and the approximate values of the stations and points") from exc


def _adjust(project, fix_interior):
    t0 = time.perf_counter()
    adj = project.adjustment
    summary = {"datum": adj.datum, "warnings": list(project.warnings)}
    project = approximate_if_needed(project, summary)
    t_approx = time.perf_counter()
    built = build_problem(project, fix_interior=fix_interior)
    problem = built.problem
    for text in built.warnings or []:
        log.info("warning: %s", text)
        summary["warnings"].append(text)
    for text in check_datum(problem, built.present):
        log.info("warning: %s", text)
        summary["warnings"].append(text)
    opts = _options(adj)
    s = solve(problem, opts)
    # the datum points' geometry again at the adjusted coordinates (the
    # approximate ones can hide a near-collinearity)
    for text in check_datum_condition(problem, built.present):
        if text not in summary["warnings"]:
            log.info("warning: %s", text)
            summary["warnings"].append(text)
    iterations = s.iterations
    if adj.robust:
        # a redescending loss starts from the Huber solution, not from the
        # least-squares one that the blunders have pulled
        summary["robust"] = robust_reweighting(
            problem, adj.robust, opts,
            warm_start="huber" if adj.robust in ("tukey", "cauchy") else None)
        s = solve(problem, opts)
        iterations += s.iterations
    snoop = None
    if adj.snooping_alpha:
        snoop = data_snooping(problem, alpha=adj.snooping_alpha, options=opts)
        summary["snooping"] = {"alpha": snoop.alpha, "critical_value": snoop.critical_value,
                               "rejected": snoop.rejected}
        if snoop.rejected:
            summary["warnings"].append(
                f"data snooping rejected {len(snoop.rejected)} observation(s) "
                f"(|w| > {snoop.critical_value:.2f}, alpha {snoop.alpha:g})")
        reference = [r for r in snoop.rejected if "coordinate" in r]
        if reference:
            summary["warnings"].append(
                "data snooping rejected the reference coordinate(s) "
                + ", ".join(f"{r['label']} (w = {r['w']:.1f})" for r in reference)
                + ": the surveyed value disagrees with the images; check it")
        s = solve(problem, opts)
        iterations += s.iterations
    if adj.variance_components:
        hist = estimate_variance_components(problem, opts)
        summary["variance_components"] = {"history": hist,
                                          "factors": dict(problem.variance),
                                          "sigma": {g: float(np.sqrt(v)) for g, v in problem.variance.items()}}
        s = solve(problem, opts)
        iterations += s.iterations
    t_solve = time.perf_counter()

    cof = cofactors(problem)
    s0sq = s.sigma0 ** 2 if np.isfinite(s.sigma0) else 1.0
    result = _collect(project, built, cof, s0sq, summary)
    if fix_interior:
        _with_calibration_covariance(result, built, s0sq, summary)
    red = redundancy_numbers(problem, cof)
    result.residuals = _residual_columns(problem, red)
    _flag_weak_points(result, problem, summary)
    t_stats = time.perf_counter()
    summary.update({
        "status": s.status, "message": s.message, "iterations": iterations,
        "sigma0": s.sigma0, "sigma0_image": s.sigma0 * _apriori_image_sigma(problem),
        "redundancy": s.redundancy, "initial_cost": s.initial_cost, "final_cost": s.final_cost,
        "cost_trace": s.cost_trace,
        "counts": {"observations": s.n_observations, "unknowns": s.n_unknowns,
                   "conditions": s.n_conditions,
                   "interior": int(sum(problem.layout.free[c].sum() for c in problem.layout.camera_cols)),
                   "exterior": int(problem.layout.free[problem.layout.station_cols].sum()),
                   "points": int(problem.layout.free[problem.layout.point_cols].sum())},
        "timings": {"approximation": t_approx - t0, "adjustment": t_solve - t_approx,
                    "statistics": t_stats - t_solve, "total": t_stats - t0},
    })
    if s.status != "converged":
        summary["warnings"].append(s.message)
    result.summary = summary
    return result


def _flag_weak_points(result, problem, summary):
    """Largest intersection angle per point; points below WEAK_ANGLE_DEG
    are flagged (points.csv ``est_weak_angle``, a summary warning,
    ``summary["weak_points"]``)."""
    from photogram.stats.geometry import (
        WEAK_ANGLE_DEG, problem_intersection_angles, weak_angle_warning, weak_points)
    angles = problem_intersection_angles(problem)
    weak = weak_points(angles)
    ids = result.project.points.ids
    result.point_extra = {"est_angle": angles, "est_weak_angle": weak.astype(int)}
    summary["weak_points"] = {"threshold_deg": WEAK_ANGLE_DEG, "count": int(weak.sum()),
                              "ids": [ids[i] for i in np.flatnonzero(weak)]}
    warning = weak_angle_warning(ids, angles)
    if warning:
        summary["warnings"].append(warning)


def _apriori_image_sigma(problem):
    """RMS of the a-priori sigmas of the image observations (image unit), so
    that sigma0 x this is the a-posteriori image sigma (DBAT's "Sigma0
    (pixels)")."""
    sig = [b.sigma[:, 0] for b in problem.blocks if b.name == "image points"]
    return float(np.sqrt(np.mean(np.concatenate(sig) ** 2))) if sig else float("nan")


def _with_calibration_covariance(result, built, s0sq, summary):
    """With the interior orientation fixed at calibrated values whose
    covariance is known (covariance.npz beside the cameras file), report the
    covariance of the stations including that uncertainty, with the
    interior-exterior cross-covariances (photogram.stats.interior.py)."""
    from photogram.stats.interior import (
        calibration_covariance, interior_sensitivity, station_rotation_to_angles)
    found = calibration_covariance(result.project)
    if found is None or built is None:
        return
    labels, Sio, folder = found
    D, cof = interior_sensitivity(built.problem, built.camera_names, result.project, labels)
    T = station_rotation_to_angles(built.problem)
    D = T @ D                                         # angles instead of rotation increments
    n_s = len(built.problem.state.X0)
    lab_st = [f"{st}.{p}" for st in result.project.stations.names
              for p in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
    cols = built.problem.layout.station_cols.ravel()
    Q_st = cof.Qcc[np.ix_(cols, cols)]
    S_full = s0sq * T @ Q_st @ T.T + D @ Sio @ D.T
    cov = np.block([[Sio, Sio @ D.T], [D @ Sio, S_full]])
    result.station_sigma = np.sqrt(np.clip(np.diag(S_full), 0, None)).reshape(n_s, 6)
    idx = np.arange(n_s)[:, None] * 6 + np.arange(6)
    result.covariances["stations"] = S_full[idx[:, :, None], idx[:, None, :]]  # (n_s, 6, 6)
    result.covariances.update({"orientation_labels": labels + lab_st, "orientation": cov})
    summary["interior_covariance"] = {
        "from": str(folder), "parameters": labels,
        "note": "station sigmas and covariance.npz include the covariance of the fixed "
                "interior orientation, propagated, with interior-exterior cross-covariances"}


def _collect(project, built, cof, s0sq, summary):
    """Estimated values and a-posteriori sigmas into a copy of the project."""
    problem = built.problem
    st = problem.state
    out = copy.deepcopy(project)
    out.points.xyz = st.points.copy()
    out.stations.position = st.X0.copy()
    out.stations.angles = matrix_to_opk(st.R)
    cams = camera_covariances(cof, s0sq)
    camera_sigma, corr = {}, {}
    for k, name in enumerate(built.camera_names):
        cam = out.cameras[name]
        for pname, v in zip(cam.parameters, st.io[k]):
            cam.parameters[pname].value = float(v)
        sig = np.sqrt(np.clip(np.diag(cams[k]), 0, None))
        camera_sigma[name] = dict(zip(cam.parameters, sig.tolist()))
        free = cam.free_mask() & (sig > 0)
        names = [n for n, f in zip(cam.parameters, free) if f]
        high = high_correlations(cams[k][np.ix_(free, free)], names)
        for a, b, r in high:
            summary["warnings"].append(f"camera {name}: correlation {a}-{b} = {r:+.3f}")
        corr[name] = high
    summary["high_correlations"] = {k: v for k, v in corr.items() if v}
    P = point_covariances(cof, s0sq)
    S = station_covariances(cof, st.R, s0sq)
    point_sigma = np.sqrt(np.clip(np.diagonal(P, axis1=1, axis2=2), 0, None))
    station_sigma = np.sqrt(np.clip(np.diagonal(S, axis1=1, axis2=2), 0, None))
    if len(built.check):
        d = st.points[built.check] - project.points.xyz[built.check]
        summary["check_points"] = {
            "ids": [project.points.ids[i] for i in built.check],
            "differences": d.tolist(),
            "rmse": np.sqrt(np.mean(d ** 2, axis=0)).tolist()}
    labels, cov = orientation_covariance(cof, problem, project, built.camera_names, s0sq)
    return BundleResult(out, summary, camera_sigma, station_sigma, point_sigma, {},
                        {"points": P, "stations": S, "cameras": cams,
                         "orientation_labels": labels, "orientation": cov})


def orientation_covariance(cof, problem, project, camera_names, s0sq):
    """Joint covariance of all interior parameters and exterior orientations
    (X0 Y0 Z0 in length units, omega phi kappa in radians), with the
    cross-covariances between stations, for propagation by later commands.
    """
    lay = problem.layout
    cols = np.concatenate([c for c in lay.camera_cols] + [lay.station_cols.ravel()])
    Q = cof.Qcc[np.ix_(cols, cols)]
    n_io = sum(len(c) for c in lay.camera_cols)
    T = np.eye(len(cols))
    from photogram.geometry import angle_increment_map
    _, E = angle_increment_map(problem.state.R)
    for s in range(len(E)):
        i = n_io + 6 * s + 3
        T[i:i + 3, i:i + 3] = E[s]
    labels = [f"{n}.{p}" for n in camera_names for p in project.cameras[n].parameters]
    labels += [f"{st}.{p}" for st in project.stations.names
               for p in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
    return labels, s0sq * T @ Q @ T.T


def _residual_columns(problem, redundancy):
    """One row per image observation: residuals, normalized residuals and
    redundancy numbers."""
    w = normalized_residuals(problem, redundancy)
    cols = {k: [] for k in ("station", "point", "x", "y", "vx", "vy", "wx", "wy", "rx", "ry", "used")}
    for k, blk in enumerate(problem.blocks):
        if blk.name != "image points":
            continue
        e, _ = blk.evaluate(problem.state)
        cols["station"].append(blk.station)
        cols["point"].append(blk.point)
        cols["x"].append(blk.xy[:, 0])
        cols["y"].append(blk.xy[:, 1])
        cols["vx"].append(e[:, 0])
        cols["vy"].append(e[:, 1])
        cols["wx"].append(w[k][:, 0])
        cols["wy"].append(w[k][:, 1])
        cols["rx"].append(redundancy[k][:, 0])
        cols["ry"].append(redundancy[k][:, 1])
        cols["used"].append(problem.active[k].astype(int))
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items()}


def run(project, *, command, output=None, fix_interior=False):
    """Adjust a (validated) project and write its results folder.

    Returns ``(folder, BundleResult)``.
    """
    from photogram.project.output_policy import project_inputs
    from photogram.project.results import write_results
    from photogram.project.results_folder import staged_results
    from photogram.report import write_report
    folder = Path(output) if output else project.output_folder()
    log.debug("%s: %s -> %s", command, project.path, folder)
    result = adjust(project, fix_interior=fix_interior)
    result.summary["command"] = command
    _check_finite(result)
    # written into a staging folder, moved into place when complete
    with staged_results(folder, command=command, inputs=project_inputs(project)) as stage:
        write_results(stage.path, result.project, result.summary,
                      camera_sigma=result.camera_sigma, station_sigma=result.station_sigma,
                      station_covariance=result.covariances.get("stations"),
                      point_sigma=result.point_sigma, residuals=result.residuals,
                      point_extra=result.point_extra,
                      log_text=_log_text(command, project.path, result.summary))
        _write_covariance(stage.path / "covariance.npz", result)
        write_report(stage.path)
    if result.summary["status"] != "converged":
        raise GeometryError(f"{result.summary['message']}; the unconverged results are in {folder}",
                            hint="raise [adjustment] max_iterations or improve the approximate values")
    return folder, result


def _write_covariance(path, result):
    """covariance.npz: ``labels`` and ``matrix`` of the joint covariance of
    interior and exterior orientation (angles in radians), and
    ``point_ids`` with ``point_covariance`` (n, 3, 3) of every point (for
    error ellipses); written atomically."""
    import io
    from photogram.project.atomic import atomic_write_bytes
    buf = io.BytesIO()
    np.savez(buf, labels=np.array(result.covariances["orientation_labels"]),
             matrix=result.covariances["orientation"],
             point_ids=np.array(result.project.points.ids, dtype=str),
             point_covariance=result.covariances["points"])
    atomic_write_bytes(path, buf.getvalue())


def read_orientation_covariance(folder):
    """(labels, matrix) written by :func:`run` (see covariance.npz); a
    damaged or pickled file is an InputError naming it (never unpickled)."""
    from photogram.project.results_read import read_orientation_covariance as read
    return read(folder)


def _check_finite(result):
    """Never write NaN or infinity as an estimate."""
    p = result.project
    seen = np.bincount(p.image_points.point, minlength=len(p.points)) > 0
    arrays = {"points": p.points.xyz[seen], "stations": p.stations.position,
              "angles": p.stations.angles, "point sigmas": result.point_sigma[seen],
              "station sigmas": result.station_sigma}
    bad = [k for k, a in arrays.items() if not np.all(np.isfinite(a))]
    bad += [f"camera {n}" for n, c in p.cameras.items() if not np.all(np.isfinite(c.values()))]
    if bad:
        raise GeometryError(f"the adjustment produced non-finite {', '.join(bad)}",
                            hint="the network is too weak or the start too far off")


def announce(command, folder, summary, args=None):
    """The one line a successful command prints (unless ``--quiet``)."""
    if not getattr(args, "quiet", False):
        print(f"{command}: {summary['status']} after {summary['iterations']} iterations, "
              f"sigma0 {summary['sigma0']:.4f}, redundancy {summary['redundancy']}; "
              f"results in {folder}")


def _log_text(command, path, summary):
    lines = [f"photogram {command} {path}",
             f"status: {summary.get('status')} ({summary.get('message', '')})",
             f"iterations: {summary.get('iterations')}",
             f"sigma0: {summary.get('sigma0'):.6g}  redundancy: {summary.get('redundancy')}",
             "cost trace: " + " ".join(f"{c:.6g}" for c in summary.get("cost_trace", []))]
    lines += [f"warning: {w}" for w in summary.get("warnings", [])]
    return "\n".join(lines) + "\n"


def calibrate(project, output=None):
    """`photogram calibrate`: self-calibrating bundle adjustment (interior
    parameters free as the project says)."""
    return run(project, command="calibrate", output=output)


def orient(project, output=None):
    """`photogram orient`: exterior orientation with the interior
    orientation held fixed."""
    return run(project, command="orient", output=output, fix_interior=True)
