"""``adjust``: one project through the calibrate/orient pipeline (module
doc of :mod:`photogram.bundle`)."""

from __future__ import annotations

import logging
import time

import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.datum import check_datum, check_datum_condition
from photogram.adjust.solver import SolverOptions, solve
from photogram.bundle.approximate import approximate_if_needed
from photogram.bundle.result import BundleResult, residual_columns
from photogram.bundle.statistics import (
    apriori_image_sigma, collect, flag_weak_points, with_calibration_covariance)
from photogram.errors import GeometryError
from photogram.stats.covariance import cofactors
from photogram.stats.rig_covariance import with_rig_cofactors
from photogram.stats.reliability import data_snooping, redundancy_numbers
from photogram.stats.robust import robust_reweighting
from photogram.stats.variance import estimate_variance_components

log = logging.getLogger("photogram")


def _options(adj):
    return SolverOptions(max_iterations=adj.max_iterations, tolerance=adj.tolerance,
                         damping=adj.damping)


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


def _peak_rss_mb():
    """Peak resident set size of this process so far (MB): ``VmHWM`` of
    /proc/self/status on Linux (``ru_maxrss`` of a child keeps its
    parent's size across fork and exec), else ``ru_maxrss``; NaN without
    either (Windows)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    try:
        import resource
    except ImportError:         # Windows
        return float("nan")
    import sys
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / (1024.0 * 1024.0) if sys.platform == "darwin" else kb / 1024.0


def _adjust(project, fix_interior):
    t0 = time.perf_counter()
    c0 = time.process_time()
    adj = project.adjustment
    summary = {"datum": adj.datum, "warnings": list(project.warnings)}
    project = approximate_if_needed(project, summary)
    t_approx = time.perf_counter()
    c_approx = time.process_time()
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
    c_solve = time.process_time()
    rss_solve = _peak_rss_mb()

    cof = cofactors(problem)
    if built.rigs is not None:         # the composed stations of rig images
        with_rig_cofactors(cof, problem)
    s0sq = s.sigma0 ** 2 if np.isfinite(s.sigma0) else 1.0
    result = collect(project, built, cof, s0sq, summary)
    if fix_interior:
        with_calibration_covariance(result, built, s0sq, summary)
    red = redundancy_numbers(problem, cof)
    result.residuals = residual_columns(problem, red)
    flag_weak_points(result, problem, summary)
    t_stats = time.perf_counter()
    c_stats = time.process_time()
    summary.update({
        "status": s.status, "message": s.message, "iterations": iterations,
        "sigma0": s.sigma0, "sigma0_image": s.sigma0 * apriori_image_sigma(problem),
        "redundancy": s.redundancy, "initial_cost": s.initial_cost, "final_cost": s.final_cost,
        "cost_trace": s.cost_trace,
        "counts": {"observations": s.n_observations, "unknowns": s.n_unknowns,
                   "conditions": s.n_conditions,
                   "interior": _interior_unknowns(problem.layout),
                   "exterior": int(problem.layout.free[problem.layout.station_cols].sum()),
                   "points": int(problem.layout.free[problem.layout.point_cols].sum())},
        "timings": {"approximation": t_approx - t0, "adjustment": t_solve - t_approx,
                    "statistics": t_stats - t_solve, "total": t_stats - t0,
                    "cpu": {"approximation": c_approx - c0, "adjustment": c_solve - c_approx,
                            "statistics": c_stats - c_solve, "total": c_stats - c0},
                    "peak_rss_mb": {"after_adjustment": rss_solve,
                                    "after_statistics": _peak_rss_mb()}},
    })
    if s.status != "converged":
        summary["warnings"].append(s.message)
    result.summary = summary
    return result


def _interior_unknowns(layout):
    """Free interior columns (a shared parameter counts once)."""
    if not layout.camera_cols:
        return 0
    return int(layout.free[np.unique(np.concatenate(layout.camera_cols))].sum())
