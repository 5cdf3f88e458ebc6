"""Residuals: overall and per-image RMS, the worst points, the largest
standardized residuals, data snooping, and residual vector plots per image
(with the convex hull of the measured points: the image coverage)."""

from __future__ import annotations

import numpy as np
from photogram.report.layout import decorate
from photogram.report.numbers import finite, num
from photogram.report.registry import section
from photogram.report.shapes import cell_means, dense, nice, segments_path
from photogram.report.table import sorted_subgroups

_INTRO = ("Residuals are the measured minus the adjusted image coordinates. The RMS is "
          "over the used observations; 'RMS' alone is the RMS of the residual vector length "
          "(DBAT's point RMS). A standardized residual w is a residual divided by its own "
          "standard deviation: |w| above the critical value (about 3.3) marks a probable "
          "blunder. The redundancy number r (0..1) is the share of an error that shows in its "
          "own residual: r < 0.1 means an error there would hardly be seen.")


def _rms(a):
    a = np.asarray(a, float)
    return float(np.sqrt(np.mean(a ** 2))) if len(a) else np.nan


def _stats(r):
    v = np.hypot(r["vx"], r["vy"])
    return len(r), _rms(r["vx"]), _rms(r["vy"]), _rms(v), float(v.max()) if len(r) else np.nan


def _w(r):
    if "wx" in r and "wy" in r:
        return np.maximum(np.abs(r["wx"].astype(float)), np.abs(r["wy"].astype(float)))
    return np.full(len(r), np.nan)


def _per_point(r, used):
    """``(ids, rays, rms)`` per point of the used observations ``used``
    (the rows ``r["used"]`` of the residuals ``r``), ids sorted."""
    pcode, pnames = r.groups("point")
    code, ids = sorted_subgroups(pcode[r["used"]], pnames)
    v2 = used["vx"] ** 2 + used["vy"] ** 2
    size = np.bincount(code, minlength=len(ids))
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.bincount(code, weights=v2, minlength=len(ids)) / size)
    return ids, size, rms


def _per_image(r, code, n) -> np.ndarray:
    """Per image (``code`` of every row, ``n`` images) over its used rows:
    count, RMS vx, RMS vy, RMS and largest vector length, largest |w|
    (NaN where there is none); as :func:`_stats` and :func:`_w` per image."""
    u = r["used"]
    c = code[u]
    vx, vy = r["vx"][u].astype(float), r["vy"][u].astype(float)
    v2 = vx ** 2 + vy ** 2
    k = np.bincount(c, minlength=n).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = [np.sqrt(np.bincount(c, weights=q, minlength=n) / k) for q in (vx ** 2, vy ** 2, v2)]
    vmax = np.full(n, -np.inf)
    np.maximum.at(vmax, c, np.sqrt(v2))
    vmax[k == 0] = np.nan
    wmax = np.full(n, np.nan)
    np.fmax.at(wmax, c, _w(r)[u])
    return np.column_stack([k, *rms, vmax, wmax])


def _largest_first(values) -> np.ndarray:
    """Order of ``values`` from the largest down, NaN last, ties in row order."""
    v = np.asarray(values, float)
    return np.lexsort((np.arange(len(v)), -np.nan_to_num(v, nan=-np.inf), np.isnan(v)))


