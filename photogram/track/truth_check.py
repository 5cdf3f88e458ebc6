"""A tracking run against the truth of simulated videos (the ``truth/``
folder that :func:`photogram.simulation.jump_video.write_jump_videos`
writes): marker centre errors, labels right / wrong / flagged, ski-line
image directions and the distance of the sampled points from the true ski
axis. For reports and benchmarks only: nothing here feeds the tracking."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["compare_with_truth", "marker_errors", "ski_errors", "line_direction"]


def _read(folder, name):
    return pd.read_csv(Path(folder) / name, comment="#", dtype={"exposure": str})


def marker_errors(markers: pd.DataFrame, truth: pd.DataFrame, *, label_px: float = 3.0) -> dict:
    """Errors of the markers found (status ok) against the true centres.

    A found marker is *right* when its own true centre is the nearest true
    marker centre of that image and lies within ``label_px``; *wrong*
    otherwise. Every true marker row (visible or not) is right, wrong or
    flagged (status not ok).

    Returns
    -------
    dict: ``rms_px`` (of the right ones), ``max_px``, ``n_ok``, ``n_right``,
    ``n_wrong``, ``n_flagged``, ``right_or_flagged`` (fraction), ``wrong``
    (list of "exposure station marker" of the wrong ones).
    """
    t = truth.copy()
    t["exposure"] = t["exposure"].astype(str)
    m = markers.merge(t[["station", "exposure", "marker", "x", "y", "visible"]],
                      on=["station", "exposure", "marker"], how="left", suffixes=("", "_true"))
    ok = m[m.status == "ok"]
    right = np.zeros(len(ok), bool)
    by_image = {key: g for key, g in t.groupby(["station", "exposure"])}
    for k, row in enumerate(ok.itertuples()):
        same = by_image.get((row.station, row.exposure), t.iloc[:0])
        d = np.hypot(same.x - row.x, same.y - row.y)
        if not len(d) or not np.isfinite(row.x_true):
            continue
        nearest = same.marker.iloc[int(np.argmin(d.to_numpy()))]
        right[k] = nearest == row.marker and np.hypot(row.x - row.x_true,
                                                      row.y - row.y_true) <= label_px
    err = np.hypot(ok.x - ok.x_true, ok.y - ok.y_true).to_numpy()
    good = err[right]
    wrong = ok[~right]
    n = len(m)
    return {"n_rows": int(n), "n_ok": int(len(ok)), "n_right": int(right.sum()),
            "n_wrong": int((~right).sum()), "n_flagged": int((m.status != "ok").sum()),
            "right_or_flagged": float((right.sum() + (m.status != "ok").sum()) / max(n, 1)),
            "rms_px": float(np.sqrt(np.mean(good ** 2))) if len(good) else float("nan"),
            "max_px": float(good.max()) if len(good) else float("nan"),
            "rms_x_px": float(np.sqrt(np.mean((ok.x - ok.x_true)[right] ** 2)))
            if right.any() else float("nan"),
            "rms_y_px": float(np.sqrt(np.mean((ok.y - ok.y_true)[right] ** 2)))
            if right.any() else float("nan"),
            "wrong": [f"{r.exposure} {r.station} {r.marker}" for r in wrong.itertuples()]}


def line_direction(xy: np.ndarray) -> np.ndarray:
    """Unit direction of the principal axis of points (n, 2)."""
    u = xy - xy.mean(0)
    _, _, vt = np.linalg.svd(u, full_matrices=False)
    return vt[0]


def ski_errors(skis: pd.DataFrame, truth: pd.DataFrame, *, own_px: float = 0.5) -> dict:
    """Direction error (degrees, modulo 180) of the line through each
    tracked ski's points against the true image of the ski axis, and the
    distance of the points from that axis (px); a ski labelled as the other
    ski (nearer to the other true axis, and farther than ``own_px`` on
    average from its own) counts as a wrong label. Where the two skis
    coincide in an image within ``own_px`` a line may be nearer the other
    ski and still measure its own: counted in ``n_near_both``, not wrong.

    Returns
    -------
    dict: ``n_lines``, ``rms_deg``, ``max_deg``, ``rms_point_px``,
    ``max_point_px``, ``n_wrong_label``, ``n_near_both``.
    """
    t = truth.copy()
    t["exposure"] = t["exposure"].astype(str)
    angles, dists, wrong, near_both = [], [], 0, 0
    by_image = {key: g for key, g in t.groupby(["station", "exposure"])}
    for (e, s, line), g in skis.groupby(["exposure", "station", "line"]):
        xy = g[["x", "y"]].to_numpy(float)
        if len(xy) < 2:
            continue
        rows = by_image.get((s, str(e)), t.iloc[:0])
        own = rows[rows.ski == line]
        if not len(own):
            continue
        d_fit = line_direction(xy)

        def axis(r):
            a = np.array([r.x_tail, r.y_tail], float)
            b = np.array([r.x_tip, r.y_tip], float)
            return a, (b - a) / np.linalg.norm(b - a)

        def distance(a, d):
            v = xy - a
            return np.abs(v[:, 0] * d[1] - v[:, 1] * d[0])
        a, d = axis(own.iloc[0])
        dist = distance(a, d)
        others = rows[rows.ski != line]
        if len(others):
            a2, d2 = axis(others.iloc[0])
            if np.mean(distance(a2, d2)) < np.mean(dist):
                if np.mean(dist) > own_px:
                    wrong += 1
                    continue
                near_both += 1
        cos = abs(float(d_fit @ d))
        angles.append(np.degrees(np.arccos(min(cos, 1.0))))
        dists.append(dist)
    ang = np.array(angles)
    dd = np.concatenate(dists) if dists else np.zeros(0)
    return {"n_lines": int(len(ang)), "n_wrong_label": int(wrong),
            "n_near_both": int(near_both),
            "rms_deg": float(np.sqrt(np.mean(ang ** 2))) if len(ang) else float("nan"),
            "max_deg": float(ang.max()) if len(ang) else float("nan"),
            "median_deg": float(np.median(ang)) if len(ang) else float("nan"),
            "rms_point_px": float(np.sqrt(np.mean(dd ** 2))) if len(dd) else float("nan"),
            "max_point_px": float(dd.max()) if len(dd) else float("nan")}


def compare_with_truth(run, folder) -> dict:
    """:func:`marker_errors` and :func:`ski_errors` of a
    :class:`~photogram.track.pipeline.TrackingRun` against ``folder``
    (truth/markers.csv, truth/skis.csv, truth/offsets.csv if present)."""
    folder = Path(folder)
    out = {"folder": str(folder)}
    if (folder / "markers.csv").is_file():
        out["markers"] = marker_errors(run.markers, _read(folder, "markers.csv"))
    if (folder / "skis.csv").is_file():
        out["skis"] = ski_errors(run.skis, _read(folder, "skis.csv"))
    if (folder / "offsets.csv").is_file():
        off = _read(folder, "offsets.csv")
        true = {str(r.station): int(r.offset) for r in off.itertuples()}
        out["offsets_true"] = true
        out["offsets_right"] = all(run.offsets.get(s, 0) == v for s, v in true.items())
    return out
