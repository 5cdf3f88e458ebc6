"""Monte Carlo pages: the analogues of the paper's Tables 1 and 2, the ratio
``sigma_mc / sigma_prop`` of every quantity against its 95 % band, and
histograms of the samples against the propagated normal distribution.

The paper (Nes, Hadem, Nilsen, Kart og Plan 72, section 5) gives in Table 1
the Monte-Carlo sigmas of the interior parameters c, x0, y0 (px, from the
lab) and of the camera positions X0, Y0, Z0 (dm, from the field) per camera,
and in Table 2 the mean coordinate sigmas sigma_X, sigma_Y, sigma_Z (dm) of
the jumper points P1..P4 at three jumper positions (t1, t9, t17). Here
Table 1 holds every station and interior quantity of the chain, Table 2
every exposure (RMS over its jumper points), each with the Monte-Carlo and
the propagated sigma.

The band: for ``n`` runs of a normal quantity with true sigma ``s``,
``(n - 1) sigma_mc^2 / s^2`` is chi-square with ``n - 1`` degrees of freedom
(NIST/SEMATECH e-Handbook of Statistical Methods, section 1.3.5.8,
"Chi-Square Test for the Standard Deviation"), so ``sigma_mc / s`` lies in
``[sqrt(chi2_{n-1}(0.025) / (n-1)), sqrt(chi2_{n-1}(0.975) / (n-1))]`` with
probability 95 % (:func:`photogram.montecarlo.report.ratio_band`).
"""

from __future__ import annotations

import numpy as np

# the generic hooks register first, whatever imports this module first: the
# section below replaces theirs under the same name
from photogram.report import hooks as _hooks  # noqa: F401
from photogram.report.layout import decorate
from photogram.report.numbers import num
from photogram.report.registry import section

__all__ = ["build", "band_of", "table1_rows", "table2_rows", "MAX_ROWS"]

#: longest per-quantity table printed in full; longer ones say what is left out
MAX_ROWS = 120
_GROUP_COLOURS = {"station": "tab:blue", "interior": "tab:orange", "point": "tab:green",
                  "jumper": "tab:red", "stick": "tab:purple"}


def _frame(data, name):
    import pandas as pd

    return pd.read_csv(data.folder / name, comment="#") if data.has(name) else None


def band_of(n_ok: int) -> tuple[float, float]:
    """The 95 % band of ``sigma_mc / sigma_prop`` for ``n_ok`` runs."""
    from photogram.montecarlo.report import ratio_band

    lo, hi = ratio_band(n_ok)
    return float(lo), float(hi)


def _split(quantity: str) -> tuple[str, str]:
    head, _, tail = str(quantity).rpartition(".")
    return (head, tail) if head else (str(quantity), "")


def _cell(mc, prop) -> str:
    return f"{num(mc, 2)} ({num(prop, 2)})"


def table1_rows(frame, group: str):
    """The paper's Table 1 for one group (``station``, ``interior`` or
    ``point``): ``(header, rows)``, one row per station / camera / point, one
    column per parameter with ``sigma_mc (sigma_prop)``, the parameter's
    unit in the header, the smallest and largest ratio last."""
    sub = frame[frame.group == group]
    if sub.empty:
        return [], []
    split = sub.quantity.map(_split)
    items = list(dict.fromkeys(a for a, _ in split))
    params = list(dict.fromkeys(b for _, b in split))
    unit = dict(zip((b for _, b in split), sub.unit.astype(str)))
    cell = {q: _cell(m, p) for q, m, p in zip(sub.quantity, sub.sigma_mc, sub.sigma_prop)}
    ratio = dict(zip(sub.quantity, sub.ratio.astype(float)))
    header = [group] + [f"s_{b} [{unit[b]}]" for b in params] + ["ratio"]
    rows = []
    for a in items:
        r = [ratio[f"{a}.{b}"] for b in params if f"{a}.{b}" in ratio]
        r = np.array([v for v in r if np.isfinite(v)])
        rows.append([a] + [cell.get(f"{a}.{b}", "-") for b in params]
                    + [f"{num(r.min(), 3)}..{num(r.max(), 3)}" if len(r) else "-"])
    return header, rows


def table2_rows(frame):
    """Per exposure: RMS over the jumper points of the Monte-Carlo and the
    propagated sigma of X, Y, Z (the paper's Table 2, every exposure)."""
    sub = frame[frame.group == "jumper"]
    if sub.empty:
        return []
    parts = sub.quantity.str.extract(r"^(?P<point>[^@]+)@(?P<exposure>.+)\.(?P<axis>[^.]+)$")
    sub = sub.assign(**parts)
    rows = []
    for ex, part in sub.groupby("exposure", sort=False):
        row = [str(ex), str(part.point.nunique())]
        for col in ("sigma_mc", "sigma_prop"):
            for axis in ("X", "Y", "Z"):
                v = part.loc[part.axis == axis, col].to_numpy(float)
                row.append(num(np.sqrt(np.nanmean(v ** 2)), 2) if len(v) else "-")
        r = part.ratio.to_numpy(float)
        row.append(f"{num(np.nanmin(r), 3)}..{num(np.nanmax(r), 3)}")
        rows.append(row)
    return rows


