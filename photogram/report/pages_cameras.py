"""One page per camera: interior parameters with sigma and significance,
high correlations, the largest distortion and a distortion plot over the
image format."""

from __future__ import annotations

import os

import numpy as np

from photogram.errors import PhotogramError
from photogram.geometry import camera_model
from photogram.report.layout import decorate
from photogram.report.numbers import finite, num, pair
from photogram.report.pages_sharing import per_station_label, shared_table, sharing_note
from photogram.report.registry import section

#: parameters that are never zero: no significance test
_NOT_TESTED = {"c", "x0", "y0", "fx", "fy", "cx", "cy"}

_INTRO = ("Interior orientation: principal distance, principal point and lens distortion. "
          "t = |value| / sigma; p is the probability of a |t| this large if the parameter were "
          "really zero (Student's t with the redundancy as degrees of freedom): p < 0.05 means "
          "the parameter is significant, otherwise it could be left out (fixed at 0). "
          "Correlations above 0.95 mean that two parameters cannot be told apart well by this "
          "network.")


def _unit(dim: int, unit: str) -> str:
    return "-" if dim == 0 else unit if dim == 1 else f"{unit}^{dim}"


def _significance(name, value, sigma, dof):
    from scipy.special import stdtr

    if name in _NOT_TESTED or not (finite(sigma) and sigma > 0 and finite(value)):
        return "-", "-", "-"
    t = abs(value) / sigma
    p = 2.0 * (1.0 - stdtr(max(float(dof), 1.0), t)) if finite(dof) else np.nan
    return f"{t:.1f}", (f"{p:.3f}" if p >= 0.001 else "<0.001"), ("yes" if p < 0.05 else "no")


def correlations(data, camera: str, limit: float = 0.95):
    """Pairs ``(a, b, r)`` with |r| > limit involving an interior parameter of
    ``camera``, from covariance.npz (or summary.json's high_correlations)."""
    cov = data.covariance
    if cov is None or "labels" not in cov:
        return [(a, b, r) for a, b, r in (data.summary.get("high_correlations") or {})
                .get(camera, [])]
    labels = [str(x) for x in cov["labels"]]
    M = np.asarray(cov["matrix"], float)
    s = np.sqrt(np.clip(np.diag(M), 0, None))
    ok = s > 0
    own = np.array([lab.split(".")[0] == camera and not per_station_label(lab)
                    for lab in labels]) & ok
    out = []
    for i in np.flatnonzero(own):
        r = M[i, ok] / (s[i] * s[ok])
        for j, rij in zip(np.flatnonzero(ok), r):
            if j != i and abs(rij) > limit and not (own[j] and j < i):
                out.append((labels[i], labels[j], float(rij)))
    return sorted(out, key=lambda t: -abs(t[2]))


#: DBAT's other lens models (photogram.geometry.dbat_models): c, x0, y0 first.
DBAT_LENS = ("brown_affine_after", "brown_aspect_first", "brown_forward")


def displacement(cam, xy):
    """Displacement (n, 2) of measured image points ``xy`` from their
    distortion-free positions (image units, y down), or None for a model
    without a pinhole part known here."""
    model, io = camera_model(cam.model), cam.values()
    if cam.model == "brown":
        ideal = io[1:3] + model.correct(xy, io)
    elif cam.model in ("opencv", "opencv_full"):
        ideal = io[2:4] + io[0:2] * model.image_to_ray(xy, io)
    elif cam.model == "aicon" or cam.model in DBAT_LENS:
        ideal = io[1:3] + io[0] * model.image_to_ray(xy, io)
    else:
        return None
    return xy - ideal


def distortion_field(cam, fmt, nx=41, ny=31):
    """Grid (X, Y) over the format and the displacement (dx, dy) of every
    grid point, or None (see :func:`displacement`)."""
    X, Y = np.meshgrid(np.linspace(0, fmt[0], nx), np.linspace(0, fmt[1], ny))
    d = displacement(cam, np.stack([X.ravel(), Y.ravel()], -1))
    if d is None:
        return None
    d = d.reshape(ny, nx, 2)
    return X, Y, d[..., 0], d[..., 1]


def _principal_point(cam):
    io = cam.values()
    if cam.model in ("brown", "aicon") or cam.model in DBAT_LENS:
        return io[1:3]
    return io[2:4] if cam.model in ("opencv", "opencv_full") else None


