"""The per-image results of the ski tracker's passes and the label
decisions over the three views (:mod:`photogram.track.skis`): which pass to
take, the three-view check with its own variance factor, the orientation
of its swaps by the labelled views, and how far apart two skis are."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from scipy.special import ndtri       # normal quantile (scipy.stats is slow to import)

from photogram.errors import GeometryError, InputError
from photogram.lines.plucker import project_line
from photogram.lines.skis import SkiCheck, check_ski_labels
from photogram.lines.space_line import intersect_line
from photogram.lines.views import fit_view_line

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


def _best_interchanged(res) -> set:
    """The stations the best assignment of the three-view check ``res``
    interchanges (relative to the others; its cost names, "as measured"
    or "swap S1+S3")."""
    best = min(res.costs, key=res.costs.get)
    return set() if best == "as measured" else set(best[len("swap "):].split("+"))


def coincide_confirmed(res, views, station, cameras, labels, coincide_px,
                       alpha=0.001) -> bool:
    """Whether the views the three-view check ``res`` decided show that the
    two skis coincide within ``coincide_px`` in ``station`` (a view the
    check could not decide), so that its labels do not matter.

    The two skis' 3D lines from the decided views (two at least, labelled
    as the check's best assignment; which ski is which does not matter
    here) are projected into ``station``; their separation at the ends of
    its measured axes, plus ``ndtri(1 - alpha)`` times its sigma
    (propagated from the lines' covariances), must stay within
    ``coincide_px``. The view's own fit is no evidence of this: a pair fit
    whose two bars both lie on one ski (the other a stub of it) is
    coincident in the image while the skis are apart. Without such
    evidence (fewer than two decided views, a degenerate geometry) False.
    """
    others = [n for n in res.stations if n not in res.undecided and n != station]
    pts = views[station].pts
    if len(others) < 2 or any(lab not in pts for lab in labels):
        return False
    flips = _best_interchanged(res)
    cam = {n: cameras[n] for n in others}
    projected = []
    try:
        for ski in (0, 1):
            img = {}
            for n in others:
                lab = labels[ski ^ (n in flips)]
                img[n] = fit_view_line(views[n].pts[lab], cameras[n], views[n].sig[lab],
                                       label=lab)
            X = intersect_line(img, cam, label=labels[ski])
            l, G = project_line(X.line, cameras[station], jacobian=True)
            projected.append((l, G @ X.line.covariance @ G.T))
    except GeometryError:
        return False
    (l1, C1), (l2, C2) = projected
    if l1[:2] @ l2[:2] < 0:                 # the same orientation: d1 - d2 is the gap
        l2 = -l2
    ends = np.vstack([pts[lab][[0, -1]] for lab in labels])
    E = np.column_stack([cameras[station].ideal(ends), np.ones(len(ends))])
    gap = np.abs(E @ (l1 - l2))
    sigma = np.sqrt(np.einsum("ij,jk,ik->i", E, C1 + C2, E))
    return bool(np.all(gap + ndtri(1 - alpha) * sigma <= coincide_px))


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
