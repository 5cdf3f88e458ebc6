"""`photogram track PROJECT`: jumper markers and ski lines tracked in the
videos of a jump -> the observation tables of `photogram intersect`
(issue 19, docs/track.md).

Writes into the output folder (whole or not at all):
``jumper_points.csv`` (exposure, station, point, x, y, sigma: the markers
found, ready for ``[observations] points``), ``ski_lines.csv`` (exposure,
station, line, x, y, sigma: points along each ski, for ``[observations]
lines``), ``tracking.csv`` (every marker of every exposure and station with
its status: ok, lost or ambiguous, and why), ``ski_checks.csv`` (the
left/right check per exposure, swaps corrected), ``ski_flags.csv`` (skis
not found in an image, or left out, and why), ``contact_sheet.png``
(frames with the labels), ``summary.json`` (counts, flags, offsets, the
skis' variance factors, timings;
with ``[track] truth`` also the errors against the truth) and ``log.txt``.
"""

from __future__ import annotations

import json
import logging

from photogram.project.atomic import atomic_write_text

log = logging.getLogger("photogram")

__all__ = ["run", "track_and_write"]


def _write_csv(path, frame, header=None):
    text = frame.to_csv(index=False, float_format="%.4f")
    atomic_write_text(path, (header or "") + text)


def track_and_write(project, output=None):
    """Track the project's videos and write its results folder; returns
    ``(folder, result)`` (:class:`photogram.track.pipeline.TrackResult`)."""
    from pathlib import Path

    from photogram.project.output_policy import project_inputs
    from photogram.project.results_folder import staged_results
    from photogram.track.pipeline import track_project
    from photogram.track.report import contact_sheet

    result = track_project(project)
    folder = Path(output) if output else project.output_folder()
    note = (f"# measured by photogram track from the videos of {project.path.name}; "
            f"sigma in px\n")
    with staged_results(folder, command="track", inputs=project_inputs(project)) as stage:
        _write_csv(stage.path / "jumper_points.csv", result.jumper_points(), note)
        _write_csv(stage.path / "ski_lines.csv", result.ski_lines(), note)
        _write_csv(stage.path / "tracking.csv", result.markers)
        _write_csv(stage.path / "ski_checks.csv", result.ski_checks)
        _write_csv(stage.path / "ski_flags.csv", result.ski_flags)
        contact_sheet(result, stage.path / "contact_sheet.png")
        text = json.dumps(result.summary, indent=1, default=str) + "\n"
        atomic_write_text(stage.path / "summary.json", text)
        atomic_write_text(stage.path / "log.txt", "\n".join(result.log) + "\n")
    return folder, result


def run(project, args=None):
    """Command-line entry: track, write, print one line (and a warning line
    when markers were flagged)."""
    folder, result = track_and_write(project)
    s = result.summary
    if s["flagged_markers"]:
        log.warning("track: %d marker observation(s) flagged (lost or ambiguous), not "
                    "guessed: see tracking.csv", s["flagged_markers"])
    if not getattr(args, "quiet", False):
        print(f"track: {s['exposures']} exposures x {len(s['stations'])} stations, "
              f"{s['markers_found']} of {s['markers_expected']} marker observations, "
              f"{s['ski_lines_found']} of {s['ski_lines_expected']} ski lines, "
              f"{s['swapped_skis']} swap(s) corrected; results in {folder}")
    return 0
