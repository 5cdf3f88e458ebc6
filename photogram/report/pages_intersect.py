"""The intersect step: the stick model figure (the ski-jump paper's Fig. 8),
every stick-model parameter over time with its sigma band, the table of
parameters per exposure, and the quality of the jumper points and ski lines."""

from __future__ import annotations

import numpy as np

from photogram.report.layout import decorate
from photogram.report.numbers import decimals_for, finite, num, sig
from photogram.report.registry import section

# photogram.jump and pages_stick are imported where a page is built: the
# reports of calibrate and orient register these sections but never build
# them, and a fresh command process need not import the ski-jump modules
# (issue 23, report speed)


_SHORT = {"alpha": "legs against the ski axis", "beta": "trunk against the ski axis",
          "gamma": "hip angle", "delta_phi": "V angle of the skis", "phi": "ski slope",
          "heading": "direction in plan", "Z0": "height of O (world Z)",
          "H": "height of O above the landing slope", "v": "speed of O"}


def _has_jump(d):
    return d.exposures is not None and len(d.exposures) > 0


def _units(data) -> str:
    return data.extra.get("units", "project")


def _unit(data, name):
    from photogram.jump.coach import unit_of

    return unit_of(name, data.angle_unit, data.length_unit, _units(data))


def _table(data):
    """exposures.csv in the units of the report (project or coach)."""
    if _units(data) == "coach":
        from photogram.jump.coach import to_coach

        return to_coach(data.exposures, data.angle_unit, data.length_unit)
    return data.exposures


def _params(data):
    from photogram.jump import definitions as defs
    from photogram.jump.coach import HEIGHT

    return [p for p in (*defs.PARAMETERS, HEIGHT) if p in data.exposures.columns]


@section("stick", "Stick model (Fig. 8)", 80, applies=_has_jump, native=True)
def build_stick(doc, data):
    from photogram.report.pages_stick import EVERY, draw_figure, landing_profile, tall

    speed = "km/h" if _units(data) == "coach" else f"{data.length_unit}/s"
    doc.start_section("Stick model (Fig. 8)", landscape=not tall(data), intro=(
        f"The jumper's stick model (head P1, hip P2, bindings P3 P4 (dots), O the midpoint of "
        f"the bindings (circle), the two skis; right ski red, left blue) every {EVERY}rd "
        f"exposure, in a side view (X, Z) and in plan (X, Y), at the intersected positions "
        f"along the flight, both at the same scale, with the speed of O [{speed}] above the "
        "head. Drawn from points3d.csv, lines3d.csv and exposures.csv (the skis: "
        "their lines through the bindings, with the project's ski length and binding "
        "position); stick.png is the same figure as a picture."
        + (" Brown: the landing slope ([intersect] landing_profile) in the side view."
           if landing_profile(data) is not None else "")))
    if not draw_figure(doc, data, _units(data)):
        doc.text("No exposure has all four jumper points and both skis: nothing to draw.",
                 size=8.5)


@section("timeseries", "Stick model over time", 81, applies=_has_jump, native=True)
def build_series(doc, data):
    from photogram.jump.coach import HEIGHT

    e = _table(data)
    names = _params(data)
    doc.start_section("Stick model over time", intro=(
        "Every stick-model parameter against time; the band is ±1 sigma (propagated from "
        "the image measurements and, if given, the orientation's covariance). alpha legs and "
        "beta trunk against the ski axis, gamma hip angle, delta_phi V angle of the skis, phi "
        "ski slope, heading, Z0 height of O (world Z), "
        + ("H height of O above the landing slope, " if HEIGHT in names else "")
        + "v speed of O (docs/stick-model.md)."))
    t = e["time"].to_numpy(float) if "time" in e.columns else np.arange(len(e), dtype=float)
    rows = (len(names) + 1) // 2
    height = min(2.3, (doc.remaining - 0.2) / max(rows, 1))
    for i in range(0, len(names), 2):
        axes = doc.axes(height, ncols=2, pad_left=0.7, pad_bottom=0.45, gap=0.2)
        for ax, name in zip(axes, names[i:i + 2]):
            y = e[name].to_numpy(float)
            ax.plot(t, y, ".-", color="tab:blue", lw=1, ms=3)
            if f"sigma_{name}" in e.columns:
                s = e[f"sigma_{name}"].to_numpy(float)
                ax.fill_between(t, y - s, y + s, color="tab:blue", alpha=0.25, lw=0)
            ax.grid(True, lw=0.3)
            decorate(ax, f"{name}: {_SHORT.get(name, '')}",
                     "time [s]", f"{name} [{_unit(data, name)}]", xpad=0.28, ypad=0.55)
        for ax in axes[len(names[i:i + 2]):]:
            ax.set_visible(False)


@section("stick_table", "Stick model per exposure", 82, applies=_has_jump, native=True)
def build_table(doc, data):
    e = _table(data)
    names = _params(data)
    doc.start_section("Stick model per exposure", intro=(
        "Value ± sigma of every parameter at every exposure ("
        + ("coach.csv holds them in these units" if _units(data) == "coach" else
           "exposures.csv holds them") + " with all digits). Units: "
        + ", ".join(f"{n} [{_unit(data, n)}]" for n in names) + "."))
    rows = []
    for _, x in e.iterrows():
        e_id = x.get("exposure")
        row = [str(e_id) if isinstance(e_id, str) and e_id else "-",
               num(x.get("time"), 3)]
        for n in names:
            s = x.get(f"sigma_{n}")
            d = decimals_for(s, 1, 4) if finite(s) else 2
            row.append(f"{x[n]:.{d}f} ± {s:.{d}f}" if finite(s) and finite(x[n])
                       else num(x[n], 4))
        rows.append(row)
    doc.table(["exp.", "time [s]"] + names, rows, size=7.5)