@section("residuals", "Residuals", 40, applies=lambda d: d.has_residuals, native=True)
def build(doc, data):
    iu = data.image_unit
    r = data.residuals
    used = r.take(r["used"])
    doc.start_section("Residuals", intro=_INTRO)
    snoop = data.summary.get("snooping")
    if np.any(np.isfinite(_w(used))):
        _histogram(doc, data, used, snoop)
    n, rx, ry, rv, vmax = _stats(used)
    big = int(np.argmax(np.hypot(used["vx"], used["vy"]))) if n else None
    rows = [("image observations", f"{len(r)} points ({n} used, {len(r) - n} rejected)"),
            ("RMS x, y", f"{num(rx, 3)}, {num(ry, 3)} {iu}"),
            ("RMS (vector length)", f"{num(rv, 3)} {iu}")]
    if big is not None:
        rows.append(("largest residual", f"{num(vmax, 3)} {iu} (point {used['point'][big]} "
                                         f"in {used['station'][big]})"))
    if "rx" in used and "ry" in used and n:
        red = np.concatenate([used["rx"], used["ry"]]).astype(float)
        rows.append(("redundancy numbers", f"min {red.min():.2f}, mean {red.mean():.2f}; "
                                           f"{int((red < 0.1).sum())} below 0.1"))
    w = _w(used)
    if np.any(np.isfinite(w)):
        rows.append(("largest |w|", f"{np.nanmax(w):.2f}"))
    doc.pairs(rows, title="Overall")
    if snoop:
        rej = snoop.get("rejected") or []
        doc.pairs([("significance level", f"alpha = {snoop.get('alpha')}"),
                   ("critical value", f"|w| > {num(snoop.get('critical_value'), 4)}"),
                   ("rejected", f"{len(rej)} observation(s)" if rej else "none")],
                  title="Data snooping (Baarda)")
        if rej:
            doc.table(["observation", "w"], [(str(x.get("label", x.get("row"))),
                                              num(x.get("w"), 3)) for x in rej],
                      align="lr")
    else:
        doc.text("Data snooping was not run (set [adjustment] snooping_alpha, e.g. 0.001).",
                 size=8)
    rows = []
    code, names = r.groups("station")
    for st, (k, sx, sy, sv, mx, wmax) in zip(names, _per_image(r, code, len(names))):
        rows.append([st, str(data.station_camera(st) or "-"), str(int(k)), num(sx, 3),
                     num(sy, 3), num(sv, 3), num(mx, 3),
                     num(wmax, 3) if np.isfinite(wmax) else "-"])
    doc.table(["station", "camera", "points", f"RMS x [{iu}]", f"RMS y [{iu}]",
               f"RMS [{iu}]", f"max [{iu}]", "max |w|"], rows, align="llrrrrrr",
              title="Per image")
    ids, size, rms = _per_point(r, used)
    worst = _largest_first(rms)[:8]
    if len(ids):
        best = int(np.nanargmin(rms)) if np.isfinite(rms).any() else 0
        doc.text(f"Per point (RMS over all images of a point): min "
                 f"{num(np.nanmin(rms) if np.isfinite(rms).any() else np.nan, 3)} {iu} "
                 f"({ids[best]}), max {num(rms[worst[0]], 3)} {iu} ({ids[worst[0]]}), "
                 f"{len(ids)} points.", size=8)
    doc.table(["point", "rays", f"RMS [{iu}]"],
              [(ids[i], str(int(size[i])), num(rms[i], 3)) for i in worst],
              title="Points with the largest RMS")
    w = _w(r)
    if np.any(np.isfinite(w)):
        rx, ry = r.get("rx"), r.get("ry")
        doc.table(["station", "point", f"vx [{iu}]", f"vy [{iu}]", "wx", "wy", "rx", "ry",
                   "used"],
                  [(r["station"][i], r["point"][i], num(r["vx"][i], 3), num(r["vy"][i], 3),
                    f"{r['wx'][i]:+.2f}", f"{r['wy'][i]:+.2f}",
                    num(None if rx is None else rx[i], 2),
                    num(None if ry is None else ry[i], 2), "yes" if r["used"][i] else "no")
                   for i in _largest_first(w)[:12]],
                  align="llrrrrrrl", title="Largest standardized residuals")


def _histogram(doc, data, used, snoop):
    w = np.concatenate([used["wx"], used["wy"]]).astype(float)
    w = w[np.isfinite(w)]
    if not len(w):
        return
    ax = doc.float_right(3.3, 2.6, pad_left=0.6, pad_bottom=0.45)
    lim = max(4.0, float(np.abs(w).max()) * 1.05)
    ax.hist(w, bins=np.linspace(-lim, lim, 41), density=True, color="tab:blue", alpha=0.7,
            label="used observations")
    t = np.linspace(-lim, lim, 200)
    ax.plot(t, np.exp(-t ** 2 / 2) / np.sqrt(2 * np.pi), color="black", lw=1, label="N(0, 1)")
    if snoop and finite(snoop.get("critical_value")):
        for s in (-1, 1):
            ax.axvline(s * snoop["critical_value"], color="tab:red", lw=0.8, ls="--")
    decorate(ax, "standardized residuals w (x and y)", "w [-]", "density [-]", ypad=0.45)
    ax.legend(loc="upper left", fontsize=6, frameon=False)


# --------------------------------------------------------------------------
# residual vectors per image


def _scale(data):
    """Enlargement of the residual vectors: their RMS becomes 8 % of the
    widest format, rounded down to 1, 2 or 5 x 10^k."""
    r = data.residuals
    v = np.hypot(r["vx"], r["vy"]).astype(float)
    widths = [f[0] for f in (data.image_format(data.station_camera(s))
                             for s in r.groups("station")[1]) if f]
    if not len(v) or not widths:
        return 1.0
    rms = float(np.sqrt(np.mean(v ** 2))) or 1.0
    return nice(0.08 * max(widths) / rms)


#: images with more used points than this show their residual vectors
#: averaged per cell of a grid of CELL_COLUMNS square cells across
CELL_POINTS, CELL_COLUMNS = 1000, 24


def _segments(ax, a, b) -> None:
    if getattr(ax, "native", False):         # one vector path, however many
        ax.segments(a, b, color="tab:blue", lw=0.9, autolim=False)
        return
    from matplotlib.patches import PathPatch

    # add_artist, not add_patch: the limits are set by the caller, and
    # add_patch would walk the path segment by segment in Python
    ax.add_artist(PathPatch(segments_path(a, b), fill=False, lw=0.9, edgecolor="tab:blue",
                            capstyle="butt", rasterized=dense(len(a))))


