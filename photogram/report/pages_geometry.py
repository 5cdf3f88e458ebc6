"""Network geometry from the observations: rays per point, intersection
angles and image coverage (DBAT's "Point Measurements", "Point Angles" and
"Photo point coverage")."""

from __future__ import annotations

import numpy as np

from photogram.report.layout import decorate
from photogram.report.numbers import num, pct
from photogram.report.registry import section
from photogram.report.shapes import coverage_fraction, polygon_area
from photogram.stats.geometry import WEAK_ANGLE_DEG

_INTRO = ("Rays: the images a point was measured (and used) in. Intersection angle: the "
          "largest angle between two rays of a point, at the point; small angles (below "
          "about 10 deg) give poor depth; points below 5 deg are flagged weak (red "
          "list, dashed line). Coverage: the part of the image format inside "
          "the convex hull of the measured points (per image), and inside the union of "
          "these hulls (per camera); a calibration needs points out to the corners.")


def weak_angle_points(data, threshold: float = WEAK_ANGLE_DEG) -> list:
    """Ids of the points (2+ used rays) whose largest intersection angle is
    below ``threshold`` degrees, smallest angle first (the same flag as
    :func:`photogram.stats.geometry.weak_points`)."""
    rays = data.ray_stats
    a = rays["angle"].astype(float)
    m = np.isfinite(a) & (a < threshold)
    ids, a = rays.ids[m], a[m]
    return [str(ids[i]) for i in np.argsort(a, kind="stable")]


def coverage(data):
    """Per station (n points, hull fraction, rectangle fraction, hull) and
    per camera the union fraction."""
    r = data.residuals
    code, names = r.groups("station")
    code = code[r["used"]]
    order = np.argsort(code, kind="stable")
    bounds = np.searchsorted(code[order], np.arange(len(names) + 1))
    xy_all = r.numbers(["x", "y"])[r["used"]][order]
    per_station, hulls = [], {}
    for i, st in enumerate(names):
        if bounds[i + 1] == bounds[i]:      # no used observation
            continue
        cam = data.station_camera(st)
        fmt = data.image_format(cam)
        xy = xy_all[bounds[i]:bounds[i + 1]]
        hull = data.hulls[st]
        area = fmt[0] * fmt[1] if fmt else np.nan
        rect = np.prod(np.ptp(xy, axis=0)) if len(xy) > 1 else 0.0
        per_station.append((st, cam, len(xy), polygon_area(hull) / area, rect / area))
        hulls.setdefault(cam, []).append(hull)
    union = {cam: coverage_fraction(h, data.image_format(cam))
             for cam, h in hulls.items() if data.image_format(cam)}
    return per_station, union


def _by_kind(data, rays) -> dict:
    """``{kind: (rays, angles)}`` of the control, check and tie points that
    have rays (points without a kind count as tie; all points are in every
    kind when the points table has no kind column), in that order."""
    n, a = rays["rays"].astype(int), rays["angle"].astype(float)
    if "kind" not in data.points:
        return {kind: (n, a) for kind in ("control", "check", "tie") if len(rays)}
    at = data.points.positions(rays.ids) if len(data.points) else np.full(len(rays), -1)
    kinds = np.where(at >= 0, data.points["kind"][at].astype(str), "tie")
    return {kind: (n[m], a[m])
            for kind in ("control", "check", "tie") if (m := kinds == kind).any()}


@section("geometry", "Rays, intersection angles, coverage", 60,
         applies=lambda d: d.has_residuals, native=True)
def build(doc, data):
    doc.start_section("Rays, intersection angles and image coverage", intro=_INTRO)
    rays = data.ray_stats
    rows = []
    for kind, (n, a) in _by_kind(data, rays).items():
        rows.append([kind, str(len(n)), f"{n.min()}-{n.max()}", f"{n.mean():.1f}",
                     num(a.min(), 3), num(a.mean(), 3), num(a.max(), 3)])
    doc.table(["points", "number", "rays", "mean rays", "min angle [deg]", "mean angle [deg]",
               "max angle [deg]"], rows, align="lrrrrrr", title="Rays and intersection angles")
    weak = weak_angle_points(data)
    angle = rays["angle"].astype(float)
    small = np.lexsort((np.nan_to_num(angle, nan=np.inf), np.isnan(angle)))
    small = small[:max(8, min(len(weak), 30))]
    weak_set = set(weak)
    doc.table(["point", "angle [deg]", "rays", "weak"],
              [(rays.ids[i], num(angle[i], 3), str(int(rays["rays"][i])),
                "WEAK" if rays.ids[i] in weak_set else "") for i in small],
              align="lrrl", title="Smallest intersection angles")
    if weak:
        more = f" and {len(weak) - 30} more" if len(weak) > 30 else ""
        doc.text(f"Weak intersection: {len(weak)} point(s) with an intersection angle below "
                 f"{WEAK_ANGLE_DEG:g} deg (poor depth, large sigma along the rays): "
                 f"{', '.join(map(str, weak[:30]))}{more}.", size=8.5, color="tab:red")
    else:
        doc.text(f"No point has an intersection angle below {WEAK_ANGLE_DEG:g} deg.", size=8.5)
    per_station, union = coverage(data)
    doc.table(["station", "camera", "points", "convex hull", "rectangle"],
              [(st, str(cam), str(n), pct(h, 0), pct(rc, 0))
               for st, cam, n, h, rc in per_station],
              align="llrrr", title="Image coverage (share of the format)")
    if union:
        doc.text("Union of the convex hulls per camera: " + ", ".join(
            f"{cam} {pct(f, 0)}" for cam, f in sorted(union.items())) + ".", size=8.5)
    ax_r, ax_a = doc.axes(2.5, ncols=2, pad_left=0.6, gap=0.3)
    n = rays["rays"].astype(int)
    if len(n):
        ax_r.hist(n, bins=np.arange(n.min(), n.max() + 2) - 0.5, color="tab:blue", rwidth=0.8)
    if getattr(ax_r, "native", False):
        ax_r.integer_ticks("x")
    else:
        ax_r.xaxis.get_major_locator().set_params(integer=True)
    decorate(ax_r, "rays per point", "rays [-]", "points [-]", ypad=0.42)
    a = rays["angle"].astype(float)
    a = a[np.isfinite(a)]
    if len(a):
        ax_a.hist(a, bins=min(30, max(5, len(a) // 3)), color="tab:green")
    ax_a.axvline(WEAK_ANGLE_DEG, color="tab:red", lw=0.8, ls="--")
    decorate(ax_a, "intersection angle per point", "largest angle between rays [deg]",
             "points [-]", ypad=0.42)
