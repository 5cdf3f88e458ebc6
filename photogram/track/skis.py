"""Ski lines tracked in synchronized videos (issue 19, item 4).

Per exposure and station the two skis are predicted from the binding
markers (P3 right, P4 left) and the previous exposure's axes in that view,
moved with the bindings (at the first exposure, or after a loss: a search
over directions through the bindings, oriented towards the helmet, then a
grid over the two axes' turns), fitted jointly as two dark bars in a band
around the prediction (:func:`photogram.track.ski_edges.fit_ski_pair`) and
sampled as points along each axis, tail to tip: the ``ski_lines.csv``
observations whose image lines ``photogram intersect`` fits by eq. (C11)
and intersects into 3D ski lines. A first prediction is labelled by the
binding each axis passes closer to; a tracked axis keeps its label unless
the bindings clearly say otherwise (they are 1-3 px apart). The sequence is
tracked forward and then backward; per exposure the three views' results
(forward or backward where they differ) are chosen by the three-view
line-transfer check (:func:`photogram.lines.skis.check_ski_labels`), which
also finds interchanged labels: swaps are corrected (as
:func:`photogram.lines.skis.swap_labels`) and reported. A ski that is not
found (no binding marker, no dark bar, axis far from its binding, seen
apart from the other ski and the body over too little of its length,
outside the image) is flagged, never guessed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from photogram.errors import InputError
from photogram.track.background import frame_gain
from photogram.track.ski_axes import (BarLine, extent_along, noise_sigma, sample_axis,
                                      search_direction)
from photogram.track.ski_edges import best_split, fit_ski_pair
from photogram.track.ski_sequence import sequence_check
from photogram.track.ski_views import _Seen, choose_views

__all__ = ["SkiTracking", "track_skis", "exposure_labels"]

TABLE_COLUMNS = ["exposure", "station", "line", "x", "y", "sigma"]
CHECK_COLUMNS = ["exposure", "status", "swapped", "detail", "check"]
FLAG_COLUMNS = ["exposure", "station", "line", "reason"]


@dataclass
class SkiTracking:
    """Result of :func:`track_skis`.

    Attributes
    ----------
    table : DataFrame
        ``exposure, station, line, x, y, sigma``: points along each ski axis
        (measured pixels, tail to tip; ``sigma`` the a-priori sigma of each
        coordinate, px), the format of ``ski_lines.csv`` plus sigma. Labels
        are after the three-view check (swaps corrected).
    checks : DataFrame
        ``exposure, status, swapped, detail, check``: ``status`` "ok",
        "swapped" (labels interchanged in the stations ``swapped``, corrected
        in ``table``) or "flagged" (the check could not confirm the labels:
        fewer than three views with both skis, no assignment fits, or the
        views disagree without a majority); ``check`` the status of
        :class:`photogram.lines.skis.SkiCheck` and ``detail`` its message.
    flags : DataFrame
        ``exposure, station, line, reason``: skis not found or ambiguous in
        one image (no rows for them in ``table``).
    lines : dict
        ``{(exposure, station): {label: BarLine}}`` the fitted axes.
    sequence : DataFrame or None
        ``station, line, n, s0, scale, outliers`` of the sequence check
        (:func:`photogram.track.ski_sequence.sequence_check`).
    """

    table: pd.DataFrame
    checks: pd.DataFrame
    flags: pd.DataFrame
    lines: dict = field(default_factory=dict)
    sequence: pd.DataFrame | None = None


def exposure_labels(markers: pd.DataFrame, n: int) -> list:
    """The exposure names of the marker table in exposure order: its sorted
    distinct ``exposure`` values, which must be ``n`` (or a subset of
    ``range(n)`` / ``range(1, n + 1)``, the exposure index)."""
    values = sorted(pd.unique(markers["exposure"]))
    if len(values) == n:
        return list(values)
    try:
        ints = {int(v) for v in values}
    except (TypeError, ValueError):
        ints = None
    if ints is not None and ints <= set(range(n)):
        return list(range(n))
    if ints is not None and ints <= set(range(1, n + 1)):
        return list(range(1, n + 1))
    raise InputError(f"ski tracking: the markers name {len(values)} exposures, "
                     f"exposure_frames has {n}", hint="one marker exposure per frame index")


#: image coordinates (the project's convention: the top-left corner of the
#: image at (0, 0), docs/measure.md) minus this are the raster positions the
#: bar fit works in (OpenCV's: pixel centres at integers)
PIXEL_OFFSET = 0.5


def _marker_lookup(markers):
    """Raster positions of the markers found (status ok)."""
    ok = markers["status"].astype(str) == "ok" if "status" in markers else True
    m = markers[ok]
    return {(e, s, p): np.array([x, y], float) - PIXEL_OFFSET
            for e, s, p, x, y in zip(m["exposure"], m["station"], m["marker"], m["x"], m["y"])}


def _initial_search(frame, background, D, bindings, toward, sigma_noise, binding_fraction,
                    width, radius, span_deg, exclude):
    """The initial pair (first exposure or after a loss) from a search over
    directions through the bindings and a grid over the two axes' turns
    (:func:`photogram.track.ski_edges.best_split`), or None."""
    mid = np.mean(bindings, 0)
    u, score = search_direction(D, mid, toward, radius=radius)
    if score < 5 * sigma_noise:
        return None
    back, fwd = extent_along(D, mid, u, 0.5 * score)
    tail = -back
    if tail < 3:
        return None
    # the tip side is often on the suit: its length from the tail's
    tip = max(fwd, tail * (1 - binding_fraction) / binding_fraction)
    pair = [BarLine(b, u, np.array([(mid - b) @ u - tail, (mid - b) @ u + tip]), width,
                    np.nan) for b in bindings]
    return best_split(frame, background, pair, sigma_noise=sigma_noise, span_deg=span_deg,
                      width=width, exclude=exclude)


def _predict(prev, bindings, prev_bindings):
    """The previous exposure's axes moved with their bindings."""
    out = []
    for l, b, pb in zip(prev, bindings, prev_bindings):
        out.append(BarLine(l.point + (b - pb), l.direction.copy(), l.ends.copy(), l.width,
                           l.contrast))
    return out


