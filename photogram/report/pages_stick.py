"""The stick model figure (the ski-jump paper's Fig. 8) drawn as vector
graphics on the report page, from the results tables (points3d.csv,
lines3d.csv, exposures.csv) with the same drawing as stick.png
(:func:`photogram.jump.figure.draw_stick`), in the project's units or the
coach's (deg, m, km/h)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.jump.coach import KMH_PER_MS
from photogram.jump.figure import chosen_exposures
from photogram.jump.stick import ski_segments
from photogram.project.model import LENGTH_UNITS, IntersectSettings
from photogram.report.layout import decorate

#: draw every EVERY-th exposure (as stick.png)
EVERY = 3

#: colours of stick.png (photogram.jump.figure)
_RIGHT, _LEFT, _BODY, _SLOPE = "tab:red", "tab:blue", "black", "tab:brown"


def _settings(data) -> IntersectSettings:
    cfg = getattr(data.project, "intersect", None)
    return cfg if isinstance(cfg, IntersectSettings) else IntersectSettings()


def stick_arrays(data):
    """``(ids, P (n,4,3), O (n,3), skis (n,2,2,3), v (n,))`` in the project's
    length unit, from the results tables; None without exposures.csv or
    points3d.csv."""
    e, p3, l3 = data.exposures, data.points3d, data.lines3d
    if e is None or p3 is None or not len(e):
        return None
    cfg = _settings(data)
    ids = [str(x) for x in e["exposure"]]
    row = {x: i for i, x in enumerate(ids)}
    n = len(ids)
    P = np.full((n, 4, 3), np.nan)
    names = {name: k for k, name in enumerate(cfg.points)}
    for r in p3.itertuples(index=False):
        i, k = row.get(str(r.exposure)), names.get(str(r.point))
        if i is not None and k is not None:
            P[i, k] = (r.X, r.Y, r.Z)
    O = e[["O_x", "O_y", "O_z"]].to_numpy(float) if "O_x" in e.columns else \
        0.5 * (P[:, 2] + P[:, 3])
    u = np.full((n, 2, 3), np.nan)
    c = np.full((n, 2, 3), np.nan)
    skis = {name: j for j, name in enumerate(cfg.skis)}
    if l3 is not None:
        for r in l3.itertuples(index=False):
            i, j = row.get(str(r.exposure)), skis.get(str(r.line))
            if i is not None and j is not None:
                u[i, j], c[i, j] = (r.dX, r.dY, r.dZ), (r.X, r.Y, r.Z)
    ok = np.flatnonzero(np.all(np.isfinite(O), axis=1))
    if len(ok) >= 2:                          # tail to tip along the flight
        forward = O[ok[-1]] - O[ok[0]]
        flip = np.einsum("nki,i->nk", u, forward) < 0
        u = np.where(flip[..., None], -u, u)
    u = u / np.linalg.norm(u, axis=2, keepdims=True)
    length = cfg.ski_length / LENGTH_UNITS.get(data.length_unit, 1.0)
    _, seg = ski_segments(P[:, 2], P[:, 3], u[:, 0], u[:, 1], c[:, 0], c[:, 1],
                          length=length, binding_fraction=cfg.binding_fraction)
    v = e["v"].to_numpy(float) if "v" in e.columns else np.full(n, np.nan)
    return ids, P, O, seg, v


def _selection(data):
    """``(stick_arrays(data), chosen exposures)``, or None when there is
    nothing to draw."""
    arrays = stick_arrays(data)
    if arrays is None:
        return None
    idx = chosen_exposures(arrays[1], arrays[3], EVERY)
    return (arrays, idx) if idx else None


def tall(data) -> bool | None:
    """True when the figure fits a portrait page better than a landscape one
    (a steep or long descent); None when there is nothing to draw."""
    chosen = _selection(data)
    if chosen is None:
        return None
    (_, P, _, skis, _), idx = chosen
    pts = np.concatenate([P[idx].reshape(-1, 3), skis[idx].reshape(-1, 3)])
    r = np.ptp(pts[np.all(np.isfinite(pts), axis=1)], axis=0) + 1e-9
    return (r[2] + max(r[1], 0.12 * r[0])) / r[0] > 0.55


def landing_profile(data):
    """The landing-slope profile ``(x, z)`` in the project's length unit
    ([intersect] landing_profile of the project, else summary.json's path
    when it names a file), or None (none given, or unreadable: the figure
    is drawn without it)."""
    from photogram.errors import PhotogramError

    path = _settings(data).landing_profile or data.summary.get("landing_profile")
    if not path or not Path(str(path)).is_file():
        return None
    from photogram.jump.coach import read_landing_profile

    try:
        profile = read_landing_profile(Path(str(path)))
    except (PhotogramError, OSError, ValueError):
        return None
    return np.asarray(profile.x, float), np.asarray(profile.z, float)


def _ground_in_view(ground, lo: float, hi: float):
    """The profile's ``(x, z)`` inside ``[lo, hi]`` (ends interpolated), or
    None when it does not overlap."""
    if ground is None:
        return None
    x, z = ground
    a, b = max(lo, x[0]), min(hi, x[-1])
    if not a < b:
        return None
    gx = np.concatenate([[a], x[(x > a) & (x < b)], [b]])
    return gx, np.interp(gx, x, z)


_PAIRS = np.array([(0, 1), (1, 2), (1, 3), (2, 3)])     # P1-P2, P2-P3, P2-P4, P3-P4


def draw_native(ax_s, ax_p, P, O, skis, v, idx, *, speed, fontsize=7.5, scale=0.9) -> None:
    """:func:`photogram.jump.figure.draw_stick` on the native writer's axes:
    the same lines, dots and circles, one path per layer and view instead of
    one matplotlib line per segment."""
    idx = list(idx)
    for ax, cols in ((ax_s, [0, 2]), (ax_p, [0, 1])):
        for j, colour in enumerate((_RIGHT, _LEFT)):
            seg = skis[idx, j][..., cols]                       # (m, 2 ends, 2)
            ax.segments(seg[:, 0], seg[:, 1], color=colour, lw=1.5 * scale, autolim=False)
        body = P[idx][..., cols]                                 # (m, 4, 2)
        ax.segments(body[:, _PAIRS[:, 0]].reshape(-1, 2), body[:, _PAIRS[:, 1]].reshape(-1, 2),
                    color=_BODY, lw=1.2 * scale, autolim=False)
        ax.plot(*body.reshape(-1, 2).T, "o", color=_BODY, ms=2.5 * scale)
        o = O[idx][:, cols]
        ax.plot(o[:, 0], o[:, 1], "o", color="white", mfc="white", mec=_BODY, ms=3.5 * scale)
        ax.set_aspect("equal")
        ax.grid(True, lw=0.3)
    for i in idx:
        if np.isfinite(v[i]):
            ax_s.annotate(speed(v[i]), (P[i, 0, 0], P[i, 0, 2]), xytext=(0, 8), ha="center",
                          fontsize=fontsize)


def draw_figure(doc, data, units: str) -> bool:
    """The side view (X, Z) above the plan (X, Y) at equal scales, as wide
    as the page allows; False if there is nothing to draw."""
    chosen = _selection(data)
    if chosen is None:
        return False
    (ids, P, O, skis, v), idx = chosen
    lu, speed = data.length_unit, f"{data.length_unit}/s"
    ground = landing_profile(data)
    if units == "coach":
        k = LENGTH_UNITS.get(lu, 1.0)
        P, O, skis, v = P * k, O * k, skis * k, v * k * KMH_PER_MS
        ground = None if ground is None else (ground[0] * k, ground[1] * k)
        lu, speed = "m", "km/h"
    pts = np.concatenate([P[idx].reshape(-1, 3), skis[idx].reshape(-1, 3)])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.04 * (hi[0] - lo[0] + 1e-9)
    lo, hi = lo - pad, hi + pad
    ground = _ground_in_view(ground, lo[0], hi[0] + pad)
    if ground is not None:                   # the side view takes the slope in
        lo[2] = min(lo[2], float(ground[1].min()) - pad)
        hi[2] = max(hi[2], float(ground[1].max()) + pad)
    hi[2] += 2.5 * pad                       # room for the speeds above the heads
    hi[0] += pad                             # and for the last one's right half
    xr, yr, zr = hi - lo
    if yr < 0.12 * xr:
        mid = 0.5 * (lo[1] + hi[1])
        lo[1], hi[1], yr = mid - 0.06 * xr, mid + 0.06 * xr, 0.12 * xr
    width = doc.width - 1.05
    room = doc.remaining - 1.6                # labels of both panels and the note
    scale = min(width / xr, room / (zr + yr))
    hs, hp = zr * scale, yr * scale
    side = lambda p: (p[..., 0], p[..., 2])   # noqa: E731
    plan = lambda p: (p[..., 0], p[..., 1])   # noqa: E731
    ax_s, = doc.axes(hs + 0.75, pad_left=0.85, pad_bottom=0.45, pad_top=0.3)
    ax_p, = doc.axes(hp + 0.75, pad_left=0.85, pad_bottom=0.5, pad_top=0.25)
    for ax, (a, b) in ((ax_s, (0, 2)), (ax_p, (0, 1))):
        ax.set_xlim(lo[a], hi[a])
        ax.set_ylim(lo[b], hi[b])
    if getattr(ax_s, "native", False):
        draw_native(ax_s, ax_p, P, O, skis, v, idx, speed=lambda x: f"{x:.1f} {speed}")
    else:
        from photogram.jump.figure import draw_stick

        draw_stick(ax_s, ax_p, P, O, skis, v, idx, side=side, plan=plan,
                   speed=lambda x: f"{x:.1f} {speed}", fontsize=7.5, scale=0.9)
    ax_s.plot([], [], color="tab:red", label="right ski (L1)")
    ax_s.plot([], [], color="tab:blue", label="left ski (L2)")
    if ground is not None:
        ax_s.plot(*ground, color=_SLOPE, lw=1.2, label="landing slope (profile)")
    ax_s.legend(loc="upper right", fontsize=7.5)     # a descent leaves that corner empty
    decorate(ax_s, f"side view (X, Z): exposures {', '.join(ids[i] for i in idx)}",
             None, f"Z [{lu}]", ypad=0.6)
    decorate(ax_p, "plan (X, Y)", f"X [{lu}]", f"Y [{lu}]", ypad=0.6)
    return True