def _n_ok(summary) -> int:
    return int(summary.get("runs", 0)) - int(summary.get("failed", 0))


# ---------------------------------------------------------------- pages
@section("montecarlo", "Monte Carlo", 90,
         applies=lambda d: d.command == "montecarlo" or d.has("table1.csv"), native=True)
def build(doc, data):
    s = data.summary
    frame = _frame(data, "summary.csv")
    n = _n_ok(s)
    lo, hi = band_of(n)
    chain = s.get("chain") or {}
    doc.start_section("Monte Carlo", intro=(
        f"{s.get('runs')} runs ({s.get('failed')} failed), seed {s.get('seed')}: each run "
        f"perturbs {', '.join(s.get('perturb') or [])} and repeats the chain; sigma_mc is the "
        "empirical standard deviation of the runs (n - 1), sigma_prop the first-order "
        "propagated one through the same chain. Units: lengths in the project's length unit, "
        "angles in its angle unit, image quantities in px (column 'unit' of summary.csv)."))
    doc.pairs([("chain", ", ".join(f"{k} {v}" for k, v in chain.items() if v not in (None, []))
                or "-"), ("truth", str(s.get("truth"))),
               ("ratio band (95 %)", f"{lo:.4f} .. {hi:.4f} for n = {n} runs: "
                                     "sqrt(chi2_(n-1)(q) / (n-1)), q = 0.025, 0.975 "
                                     "(NIST/SEMATECH e-Handbook 1.3.5.8)"),
               ("full tables", "summary.csv (every quantity), table1.csv, table2.csv, "
                               "samples.csv (every run)")], title="Settings")
    if frame is None or frame.empty:
        doc.text("summary.csv is missing: no tables (run photogram montecarlo again).")
        return
    _table1(doc, frame)
    _table2(doc, frame, data)
    _ratios(doc, frame, lo, hi, n)
    _histograms(doc, data, frame)


def _table1(doc, frame):
    titles = {"station": "stations (exterior orientation of the adjustment step)",
              "interior": "interior orientation (drawn from the calibration's covariance)",
              "point": "collected points"}
    first = True
    for group, what in titles.items():
        header, rows = table1_rows(frame, group)
        if not rows:
            continue
        if first:
            doc.subheading("Table 1 (the paper's Table 1: sigma of c, x0, y0 per camera and "
                           "of X0, Y0, Z0 per station)")
            doc.text("Each cell: sigma_mc (sigma_prop); 'ratio': the smallest and largest "
                     "sigma_mc / sigma_prop of the row. table1.csv holds the same numbers.",
                     size=7.5, color="0.3")
            first = False
        doc.table(header, rows, size=7, title=f"{what}: {len(rows)} rows")


def _table2(doc, frame, data):
    rows = table2_rows(frame)
    if rows:
        unit = frame.loc[frame.group == "jumper", "unit"].iloc[0]
        doc.subheading(f"Table 2: sigma of the jumper points per exposure [{unit}]")
        doc.text("The paper's Table 2 gives the mean sigma_X, sigma_Y, sigma_Z of P1..P4 at "
                 "three jumper positions (t1, t9, t17); here every exposure, Monte Carlo (MC) "
                 "and propagated (prop).", size=7.5, color="0.3")
        doc.table(["exposure", "points", "MC sX", "MC sY", "MC sZ", "prop sX", "prop sY",
                   "prop sZ", "ratio"], rows, size=7.5,
                  note=f"RMS over the jumper points of each exposure; all {len(rows)} "
                       "exposures. Per point and axis over the exposures: table2.csv.")
    t2 = _frame(data, "table2.csv")
    if t2 is not None and not t2.empty:
        doc.table(["quantity", "unit", "exposures", "sigma_mc", "sigma_prop", "ratio",
                   "ratio min", "ratio max", "RMS bias"],
                  [(r.quantity, r.unit, r.exposures, num(r.sigma_mc, 3), num(r.sigma_prop, 3),
                    num(r.ratio, 3), num(r.ratio_min, 3), num(r.ratio_max, 3),
                    num(r.rms_bias, 2)) for r in t2.itertuples(index=False)],
                  title="Table 2 (table2.csv): per jumper point and axis, stick-model "
                        "parameter; RMS over the exposures", size=7)


