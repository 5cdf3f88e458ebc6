"""The per-image results of the ski tracker's passes and the label
decisions over the three views (:mod:`photogram.track.skis`): which pass to
take, the three-view check with its own variance factor, the orientation
of its swaps by the labelled views, and how far apart two skis are; and
:func:`choose_views`, which makes these decisions per exposure and keeps
the points (the rows of ``ski_lines.csv`` before the sequence check)."""

from __future__ import annotations

import itertools
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


def choose_views(names, stations, forward, backward, cameras, labels, bind_names, lookup, *,
                 check=True, trust_bindings=False, coincide_px=1.0):
    """Per exposure, the views' results of the tracker's passes taken, their
    labels checked and the points kept (:func:`photogram.track.skis.track_skis`,
    whose parameters these are).

    Among the combinations of the passes' results (forward or backward in
    each view where they differ), those with the most views with both skis
    (then the most skis found) are checked; the one whose best assignment
    fits best is taken. The three-view check's swaps are applied (oriented
    by the labelled views); a view the check saw and did not decide, whose
    skis are apart (or not shown to coincide by the decided views), is left
    to the sequences.

    Parameters
    ----------
    names : list
        The exposure names, in exposure order.
    stations : list
    forward, backward : dict {(exposure index, station): _Seen}
        The two passes' results (``backward`` empty with one pass).
    cameras : dict {station: ViewCamera}
    labels, bind_names : list
        The two skis' labels and their binding markers.
    lookup : dict {(exposure, station, marker): ndarray (2,)}
        The ok markers (raster positions; only which are there is used).
    check, trust_bindings, coincide_px
        As :func:`photogram.track.skis.track_skis`.

    Returns
    -------
    rows : list of (exposure, station, line, x, y, sigma)
    checks : list of (exposure, status, swapped, detail, check)
    flags : list of (exposure, station, line, reason)
    fitted : dict {(exposure, station): {label: BarLine}}
    pending : dict {(exposure, station): why its labels are open}
    """
    rows, checks, flags, fitted = [], [], [], {}
    pending = {}                      # (exposure, station) -> why its labels are open
    for i, e in enumerate(names):
        options = []
        for st in stations:
            f, b = forward[(i, st)], backward.get((i, st))
            options.append([f] if b is None or _same(f, b) else [f, b])
        # the combinations with the most complete views (then found skis)
        # are checked; the one whose best assignment fits best is taken
        combos = [dict(zip(stations, combo)) for combo in itertools.product(*options)]
        counts = [(sum(len(v.pts) == 2 for v in vw.values()), sum(len(v.pts) for v in vw.values()))
                  for vw in combos]
        top = max(counts)
        best = None
        for views, n in zip(combos, counts):
            if n != top:
                continue
            res = _check(views, cameras, labels, e, rescale=False) if check else None
            cost = res.best_cost if isinstance(res, SkiCheck) else np.inf
            if best is None or cost < best[0]:
                best = (cost, views, res)
        _, views, res = best
        if isinstance(res, SkiCheck) and res.status == "inconsistent":
            res = _check(views, cameras, labels, e, first=res)
        by_view = {st: dict(v.pts) for st, v in views.items() if v.pts}
        sig_view = {st: dict(v.sig) for st, v in views.items() if v.pts}
        for st, v in views.items():
            for lab, reason in v.flags:
                for la in ([lab] if lab else labels):
                    flags.append((e, st, la, reason))
            if v.lines is not None:
                fitted[(e, st)] = dict(zip(labels, v.lines))
        status, swapped, detail, raw = "flagged", [], "", ""
        if isinstance(res, SkiCheck):
            raw, detail = res.status, res.message
            # the binding markers were labelled in 3D (three views and the
            # jumper's right): a swap against both of them in a view is
            # conflicting evidence, flagged, not applied
            against = [st for st in (res.swapped if res.status == "swapped" else ())
                       if trust_bindings and all((e, st, b) in lookup for b in bind_names)]
            if against:
                raw, detail = res.status, (res.message + "; not applied: the binding markers "
                                           f"of {', '.join(against)} say otherwise")
            elif res.status in ("ok", "swapped") and not any(
                    views[st].labelled for st in res.stations):
                raw, detail = "unlabelled", (res.message + "; no view has labelled skis "
                                             "(binding markers not split)")
            elif res.status in ("ok", "swapped"):
                flip = _oriented_flips(res, views)
                status = "swapped" if flip else "ok"
                swapped = flip
                for st in swapped:
                    pts = by_view[st]
                    by_view[st] = {labels[0]: pts[labels[1]], labels[1]: pts[labels[0]]}
                    sig_view[st] = dict(zip(labels, [sig_view[st][labels[1]],
                                                     sig_view[st][labels[0]]]))
                    fitted[(e, st)] = dict(zip(labels, views[st].lines[::-1]))
            elif res.status == "ok" or (
                    res.status == "ambiguous" and res.costs["as measured"] <= res.threshold
                    and res.costs["as measured"] - min(res.costs.values()) < res.margin):
                # ambiguous only where a view cannot separate the skis (e.g.
                # they coincide in it): the labels as measured fit as well as any
                status = "ok"
        elif isinstance(res, str):
            raw, detail = "error", res
        elif check:
            n = sum(len(v) == 2 for v in by_view.values())
            detail = f"both skis found in {n} view(s); the check needs 3"
        confirmed = raw in ("ok", "swapped") and status in ("ok", "swapped")
        checked = set(res.stations) - set(res.undecided) \
            if isinstance(res, SkiCheck) and confirmed else set()
        for st, v in by_view.items():
            sep = _separation(views[st].lines)
            in_check = st in res_stations(res)
            undecided = in_check and st not in checked
            # an undecided view's labels do not matter only where the skis
            # coincide in it: its own fit may be one ski twice, so the
            # decided views must show it (ski_views.coincide_confirmed)
            coincide = sep <= coincide_px and not (undecided and not coincide_confirmed(
                res, views, st, cameras, labels, coincide_px))
            if (undecided or not views[st].labelled and not confirmed) and not coincide:
                # the skis are apart in this view (or not shown to coincide),
                # the check saw it and did not decide which is which (or
                # nothing labelled them): the sequences decide, or the view
                # is flagged
                why = ("not decided by the three-view check" if in_check
                       else "binding markers not split, no three-view check")
                apart = (f"the skis {sep:.2g} px apart in this view" if sep > coincide_px else
                         f"the skis {sep:.2g} px apart in this view's fit, not shown to "
                         f"coincide by the other views")
                pending[(e, st)] = f"{why} ({apart})"
            elif not views[st].labelled and not confirmed:
                # skis found where the bindings' blob is, nearly coincident,
                # but no view of the exposure has labelled skis
                for lab in v:
                    flags.append((e, st, lab, "labels unknown (binding markers not split, "
                                              "not confirmed by the three-view check)"))
                continue
            for lab, pts in v.items():
                for x, y in pts:
                    rows.append((e, st, lab, x, y, sig_view[st][lab]))
        checks.append((e, status, ",".join(swapped), detail, raw))
    return rows, checks, flags, fitted, pending
