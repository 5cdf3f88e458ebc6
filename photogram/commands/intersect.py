"""`photogram intersect PROJECT`: jumper points and ski lines per exposure,
the left/right ski check and the stick model with propagated sigmas.

Writes into the output folder: ``exposures.csv`` (every stick-model
parameter with its sigma, one row per exposure), ``points3d.csv`` (jumper
points with sigmas), ``lines3d.csv`` (ski lines: point, direction, sigmas,
segment), ``jump.trc`` (OpenSim markers, Y up), ``stick.png`` (the paper's
Fig. 8), ``timeseries.png``, and the standard ``summary.json``,
``points.csv``, ``residuals.csv``, ``log.txt``; with coach units
(:mod:`photogram.jump.coach`) also ``coach.csv``.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd

from photogram.errors import InputError, PhotogramError
from photogram.io.trc import write_trc
from photogram.jump.figure import plot_stick_figure, time_series_figure
from photogram.jump.pipeline import intersect_jump
from photogram.project.atomic import atomic_write_text

log = logging.getLogger("photogram")


def _orientation(project):
    """(labels, matrix) of the results folders named in ``[intersect]
    orientation``, or None. The orient results of a project whose cameras
    come from a calibration already hold the joint covariance of interior and
    exterior orientation; blocks of several folders are combined without
    cross terms, a later folder replacing what an earlier one gives. An
    empty list is no orientation (image noise only); folders that do not
    cover the exterior orientation of every measuring station are refused
    (:func:`_check_stations_covered`)."""
    from photogram.project.results_read import read_orientation_covariance
    where = project.intersect.orientation
    if not where:
        return None
    folders = list(where)
    labels, blocks = [], []
    for folder in folders:
        path = Path(folder) / "covariance.npz"
        if not path.is_file():
            raise InputError("no covariance.npz in the orientation results folder", file=path,
                             hint="run photogram orient (or calibrate) first, or remove "
                                  "[intersect] orientation")
        lab, mat = read_orientation_covariance(folder)
        labels.append(lab)
        blocks.append(mat)
    from photogram.stats.propagation import combine_covariance_blocks
    union, total = combine_covariance_blocks(labels, blocks)   # later folders override
    _check_stations_covered(project, folders, union)
    return union, total


def _check_stations_covered(project, folders, labels):
    """Refuse an orientation covariance without the exterior orientation of
    the stations that measure the jumper.

    The stations' exterior orientation was adjusted with the calibrated
    interior orientation held fixed, so it absorbs most of an interior
    error; only the joint covariance of both (the orient results) describes
    that. Propagating the interior covariance alone (``orientation =
    ["../lab/results"]``) inflated the point sigmas of the simulated jump
    6-16 times and those of Z0 and v 12-20 times.
    """
    from photogram.stats.propagation import STATION_PARAMETERS
    have = set(labels)
    used = sorted(set(np.unique(project.image_points.station).tolist()))
    names = [project.stations.names[i] for i in used]
    missing = [s for s in names if not all(f"{s}.{p}" in have for p in STATION_PARAMETERS)]
    if not missing:
        return
    line = None
    try:
        from photogram.project.toml_source import TomlSource
        line = TomlSource.load(Path(project.path)).line_of(("intersect", "orientation"))
    except (PhotogramError, OSError):          # the line is a courtesy; the message stands
        line = None
    shown = ", ".join(str(Path(f).name if Path(f).name != "results" else
                          Path(f).parent.name + "/results") for f in folders)
    src = project.sources.get("stations")
    where = None
    if src is not None and (Path(src).parent / "covariance.npz").is_file():
        where = Path(src).parent
    suggestion = (f'add the orientation results of these stations, e.g. orientation = '
                  f'["{_relative(where, project)}"] (their covariance.npz holds interior and '
                  f'exterior orientation jointly)' if where is not None else
                  "add the results folder of photogram orient for these stations (its "
                  "covariance.npz holds interior and exterior orientation jointly), or remove "
                  "[intersect] orientation")
    raise InputError(
        f"[intersect] orientation ({shown}) has no covariance of the exterior orientation of "
        f"station{'s' if len(missing) > 1 else ''} {', '.join(missing)}: the interior "
        f"orientation alone, propagated with the stations held exact, overstates the point "
        f"sigmas many times (the stations' orientation, adjusted with that interior "
        f"orientation, absorbs most of its error)", file=project.path, line=line,
        hint=suggestion)


def _relative(folder, project):
    import os
    try:
        return Path(os.path.relpath(Path(folder).resolve(),
                                    Path(project.path).resolve().parent)).as_posix()
    except ValueError:
        return Path(folder).as_posix()


def _points_table(result, unit):
    rows = []
    for e, exposure in enumerate(result.exposures):
        for k, name in enumerate(result.project.intersect.points):
            s = np.sqrt(np.clip(np.diag(result.cov_P[e])[3 * k:3 * k + 3], 0, None))
            if not np.all(np.isfinite(result.P[e, k])):   # not measured: no sigma (not 0)
                s = np.full(3, np.nan)
            rows.append({"exposure": exposure, "time": result.times[e], "point": name,
                         "X": result.P[e, k, 0], "Y": result.P[e, k, 1], "Z": result.P[e, k, 2],
                         "sX": s[0], "sY": s[1], "sZ": s[2]})
    return pd.DataFrame(rows)


def _lines_table(result):
    rows = []
    for (exposure, ski), res in result.lines.items():
        L = res.line
        seg = res.segment
        rows.append({"exposure": exposure, "line": ski,
                     "X": L.point[0], "Y": L.point[1], "Z": L.point[2],
                     "dX": L.direction[0], "dY": L.direction[1], "dZ": L.direction[2],
                     "sigma_angle_rad": L.sigma_angle if L.covariance is not None else np.nan,
                     "sigma_position": L.sigma_position if L.covariance is not None else np.nan,
                     "stations": " ".join(res.stations), "sigma0": res.sigma0,
                     "X1": seg[0, 0], "Y1": seg[0, 1], "Z1": seg[0, 2],
                     "X2": seg[1, 0], "Y2": seg[1, 1], "Z2": seg[1, 2]})
    return pd.DataFrame(rows)


def _write_csv(path, frame):
    atomic_write_text(path, frame.to_csv(index=False, float_format="%.10g"))


def write_jump(folder, result, project, units="project"):
    """All files of the intersect step (atomically); ``units="coach"`` adds
    coach.csv and draws the figures in deg, m and km/h."""
    from photogram.jump.coach import HEIGHT, coach_table, to_coach
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    unit = project.units.angle
    table = result.model.to_frame(angle_unit=unit, exposures=result.exposures)
    if result.height is not None:
        table[HEIGHT], table["sigma_" + HEIGHT] = result.height
    _write_csv(folder / "exposures.csv", table)
    coach = units == "coach"
    if coach:
        _write_csv(folder / "coach.csv", coach_table(table, unit, project.units.length))
    _write_csv(folder / "points3d.csv", _points_table(result, project.units.length))
    _write_csv(folder / "lines3d.csv", _lines_table(result))
    to_m = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001}[project.units.length]
    markers = {name: result.P[:, k] * to_m for k, name in enumerate(project.intersect.points)}
    markers["O"] = result.model.O * to_m
    for j, ski in enumerate(project.intersect.skis):
        markers[f"{ski}_tail"] = result.model.skis[:, j, 0] * to_m
        markers[f"{ski}_tip"] = result.model.skis[:, j, 1] * to_m
    write_trc(folder / "jump.trc", result.times, markers, units="m")
    profile = None
    if project.intersect.landing_profile:
        from photogram.jump.coach import read_landing_profile
        profile = read_landing_profile(project.intersect.landing_profile)
    plot_stick_figure(result.model, folder / "stick.png", coach=coach, profile=profile)
    if coach:
        shown = to_coach(table, unit, project.units.length)
        shown.attrs.update(angle_unit="deg", length_unit="m", speed_unit="km/h")
    else:
        shown = table
    time_series_figure(shown, folder / "timeseries.png")


def intersect_and_write(project, output=None, units=None, report=True):
    """Intersect the project and write its results folder (report.pdf
    unless ``report`` is false); returns ``(folder, result)`` with
    ``result.summary`` as in summary.json. ``units`` ("project" or "coach")
    overrides the project's ``[report] units``."""
    from photogram.jump.coach import check_units
    from photogram.project.output_policy import project_inputs
    from photogram.project.results import write_results
    from photogram.project.results_folder import staged_results
    from photogram.report import write_report
    units = check_units(units or project.report.units)
    result = intersect_jump(project, _orientation(project))
    folder = Path(output) if output else project.output_folder()
    s = result.summary
    summary = {"status": s["status"], "iterations": s["iterations"], "sigma0": s["sigma0"],
               "redundancy": s["redundancy"], "command": "intersect",
               "exposures": s["exposures"], "ski_checks": s["ski_checks"],
               "swapped_skis": s["swapped_skis"], "warnings": s["warnings"],
               "orientation_covariance": project.intersect.orientation}
    if project.intersect.landing_profile:     # only then: default outputs stay as they were
        summary["landing_profile"] = project.intersect.landing_profile
    if units != "project":
        summary["report_units"] = units
    # written into a staging folder, moved into place when complete
    with staged_results(folder, command="intersect", inputs=project_inputs(project)) as stage:
        write_results(stage.path, result.project, summary, point_sigma=result.point_sigma,
                      residuals=result.residuals,
                      log_text=json.dumps(summary, indent=1, default=str) + "\n")
        write_jump(stage.path, result, project, units)
        if report:
            write_report(stage.path, units=units)
    result.summary = summary
    return folder, result


def run(project, args=None):
    """Command-line entry: intersect, write, print one line (and one warning
    line on stderr when the jumper is implausible: size, speed, height)."""
    folder, result = intersect_and_write(project, units=getattr(args, "units", None),
                                         report=not getattr(args, "no_report", False))
    odd = [w for w in result.summary["warnings"] if w.startswith("implausible")]
    if odd:
        more = f" (and {len(odd) - 1} more in summary.json)" if len(odd) > 1 else ""
        log.warning("intersect: warning: %s%s", odd[0], more)
    if not getattr(args, "quiet", False):
        s = result.summary
        swapped = sum(1 for v in s["swapped_skis"].values() if v)
        print(f"intersect: {s['exposures']} exposures, sigma0 {s['sigma0']:.4f}, "
              f"{swapped} exposure(s) with interchanged skis; results in {folder}")
    return 0
