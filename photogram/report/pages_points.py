"""Object points: precision statistics, error ellipses in plan and
elevation, control and check point differences, rays, intersection angles
and image coverage."""

from __future__ import annotations

import numpy as np
from photogram.report.layout import decorate, equal_limits
from photogram.report.numbers import finite, num, sig
from photogram.report.registry import section
from photogram.report.shapes import dense, ellipses, nice

_KIND_STYLE = {"control": ("^", "tab:red"), "check": ("s", "tab:orange"),
               "tie": (".", "0.2")}


def _kinds(data, ids):
    p = data.points
    if "kind" not in p:
        return ["tie"] * len(ids)
    return p["kind"][p.positions(list(ids))].astype(str).tolist()


def _xyz(data, ids, cols=("X", "Y", "Z")):
    p = data.points
    return p.numbers(list(cols))[p.positions(list(ids))].reshape(-1, len(cols))


@section("points", "Point precision", 50, applies=lambda d: len(d.point_sigma[0]) > 0,
         native=True)
def build(doc, data):
    lu = data.length_unit
    ids, s = data.point_sigma
    total = np.sqrt(np.mean(s ** 2, axis=1))
    doc.start_section("Point precision", intro=(
        "A-posteriori standard deviations of the estimated object points (fixed points "
        "left out). 'total' is the RMS of the X, Y and Z sigmas (DBAT's total standard "
        "deviation). The relative precision is the size of the network divided by the mean "
        "total sigma."))
    rows = [[ax, sig(c.min()), sig(c.mean()), sig(c.max()), sig(np.sqrt(np.mean(c ** 2)))]
            for ax, c in zip(("X", "Y", "Z", "total"), (*s.T, total))]
    doc.table(["sigma", f"min [{lu}]", f"mean [{lu}]", f"max [{lu}]", f"RMS [{lu}]"], rows,
              title=f"{len(ids)} points with estimated coordinates")
    xyz = _xyz(data, ids)
    size = float(np.linalg.norm(np.ptp(xyz, axis=0))) if len(xyz) > 1 else np.nan
    if finite(size) and total.mean() > 0:
        doc.text(f"Network size (bounding-box diagonal of these points) {num(size, 4)} {lu}; "
                 f"relative precision 1 : {size / total.mean():,.0f}.", size=8.5)
    rays = data.ray_stats if data.has_residuals else None
    order = np.argsort(-total)[:15]
    at = rays.positions([ids[k] for k in order]) if rays is not None else -np.ones(len(order))
    kinds = _kinds(data, [ids[k] for k in order])
    rows = []
    for j, k in enumerate(order):
        pid = ids[k]
        nr = int(rays["rays"][at[j]]) if at[j] >= 0 else None
        ang = rays["angle"][at[j]] if nr is not None else np.nan
        rows.append([pid, kinds[j], str(nr if nr is not None else "-"),
                     num(ang, 3), sig(s[k, 0]), sig(s[k, 1]), sig(s[k, 2]), sig(total[k])])
    doc.table(["point", "kind", "rays", "angle [deg]", f"sX [{lu}]", f"sY [{lu}]",
               f"sZ [{lu}]", f"total [{lu}]"], rows, align="llrrrrrr",
              title="Least precise points")


# --------------------------------------------------------------------------
# error ellipses


def _covariances(data, ids):
    """(n, 3, 3) covariances of ``ids``: from covariance.npz, else diagonal
    from the sigmas of points.csv; and whether they are full."""
    cov = data.covariance
    if cov is not None and "point_covariance" in cov:
        index = {str(k): i for i, k in enumerate(cov["point_ids"])}
        if all(i in index for i in ids):
            return np.asarray(cov["point_covariance"], float)[[index[i] for i in ids]], True
    s = _xyz(data, ids, ("est_sX", "est_sY", "est_sZ"))
    return np.einsum("ni,ij->nij", s ** 2, np.eye(3)), False


def _ellipse_panel(ax, xy, C2, k, kinds, labels):
    abt = ellipses(C2)
    if getattr(ax, "native", False):         # one vector path, however many
        ax.ellipses(xy, k * abt[:, 0], k * abt[:, 1], abt[:, 2], color="tab:blue", lw=0.7)
    else:
        from matplotlib.collections import EllipseCollection

        ax.add_collection(EllipseCollection(
            2 * k * abt[:, 0], 2 * k * abt[:, 1], abt[:, 2], units="xy", offsets=xy,
            offset_transform=ax.transData, facecolors="none", edgecolors="tab:blue", lw=0.7,
            rasterized=dense(len(xy))))
    kinds = np.asarray(kinds, dtype=str)
    for kind, (marker, colour) in _KIND_STYLE.items():
        m = kinds == kind
        if m.any():
            ax.plot(xy[m, 0], xy[m, 1], marker, color=colour, ms=3 if kind == "tie" else 4,
                    ls="none", label=kind, rasterized=dense(int(m.sum())))
    placed = []
    near = 0.06 * float(np.ptp(xy, axis=0).max() or 1.0)
    for i in labels:                         # skip labels that would overlap
        if all(np.hypot(*(xy[i] - q)) > near for q in placed):
            ax.annotate(labels[i], xy[i], xytext=(3, 3), textcoords="offset points", size=6)
            placed.append(xy[i])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = 0.08 * max(hi - lo) + k * abt[:, 0].max()
    equal_limits(ax, lo - pad, hi + pad)
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.grid(True, lw=0.3)


@section("ellipses", "Error ellipses", 52, applies=lambda d: len(d.point_sigma[0]) > 0,
         native=True)