def _cell_vectors(ax, xy, v, size, k) -> None:
    """Mean residual vector per cell from the cell centre (dot), over the
    number of points per cell in grey."""
    centres, means, counts = cell_means(xy, v, size, CELL_COLUMNS)
    cell = size[0] / CELL_COLUMNS
    ax.imshow(np.ma.masked_equal(counts, 0), cmap="Greys", vmin=0, vmax=2.5 * counts.max(),
              extent=(0, CELL_COLUMNS * cell, counts.shape[0] * cell, 0),
              interpolation="nearest", zorder=0.5)
    ax.plot(centres[:, 0], centres[:, 1], ".", ms=2, color="0.2")
    _segments(ax, centres, centres + k * means)


def _vector_plot(ax, data, station, g, k, iu):
    fmt = data.image_format(data.station_camera(station))
    a = g.numbers(["x", "y", "vx", "vy"])
    u = g["used"].astype(bool)
    xy = a[:, :2]
    hull = data.hulls.get(station, np.zeros((0, 2)))
    if fmt and getattr(ax, "native", False):
        ax.add_rect(0, 0, fmt[0], fmt[1], color="0.3", lw=0.8)
    elif fmt:
        from matplotlib.patches import Rectangle

        ax.add_patch(Rectangle((0, 0), fmt[0], fmt[1], fill=False, lw=0.8, color="0.3"))
    if len(hull) >= 3:
        ax.fill(hull[:, 0], hull[:, 1], color="tab:green", alpha=0.12, lw=0)
    v = a[u, 2:]
    w, h = fmt if fmt else (xy[:, 0].max(), xy[:, 1].max())
    if u.sum() > CELL_POINTS:
        _cell_vectors(ax, xy[u], v, (w, h), k)
    else:
        ax.plot(xy[u, 0], xy[u, 1], ".", ms=2, color="0.2", rasterized=dense(int(u.sum())))
        _segments(ax, xy[u], xy[u] + k * v)
    if (~u).any():
        ax.plot(xy[~u, 0], xy[~u, 1], "x", color="tab:red", ms=4, label="rejected",
                rasterized=dense(int((~u).sum())))
    ref = nice(0.12 * w / k)
    y0 = 1.06 * h
    ax.plot([w - k * ref, w], [y0, y0], color="tab:blue", lw=2, solid_capstyle="butt")
    ax.text(w - k * ref, y0 + 0.02 * h, f"{num(ref, 2)} {iu} ", ha="right", va="center", size=6.5)
    ax.set_xlim(0, w)
    ax.set_ylim(1.12 * h, 0)
    ax.set_aspect("equal")
    ax.set_xticks(np.linspace(0, w, 3))
    ax.set_yticks(np.linspace(0, h, 3))
    ax.tick_params(labelsize=6)
    n, rv = int(u.sum()), _rms(np.hypot(v[:, 0], v[:, 1]))
    decorate(ax, f"{station} ({data.station_camera(station)}): {n} points, RMS {num(rv, 2)} {iu}",
             f"x [{iu}]", f"y [{iu}]", xpad=0.25, ypad=0.4, size=7.5)


@section("residual_vectors", "Residual vectors per image", 45,
         applies=lambda d: d.has_residuals, native=True)
def build_vectors(doc, data):
    iu = data.image_unit
    k = _scale(data)
    r = data.residuals
    code, names = r.groups("station")
    used_per_image = np.bincount(code[r["used"]], minlength=len(names))
    doc.start_section("Residual vectors per image", intro=(
        f"Residuals enlarged {k:g} times (the bar below each image is the length given), "
        "drawn as lines from the measured points (dots) over the image format. Green: "
        "convex hull of the measured points (image coverage); red x: rejected observations. "
        "Systematic patterns (all lines turning together, growing towards the edges) point "
        "to an error of the camera model; a single long line to a blunder." + (
            f" Images with more than {CELL_POINTS} points: the residuals are averaged per "
            f"cell of a grid of {CELL_COLUMNS} square cells across the format and drawn from "
            "the cell centres; grey: points per cell (darker = more)."
            if (used_per_image > CELL_POINTS).any() else "")))
    order = np.argsort(code, kind="stable")
    bounds = np.searchsorted(code[order], np.arange(len(names) + 1))
    images = [(names[i], r.take(order[bounds[i]:bounds[i + 1]])) for i in range(len(names))]
    for i in range(0, len(images), 2):
        pair_ = images[i:i + 2]
        aspect = max((f[1] / f[0]) for f in (data.image_format(data.station_camera(s))
                                             or (4, 3) for s, _ in pair_))
        height = min(4.2, 2.6 * aspect * 1.12 + 0.7)
        axes = doc.axes(height, ncols=2, pad_left=0.55, pad_right=0.15, pad_top=0.3,
                        pad_bottom=0.4, gap=0.25)
        for ax, (station, g) in zip(axes, pair_):
            _vector_plot(ax, data, station, g, k, iu)
        for ax in axes[len(pair_):]:
            ax.set_visible(False)
