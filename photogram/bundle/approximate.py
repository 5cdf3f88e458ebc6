"""Approximate values for the adjustment when the project lacks some."""

from __future__ import annotations

import numpy as np


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
