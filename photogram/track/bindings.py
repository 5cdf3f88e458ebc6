"""The two binding markers split out of one merged blob (issue 19).

The three cameras stand on one side of the hill, so the right and left
binding markers (P3, P4: balls 2.4 dm apart across the jumper, 50-80 m
away) image 1-3 px apart and merge into one blob in most frames; the
marker tracker (:func:`photogram.track.tracks.track_markers`) then flags
both ``ambiguous``. :func:`split_merged_bindings` measures such blobs and,
where the data allow it, gives both markers back with status ``ok``:

1. **Where is the blob?** Per exposure, the marker candidates of every
   view (:func:`photogram.track.markers.detect_markers`) that are not on
   an ``ok`` marker of the table and have at least ``min_flux`` of the
   flux and peak of that image's single markers (gaps of snow and edges
   are fainter) are combined, one candidate (or none) per view. The
   combination seen in the most views (at least two) whose triangulation
   (:func:`photogram.track.rays.triangulate`, view biases removed, see
   4.) reprojects within ``locate_tol`` px in every view, at
   ``hip_distance`` from the hip and behind it along the flight, with the
   smallest RMS residual, is the binding pair; any other such point more
   than ``pair_distance[1]`` from it makes the exposure ambiguous
   ("binding blob not located"). In a view where the pair shows as two
   candidates (within 4 px), their mean is the blob centre.
2. **The spot's shape.** The ``ok`` single markers (the helmet, the hip:
   the same balls, nearly the same distance and motion blur) are fitted
   in the white top-hat of their frame (the grey values above the local
   background, as :mod:`photogram.track.markers`) with one soft
   elliptical disc over a constant, ``A erfc((rho - 1) / w) / 2 + b``
   (``rho`` the elliptical radius of a shape matrix ``Q``: disc, defocus
   and motion blur together); the shape of an image is the median of
   those of its station within ``shape_window`` exposures.
3. **Two spots.** The blob's top-hat in a ``2 half + 1`` px window is
   fitted (batched Levenberg-Marquardt) with two such discs of that shape
   and one amplitude at ``c + d`` and ``c - d`` over a constant, ``c`` and
   ``d`` free. The discs are opaque: the model is their *union*
   ``g1 + g2 - g1 g2``, not the sum (a sum makes overlapping discs look
   too wide and overestimates small separations, by 0.6 px at 0.5 px).
   It starts from the moments: two equal discs have the second moments
   ``Q / 4 + d d^T``, so the excess variance along the major axis gives
   ``|d|``. The point sigmas: the linear propagation of the residual
   scatter (at least the background noise) through the fit, root-sum-
   squared with ``sigma_floor`` (0.15 px: the model is not the rendered
   disc over the suit, boots and skis; the renderer's own figure for an
   isolated marker on the body is up to 0.14 px), and at least the scatter
   of the split track about a local quadratic in time
   (:func:`photogram.track.tracks2d.scatter_sigma`). A separation ``2 |d|``
   below ``min_snr`` (3) of its own sigmas is not measured: the rows stay
   ``ambiguous`` ("separation not measurable").
4. **Labels from geometry**, never a guess. Per exposure, over the views
   that were split, each view has two assignments (which of ``c +- d`` is
   P3). For every combination P3 and P4 are triangulated; its chi-square is
   the sum of squared reprojection residuals over the point sigmas, after
   removing each view's bias (the median residual vector of the ok single
   markers triangulated in three views over the whole jump: a systematic
   error of the orientation). Interchanging P3 and P4 in *every* view
   gives the same chi-square; that choice is made by the side: P3 is the
   jumper's **right** binding, i.e. ``(P3 - P4)`` points along
   ``flight x up`` (world Z up, flight = the 3D velocity of the hip over
   the exposures; :mod:`photogram.jump.definitions`). The best
   combination is accepted only if (a) its chi-square is below the
   ``chi2_quantile`` quantile, (b) the second best combination's
   chi-square exceeds it by ``chi2_margin`` (the assignment is *clearly*
   better than the alternative), (c) ``|P3 - P4|`` is within
   ``pair_distance`` and (d) ``P3 - P4`` is across the flight (angle to the
   flight at least ``min_across_deg``) and its side component is at least
   ``min_side`` of its length. Otherwise all rows of the exposure stay
   ``ambiguous`` with the reason. A single split view cannot be labelled
   by the views (one ray per point).
5. **Continuity in time** (``continuity`` exposures): an exposure left
   with a single split view, or with no clearly better assignment, takes
   the 3D direction of ``P3 - P4`` from the labelled exposures around it
   (interpolated between both sides, or the neighbour at one exposure),
   placed at this exposure's triangulated blob centre and projected into
   each split view; a view's assignment is the one whose separation
   vector points the same way, accepted only within ``arccos(min_cos)``
   of the predicted direction (or its reverse) in every split view and,
   with two or more views, a chi-square below the quantile. The reason
   then says ``"...; labels from the neighbouring exposures"``.

Rows that are split get status ``ok``, reason ``"split from a merged blob
(separation d px)"`` and the sigma of step 3; a row never gets a label the
three views did not support.

The binding midpoint
--------------------
Wherever a blob of the pair was located (split or not), the second
returned table, ``report.midpoints``, holds the blob centre in that view:
``exposure, station, x, y, sigma, split`` -- the image of the **midpoint**
of the two binding markers (the stick model's origin ``O``,
:mod:`photogram.jump.definitions`), with the sigma of the fitted centre
``c``. It is kept out of the marker table on purpose: it is no P3 or P4
observation; a caller may use it as an observation of ``O``.

Measured (tests/test_track_bindings.py; tracker, cameras and truth of the
rendered sets of photogram.simulation.jump_video in one pixel frame):
normal set, 67 of the 67 station-exposures where the tracker flags the
pair merged are split and labelled, the points 0.23 px RMS from the truth
(max 0.68 px), no wrong label, errors over sigmas 0.99 RMS per coordinate;
the midpoints 0.20 px RMS (error/sigma 0.91). The split points are
biased by about -0.14 px in y and the separations mostly underestimated
(by up to 0.4 px in S2), probably by the local background varying under
the blob (boots, skis, the edge of the silhouette): a model of opaque
markers over the opening of the frame (height ``a - open(I)``) halved the
error in S1 and S2 but biased S3 and resolved almost nothing on the
harsh set, so it is not used. Harsh set (not tuned on): 31 of 72 (10
by continuity), 0.37 px RMS, no wrong label, error/sigma 1.5; the rest
stay ambiguous (separation not measurable, views inconsistent, no clear
assignment, a single split view).

Coordinates: photogram's image frame by default (first pixel centre at
(0.5, 0.5), ``pixel_offset=0.5``), as the tracker's; ``pixel_offset=0``
for OpenCV's frame. The table, the cameras and this must agree.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from photogram.errors import InputError
from photogram.track.binding_blobs import shape_near, split_blob, spot_shapes, view_candidates
from photogram.track.binding_labels import (_from_neighbours, _hip_track, _locate, _lone_offsets,
                                            label_pairs)
from photogram.track.binding_table import (  # noqa: F401  (re-exported)
    MIDPOINT_COLUMNS, SPLIT_REASON, SplitReport, _frame_of, finish_table, make_report)
from photogram.track.spots import fit_spot_shape  # noqa: F401  (re-exported)
from photogram.track.two_spots import fit_two_spots  # noqa: F401  (re-exported)

__all__ = ["SplitReport", "split_merged_bindings", "fit_two_spots", "fit_spot_shape",
           "label_pairs", "MIDPOINT_COLUMNS"]

CONTINUITY_NOTE = "; labels from the neighbouring exposures"


def split_merged_bindings(table: pd.DataFrame, frames: dict, backgrounds: dict, cameras: dict,
                          exposure_frames, *, pair=("P3", "P4"), hip: str = "P2",
                          offsets: dict | None = None, pixel_offset: float = 0.5,
                          length_unit: float = 0.1, half: int = 4, tophat: int = 7,
                          locate_tol: float = 1.0, hip_distance=(0.4, 1.6),
                          pair_distance=(0.15, 0.40), min_snr: float = 3.0,
                          sigma_floor: float = 0.15, chi2_quantile: float = 0.999,
                          chi2_margin: float = 9.0, min_across_deg: float = 60.0,
                          min_side: float = 0.5, k_sigma: float = 5.0,
                          min_flux: float = 0.5, shape_window: int = 3,
                          continuity: int = 2, min_cos: float = 0.8, lone_tol: float = 3.0,
                          spot_model: str = "tophat", candidates: dict | None = None):
    """Split the binding markers out of merged blobs (module doc).

    Parameters
    ----------
    table : DataFrame
        The marker table of :func:`photogram.track.tracks.track_markers`
        (``exposure, station, marker, x, y, sigma, status, reason``).
    frames : dict station -> (F, H, W) uint8
    backgrounds : dict station -> Background or (H, W) median image
    cameras : dict station -> ViewCamera
        In the table's image frame.
    exposure_frames : array_like (E,) or dict station -> array_like (E,)
        Frame index of each exposure (in exposure order, as
        :func:`photogram.track.skis.track_skis`), plus ``offsets[station]``.
    pair : (str, str)
        The right and the left binding marker (P3 right, P4 left).
    hip : str
        The marker whose 3D track gives the flight direction and the
        neighbourhood of the bindings.
    offsets : dict, optional
        Added to ``exposure_frames`` per station.
    pixel_offset : float
        Image-frame coordinate of the first pixel's centre (0.5 photogram,
        0 OpenCV).
    length_unit : float
        Metres per length unit of the cameras (0.1: dm).
    half, tophat : int
        Half side of the fitting window; side of the top-hat square (px).
    locate_tol : float
        Largest reprojection residual (px) of the located blob.
    hip_distance : (float, float)
        Plausible distance (m) of the binding midpoint from the hip.
    pair_distance : (float, float)
        Plausible distance (m) between the two bindings.
    min_snr : float
        A separation is measured when above ``min_snr`` of its sigmas.
    sigma_floor : float
        Smallest sigma (px) of a split point.
    chi2_quantile, chi2_margin, min_across_deg, min_side : float
        The label check (:func:`label_pairs`).
    k_sigma : float
        Candidate threshold (:func:`photogram.track.markers.detect_markers`).
    min_flux : float
        A candidate for the pair's blob has at least this fraction of the
        flux and the peak of the single markers of its image.
    shape_window : int
        The spot's shape is the median of the single markers' within this
        many exposures (the same station).
    continuity : int
        Exposures that the views could not label (one split view, or no
        clear assignment) take the direction of ``P3 - P4`` from labelled
        exposures at most this far (both sides, or one side at distance 1);
        0: never.
    min_cos : float
        ... when the measured separation vector is within ``arccos(min_cos)``
        of the predicted one (or its reverse) in every split view.
    candidates : dict station -> list of Candidates, optional
        The marker candidates of every frame, as the marker tracker found
        them (:class:`photogram.track.tracks.TrackResult`, the same
        ``k_sigma`` and pixel convention): not detected again.
    lone_tol : float
        Where one binding of a view is ok and the other not, the ok one
        farther than this (px) from the blob located in 3D (in that view,
        or the projection of its 3D point where that view has no candidate)
        is flagged ambiguous and the view split like the others.
    spot_model : {"tophat", "composite"}
        "tophat": two equal spots over a constant fitted to the white top-hat
        (:func:`photogram.track.two_spots.fit_two_spots`). "composite": two
        opaque spots over the scene behind them (:func:`photogram.track.spots._behind`,
        :func:`photogram.track.two_spots.fit_two_spots_over`). Measured on the
        rendered sets (docs/track.md): the composite model removes the
        top-hat's 0.15 px bias of the normal set (mean error (0.06, -0.15)
        -> (0.03, 0.08) px, 71 pairs both) but on the harsh set it splits
        10 pairs at 0.65 px RMS against the top-hat's 22 at 0.30 px: the
        default stays the top-hat.

    Returns
    -------
    table : DataFrame
        A copy of ``table`` with the resolved rows of the pair ``ok``
        (x, y, sigma, reason "split from a merged blob (separation d px)");
        unresolved rows stay ``ambiguous``, their reason extended by why.
    report : SplitReport
        With ``midpoints``: the images of the binding midpoint.
    """
    need = {"exposure", "station", "marker", "x", "y", "sigma", "status", "reason"}
    if not need <= set(table.columns):
        raise InputError("the marker table needs columns " + ", ".join(sorted(need)))
    right_m, left_m = (str(m) for m in pair)
    stations = [s for s in frames if s in cameras]
    out = table.copy()
    out["reason"] = out["reason"].astype(object)
    when, names = _frame_of(table, exposure_frames, stations, offsets)
    # the rows by (exposure, station, marker): the table's row (attribute
    # access) and its label in ``out``, looked up without pandas masks
    tab = {(r.exposure, r.station, r.marker): r for r in table.itertuples()}
    at = {(r.exposure, r.station, r.marker): r.Index for r in table.itertuples()}

    def row(e, s, m):
        return tab.get((e, s, m))

    # the changes of ``out``, applied in order after the loops (``out`` is
    # not read before; one pandas assignment per column instead of one per
    # row: a row assignment costs ~4 ms)
    updates = []

    def _set(e, s, m, **values):
        i = at.get((e, s, m))
        if i is not None:
            updates.append((i, values))

    # per exposure: the hip in 3D (the flight direction) and the view biases
    cams = [cameras[s] for s in stations]
    singles = [m for m in pd.unique(table["marker"]) if m not in (right_m, left_m)]
    ok = table[table.status == "ok"]
    singles_at = {k: g[["x", "y"]].to_numpy(float) for k, g in
                  ok[ok.marker.isin(singles)].groupby(["exposure", "station"])}
    sidx = {s: i for i, s in enumerate(stations)}
    eidx = {e: i for i, e in enumerate(names)}
    bias, X_hip, vel = _hip_track(cams, ok, stations, names, singles, hip)
    up = np.array([0.0, 0.0, 1.0])

    # the spot of a single marker per station and exposure (module doc,
    # step 2): fitted to the ok single markers of every exposure frame
    sing_ok = ok[ok.marker.isin(singles) & ok.station.isin(stations) & ok.exposure.isin(names)]
    shape_at = spot_shapes(frames, sing_ok, stations, when, eidx, half=half, tophat=tophat,
                           pixel_offset=pixel_offset)

    blobs, labels, mids = [], [], []
    pending = {}                                   # exposure -> (split views, located)
    X_pair = np.full((len(names), 2, 3), np.nan)   # labelled P3, P4 in 3D

    def _write(e, split_views, assign, note):
        """The split points of exposure ``e`` under their labels."""
        for (s, p, sg_, sep), a in zip(split_views, assign):
            for m, q in ((right_m, p[a]), (left_m, p[1 - a])):
                _set(e, s, m, x=q[0], y=q[1], sigma=sg_, status="ok",
                     reason=SPLIT_REASON.format(sep) + note)
            counts["resolved"] += 1
            notes.pop((e, s), None)
    counts = {"flagged": 0, "located": 0, "split": 0, "resolved": 0, "ambiguous": 0}
    notes = {}                       # (e, s) -> why not resolved

    for e in names:
        flagged = []
        for s in stations:
            a, b = row(e, s, right_m), row(e, s, left_m)
            # both flagged: one merged blob (ambiguous), or lost by the 2D
            # tracker (no seed, the track ended) and found here in 3D
            if a is not None and b is not None and a.status != "ok" and b.status != "ok":
                flagged.append(s)
        if not flagged:
            continue
        counts["flagged"] += len(flagged)
        # 1. locate the blob in 3D from candidates of every view
        per_view, imgs = view_candidates(e, stations, when, frames, backgrounds, row,
                                         (right_m, left_m), singles_at, candidates,
                                         k_sigma=k_sigma, pixel_offset=pixel_offset,
                                         min_flux=min_flux)
        found = _locate(cams, per_view, bias, X_hip[eidx[e]], vel[eidx[e]],
                        locate_tol, hip_distance, length_unit)
        if not isinstance(found, str):
            # a view where one binding is ok and the other not: the ok one
            # must be on the blob located in 3D from every view (a seed that
            # snapped to the wrong blob is not seen by the 3D check, the
            # other views' bindings being merged)
            pair_rows = [None if s in flagged else {m: row(e, s, m) for m in (right_m, left_m)}
                         for s in stations]
            for s, m, off in _lone_offsets(found, cams, bias, stations, pair_rows):
                if off > lone_tol:
                    _set(e, s, m, status="ambiguous",
                         reason=f"{off:.1f} px from the bindings' blob located in 3D from "
                                "the views")
                    flagged.append(s)
                    counts["flagged"] += 1
        if isinstance(found, str):
            for s in flagged:
                notes[(e, s)] = found
            continue
        # 2-3. shapes and two-spot fits in the flagged views where located
        split_views = []
        for s in flagged:
            i = sidx[s]
            centre = found[i]
            if not np.all(np.isfinite(centre)):
                notes[(e, s)] = "binding blob not located in this view"
                continue
            counts["located"] += 1
            fr, noise, med = imgs[s]
            shape = shape_near(shape_at[s], eidx[e], shape_window)
            if not np.isfinite(shape).all():
                notes[(e, s)] = "no single marker to take the spot's shape from"
                mids.append((e, s, centre[0], centre[1], np.nan, False))
                continue
            fit, c, csig, measurable, outcome = split_blob(
                fr, noise, med, centre, shape, spot_model=spot_model, half=half, tophat=tophat,
                pixel_offset=pixel_offset, sigma_floor=sigma_floor, min_snr=min_snr)
            sep, ssig = fit["separation"][0], fit["sep_sigma"][0]
            blobs.append((e, s, c[0], c[1], fit["half_sep"][0][0], fit["half_sep"][0][1], sep,
                          ssig, fit["sigma"][0], outcome))
            mids.append((e, s, c[0], c[1], csig, bool(measurable)))
            if measurable:
                counts["split"] += 1
                split_views.append((s, fit["points"][0], fit["sigma"][0], sep))
            else:
                notes[(e, s)] = outcome
        # 4. labels from the views jointly
        if len(split_views) < 2:
            for s, *_ in split_views:
                notes[(e, s)] = (f"split in {len(split_views)} view only: "
                                 "left/right needs two views")
            if split_views:
                labels.append((e, len(split_views), np.nan, np.nan, np.nan, np.nan,
                               "needs two split views"))
                pending[e] = (split_views, found)
            continue
        vcams = [cameras[s] for s, *_ in split_views]
        pts = np.array([p - bias[sidx[s]] for s, p, *_ in split_views])
        sg = np.array([sg for _, _, sg, _ in split_views])
        v = vel[eidx[e]]
        right = np.cross(v, up) if np.all(np.isfinite(v)) else None
        lab = label_pairs(vcams, pts, sg, right=right, up=up, length_unit=length_unit,
                          pair_distance=pair_distance, min_across_deg=min_across_deg,
                          min_side=min_side, chi2_quantile=chi2_quantile,
                          chi2_margin=chi2_margin)
        labels.append((e, len(split_views), lab["chi2"], lab["chi2_second"], lab["distance"],
                       lab["across_deg"], "ok" if lab["ok"] else lab["reason"]))
        if not lab["ok"]:
            for s, *_ in split_views:
                notes[(e, s)] = lab["reason"]
            if lab["reason"].startswith("assignment not clear"):
                pending[e] = (split_views, found)
            continue
        X_pair[eidx[e]] = lab["X"]
        _write(e, split_views, lab["assign"], "")
    # 5. continuity in time: an exposure whose views could not decide
    # (one split view, or no clear assignment) takes the direction of
    # P3 - P4 from the 3D pairs of its labelled neighbours
    if continuity:
        for e, (split_views, found) in pending.items():
            lab = _from_neighbours(e, eidx[e], split_views, found, X_pair, bias, sidx, cameras,
                                   cams, continuity, min_cos, chi2_quantile)
            labels.append((e, len(split_views), lab["chi2"], np.nan, np.nan, np.nan,
                           "ok (continuity)" if lab["ok"] else lab["reason"]))
            if lab["ok"]:
                _write(e, split_views, lab["assign"], CONTINUITY_NOTE)
            else:
                for s, *_ in split_views:
                    notes[(e, s)] = notes.get((e, s), "") + "; " + lab["reason"]
    finish_table(out, updates, notes, names, eidx, (right_m, left_m))
    report = make_report(mids, blobs, labels, counts)
    return out, report
