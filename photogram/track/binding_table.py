"""The marker table's side of the bindings' split
(:mod:`photogram.track.bindings`): its report (:class:`SplitReport`,
:data:`MIDPOINT_COLUMNS`), the frame of every exposure and station, the
changes of the table collected in the loops and applied per column, the
split tracks' sigma floor (their own scatter in time) and the reasons of
the rows left ambiguous."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from photogram.track.skis import exposure_labels
from photogram.track.tracks2d import scatter_sigma

__all__ = ["SplitReport", "MIDPOINT_COLUMNS"]

#: columns of ``SplitReport.midpoints``
MIDPOINT_COLUMNS = ["exposure", "station", "x", "y", "sigma", "split"]
SPLIT_REASON = "split from a merged blob (separation {:.2f} px)"


@dataclass
class SplitReport:
    """What :func:`photogram.track.bindings.split_merged_bindings` did.

    Attributes
    ----------
    midpoints : DataFrame
        :data:`MIDPOINT_COLUMNS`: per exposure and station where the pair's
        blob was located, its centre: the image of the binding midpoint
        (:mod:`photogram.track.bindings`), ``split`` True where the blob was
        split into two.
    blobs : DataFrame
        Per located blob: exposure, station, x, y (centre), dx, dy (half
        separation vector ``d``), separation (px), sep_sigma, sigma (of
        each split point), outcome (``"split"``, or why not).
    labels : DataFrame
        Per exposure with split views: exposure, views, chi2, chi2_second,
        distance (|P3 - P4|, m), across_deg, outcome (``"ok"`` or why
        not); an exposure handed to the continuity step has a second row
        (outcome ``"ok (continuity)"`` or why not).
    counts : dict
        flagged (station-exposures where the pair was merged/ambiguous),
        located, split (separation measured), resolved (labelled ok),
        ambiguous (left ambiguous).
    """

    midpoints: pd.DataFrame
    blobs: pd.DataFrame
    labels: pd.DataFrame
    counts: dict = field(default_factory=dict)



def _frame_of(table, exposure_frames, stations, offsets):
    offsets = offsets or {}
    if isinstance(exposure_frames, dict):
        fo = {s: np.asarray(exposure_frames[s], int) + offsets.get(s, 0) for s in stations}
    else:
        ef = np.asarray(exposure_frames, int)
        fo = {s: ef + offsets.get(s, 0) for s in stations}
    names = exposure_labels(table, len(next(iter(fo.values()))))
    return {e: {s: int(fo[s][i]) for s in stations} for i, e in enumerate(names)}, names


def _apply(out: pd.DataFrame, updates: list) -> None:
    """Apply ``updates`` ``[(row label, {column: value})]`` to ``out`` in
    order (a later value of a cell replaces an earlier one), one assignment
    per column."""
    cols: dict = {}
    for i, values in updates:
        for c, v in values.items():
            cols.setdefault(c, {})[i] = v
    for c, vals in cols.items():
        out.loc[list(vals), c] = list(vals.values())


def finish_table(out: pd.DataFrame, updates: list, notes: dict, names: list, eidx: dict,
                 pair) -> None:
    """Apply ``updates`` to ``out`` (:func:`_apply`), raise the sigma of the
    split tracks to their own scatter in time and extend the reason of the
    rows of the ``pair`` left ambiguous by ``notes`` {(exposure, station):
    why not split}; in place."""
    right_m, left_m = pair
    _apply(out, updates)
    # the sigma of a split track is at least its own scatter about a local
    # quadratic in time (exposure order; as the tracker's markers)
    split = out.reason.astype(str).str.startswith("split from a merged blob")
    for (s, m), g in out[split].groupby(["station", "marker"]):
        xy = np.full((len(names), 2), np.nan)
        pos = np.array([eidx[e] for e in g.exposure])
        xy[pos] = g[["x", "y"]].to_numpy(float)
        emp = scatter_sigma(xy, np.isfinite(xy).all(1))
        if np.isfinite(emp):
            out.loc[g.index, "sigma"] = np.maximum(g.sigma.to_numpy(float), emp)
    for (e, s), why in notes.items():
        sel = (out.exposure == e) & (out.station == s) & out.marker.isin([right_m, left_m]) \
            & (out.status != "ok")
        out.loc[sel, "reason"] = out.loc[sel, "reason"].astype(str) + "; not split: " + why


def make_report(mids: list, blobs: list, labels: list, counts: dict) -> SplitReport:
    """The :class:`SplitReport` of the rows collected in the loops
    (``counts["ambiguous"]`` filled in)."""
    counts["ambiguous"] = counts["flagged"] - counts["resolved"]
    report = SplitReport(
        midpoints=pd.DataFrame(mids, columns=MIDPOINT_COLUMNS),
        blobs=pd.DataFrame(blobs, columns=["exposure", "station", "x", "y", "dx", "dy",
                                           "separation", "sep_sigma", "sigma", "outcome"]),
        labels=pd.DataFrame(labels, columns=["exposure", "views", "chi2", "chi2_second",
                                             "distance", "across_deg", "outcome"]),
        counts=counts)
    return report
