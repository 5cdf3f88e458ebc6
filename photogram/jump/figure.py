"""Figures of the stick model (matplotlib, Agg, written atomically).

* :func:`plot_stick_figure`: the ski-jump paper's Fig. 8: the stick model
  (P1..P4, the two ski segments, O) of every ``every``-th exposure projected
  on the XZ plane (side view) and the XY plane (plan view), laid out along
  the flight at the true positions, with the speed of O annotated.
* :func:`time_series_figure`: every parameter against time with its ±1 sigma
  band.

Output is deterministic for equal input: matplotlib's default style (not the
user's matplotlibrc) and no Software/date metadata in the PNG.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.jump import definitions as defs
from photogram.jump.coach import KMH_PER_MS
from photogram.project.atomic import atomic_write_bytes

__all__ = ["plot_stick_figure", "time_series_figure", "draw_stick", "chosen_exposures"]

_RIGHT, _LEFT, _BODY = "tab:red", "tab:blue", "black"
_SLOPE = "tab:brown"


def chosen_exposures(P, skis, every: int) -> list[int]:
    """The exposures a stick figure draws: every ``every``-th one whose
    points and skis are all measured; where gaps (points or skis not
    measured, e.g. flagged by photogram track) leave none of those, every
    ``every``-th complete one."""
    complete = [i for i in range(len(P))
                if np.all(np.isfinite(P[i])) and np.all(np.isfinite(skis[i]))]
    return [i for i in complete if i % int(every) == 0] or complete[::int(every)]


def _new_figure(size):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


def keep_labels_inside(fig, margin_px: float = 4.0) -> float:
    """Widen the left margin until every axis' y label and tick labels lie
    inside the figure; return the leftmost label edge (px) after it.

    ``tight_layout`` places the axes before ``set_aspect("equal",
    adjustable="box")`` moves them, so a tall side view's y label could end
    left of the figure (stick.png's "Z" label was clipped). The figure is
    laid out as for drawing (ticks, aspect, text) without rasterising it:
    the PNG is drawn once, when it is saved."""
    for _ in range(3):
        fig.draw_without_rendering()
        renderer = fig.canvas.get_renderer()
        x0 = min(min([ax.yaxis.label.get_window_extent(renderer).x0] +
                     [t.get_window_extent(renderer).x0 for t in ax.get_yticklabels()
                      if t.get_text()]) for ax in fig.axes)
        if x0 >= margin_px:
            return float(x0)
        width = fig.get_figwidth() * fig.dpi
        fig.subplots_adjust(left=fig.subplotpars.left + (margin_px - x0) / width)
    return float(x0)


def _save(fig, path: str | Path, dpi: int) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    return atomic_write_bytes(path, buf.getvalue())


def _style():
    import matplotlib.style

    return matplotlib.style.context("default")


def _plan_axes(model, along: str):
    """Unit vectors (horizontal abscissa, lateral) in world XY and labels."""
    if along == "x":
        return np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), ("X", "Y")
    if along != "flight":
        raise InputError(f"unknown along={along!r}", hint='use "x" or "flight"')
    ok = np.flatnonzero(np.all(np.isfinite(model.O), axis=1))
    if len(ok) < 2:
        raise InputError('along="flight" needs O at two exposures at least')
    h = model.O[ok[-1]] - model.O[ok[0]]
    h[2] = 0.0
    if np.linalg.norm(h) == 0:
        raise InputError('along="flight": O does not move horizontally')
    h /= np.linalg.norm(h)
    return h, np.array([-h[1], h[0], 0.0]), ("along flight", "lateral")


def draw_stick(ax_s, ax_p, P, O, skis, v, idx, *, side, plan, speed, fontsize=7,
               scale=1.0):
    """Draw the stick model of the exposures ``idx`` into a side-view and a
    plan-view axes (shared by stick.png and the report's vector Fig. 8).

    Parameters
    ----------
    ax_s, ax_p : matplotlib Axes
    P : ndarray (n, 4, 3)
        P1..P4; ``O`` (n, 3); ``skis`` (n, 2, 2, 3) tail and tip per ski
        (0 right, 1 left); ``v`` (n,) the speed of O (NaN: not annotated).
    idx : list of int
    side, plan : callable
        ``(..., 3) -> (abscissa, ordinate)`` of each view.
    speed : callable
        ``v -> str``, the annotation above the head.
    fontsize : float
        Of the speed annotations (points).
    scale : float
        Line widths and marker sizes times this.
    """
    for ax, proj in ((ax_s, side), (ax_p, plan)):
        for i in idx:
            for ski, colour in zip(skis[i], (_RIGHT, _LEFT)):
                ax.plot(*proj(ski), color=colour, lw=1.5 * scale)
            P1, P2, P3, P4 = P[i]
            for a, b in ((P1, P2), (P2, P3), (P2, P4), (P3, P4)):
                ax.plot(*proj(np.stack([a, b])), color=_BODY, lw=1.2 * scale)
            ax.plot(*proj(P[i]), "o", color=_BODY, ms=2.5 * scale)
            ax.plot(*proj(O[i][None]), "o", mfc="white", mec=_BODY, ms=3.5 * scale)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, lw=0.3)
    for i in idx:
        if np.isfinite(v[i]):
            x, z = side(P[i, 0])
            ax_s.annotate(speed(v[i]), (x, z), xytext=(0, 8), textcoords="offset points",
                          ha="center", fontsize=fontsize)


def _profile_in_view(profile, k, along, x_lo, x_hi):
    """The profile's (x, z) inside ``[x_lo, x_hi]`` (scaled by ``k``, ends
    interpolated), or None (no profile, abscissa not world X, no overlap)."""
    if profile is None or along != "x":
        return None
    x = np.asarray(profile.x, float) * k
    z = np.asarray(profile.z, float) * k
    lo, hi = max(x_lo, x[0]), min(x_hi, x[-1])
    if not lo < hi:
        return None
    inside = (x > lo) & (x < hi)
    gx = np.concatenate([[lo], x[inside], [hi]])
    return gx, np.interp(gx, x, z)


def plot_stick_figure(model, path_png: str | Path, every: int = 3, *, along: str = "x",
                      dpi: int = 100, title: str | None = None, coach: bool = False,
                      profile=None) -> Path:
    """The stick model at evenly spaced exposures in side and plan view.

    Parameters
    ----------
    model : StickModel
    path_png : str or Path
        PNG to write (atomically; the folder must exist).
    every : int
        Draw exposures 0, every, 2 every, ...
    along : "x" or "flight"
        Abscissa of both views: world X, or the horizontal direction of the
        flight (O from the first to the last exposure).
    dpi : int
    title : str, optional
    coach : bool
        Lengths in m and the speed in km/h (default: the model's length
        unit and that unit per second).
    profile : ProfileGround, optional
        The landing-slope profile (world X, Z in the model's length unit,
        :func:`photogram.jump.coach.read_landing_profile`), drawn in the side
        view under the jumper when ``along`` is "x" (the profile's abscissa);
        the view's height range takes it in.

    Returns
    -------
    Path
    """
    if int(every) < 1:
        raise InputError(f"every must be >= 1, got {every}")
    ex, ey, (lx, ly) = _plan_axes(model, along)
    unit = model.length_unit
    k = 1.0
    speed = f"{unit}/s"
    if coach:
        from photogram.project.model import LENGTH_UNITS
        k, unit, speed = LENGTH_UNITS[unit], "m", "km/h"
    P, O, skis = model.P * k, model.O * k, model.skis * k
    v = model.values["v"] * (k * KMH_PER_MS if coach else 1.0)
    idx = chosen_exposures(model.P, model.skis, every)
    if not idx:
        with _style():
            fig = _new_figure((8, 2))
            fig.text(0.5, 0.5, "no exposure with all jumper points and both skis",
                     ha="center", va="center")
            return _save(fig, path_png, dpi)

    def side(p):   # (..., 3) -> abscissa, Z
        return p @ ex, p[..., 2]

    def plan(p):   # (..., 3) -> abscissa, lateral
        return p @ ex, p @ ey

    # equal scales in both panels: the panel heights follow the data ranges
    # (a steep descent needs a tall side view), with a common abscissa range
    pts = np.concatenate([P[idx].reshape(-1, 3), skis[idx].reshape(-1, 3)])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    xs, zs = side(pts)
    _, ys = plan(pts)
    pad = 0.05 * (np.ptp(xs) + 1e-9)
    ground = _profile_in_view(profile, k, along, xs.min() - pad, xs.max() + pad)
    if ground is not None:
        zs = np.concatenate([zs, ground[1]])
    xr = np.ptp(xs) + 2 * pad
    zr, yr = np.ptp(zs) + 2 * pad, max(np.ptp(ys) + 2 * pad, 0.15 * xr)
    height = float(np.clip(11.0 * (zr + yr) / xr + 1.5, 4.0, 14.0))
    with _style():
        fig = _new_figure((12, height))
        ax_s, ax_p = fig.subplots(2, 1, gridspec_kw={"height_ratios": [zr, yr]})
        ax_s.set_xlim(xs.min() - pad, xs.max() + pad)
        ax_p.set_xlim(xs.min() - pad, xs.max() + pad)
        ax_s.set_ylim(zs.min() - pad, zs.max() + pad)
        ymid = 0.5 * (ys.min() + ys.max())
        ax_p.set_ylim(ymid - yr / 2, ymid + yr / 2)
        draw_stick(ax_s, ax_p, P, O, skis, v, idx, side=side, plan=plan,
                   speed=lambda x: f"{x:.1f} {speed}")
        if ground is not None:
            ax_s.plot(*ground, color=_SLOPE, lw=1.2, label="landing slope (profile)")
            ax_s.legend(loc="upper right", fontsize=7)
        ax_s.set_ylabel(f"Z [{unit}]")
        ax_p.set_ylabel(f"{ly} [{unit}]")
        ax_p.set_xlabel(f"{lx} [{unit}]")
        ax_s.set_title(title or f"stick model every {every} exposures "
                       f"({model.fps:g} fps): side view (XZ) and plan (XY)", fontsize=9)
        ax_p.plot([], [], color=_RIGHT, label="right ski (L1)")
        ax_p.plot([], [], color=_LEFT, label="left ski (L2)")
        ax_p.legend(loc="upper right", fontsize=7)
        fig.tight_layout()
        keep_labels_inside(fig)
        return _save(fig, path_png, dpi)


def time_series_figure(frame, path_png: str | Path, *, dpi: int = 100) -> Path:
    """Every parameter of a ``StickModel.to_frame()`` table against time,
    with ±1 sigma bands where ``sigma_<name>`` columns exist.

    Units are taken from ``frame.attrs`` (``angle_unit``, ``length_unit``;
    default rad and the unnamed unit).
    """
    names = [p for p in (*defs.PARAMETERS, "H") if p in frame.columns]
    if not names:
        raise InputError("the table has none of the stick model parameters",
                         hint=f"expected columns {', '.join(defs.PARAMETERS)}")
    aunit = frame.attrs.get("angle_unit", "rad")
    lunit = frame.attrs.get("length_unit", "")
    t = frame["time"].to_numpy(float) if "time" in frame.columns else np.arange(len(frame))
    ncol = 2
    nrow = (len(names) + ncol - 1) // ncol
    with _style():
        fig = _new_figure((10, 2.0 * nrow + 0.6))
        axes = np.atleast_1d(fig.subplots(nrow, ncol, sharex=True)).ravel()
        for ax, name in zip(axes, names):
            y = frame[name].to_numpy(float)
            ax.plot(t, y, color="tab:blue", lw=1.2, marker=".", ms=3)
            if "sigma_" + name in frame.columns:
                s = frame["sigma_" + name].to_numpy(float)
                ax.fill_between(t, y - s, y + s, color="tab:blue", alpha=0.25, lw=0)
            if name in defs.ANGLE_PARAMETERS:
                u = aunit
            elif name == "v":
                u = frame.attrs.get("speed_unit", f"{lunit}/s")
            else:
                u = lunit
            ax.set_ylabel(f"{name} [{u}]", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(True, lw=0.3)
        for ax in axes[len(names):]:
            ax.set_visible(False)
        for ax in axes[max(0, len(names) - ncol):len(names)]:
            ax.set_xlabel("time [s]" if "time" in frame.columns else "exposure", fontsize=8)
        fig.suptitle("stick model parameters (band: ±1 sigma)", fontsize=9)
        fig.tight_layout()
        return _save(fig, path_png, dpi)