def _ratios(doc, frame, lo, hi, n):
    r = frame.ratio.to_numpy(float)
    ok = np.isfinite(r)
    doc.new_page()
    doc.subheading("sigma_mc / sigma_prop of every quantity and its 95 % band")
    doc.text(f"{int(ok.sum())} of {len(r)} quantities have a propagated sigma. Grey: the band "
             f"{lo:.4f} .. {hi:.4f} in which the ratio of a quantity lies with 95 % "
             f"probability for n = {n} runs if its propagated sigma is right.", size=8)
    ax, = doc.axes(3.4, pad_right=1.6)
    x = np.arange(len(r))
    ax.axhspan(lo, hi, color="0.85", label="95 % band")
    ax.axhline(1.0, color="0.4", lw=0.6)
    for g, colour in _GROUP_COLOURS.items():
        m = (frame.group.to_numpy() == g) & ok
        if m.any():
            ax.plot(x[m], r[m], ".", ms=3, color=colour, label=g)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    decorate(ax, None, "quantity (order of summary.csv)", "sigma_mc / sigma_prop [-]")
    ax.grid(True, lw=0.3)
    out = ok & ((r < lo) | (r > hi))
    rows = []
    for g, part in frame[ok].groupby("group", sort=False):
        rr = part.ratio.to_numpy(float)
        k = int(((rr < lo) | (rr > hi)).sum())
        rows.append((g, len(rr), num(np.median(rr), 3), num(rr.min(), 3), num(rr.max(), 3), k,
                     f"{100 * k / len(rr):.1f} %"))
    doc.table(["group", "quantities", "median", "min", "max", "outside band", "share"], rows,
              title="Ratios per group", size=7.5,
              note="If every propagated sigma were right, about 5 % of the quantities would "
                   "fall outside the band by chance (fewer or more, since the quantities are "
                   "correlated).")
    sub = frame[out]
    shown = sub.head(MAX_ROWS)
    doc.table(["quantity", "unit", "sigma_mc", "sigma_prop", "ratio"],
              [(q.quantity, q.unit, num(q.sigma_mc, 3), num(q.sigma_prop, 3), num(q.ratio, 4))
               for q in shown.itertuples(index=False)],
              title=f"Quantities outside the band: {len(sub)}", size=7,
              note=(f"{len(sub) - len(shown)} more rows omitted (the first {len(shown)} "
                    "shown); all of them in summary.csv (column ratio)."
                    if len(sub) > len(shown) else None))


def pick_quantities(frame, k: int = 4) -> list[str]:
    """A few quantities to show as histograms: per group (station, interior,
    jumper, stick) the one with the largest propagated sigma."""
    out = []
    for g in ("station", "interior", "point", "jumper", "stick"):
        part = frame[(frame.group == g) & np.isfinite(frame.sigma_prop)
                     & (frame.sigma_prop > 0)]
        if len(part) and len(out) < k:
            out.append(str(part.loc[part.sigma_prop.idxmax(), "quantity"]))
    return out


def _histograms(doc, data, frame):
    if not data.has("samples.csv"):
        return
    import pandas as pd

    names = pick_quantities(frame)
    if not names:
        return
    samples = pd.read_csv(data.folder / "samples.csv", usecols=names + ["failed"])
    samples = samples[samples.failed == 0]
    doc.subheading("Samples against the propagated normal distribution (largest "
                   "propagated sigma of each group)")
    idx = frame.set_index("quantity")
    for i in range(0, len(names), 2):
        axes = doc.axes(2.6, ncols=2, gap=0.2)
        for ax, q in zip(axes, names[i:i + 2]):
            row = idx.loc[q]
            v = samples[q].to_numpy(float)
            v = v[np.isfinite(v)]
            ax.hist(v, bins=min(40, max(8, len(v) // 15)), density=True, color="0.75",
                    edgecolor="0.5", lw=0.3, label=f"{len(v)} runs")
            t, sp = float(row.truth), float(row.sigma_prop)
            xs = np.linspace(min(v.min(), t - 4 * sp), max(v.max(), t + 4 * sp), 200)
            ax.plot(xs, np.exp(-0.5 * ((xs - t) / sp) ** 2) / (sp * np.sqrt(2 * np.pi)),
                    color="tab:red", lw=1.0, label="normal(truth, sigma_prop)")
            ax.set_ylim(0, ax.get_ylim()[1] * 1.3)
            ax.legend(fontsize=6, loc="upper left", frameon=False)
            decorate(ax, f"{q} [{row.unit}]: ratio {num(row.ratio, 3)}",
                     f"{q} [{row.unit}]", "density")
            ax.ticklabel_format(axis="x", useOffset=False)
            ax.tick_params(axis="x", labelsize=6)
    doc.text("Grey: the runs; red: the normal distribution the propagation predicts about "
             "the true value (truth column of summary.csv). The bias is mean - truth.",
             size=7.5, color="0.3")
