"""Summary page (project, adjustment statistics, cost trace, warnings) and
the variance components page."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import photogram
from photogram.project.results_folder import final_folder
from photogram.report.layout import char_width, decorate
from photogram.report.numbers import finite, num
from photogram.report.registry import section

_DATUM = {"control": "control points fixed", "weighted": "control points as weighted observations",
          "free": "free network (inner constraints, minimum trace)",
          "dependent": "dependent relative orientation (a base station and one coordinate "
                       "of another fixed, as DBAT)"}

_HOW_TO_READ = (
    "How to read this report. sigma0 compares how well the measurements fit with how well "
    "they were assumed to fit: near 1 the assumed image precision was right; well above 1 "
    "the measurements are worse than assumed or contain blunders (see Residuals). Every "
    "standard deviation (sigma) in this report is a-posteriori, i.e. scaled by sigma0; about "
    "two thirds of the true errors are smaller than one sigma and almost all (95 %) smaller "
    "than two. Lengths are in the project's length unit, image quantities in the image unit.")


def _sigma0_test(sigma0, r, alpha=0.05):
    """Two-sided 95 % interval of sigma0 for redundancy r, and a verdict."""
    from scipy.special import chdtri

    if not (finite(sigma0) and finite(r) and r > 0):
        return None
    lo, hi = (np.sqrt(chdtri(r, 1 - q) / r) for q in (alpha / 2, 1 - alpha / 2))
    if sigma0 < lo:
        verdict = "below: the measurements fit better than their a-priori sigmas say"
    elif sigma0 > hi:
        verdict = ("above: the measurements fit worse than their a-priori sigmas say "
                   "(too optimistic sigmas, blunders or a model error)")
    else:
        verdict = "inside: the a-priori sigmas agree with the fit"
    return lo, hi, verdict


def _input_files(data):
    if data.project is None:
        return [("files", data.project_note or "not known")]
    p = data.project
    folder = Path(p.path).parent if p.path else None

    def rel(path):
        path = Path(path)
        try:
            return str(path.relative_to(folder)) if folder else str(path)
        except ValueError:
            return str(path)

    files = [(k.replace("_", " "), rel(v)) for k, v in sorted(p.sources.items())]
    known = {f for _, f in files}
    files += [("cameras", c) for c in sorted({rel(c.source) for c in p.cameras.values()
                                              if c.source} - known)]
    return files or [("tables", "(all in the project file)")]


def _computed_by(s) -> str:
    """Which photogram wrote the results and which the report."""
    report = f"report by photogram {photogram.__version__}"
    if s.get("software_version"):
        return f"photogram {s['software_version']}, {report}"
    return f"(version not recorded in summary.json: an older results folder), {report}"


def _counts(s):
    c = s.get("counts") or {}
    if "unknowns" in c:
        return [("observations", f"{c.get('observations')} (image coordinates, priors, "
                                 "constraints)"),
                ("unknowns", f"{c.get('unknowns')} = interior {c.get('interior')} + exterior "
                             f"{c.get('exterior')} + points {c.get('points')}"),
                ("datum conditions", str(c.get("conditions", 0)))]
    keys = ("cameras", "stations", "points", "image_points", "image_lines", "rays_min",
            "rays_max")
    return [(k.replace("_", " "), str(c[k])) for k in keys if k in c]


@section("summary", "Summary", 10, native=True)
def build(doc, data):
    s = data.summary
    doc.start_section("Summary", heading=False)
    doc.heading(f"Accuracy report: {data.name}", size=15)
    adjustment = s.get("sigma0") is not None or s.get("redundancy") is not None
    status = s.get("status")
    doc.text(f"photogram {data.command}" + (f": {status}" if status else "")
             + (f" ({s['message']})" if s.get("message") else ""), size=9.5)
    if adjustment:
        doc.text(_HOW_TO_READ, size=8, color="0.25")
    info = data.info
    rows = [("project", data.name), ("project file", str(info.get("path", "-"))),
            ("results folder", str(final_folder(Path(data.folder).resolve()))),
            ("computed by", _computed_by(s))]
    if info.get("length_unit"):
        rows.append(("units", f"length {data.length_unit}, angles {data.angle_unit}, image "
                              f"{data.image_unit}"))
    if info.get("rotation_direction"):
        rows.append(("rotation", f"{info.get('rotation', 'omega-phi-kappa')}, "
                                 f"{info['rotation_direction']}"))
    if s.get("datum"):
        rows.append(("datum", f"{s['datum']} ({_DATUM.get(s['datum'], '')})"))
    if s.get("orientation_covariance"):
        rows += [("orientation from", str(f)) for f in s["orientation_covariance"]]
    doc.pairs(rows, title="Project")
    doc.pairs(_input_files(data), title="Input files")

    sigma0, r = s.get("sigma0"), s.get("redundancy")
    if not adjustment:                        # Monte Carlo, mocap: their own pages follow
        doc.subheading("Warnings")
        doc.bullets(s.get("warnings"), size=8)
        return
    stats = [("a-priori sigma0", "1 (unitless: weights are 1/sigma^2 of the a-priori sigmas)"),
             ("a-posteriori sigma0", f"{num(sigma0, 5)} (unitless)")]
    if finite(s.get("sigma0_image")):
        stats.append(("sigma0 in image units",
                      f"{num(s['sigma0_image'], 4)} {data.image_unit} (DBAT's 'Sigma0 (pixels)')"))
    stats.append(("redundancy", str(r)))
    test = _sigma0_test(sigma0, r)
    if test:
        stats.append(("sigma0 test (95 %)", f"interval {test[0]:.3f} .. {test[1]:.3f}: "
                                           f"{test[2]}"))
    stats += _counts(s)
    stats.append(("iterations", str(s.get("iterations"))))
    if finite(s.get("initial_cost")):
        stats.append(("cost", f"{num(s['initial_cost'], 6)} -> {num(s.get('final_cost'), 6)} "
                              "(half the sum of squared normalized residuals)"))
    for key in ("exposures",):
        if key in s:
            stats.append((key, str(s[key])))
    doc.pairs(stats, title="Adjustment")

    trace = [c for c in s.get("cost_trace") or [] if finite(c)]
    if len(trace) >= 2:
        ax, = doc.axes(2.3, widths=[1.0], pad_left=1.0, pad_right=3.2)
        ax.plot(np.arange(len(trace)), trace, "o-", ms=3, color="tab:blue")
        if max(trace) > 20 * min(trace) > 0:
            ax.set_yscale("log")
        else:
            ax.ticklabel_format(axis="y", useOffset=False, style="plain")
        if getattr(ax, "native", False):
            ax.integer_ticks("x")
            pad = ax.ylabel_pad()
        else:
            ax.xaxis.get_major_locator().set_params(integer=True)
            pad = tick_label_pad(ax)
        decorate(ax, "cost per iteration (Gauss-Newton / Levenberg-Marquardt)", "iteration",
                 "cost [-]", ypad=pad)
        ax.grid(True, which="both", lw=0.3)
    doc.subheading("Warnings")
    doc.bullets(s.get("warnings"), size=8)


def tick_label_pad(ax, size: float = 7.0) -> float:
    """Distance (inches) from the axes to the y label that clears the widest
    tick label of ``ax`` (``size`` pt; mathtext such as 10^6 counted by its
    visible characters), at least 0.45."""
    lo, hi = sorted(ax.get_ylim())
    locs = [t for t in ax.yaxis.get_major_locator()() if lo <= t <= hi]
    fmt = ax.yaxis.get_major_formatter()
    fmt.set_locs(locs)
    text = [fmt(t) for t in locs]
    chars = [len(t.replace("\\mathdefault", "").replace("$", "").replace("{", "")
                 .replace("}", "").replace("^", "")) for t in text] or [0]
    return max(0.45, max(chars) * char_width(size, mono=False) + 0.2)


@section("variance", "Variance components", 15,
         applies=lambda d: bool(d.summary.get("variance_components")), native=True)
def build_variance(doc, data):
    vc = data.summary["variance_components"]
    doc.start_section("Variance components", intro=(
        "The a-priori sigmas of each group of observations were scaled until every group fits "
        "with sigma0 = 1 (appendix D.3). A factor s^2 above 1: that group is less precise than "
        "assumed (its sigmas are multiplied by s); below 1: more precise."))
    factors, sig = vc.get("factors") or {}, vc.get("sigma") or {}
    doc.table(["group", "variance factor s^2", "sigma factor s"],
              [(g, num(factors[g], 4), num(sig.get(g), 4)) for g in factors],
              title="Estimated variance factors")
    hist = vc.get("history") or []
    groups = [g for g in factors if any(g in h for h in hist)]
    if hist and groups:
        ax, = doc.axes(3.0, pad_right=2.5)
        for g in groups:
            ax.plot(range(1, len(hist) + 1), [h.get(g, np.nan) for h in hist], "o-", ms=3,
                    label=g)
        decorate(ax, None, "iteration of the variance component estimation",
                 "variance factor s^2 [-]")
        ax.grid(True, lw=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
