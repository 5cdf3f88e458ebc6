"""`photogram calibrate` and `photogram orient`: configurations of the one
engine, from a project file to a results folder.

The pipeline itself (approximate -> build -> datum -> solve -> robust /
snooping / variance components -> statistics) is
:func:`photogram.bundle.adjust`; this command takes a project and the
output options, calls it, writes the results folder (summary.json,
cameras.toml, stations.csv, points.csv, residuals.csv, covariance.npz,
log.txt, report.pdf; staged and locked) and announces it.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from photogram.bundle import adjust, check_finite
from photogram.errors import GeometryError

log = logging.getLogger("photogram")


def run(project, *, command, output=None, fix_interior=False, report=True):
    """Adjust a (validated) project and write its results folder (without
    report.pdf when ``report`` is false: ``--no-report``; `photogram report`
    builds it later from the folder).

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
    check_finite(result)
    # written into a staging folder, moved into place when complete
    tables = {}                     # what was written, handed to the report
    with staged_results(folder, command=command, inputs=project_inputs(project)) as stage:
        write_results(stage.path, result.project, result.summary,
                      camera_sigma=result.camera_sigma, station_sigma=result.station_sigma,
                      station_covariance=result.covariances.get("stations"),
                      point_sigma=result.point_sigma, residuals=result.residuals,
                      point_extra=result.point_extra,
                      log_text=_log_text(command, project.path, result.summary),
                      tables=tables)
        _write_covariance(stage.path / "covariance.npz", result)
        if report:                  # the project as read (adjust works on a copy)
            write_report(stage.path, project=project, tables=tables)
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
    shared = {}
    if "interior_labels" in result.covariances:    # shared interior parameters, each once
        shared = {"interior_labels": np.array(result.covariances["interior_labels"]),
                  "interior_matrix": result.covariances["interior"]}
    np.savez(buf, labels=np.array(result.covariances["orientation_labels"]),
             matrix=result.covariances["orientation"],
             point_ids=np.array(result.project.points.ids, dtype=str),
             point_covariance=result.covariances["points"], **shared)
    atomic_write_bytes(path, buf.getvalue())


def wants_report(args) -> bool:
    """False when the command line says ``--no-report``."""
    return not getattr(args, "no_report", False)


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


def calibrate(project, output=None, report=True):
    """`photogram calibrate`: self-calibrating bundle adjustment (interior
    parameters free as the project says)."""
    return run(project, command="calibrate", output=output, report=report)


def orient(project, output=None, report=True):
    """`photogram orient`: exterior orientation with the interior
    orientation held fixed."""
    return run(project, command="orient", output=output, fix_interior=True, report=report)
