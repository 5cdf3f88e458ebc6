"""3D lines from measured image points: steps A and B (two-step,
:func:`photogram.lines.space_line.intersect_line` after
:func:`photogram.lines.fit_view_line`) or the one-step solution
(:func:`photogram.lines.one_step.intersect_line_one_step`). Above both
modules (the one-step solution builds on the two-step one's pieces), so
that neither imports the other's caller."""

from __future__ import annotations

from photogram.errors import InputError
from photogram.lines.one_step import intersect_line_one_step
from photogram.lines.space_line import LineIntersection, _check_count, _sigma_of, intersect_line
from photogram.lines.views import fit_view_line

__all__ = ["intersect_line_from_points"]


def intersect_line_from_points(points_by_view, cameras, sigma=1.0, *, label: str | None = None,
                               method: str = "two-step", **kwargs) -> LineIntersection:
    """Steps A and B (``method="two-step"``: fit each image line with
    :func:`fit_view_line`, then :func:`intersect_line`) or the one-step
    solution (``"one-step"``, :func:`intersect_line_one_step`) from measured
    points ``{station: (n_j, 2)}``."""
    _check_count(points_by_view, label)
    if method == "one-step":
        return intersect_line_one_step(points_by_view, cameras, sigma, label=label, **kwargs)
    if method != "two-step":
        raise InputError(f"unknown method {method!r}", hint='use "two-step" or "one-step"')
    missing = [n for n in points_by_view if n not in cameras]
    if missing:
        raise InputError(f"no camera (orientation) for station(s) {', '.join(missing)}")
    lines = {n: fit_view_line(xy, cameras[n], _sigma_of(sigma, n, len(xy)), label=label)
             for n, xy in points_by_view.items()}
    return intersect_line(lines, cameras, label=label, **kwargs)