def _point_sigma(line, pts, floor):
    """A-priori sigma per coordinate of the n points sampled along a fitted
    axis: ``n`` collinear points with sigma ``s`` fix a line whose mean
    variance across, over the points, is ``2 s^2 / n``; matched to the fit's
    (its covariance of angle and shift), with ``floor`` added in quadrature
    (model error)."""
    t = (pts - line.point) @ line.direction
    v = np.mean(line.sigma_across(t) ** 2)
    s = np.sqrt(len(pts) / 2 * v) if np.isfinite(v) else np.nan
    return float(np.hypot(s, floor)) if np.isfinite(s) else float(floor * 10)


def track_skis(frames, backgrounds, cameras, markers, exposure_frames, *,
               skis={"L1": "P3", "L2": "P4"}, ski_length=26.3, binding_fraction=0.43,
               points_per_ski=15, offsets=None, helmet="P1", hip="P2",
               ski_width=1.5, search_radius=15.0, split_deg=8.0,
               track_turn_deg=3.0, max_binding_distance=3.0, min_support=0.15,
               sigma_floor=0.15, marker_mask=4.0, label_margin=1.0, gain=True,
               two_pass=True, check=True, trust_bindings=False, midpoints=None,
               coincide_px=1.0, sequence=True, **fit_options) -> SkiTracking:
    """Track both ski lines through the exposures of synchronized videos.

    Parameters
    ----------
    frames : dict {station: ndarray (F, H, W) uint8}
    backgrounds : dict {station: ndarray (H, W) float}
        Median background of each video.
    cameras : dict {station: ViewCamera}
        Estimated orientation (for the three-view label check).
    markers : DataFrame
        ``exposure, station, marker, x, y, sigma, status, reason`` (marker
        tracker); only rows with status "ok" are used.
    exposure_frames : array_like (E,) or dict {station: array_like (E,)}
        Frame index of each exposure (plus ``offsets[station]`` if given),
        the same for every station or per station.
    skis : dict {line label: binding marker}
        Right ski first by convention (L1 on P3, L2 on P4).
    ski_length : float
        Ski length (object units). Not used by the 2D tracking (the
        prediction from the previous exposure's 3D lines is not
        implemented); kept for that and for the callers' symmetry with
        ``photogram intersect``.
    binding_fraction : float
        Binding position from the tail, as a fraction of the ski length:
        the tip side of the first prediction is ``(1 - f) / f`` times the
        tail side (the tail side is free of the body).
    points_per_ski : int
        Points sampled along each axis.
    offsets : dict {station: int}, optional
        Frame offset of each station.
    helmet, hip : str
        Markers the skis' tips point towards (first prediction).
    ski_width : float
        Initial bar width (px).
    search_radius : float
        Length of the rays of the direction search (px).
    split_deg : float
        After a search, each axis is turned by up to this (deg) to find the
        pair that fits best (the skis' V seen in the image).
    track_turn_deg : float
        Largest turn (deg) of an axis from the previous exposure's.
    min_support : float
        A ski whose fitted bar is seen apart from the other ski (and not
        masked as body) over less than this share of its area is flagged
        as ambiguous.
    max_binding_distance : float
        An axis farther than this (px) from its binding marker is not that
        ski: flagged.
    marker_mask : float
        Radius (px) around every marker left out of the fit (the bright
        marker discs are drawn over the skis).
    sigma_floor : float
        Model error of a sampled point (px), added in quadrature to the
        fit's precision.
    label_margin : float
        A tracked axis takes the other label only if both bindings together
        are closer to the interchanged axes by more than this (px); at a
        first prediction the bindings alone decide.
    gain : bool
        Scale the background by each frame's median brightness ratio to it
        (auto exposure, flicker) before comparing.
    two_pass : bool
        Track forward, then backward from the last exposure's state; per
        exposure the views' results (forward or backward, where they
        differ) are chosen by the three-view check (most views with both
        skis, then the smallest chi-square).
    check : bool
        Run the three-view label check.
    trust_bindings : bool
        True: a swap the three-view ski check finds in a view where both
        binding markers are ok is flagged, not applied (the bindings' labels
        are checked in 3D). Default False: the check's swaps are applied.
        Measured on the rendered normal set (docs/track.md): with True 19
        wrong ski labels, with False 1-7 (the images of the bindings are 1-3
        px apart where the skis cross, so which bar is nearer which binding
        does not tell the labels reliably).
    **fit_options
        Passed to :func:`photogram.track.ski_edges.fit_ski_pair`.

    Returns
    -------
    SkiTracking
    """
    labels = list(skis)
    if len(labels) != 2:
        raise InputError(f"ski tracking: two skis expected, got {labels}")
    bind_names = [skis[lab] for lab in labels]
    offsets = offsets or {}
    stations = list(frames)
    if isinstance(exposure_frames, dict):
        frame_of = {st: np.asarray(exposure_frames[st], dtype=int) + offsets.get(st, 0)
                    for st in stations}
    else:
        ef = np.asarray(exposure_frames, dtype=int)
        frame_of = {st: ef + offsets.get(st, 0) for st in stations}
    E = len(next(iter(frame_of.values())))
    names = exposure_labels(markers, E)
    lookup = _marker_lookup(markers)
    blob_at = {} if midpoints is None else {
        (e, s): np.array([x, y], float) - PIXEL_OFFSET
        for e, s, x, y in zip(midpoints["exposure"], midpoints["station"], midpoints["x"],
                              midpoints["y"]) if np.isfinite(x) and np.isfinite(y)}
    # (station, frame) -> (gain, noise sigma), found once for both passes;
    # the float images themselves are made again when needed (three
    # full-frame float64 images per view: about 0.5 GB kept over a jump)
    prepared = {}

    def _prepared(st, F, fi):
        img = F[fi].astype(float)
        bgd = np.asarray(backgrounds[st], float)
        if (st, fi) not in prepared:
            # brightness of this frame against the background (auto
            # exposure): the median ratio, the jumper a small part of it
            g = frame_gain(img, bgd) if gain else None
            D = (bgd * g if gain else bgd) - img
            prepared[(st, fi)] = (g, noise_sigma(D))
        g, sn = prepared[(st, fi)]
        if gain:
            bgd = bgd * g
        return img, bgd, bgd - img, sn

    def one_image(i, st, prev):
        """Fit both skis in one image; updates ``prev`` (the tracking
        state of the station); returns a _Seen."""
        e = names[i]
        seen = _Seen()
        F = frames[st]
        fi = int(frame_of[st][i])
        if not 0 <= fi < len(F):
            seen.flags.append((None, f"frame {fi} outside the video"))
            prev.pop(st, None)
            return seen
        img, bgd, D, sn = _prepared(st, F, fi)
        bind = [lookup.get((e, st, b)) for b in bind_names]
        from_blob = all(b is None for b in bind) and (e, st) in blob_at
        if from_blob:
            # the bindings' merged blob, not split: where the skis are, not
            # which is which (the labels then come from tracking or the
            # three-view check, or the view is flagged)
            bind = [blob_at[(e, st)]] * 2
        if all(b is None for b in bind):
            seen.flags.append((None, "no binding marker"))
            prev.pop(st, None)
            return seen
        bind = [b if b is not None else bind[1 - k] for k, b in enumerate(bind)]
        toward = lookup.get((e, st, helmet), lookup.get((e, st, hip)))
        discs = [(xy, marker_mask) for (e_, s_, _), xy in lookup.items()
                 if e_ == e and s_ == st]
        opts = dict(fit_options)
        tracked = st in prev
        if tracked:
            initial = _predict(prev[st][0], bind, prev[st][1])
            opts.setdefault("max_turn_deg", track_turn_deg)
        else:
            initial = _initial_search(img, bgd, D, bind, toward, sn, binding_fraction,
                                      ski_width, search_radius, split_deg, discs)
            if initial is None:
                seen.flags.append((None, "no dark bar through the bindings"))
                return seen
        fit = fit_ski_pair(img, bgd, initial, sigma_noise=sn, exclude=discs, **opts)
        if not fit.ok:
            seen.flags.append((None, fit.reason))
            prev.pop(st, None)
            return seen
        lines = list(fit.lines)
        # labels: each axis through its own binding; a tracked axis keeps its
        # label unless the bindings say otherwise by more than label_margin
        # (where the skis nearly coincide the bindings cannot tell them apart)
        dist = np.abs([[l.distance(b)[0] for l in lines] for b in bind])
        better = dist[0, 0] + dist[1, 1] - dist[0, 1] - dist[1, 0]
        if better > (label_margin if tracked else 0.0):
            lines = lines[::-1]
        # labels known: from the binding markers, or kept from a labelled
        # tracked axis; a first prediction from the blob has none
        seen.labelled = not from_blob or (tracked and prev[st][2])
        prev[st] = (lines, bind, seen.labelled)
        seen.lines = lines
        for k, lab in enumerate(labels):
            d = abs(lines[k].distance(bind[k])[0])
            if lines[k].support < min_support:
                seen.flags.append((lab, "ski not seen apart from the other ski and the body "
                                        f"(support {lines[k].support:.2f})"))
                continue
            if d > max_binding_distance:
                seen.flags.append((lab, f"axis {d:.2g} px from binding {bind_names[k]}"))
                continue
            pts = sample_axis(lines[k], points_per_ski, D.shape)
            if len(pts) < 2:
                seen.flags.append((lab, "ski outside the image"))
                continue
            seen.sig[lab] = _point_sigma(lines[k], pts, sigma_floor)
            seen.pts[lab] = pts + PIXEL_OFFSET          # image coordinates from here on
        return seen

    # two passes, forward and backward (the backward one starts from the
    # forward one's last state: the first exposures get a tracked prediction)
    prev: dict = {}
    forward = {(i, st): one_image(i, st, prev) for i in range(E) for st in stations}
    backward = {}
    if two_pass:
        for i in reversed(range(E)):
            for st in stations:
                backward[(i, st)] = one_image(i, st, prev)

    rows, checks, flags, fitted, pending = choose_views(
        names, stations, forward, backward, cameras, labels, bind_names, lookup,
        check=check, trust_bindings=trust_bindings, coincide_px=coincide_px)

    table = pd.DataFrame(rows, columns=TABLE_COLUMNS)
    factors = None
    if sequence and len(table):
        table, seq_flags, factors, _ = sequence_check(table, names, pending=pending)
        flags += seq_flags
    elif pending:
        drop = [(e, s) in pending for e, s in zip(table.exposure, table.station)]
        for (e, s), why in pending.items():
            for lab in table[(table.exposure == e) & (table.station == s)].line.unique():
                flags.append((e, s, lab, f"labels not decided: {why}"))
        table = table[~np.array(drop, bool)].reset_index(drop=True)
    return SkiTracking(table, pd.DataFrame(checks, columns=CHECK_COLUMNS),
                       pd.DataFrame(flags, columns=FLAG_COLUMNS), fitted, factors)
