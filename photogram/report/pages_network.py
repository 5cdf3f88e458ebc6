"""The network: cameras and points in 3D and in plan."""

from __future__ import annotations

import numpy as np
from photogram.report.layout import decorate, equal_limits
from photogram.report.registry import section
from photogram.report.shapes import dense, native_ray_layer, ray_layer

_STYLE = {"control": ("^", "tab:red", 14), "check": ("s", "tab:orange", 12),
          "tie": ("o", "0.3", 3)}


def _points(data):
    p = data.points
    xyz = p.numbers(["X", "Y", "Z"]).reshape(-1, 3)
    ok = np.all(np.isfinite(xyz), axis=1)
    if data.has_residuals:
        seen = set(data.residuals["point"].tolist())
        ok &= np.fromiter((i in seen for i in p.ids), dtype=bool, count=len(p))
    kinds = p["kind"].astype(str) if "kind" in p else np.full(len(p), "tie")
    return xyz[ok], kinds[ok]


def _stations(data):
    names = [n for n in dict.fromkeys(data.stations.ids.tolist()) if n in data.rotation
             and np.all(np.isfinite(data.centres[n]))]
    C = np.array([data.centres[n] for n in names]).reshape(-1, 3)
    D = np.array([-data.rotation[n][2] for n in names]).reshape(-1, 3)   # viewing directions
    return names, C, D


def _equal_box(ax, xyz):
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    mid, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-9)
    for setter, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
        setter(m - half, m + half)
    ax.set_box_aspect((1, 1, 1))


def _plan_limits(ax, allp, size):
    """Equal-scale limits of the plan view around every point and camera."""
    pad = 0.05 * size
    equal_limits(ax, allp[:, :2].min(axis=0) - pad, allp[:, :2].max(axis=0) + pad)


def _view3d(ax3, xyz, kinds, names, C, D, allp, size, lu):
    """The 3D view: points by kind, cameras with their viewing directions."""
    if getattr(ax3, "native", False):
        for kind, (marker, colour, ms) in _STYLE.items():
            m = kinds == kind
            if m.any():
                ax3.scatter(xyz[m], marker=marker, color=colour, s=ms, label=kind)
        if len(C):
            ax3.scatter(C, marker="^", color="black", s=25, label="camera")
            ax3.segments(C, C + 0.12 * size * D, color="black", lw=0.8)
            for c, n in zip(C, names):
                ax3.text(c, n, size=6.5)
        ax3.set_box(allp)
        ax3.set_labels(f"X [{lu}]", f"Y [{lu}]", f"Z [{lu}]")
        ax3.legend(loc="upper left", fontsize=7)
        return
    from matplotlib.ticker import MaxNLocator

    for kind, (marker, colour, ms) in _STYLE.items():
        m = kinds == kind
        if m.any():
            ax3.scatter(*xyz[m].T, marker=marker, color=colour, s=ms, depthshade=False,
                        label=kind, rasterized=dense(int(m.sum())))
    if len(C):
        ax3.scatter(*C.T, marker="^", color="black", s=25, depthshade=False, label="camera")
        E = C + 0.12 * size * D
        for c, e, n in zip(C, E, names):
            ax3.plot(*np.stack([c, e]).T, color="black", lw=0.8)
            ax3.text(*c, f" {n}", size=6.5)
    _equal_box(ax3, allp)
    ax3.set_xlabel(f"X [{lu}]")
    ax3.set_ylabel(f"Y [{lu}]")
    ax3.set_zlabel(f"Z [{lu}]")
    ax3.tick_params(labelsize=6)
    for axis in (ax3.xaxis, ax3.yaxis, ax3.zaxis):
        axis.set_major_locator(MaxNLocator(4))
        axis.get_major_formatter().set_useOffset(False)
        axis.get_major_formatter().set_scientific(False)
    ax3.legend(loc="upper left", fontsize=7)


def _rays(ax, a, b, allp, size):
    """Every ray in plan: one image of the stacked lines when dense, else one
    layer of lines."""
    native = getattr(ax, "native", False)
    if dense(len(a)):       # one image of the stacked rays (ray_layer), limits first
        _plan_limits(ax, allp, size)
        if native:
            native_ray_layer(ax, a, b, "tab:blue", 0.15, zorder=1)
        else:
            ray_layer(ax, a, b, "tab:blue", 0.15, zorder=1)
    elif native:
        ax.segments(a, b, color="tab:blue", lw=0.3, alpha=0.15, zorder=1, autolim=False)
    else:                   # limits: _plan_limits below (autolim would measure every ray)
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(np.stack([a, b], axis=1), colors="tab:blue",
                                         lw=0.3, alpha=0.15), autolim=False)


@section("network", "Network", 70, applies=lambda d: len(d.results.stations) > 0,
         native=True)
def build(doc, data):
    lu = data.length_unit
    xyz, kinds = _points(data)
    names, C, D = _stations(data)
    allp = np.vstack([xyz, C]) if len(C) else xyz
    if not len(allp):
        return
    size = float(np.ptp(allp, axis=0).max()) or 1.0
    rays = data.has_residuals and len(C) > 0 and bool(np.any(data.residuals["used"]))
    doc.start_section("Network", intro=(
        "Projection centres (black triangles, with the viewing direction) and the measured "
        "points (red triangles: control, orange squares: check, grey dots: tie or object "
        "points) in 3D and in plan; " + (
            "in the plan view every ray from a camera to a point it measured (used "
            "observations of residuals.csv) is drawn as a thin blue line (beyond 2500 rays as "
            "one image of the stacked lines, darker where more rays cross)." if rays else
            "no rays are drawn: residuals.csv lists no used observation of these stations.")))
    ax3, = doc.axes(4.4, projection="3d", pad_left=0.3, pad_bottom=0.2, pad_top=0.1)
    _view3d(ax3, xyz, kinds, names, C, D, allp, size, lu)
    span = np.ptp(allp[:, :2], axis=0) + 1e-9
    height = float(np.clip(5.6 * span[1] / span[0], 2.5, 5.2)) + 0.8
    ax, = doc.axes(max(3.0, min(height, doc.remaining - 0.1)), pad_left=0.9, pad_right=0.4)
    if rays:
        r, pts = data.residuals, data.points
        used = r["used"]
        code, snames = r.groups("station")
        index = {n: i for i, n in enumerate(names)}
        si = np.array([index.get(n, -1) for n in snames], dtype=int)[code[used]]
        pi = data.used_point_rows
        ok = (si >= 0) & (pi >= 0)
        a = C[si[ok], :2]
        b = pts.numbers(["X", "Y"])[pi[ok]]
        _rays(ax, a, b, allp, size)
    for kind, (marker, colour, ms) in _STYLE.items():
        m = kinds == kind
        if m.any():
            ax.scatter(*xyz[m, :2].T, marker=marker, color=colour, s=ms, zorder=3,
                       rasterized=dense(int(m.sum())))
    if len(C):
        ax.scatter(*C[:, :2].T, marker="^", color="black", s=25, zorder=4)
        ax.quiver(C[:, 0], C[:, 1], D[:, 0], D[:, 1], angles="xy", scale_units="xy",
                  scale=1 / (0.12 * size), width=0.003, color="black", zorder=4)
        for c, n in zip(C, names):
            ax.annotate(n, c[:2], xytext=(3, 3), textcoords="offset points", size=6.5)
    _plan_limits(ax, allp, size)
    ax.grid(True, lw=0.3)
    ax.ticklabel_format(useOffset=False, style="plain")
    decorate(ax, "plan (X, Y)", f"X [{lu}]", f"Y [{lu}]", ypad=0.75)