def _plot_distortion(doc, data, cam, fmt, field):
    X, Y, dx, dy = field
    mag = np.hypot(dx, dy)
    unit = data.image_unit
    ax_map, ax_rad = doc.axes(3.3, ncols=2, widths=[1.45, 1.0], pad_left=0.6, pad_right=0.45,
                              gap=0.15)
    if getattr(ax_map, "native", False):
        _native_map(ax_map, cam, fmt, mag, unit)
    else:
        cs = ax_map.contourf(X, Y, mag, levels=12, cmap="viridis")
        cb = doc.page.figure.colorbar(cs, ax=ax_map, fraction=0.05, pad=0.02)
        cb.set_label(f"|distortion| [{unit}]")
    step = (slice(None, None, 4), slice(None, None, 4))
    biggest = float(mag.max()) or 1.0
    scale = biggest / (0.08 * fmt[0])          # data units of arrow per unit of length
    ax_map.quiver(X[step], Y[step], dx[step], dy[step], angles="xy", scale_units="xy",
                  scale=scale, color="black", width=0.005)
    pp = _principal_point(cam)
    if pp is not None:
        ax_map.plot(*pp, "+", color="red", ms=9, mew=1.2)
    ax_map.set_xlim(0, fmt[0])
    ax_map.set_ylim(fmt[1], 0)
    ax_map.set_aspect("equal")
    decorate(ax_map, "distortion, + principal point", f"x [{unit}]", f"y [{unit}] (down)")
    # along the half-diagonal to the corner farthest from the principal point
    if pp is not None:
        corners = np.array([[0, 0], [fmt[0], 0], [0, fmt[1]], [fmt[0], fmt[1]]], float)
        far = corners[np.argmax(np.linalg.norm(corners - pp, axis=1))]
        line = pp + np.linspace(0, 1, 60)[:, None] * (far - pp)
        ax_rad.plot(np.linalg.norm(line - pp, axis=1),
                    np.linalg.norm(displacement(cam, line), axis=1), color="tab:blue")
        ax_rad.grid(True, lw=0.3)
        decorate(ax_rad, "towards the farthest corner",
                 f"distance from the principal point [{unit}]", f"|distortion| [{unit}]")
    else:
        ax_rad.set_visible(False)


def _native_map(ax, cam, fmt, mag, unit):
    """The distortion magnitude as filled bands (as matplotlib's contourf
    with 12 levels): the field on a finer grid, cut into the levels of nice
    steps, one image; and its colour bar."""
    from photogram.report.pdf.ticks import nice_ticks

    levels = nice_ticks(0.0, float(mag.max()), 12)
    if len(levels) < 2 or levels[-1] < mag.max():
        step = levels[1] - levels[0] if len(levels) > 1 else float(mag.max()) or 1.0
        levels = np.append(levels, levels[-1] + step)
    fine = distortion_field(cam, fmt, nx=161, ny=121)
    m = np.hypot(fine[2], fine[3])
    band = np.clip(np.searchsorted(levels, m, side="right") - 1, 0, len(levels) - 2)
    mid = (levels[band] + levels[band + 1]) / 2
    sx, sy = fmt[0] / 160 / 2, fmt[1] / 120 / 2
    bar = ax.imshow(mid, extent=(-sx, fmt[0] + sx, fmt[1] + sy, -sy), cmap="viridis",
                    vmin=levels[0], vmax=levels[-1])
    ax.colorbar(bar, label=f"|distortion| [{unit}]", fraction=0.05, pad=0.02)


def _heatmap(doc, data, name):
    cov = data.covariance
    if cov is None or "labels" not in cov:
        return
    labels = [str(x) for x in cov["labels"]]
    idx = [i for i, lab in enumerate(labels)
           if lab.split(".")[0] == name and not per_station_label(lab)]
    M = np.asarray(cov["matrix"], float)[np.ix_(idx, idx)]
    s = np.sqrt(np.clip(np.diag(M), 0, None))
    keep = s > 0
    if keep.sum() < 2:
        return
    C = M[np.ix_(keep, keep)] / np.outer(s[keep], s[keep])
    names = [labels[i].split(".", 1)[1] for i, k in zip(idx, keep) if k]
    ax = doc.float_right(3.2, 3.0, pad_left=0.45, pad_bottom=0.45)
    native = getattr(ax, "native", False)
    im = ax.imshow(C, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(len(names)), names, rotation=90)
    ax.set_yticks(range(len(names)), names)
    for i in range(len(names)):
        for j in range(len(names)):
            ax.text(j, i, f"{C[i, j]:.2f}", ha="center", va="center", size=5.5,
                    color="white" if abs(C[i, j]) > 0.6 else "black")
    if native:
        ax.colorbar(im, label="correlation [-]", fraction=0.05, pad=0.03)
    else:
        cb = doc.page.figure.colorbar(im, ax=ax, fraction=0.05, pad=0.03)
        cb.set_label("correlation [-]")
    decorate(ax, "correlations (interior)")


def is_fixed(cam) -> bool:
    """True when no parameter of ``cam`` was estimated (every one fixed)."""
    return not any(p.free for p in cam.parameters.values())