def _span(values) -> str:
    """"a-b" (or "a") of integer counts; "-" if none are known."""
    if values is None:
        return "-"
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if not v.size:
        return "-"
    lo, hi = int(v.min()), int(v.max())
    return str(lo) if lo == hi else f"{lo}-{hi}"


def point_geometry(data, p3):
    """Rays and intersection angle (deg) of every row of points3d.csv
    (point ``P1`` at exposure ``001`` is ``P1@001`` in residuals.csv and
    points.csv); NaN where the residuals do not list the point."""
    import pandas as pd

    ids = p3["point"].astype(str) + "@" + p3["exposure"].astype(str)
    rays = data.rays if data.has_residuals else pd.DataFrame(columns=["rays", "angle"])
    got = rays.reindex(ids.to_numpy())
    return pd.DataFrame({"point": p3["point"].astype(str).to_numpy(),
                         "rays": got["rays"].to_numpy(float),
                         "angle": got["angle"].to_numpy(float)})


@section("intersect_quality", "Jumper points and ski lines", 83,
         applies=lambda d: d.points3d is not None or d.lines3d is not None, native=True)
def build_quality(doc, data):
    lu = data.length_unit
    s = data.summary
    doc.start_section("Jumper points and ski lines", intro=(
        "Precision of the intersected jumper points and ski lines, and the left/right ski "
        "check: 'ok' the two skis are told apart consistently in all images, 'inconsistent' "
        "they disagree between images, 'ambiguous' too close to tell."))
    checks = s.get("ski_checks") or {}
    if checks:
        counts = {}
        for v in checks.values():
            counts[v] = counts.get(v, 0) + 1
        swapped = [k for k, v in (s.get("swapped_skis") or {}).items() if v]
        doc.pairs([(k, f"{n} exposure(s)") for k, n in sorted(counts.items())]
                  + [("interchanged skis", ", ".join(swapped) or "none")],
                  title="Left/right ski check")
        bad = [k for k, v in checks.items() if v != "ok"]
        if bad:
            doc.text("Not 'ok': " + ", ".join(f"{k} ({checks[k]})" for k in bad), size=8)
    p3 = data.points3d
    if p3 is not None and len(p3):
        geo = point_geometry(data, p3)
        rows = []
        for name, g in p3.groupby("point", sort=True):
            n, a = geo.loc[geo["point"] == name, "rays"], geo.loc[geo["point"] == name, "angle"]
            g = g[np.isfinite(g["X"].to_numpy(float))]          # measured exposures only
            total = np.sqrt((g[["sX", "sY", "sZ"]] ** 2).to_numpy(float).mean(axis=1))
            rows.append([name, str(len(g)), _span(n), num(a.min(), 3), num(a.mean(), 3)]
                        + [sig(g[c].mean()) for c in ("sX", "sY", "sZ")]
                        + [sig(np.nanmax(total)) if np.isfinite(total).any() else "-"])
        doc.table(["point", "exp.", "rays", "min angle", "mean angle", f"sX [{lu}]",
                   f"sY [{lu}]", f"sZ [{lu}]", f"max total [{lu}]"], rows,
                  title="Jumper points", size=7.5,
                  note="exp.: exposures the point was intersected at; "
                       "rays: images the point was measured (and used) in, per exposure; "
                       "angle [deg]: the largest angle between two of its rays, at the point "
                       "(smallest and mean over the exposures); sX, sY, sZ: mean sigmas over "
                       "the exposures; max total: the largest RMS of sX, sY, sZ.")
    l3 = data.lines3d
    if l3 is not None and len(l3):
        rows = []
        for name, g in l3.groupby("line", sort=True):
            ang = np.degrees(g["sigma_angle_rad"].to_numpy(float))
            views = g["stations"].astype(str).str.split().str.len() if "stations" in g.columns \
                else None
            rows.append([name, str(len(g)), _span(views), num(np.nanmean(ang), 3),
                         num(np.nanmax(ang), 3),
                         sig(g["sigma_position"].mean()), num(g["sigma0"].mean(), 3),
                         num(g["sigma0"].max(), 3)])
        doc.table(["line", "exposures", "images", "mean s(dir) [deg]", "max s(dir) [deg]",
                   f"mean s(pos) [{lu}]", "mean sigma0", "max sigma0"], rows,
                  title="Ski lines")
        ax, = doc.axes(2.6, pad_right=1.4)
        for name, g in l3.groupby("line", sort=True):
            ax.plot(g["exposure"].astype(int), g["sigma0"], "o-", ms=3, label=name)
        ax.axhline(1.0, color="0.5", lw=0.8, ls="--")
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
        ax.grid(True, lw=0.3)
        decorate(ax, "sigma0 of each ski line fit", "exposure [-]", "sigma0 [-]")
