"""The left/right ski label check over three (or more) views.

With three (or more) views the labels L1/L2 of the two skis must be
consistent: the 3D line of L1 from all views has a small chi-square
(``2 k - 4`` degrees of freedom), while a ski labelled L1 in one view and L2
in the others gives planes that do not meet in one line. Every assignment
(labels as measured, or interchanged in one set of views) is scored by the
sum of the two skis' chi-squares; the smallest wins if it beats the runner-up
by a margin (by default the chi-square quantile of the test level). Per
view, the transfer from the other views (angle, distances of the measured
segment's end points from the transferred line) says where and how large
the disagreement is.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy.special import chdtri      # chi-square quantile (scipy.stats is slow to import)

from photogram.errors import GeometryError, InputError
from photogram.lines.batch import intersect_lines_full
from photogram.lines.plucker import SpaceLine, project_line
from photogram.lines.space_line import intersect_line
from photogram.lines.transfer import compare_lines
from photogram.lines.views import fit_view_line

__all__ = ["TransferCheck", "SkiCheck", "check_ski_labels", "check_ski_sequence",
           "swap_labels"]


@dataclass
class TransferCheck:
    """Transfer of one ski into one view from the other views."""

    station: str
    label: str
    from_stations: tuple
    angle_deg: float
    distances: np.ndarray
    chi2: float


@dataclass(eq=False)
class SkiCheck:
    """Result of :func:`check_ski_labels`.

    Attributes
    ----------
    status : str
        ``"ok"`` (labels consistent in all stations), ``"swapped"`` (labels
        interchanged in ``swapped``, relative to the majority of the
        stations that separate the skis), ``"ambiguous"`` (some station
        cannot separate the skis, e.g. it sees the V edge-on, and nothing
        is swapped among the others, or the others disagree without a
        majority) or ``"inconsistent"`` (no assignment fits: a bad
        measurement, sigma or orientation).
    swapped : list of str
        Stations whose labels are interchanged (empty unless "swapped").
    undecided : list of str
        Stations where interchanging the labels alone changes the cost by
        less than ``margin``.
    costs : dict {str: float}
        Sum of the two skis' chi-squares per assignment (``"as measured"``,
        ``"swap S2"``, ...).
    dof : int
        Degrees of freedom of each cost.
    threshold : float
        Chi-square quantile an acceptable assignment must stay below.
    margin : float
        Required lead of the winner over the runner-up.
    transfer : list of TransferCheck
        Per station and ski, as measured.
    transfer_fixed : list of TransferCheck
        The same after interchanging (only for "swapped").
    corrected : dict or None
        ``lines_by_view`` with the labels fixed (only with ``fix=True``).
    message : str
    """

    exposure: object
    labels: tuple
    stations: list
    status: str
    swapped: list
    costs: dict
    dof: int
    threshold: float
    margin: float
    transfer: list
    transfer_fixed: list = field(default_factory=list)
    undecided: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    corrected: dict | None = None
    message: str = ""


def _fit_all(lines_by_view, cameras, sigma, labels, stations):
    out = {}
    for n in stations:
        s = sigma.get(n, 1.0) if isinstance(sigma, dict) else sigma
        out[n] = {lab: fit_view_line(lines_by_view[n][lab], cameras[n], s, label=lab)
                  for lab in labels}
    return out


def _assignment(fitted, stations, labels, flips, ski):
    """Image lines of ski ``ski`` (0/1) under the flips (0/1 per station)."""
    return {n: fitted[n][labels[ski ^ f]] for n, f in zip(stations, flips)}


# scoring needs a few digits of chi2: wrong assignments converge slowly
_FAST = {"strict": False, "max_iterations": 12, "tol": 1e-7}
_FAST_BATCH = {"max_iterations": 12, "tol": 1e-7}


def _cost(fitted, stations, labels, flips, cameras):
    total = 0.0
    for ski in (0, 1):
        try:
            X = intersect_line(_assignment(fitted, stations, labels, flips, ski), cameras,
                               label=labels[ski], **_FAST)
        except GeometryError:
            return np.inf
        total += X.chi2
    return total


def _batch(groups, cameras):
    """The 3D lines of several groups of image lines (``[{station: ImageLine}]``,
    the same number of views each) in one call of the estimator of
    :func:`intersect_line` with the ski check's settings; each line exactly
    what :func:`intersect_line` gives for its group alone (the batch
    evaluates every line by itself). None where the normal equations of
    any line are singular (the caller then takes one group at a time, which
    names the failing one)."""
    R = np.array([[cameras[n].R for n in g] for g in groups])
    X0 = np.array([[cameras[n].X0 for n in g] for g in groups])
    c = np.array([[cameras[n].c for n in g] for g in groups], dtype=float)
    l = np.array([[line.homogeneous for line in g.values()] for g in groups])
    cov_l = np.array([[line.cov_homogeneous for line in g.values()] for g in groups])
    ends = np.array([[line.end_points for line in g.values()] for g in groups])
    try:
        return intersect_lines_full(l, cov_l, ends, R, X0, c, **_FAST_BATCH)
    except GeometryError:
        return None


def _costs(fitted, stations, labels, all_flips, cameras):
    """:func:`_cost` of every assignment in ``all_flips``, all lines in one
    batch (the same numbers)."""
    groups = [_assignment(fitted, stations, labels, flips, ski)
              for flips in all_flips for ski in (0, 1)]
    out = _batch(groups, cameras)
    if out is None:
        return [_cost(fitted, stations, labels, flips, cameras) for flips in all_flips]
    return [0.0 + float(out.chi2[2 * i]) + float(out.chi2[2 * i + 1])
            for i in range(len(all_flips))]


def _transfers(fitted, stations, labels, flips, cameras):
    """Per station and ski, the line of the other stations transferred into
    it (:class:`TransferCheck`): the lines of all stations and skis in one
    batch (the same numbers as :func:`_transfers_one` by one)."""
    groups, measured = [], []
    for n in stations:
        for ski in (0, 1):
            lines = _assignment(fitted, stations, labels, flips, ski)
            measured.append(lines.pop(n))
            groups.append(lines)
    out = _batch(groups, cameras)
    if out is None:
        return _transfers_one(fitted, stations, labels, flips, cameras)
    checks = []
    for j, n in enumerate(stations):
        others = tuple(m for m in stations if m != n)
        for ski in (0, 1):
            i = 2 * j + ski
            try:
                line = SpaceLine(out.P[i], out.D[i], covariance=out.cov[i], label=labels[ski])
                l, G = project_line(line, cameras[n], jacobian=True)
                cmp = compare_lines(l, measured[i], G @ line.covariance @ G.T)
                checks.append(TransferCheck(n, labels[ski ^ flips[j]], others,
                                            float(np.degrees(cmp.angle)), cmp.distances,
                                            cmp.chi2))
            except GeometryError:
                checks.append(TransferCheck(n, labels[ski ^ flips[j]], others,
                                            float("nan"), np.full(2, np.nan), float("nan")))
    return checks


def _transfers_one(fitted, stations, labels, flips, cameras):
    out = []
    for j, n in enumerate(stations):
        others = [m for m in stations if m != n]
        for ski in (0, 1):
            lines = _assignment(fitted, stations, labels, flips, ski)
            measured = lines.pop(n)
            try:
                X = intersect_line(lines, cameras, label=labels[ski], **_FAST)
                l, G = project_line(X.line, cameras[n], jacobian=True)
                cmp = compare_lines(l, measured, G @ X.line.covariance @ G.T)
                out.append(TransferCheck(n, labels[ski ^ flips[j]], tuple(others),
                                         float(np.degrees(cmp.angle)), cmp.distances,
                                         cmp.chi2))
            except GeometryError:
                out.append(TransferCheck(n, labels[ski ^ flips[j]], tuple(others),
                                         float("nan"), np.full(2, np.nan), float("nan")))
    return out


def _name(swapped):
    return "as measured" if not swapped else "swap " + "+".join(swapped)


def check_ski_labels(lines_by_view, cameras, sigma=1.0, *, labels=None, exposure=None,
                     alpha: float = 0.001, margin: float | None = None,
                     fix: bool = False, transfers: bool = True) -> SkiCheck:
    """Detect interchanged left/right ski labels in one exposure.

    Parameters
    ----------
    lines_by_view : dict {station: {label: array (n, 2)}}
        Measured image points along each ski (two labels, e.g. "L1", "L2").
    cameras : dict {station: ViewCamera}
    sigma : float or dict {station: float}
        A-priori sigma of the measured points (image units).
    labels : pair of str, optional
        The two ski labels (default: the two labels found).
    exposure : optional
        Name of the exposure, for the message.
    alpha : float
        Test level: an acceptable assignment has a cost below the
        ``1 - alpha`` chi-square quantile.
    margin : float, optional
        Lead the winning assignment needs over the runner-up (default: that
        quantile).
    fix : bool
        Also return the corrected measurements (:func:`swap_labels`).
    transfers : bool
        Compute the transferred lines of the report (``transfer``,
        ``transfer_fixed``); False leaves them empty (a caller that needs
        the decision only, e.g. the video tracker's many checks).

    Returns
    -------
    SkiCheck

    Raises
    ------
    InputError
        Not exactly two labels, or a station without a camera.
    GeometryError
        Fewer than three stations with both skis.
    """
    if labels is None:
        found = list(dict.fromkeys(lab for v in lines_by_view.values() for lab in v))
        if len(found) != 2:
            raise InputError(f"ski check: expected two ski labels, found {found}",
                             hint="pass labels=(left, right)")
        labels = tuple(found)
    labels = tuple(labels)
    where = f"exposure {exposure}: " if exposure is not None else ""
    stations = [n for n, v in lines_by_view.items() if all(lab in v for lab in labels)]
    skipped = [n for n in lines_by_view if n not in stations]
    missing = [n for n in stations if n not in cameras]
    if missing:
        raise InputError(f"{where}no camera (orientation) for station(s) {', '.join(missing)}")
    k = len(stations)
    if k < 3:
        raise GeometryError(
            f"{where}both skis ({labels[0]}, {labels[1]}) are measured in {k} image"
            f"{'' if k == 1 else 's'}{' (' + ', '.join(stations) + ')' if k else ''}; "
            f"the label check needs at least 3 (two images always agree)",
            hint="measure both skis in a third image")
    fitted = _fit_all(lines_by_view, cameras, sigma, labels, stations)
    dof = 2 * (2 * k - 4)
    threshold = float(chdtri(dof, alpha))
    margin = threshold if margin is None else float(margin)

    by_flips, costs = {}, {}
    all_flips = [(0,) + rest for rest in itertools.product((0, 1), repeat=k - 1)]
    for flips, c in zip(all_flips, _costs(fitted, stations, labels, all_flips, cameras)):
        by_flips[flips] = c
        sw = [n for n, f in zip(stations, flips) if f]
        if len(sw) > k - len(sw):          # the same assignment, fewer swaps
            sw = [n for n, f in zip(stations, flips) if not f]
        costs[_name(sw)] = by_flips[flips]

    def cost(f):
        return by_flips[f if f[0] == 0 else tuple(1 - x for x in f)]

    best = min(by_flips, key=by_flips.get)
    c_best = by_flips[best]
    # a station is decided if interchanging its labels alone costs the margin
    lead = {n: cost(tuple(f ^ (i == j) for i, f in enumerate(best))) - c_best
            for j, n in enumerate(stations)}
    undecided = [n for n in stations if lead[n] < margin]
    decided = [j for j, n in enumerate(stations) if n not in undecided]
    n_flip = sum(best[j] for j in decided)
    if n_flip > len(decided) - n_flip:     # orient: fewest swaps among the decided
        best = tuple(1 - f for f in best)
        n_flip = len(decided) - n_flip
    tie = 0 < n_flip == len(decided) - n_flip
    swapped = [stations[j] for j in decided if best[j]]
    given = costs["as measured"]
    lab = f"{labels[0]}/{labels[1]}"
    note = (f"; {', '.join(undecided)} cannot separate the skis (lead below {margin:.3g})"
            if undecided else "")
    if c_best > threshold:
        status = "inconsistent"
        msg = (f"{where}no assignment of {lab} fits (best chi2 {c_best:.3g} > "
               f"{threshold:.3g}, {dof} dof): check the measurements, sigma and orientation")
    elif tie or not decided:
        status = "ambiguous"
        msg = (f"{where}labels {lab} cannot be decided: "
               + (f"{' and '.join(stations[j] for j in decided)} disagree with no majority"
                  if tie else "no station separates the skis") + note)
        swapped = []
    elif swapped:
        status = "swapped"
        msg = (f"{where}labels {lab} interchanged in {', '.join(swapped)} (chi2 "
               f"{c_best:.3g} after swapping, {given:.3g} as measured, {dof} dof){note}")
    elif undecided:
        status = "ambiguous"
        msg = (f"{where}labels {lab} consistent in "
               f"{', '.join(stations[j] for j in decided)} (chi2 {given:.3g}){note}")
    else:
        status = "ok"
        alt = min((c for name, c in costs.items() if name != "as measured"), default=np.inf)
        msg = (f"{where}labels {lab} consistent in {', '.join(stations)} (chi2 "
               f"{given:.3g}, {dof} dof; best alternative {alt:.3g})")
    result = SkiCheck(
        exposure=exposure, labels=labels, stations=stations, status=status, swapped=swapped,
        costs=costs, dof=dof, threshold=threshold, margin=margin,
        transfer=_transfers(fitted, stations, labels, (0,) * k, cameras) if transfers else [],
        undecided=undecided, skipped=skipped, message=msg)
    if status == "swapped" and transfers:
        flips = tuple(1 if n in swapped else 0 for n in stations)
        result.transfer_fixed = _transfers(fitted, stations, labels, flips, cameras)
    if fix:
        result.corrected = swap_labels(lines_by_view, result)
    return result


def check_ski_sequence(exposures, cameras, sigma=1.0, **kwargs) -> dict:
    """:func:`check_ski_labels` for ``{exposure: lines_by_view}``; returns
    ``{exposure: SkiCheck}``."""
    return {e: check_ski_labels(v, cameras, sigma, exposure=e, **kwargs)
            for e, v in exposures.items()}


def swap_labels(lines_by_view, which, labels=None) -> dict:
    """A copy of ``lines_by_view`` with the two ski labels interchanged in
    some stations.

    Parameters
    ----------
    lines_by_view : dict {station: {label: points}}
    which : SkiCheck, str or iterable of str
        A check result (its ``swapped`` stations; nothing unless its status
        is "swapped"), one station or several.
    labels : pair of str, optional
        Default: the check's labels, or the two labels found.
    """
    if isinstance(which, SkiCheck):
        labels = labels or which.labels
        stations = list(which.swapped)
    elif isinstance(which, str):
        stations = [which]
    else:
        stations = list(which)
    if labels is None:
        found = list(dict.fromkeys(lab for v in lines_by_view.values() for lab in v))
        if len(found) != 2:
            raise InputError(f"swap_labels: expected two labels, found {found}",
                             hint="pass labels=(left, right)")
        labels = found
    a, b = labels
    unknown = [n for n in stations if n not in lines_by_view]
    if unknown:
        raise InputError(f"swap_labels: unknown station(s) {', '.join(unknown)}")
    out = {}
    for n, v in lines_by_view.items():
        v = dict(v)
        if n in stations:
            va, vb = v.pop(a, None), v.pop(b, None)
            if vb is not None:
                v[a] = vb
            if va is not None:
                v[b] = va
        out[n] = v
    return out