def _input_covariance(data, name):
    """The results folder whose covariance of the fixed interior orientation of
    camera ``name`` was propagated into this adjustment, or None."""
    ic = data.summary.get("interior_covariance")
    if not isinstance(ic, dict):
        return None
    own = [p for p in ic.get("parameters") or [] if str(p).split(".")[0] == name]
    return os.path.normpath(str(ic["from"])) if own and ic.get("from") else (
        "an earlier calibration" if own else None)


def camera_source(data, name, cam):
    """The file a fixed camera was taken from (as the project names it), or None."""
    if cam.source:
        return cam.source
    prj = data.project.cameras.get(name) if data.project is not None else None
    return getattr(prj, "source", None)


def _fixed_note(data, name, cam, source):
    src = camera_source(data, name, cam)
    where = f" (from {src})" if src else ""
    text = (f"Every parameter of this camera is fixed in this adjustment{where}: it has no "
            "sigma, t or p here.")
    if source:
        return text + (" The correlations below are those of the calibration the values come "
                       f"from ({source}; its report shows them all), whose covariance was "
                       "propagated into this adjustment; they are not estimated here.")
    return text + " A fixed camera has no estimated correlations."


def _correlation_table(doc, data, name, fixed, source):
    if fixed and not source:
        return
    high = correlations(data, name)
    title = "Correlations above 0.95" + (" (of the input calibration)" if fixed else "")
    doc.table(["parameter", "with", "correlation"],
              [(a, b, f"{r:+.3f}") for a, b, r in high[:15]], align="llr", title=title,
              note=(f"... and {len(high) - 15} more" if len(high) > 15 else None))


def _distortion(doc, data, cam, fmt):
    field = None
    if fmt is not None:
        try:
            field = distortion_field(cam, fmt)
        except PhotogramError as exc:
            doc.text(f"distortion not evaluated: {exc.one_line()}", size=8)
    if field is None:
        return
    mag = np.hypot(field[2], field[3])
    k = np.unravel_index(np.argmax(mag), mag.shape)
    half_diag = 0.5 * np.hypot(*fmt)
    if not mag[k] > 1e-9 * half_diag:
        state = "fixed at 0" if is_fixed(cam) else "not estimated (every distortion term 0)"
        doc.text(f"No distortion: the lens distortion of this camera is {state}; there is no "
                 "distortion to map.", size=8.5)
        return
    px = ""
    if data.image_unit == "mm" and cam.pixel_size:
        px = f" ({mag[k] / cam.pixel_size[0]:.1f} px)"
    doc.text(f"Largest distortion: {num(mag[k], 3)} {data.image_unit}{px}, "
             f"{100 * mag[k] / half_diag:.2f} % of the half-diagonal, at "
             f"x = {field[0][k]:.0f}, y = {field[1][k]:.0f} {data.image_unit}. The arrows "
             "point from the distortion-free to the measured position (longest arrow = "
             "largest distortion of the arrow grid).", size=8.5)
    _plot_distortion(doc, data, cam, fmt, field)


@section("cameras", "Cameras (interior orientation)", 20,
         applies=lambda d: bool(d.results.cameras), native=True)
def build(doc, data):
    dof = data.summary.get("redundancy")
    for name, cam in sorted(data.results.cameras.items()):
        fmt = data.image_format(name)
        size = f"{cam.image_size[0]} x {cam.image_size[1]} px" if cam.image_size else "size ?"
        pix = (f", pixel {cam.pixel_size[0]:g} x {cam.pixel_size[1]:g} mm"
               if cam.pixel_size else "")
        fixed = is_fixed(cam)
        source = _input_covariance(data, name) if fixed else None
        doc.start_section(f"Camera {name}", intro=_INTRO)
        doc.text(f"model {cam.model}, image {size}{pix}; values in {data.image_unit}", size=8.5)
        if fixed:
            doc.text(_fixed_note(data, name, cam, source), size=8.5)
        model = camera_model(cam.model)
        rows = []
        for (pname, par), dim in zip(cam.parameters.items(), model.parameter_dims):
            s = par.sigma_estimated
            v, sv = pair(par.value, s if par.free else None)
            rows.append([pname, _unit(dim, data.image_unit), v, sv,
                         ("estimated" if par.free else "fixed") + sharing_note(cam, pname),
                         *_significance(pname, par.value, s if par.free else None, dof)])
        doc.table(["parameter", "unit", "value", "sigma", "", "t", "p", "significant"], rows,
                  align="llrrlrrl", title="Parameters")
        shared_table(doc, data, name, cam)
        if not fixed:            # a fixed camera's matrix is its calibration's (see there)
            _heatmap(doc, data, name)
        _correlation_table(doc, data, name, fixed, source)
        _distortion(doc, data, cam, fmt)
        doc.clear_float()