def build_ellipses(doc, data):
    lu = data.length_unit
    ids, s = data.point_sigma
    C, full = _covariances(data, ids)
    xyz = _xyz(data, ids)
    kinds = _kinds(data, ids)
    h = 0 if np.ptp(xyz[:, 0]) >= np.ptp(xyz[:, 1]) else 1
    hname = "XY"[h]
    extent = float(max(np.ptp(xyz[:, :2], axis=0).max(), np.ptp(xyz[:, 2]), 1e-12))
    doc.start_section("Error ellipses", intro=(
        f"1-sigma error ellipses of the points in plan (X, Y) and in elevation ({hname}, Z), "
        "enlarged by the factor in each title. "
        + ("From the full 3x3 covariance of every point (covariance.npz). " if full else
           "Only the sigmas of points.csv are known here (no correlations): the ellipses are "
           "drawn along the axes. ")
        + "About 39 % of the true positions lie inside the 1-sigma ellipse, 95 % inside 2.45 "
          "times it. Long ellipses show a weak direction of the network."))
    panels = ((f"plan: X, Y [{lu}]", (0, 1)), (f"elevation: {hname}, Z [{lu}]", (h, 2)))
    heights = []
    for _, cols in panels:
        span = np.ptp(xyz[:, cols], axis=0) + 1e-12 * extent
        heights.append(float(np.clip(5.0 * span[1] / span[0], 1.6, 4.6)) + 0.8)
    fit = min(1.0, (doc.remaining - 0.1) / sum(heights))
    for (title, cols), height in zip(panels, heights):
        xy, C2 = xyz[:, cols], C[:, cols][:, :, cols]
        a = ellipses(C2)[:, 0]
        k = nice(0.025 * extent / max(float(np.median(a)), 1e-300))
        worst = {int(i): ids[i] for i in np.argsort(-a)[:5]}
        ax, = doc.axes(max(2.0, height * fit), pad_left=0.9, pad_right=1.3)
        _ellipse_panel(ax, xy, C2, k, kinds, worst)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
        decorate(ax, f"{title}; ellipses x {k:g}; labels: the largest",
                 f"{'XYZ'[cols[0]]} [{lu}]", f"{'XYZ'[cols[1]]} [{lu}]", ypad=0.7)


# --------------------------------------------------------------------------
# control and check points


def _control_rows(data):
    p = data.project
    if p is None:
        return []
    est, ids = data.points, p.points.ids
    # only the control points are looked up (not all 26,000 points of a large network)
    ctrl = [i for i, kind in enumerate(p.points.kind) if str(kind) == "control"]
    at = est.positions([ids[i] for i in ctrl]) if len(est) else np.full(len(ctrl), -1)
    xyz = est.numbers(["X", "Y", "Z"]) if len(est) else np.zeros((0, 3))
    rows = []
    for i, row in zip(ctrl, at):
        if row < 0:
            continue
        d = xyz[row] - p.points.xyz[i]
        if np.all(np.isfinite(d)):
            rows.append((ids[i], d, p.points.sigma[i]))
    return rows


def _largest(values) -> float:
    """The largest finite value (NaN when there is none: printed as '-')."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return float(v.max()) if v.size else float("nan")


def _diff_table(doc, data, rows, title, note=None):
    lu = data.length_unit
    out = []
    for pid, d, prior in rows:
        out.append([pid, num(d[0], 3), num(d[1], 3), num(d[2], 3), num(np.hypot(d[0], d[1]), 3),
                     num(np.linalg.norm(d), 3)] + ([sig(_largest(prior))] if prior is not None
                                                   else []))
    if rows:
        D = np.array([d for _, d, _ in rows])
        rmse = np.sqrt(np.mean(D ** 2, axis=0))
        out.append(["RMSE", num(rmse[0], 3), num(rmse[1], 3), num(rmse[2], 3),
                    num(np.hypot(rmse[0], rmse[1]), 3), num(np.linalg.norm(rmse), 3)]
                   + ([""] if rows[0][2] is not None else []))
    head = ["point", f"dX [{lu}]", f"dY [{lu}]", f"dZ [{lu}]", f"dXY [{lu}]", f"dXYZ [{lu}]"]
    if rows and rows[0][2] is not None:
        head.append(f"a-priori sigma [{lu}]")
    doc.table(head, out, title=title, note=note)


def _has_control(d):
    return bool(d.summary.get("check_points")) or bool(_control_rows(d))


@section("control", "Control and check points", 55, applies=_has_control, native=True)
def build_control(doc, data):
    doc.start_section("Control and check points", intro=(
        "Differences d = adjusted - reference coordinates. Check points are not used in the "
        "adjustment: their RMSE is an independent measure of the accuracy. Control points "
        "define the datum; with weighted control their differences should be of the order "
        "of their a-priori sigmas."))
    cp = data.summary.get("check_points")
    if cp:
        rows = [(pid, np.asarray(d, float), None) for pid, d in zip(cp["ids"], cp["differences"])]
        _diff_table(doc, data, rows, f"Check points ({len(rows)})")
    ctrl = _control_rows(data)
    if ctrl:
        fixed = all(np.all(np.asarray(pr) == 0) for _, _, pr in ctrl)
        _diff_table(doc, data, ctrl, f"Control points ({len(ctrl)})",
                    note=("The control points were fixed (datum = control): their differences "
                          "are zero by construction." if fixed else None))
    elif data.project is None:
        doc.text(f"Control point differences: not shown, {data.project_note}.", size=8)
