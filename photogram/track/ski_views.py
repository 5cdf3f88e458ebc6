"""The per-image results of the ski tracker's passes and the label
decisions over the three views (:mod:`photogram.track.skis`): which pass to
take, the three-view check with its own variance factor, the orientation
of its swaps by the labelled views, and how far apart two skis are."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.lines.skis import SkiCheck, check_ski_labels

__all__ = []


@dataclass
class _Seen:
    """One image in one tracking pass: the axes (label order), the sampled
    points and their sigma per label, and flags (label or None, reason)."""

    lines: list | None = None
    labelled: bool = True
    pts: dict = field(default_factory=dict)
    sig: dict = field(default_factory=dict)
    flags: list = field(default_factory=list)


def res_stations(res) -> list:
    """The stations of a three-view check result (none for no result)."""
    return list(res.stations) if isinstance(res, SkiCheck) else []


def _separation(lines) -> float:
    """Largest distance (px) of one fitted axis' ends from the other axis:
    how far apart the two skis are in the image (0 without both)."""
    if lines is None or len(lines) != 2:
        return 0.0
    a, b = lines
    return float(max(np.abs(a.distance(np.array([b.tail, b.tip]))).max(),
                     np.abs(b.distance(np.array([a.tail, a.tip]))).max()))


def _oriented_flips(res, views) -> list:
    """The stations whose labels the three-view check ``res`` ("ok" or
    "swapped") interchanges, oriented by the views with labelled skis: the
    check finds which views agree, not which ski is the right one (a swap
    of every view fits as well), so where most labelled views would be
    interchanged the complement is interchanged instead."""
    flipped = set(res.swapped) if res.status == "swapped" else set()
    labelled = [st for st in res.stations if views[st].labelled]
    if sum(st in flipped for st in labelled) * 2 > len(labelled):
        flipped = set(res.stations) - flipped
    return [st for st in res.stations if st in flipped]


def _same(a, b, tol_deg=0.02, tol_px=0.05):
    """Two passes found the same axes (and the same skis) in an image."""
    if set(a.pts) != set(b.pts) or [f[1] for f in a.flags] != [f[1] for f in b.flags]:
        return False
    for lab in a.pts:
        d = a.pts[lab] - b.pts[lab]
        if np.abs(d).max() > tol_px:
            return False
    return True


def _check(views, cameras, labels, exposure, max_s0=10.0, rescale=True, first=None):
    """The three-view label check of the views' points (SkiCheck), None
    when fewer than three views have both skis, or the error message. Where
    no assignment fits within the points' sigmas, the check is repeated
    with the sigmas scaled by the best assignment's ``s0`` (at most
    ``max_s0``): the labels are then decided by how clearly the best
    assignment beats the others at that noise level (``rescale=False``:
    not repeated; ``first``: the check's result without rescaling, when
    known; ``best_cost`` is the best assignment's chi-square in the points'
    own sigmas either way)."""
    complete = [st for st, v in views.items() if len(v.pts) == 2]
    if len(complete) < 3:
        return None
    pts = {st: views[st].pts for st in complete}
    sig = {st: float(np.mean(list(views[st].sig.values()))) for st in complete}
    try:
        res = first if first is not None else check_ski_labels(
            pts, cameras, sig, labels=tuple(labels), exposure=exposure, fix=True,
            transfers=False)
        best_cost = min(res.costs.values())
        if rescale and res.status == "inconsistent":
            # the points' sigmas describe the image fit, not the estimated
            # orientation between the views: the chi-squares in units of the
            # best assignment's own (a posteriori variance factor s0^2 =
            # chi2 / dof, as a bundle's sigma0), the decision on the leads
            s0 = float(np.sqrt(min(res.costs.values()) / res.dof))
            if s0 <= max_s0:
                res = check_ski_labels(pts, cameras, {st: v * s0 for st, v in sig.items()},
                                       labels=tuple(labels), exposure=exposure, fix=True,
                                       transfers=False)
                res.message += f" (point sigmas scaled by s0 = {s0:.2g})"
        res.best_cost = best_cost            # in the points' own sigmas
        return res
    except (GeometryError, InputError) as exc:
        return str(exc)
