"""Motion-capture pages: the run, the cameras (median residual vector,
frames tracked, a warning for cameras whose residuals stand out), bone-length
stability and the figures ``photogram mocap`` writes (trajectory.png,
angles.png, reprojection.png, skeletons.png).

The camera rule is :func:`photogram.mocap.evaluation.checks.outlier_cameras`
(median reprojection error above 2.5 x the other cameras' median and 5 px
above it), applied to reprojection.csv, so that a results folder written
before the command warned about it gets the warning too.
"""

from __future__ import annotations

import numpy as np

# the generic hooks register first, whatever imports this module first: the
# section below replaces theirs under the same name
from photogram.report import hooks as _hooks  # noqa: F401
from photogram.report.layout import decorate
from photogram.report.numbers import finite, num
from photogram.report.registry import section

__all__ = ["build", "camera_rows", "bone_stability", "camera_warnings", "METRIC_UNITS"]

#: metrics.csv columns and their units (L: the project's length unit)
METRIC_UNITS = {"com_x": "L", "com_y": "L", "com_z": "L", "speed": "L/s",
                "knee_flexion_r": "deg", "knee_flexion_l": "deg", "hip_flexion_r": "deg",
                "hip_flexion_l": "deg", "lean": "deg", "fore_aft_angle": "deg",
                "fore_aft_distance": "L"}
_FIGURES = (("trajectory.png", "Trajectory of the centre of mass, plan view (world X, Y)", 4.6),
            ("reprojection.png", "Reprojection errors per camera (px)", 3.6),
            ("angles.png", "Joint angles (deg) and speed of the centre of mass over time (s)",
             6.9),
            ("skeletons.png", "Skeletons, side view", 2.4))


def _csv(data, name):
    import pandas as pd

    if not data.has(name):
        return None
    return pd.read_csv(data.folder / name, comment="#", keep_default_na=True)


def _unit(data) -> str:
    return data.length_unit or "m"


# ---------------------------------------------------------------- cameras
def camera_warnings(reprojection) -> tuple[dict, list[str]]:
    """``(flagged, lines)``: the cameras of reprojection.csv (a DataFrame with
    ``camera`` and ``median_px``) whose residuals stand out, and the warning
    lines (:func:`photogram.mocap.evaluation.checks.check_outliers`)."""
    from photogram.mocap.evaluation.checks import check_outliers, outlier_cameras

    if reprojection is None or reprojection.empty:
        return {}, []
    med = {str(c): (float(m) if finite(m) else None)
           for c, m in zip(reprojection.camera, reprojection.median_px)}
    return outlier_cameras(med), check_outliers({c: {"median_px": m} for c, m in med.items()})


def frames_tracked(detections, cameras, n_frames: int) -> dict:
    """Camera -> fraction of the frames in which it has at least one used
    detection (detections.csv)."""
    if detections is None or detections.empty or n_frames <= 0:
        return {}
    seen = detections.groupby("camera")["frame"].nunique()
    return {str(c): float(seen.get(c, 0)) / n_frames for c in cameras}


def camera_rows(reprojection, detections, n_frames: int, flagged: dict) -> list[list[str]]:
    """Per camera: frames tracked, median error, median residual vector,
    mean, 90th percentile (px), detections, and the flag."""
    cams = [str(c) for c in reprojection.camera]
    tracked = frames_tracked(detections, cams, n_frames)
    rows = []
    for r in reprojection.itertuples(index=False):
        c = str(r.camera)
        frac = tracked.get(c)
        rows.append([c, "-" if frac is None else f"{100 * frac:.1f} %", num(r.median_px, 3),
                     _vector(getattr(r, "median_dx_px", None), getattr(r, "median_dy_px", None)),
                     num(r.mean_px, 3), num(r.p90_px, 3), str(r.n),
                     "STANDS OUT" if c in flagged else "ok"])
    return rows


def _vector(dx, dy) -> str:
    if not (finite(dx) and finite(dy)):
        return "-"
    dx, dy = (round(float(v), 1) + 0.0 for v in (dx, dy))     # no "-0.0"
    return f"({dx:+.1f}, {dy:+.1f})"


# ---------------------------------------------------------------- bones
def _limb_joints(name: str, joints: set) -> tuple[str, str] | None:
    for i, ch in enumerate(name):
        if ch == "-" and name[:i] in joints and name[i + 1:] in joints:
            return name[:i], name[i + 1:]
    return None


def bone_stability(joints3d, limbs) -> list[dict]:
    """Per limb the length over the frames of joints3d.csv: ``frames`` (both
    joints present), ``mean``, ``sd`` (n - 1), ``min``, ``max``, ``range``
    and ``cv`` (sd / mean)."""
    cols = set(joints3d.columns)
    joints = {c[:-2] for c in cols if c.endswith("_X") and f"{c[:-2]}_Z" in cols}
    out = []
    for name in limbs:
        pair = _limb_joints(name, joints)
        if pair is None:
            continue
        a, b = ([f"{j}_{x}" for x in "XYZ"] for j in pair)
        d = np.linalg.norm(joints3d[a].to_numpy(float) - joints3d[b].to_numpy(float), axis=1)
        d = d[np.isfinite(d)]
        if len(d) < 2:
            continue
        m, sd = float(d.mean()), float(d.std(ddof=1))
        out.append({"limb": name, "frames": len(d), "mean": m, "sd": sd, "min": float(d.min()),
                    "max": float(d.max()), "range": float(d.max() - d.min()),
                    "cv": sd / m if m > 0 else np.nan})
    return out


# ---------------------------------------------------------------- pages
@section("mocap", "Motion capture", 95,
         applies=lambda d: d.command == "mocap" or d.has("joints3d.csv"), native=True)
def build(doc, data):
    s = data.summary
    L = _unit(data)
    rp = _csv(data, "reprojection.csv")
    flagged, lines = camera_warnings(rp)
    doc.start_section("Motion capture", intro=(
        f"photogram mocap: 3D joints of the athlete from {s.get('counts', {}).get('cameras')} "
        f"cameras. Units: lengths {L}, speed {L}/s, angles deg, image quantities px, time s; "
        "world axes, Z up."))
    _overview(doc, s, L)
    doc.subheading("Warnings")
    known = list(s.get("warnings") or [])
    doc.bullets(known + [w for w in lines if w not in known], size=7.5)
    _metrics(doc, data, L)
    _cameras(doc, data, s, rp, flagged)
    _bones(doc, data, s, L)
    _figures(doc, data)


def _overview(doc, s, L):
    c = s.get("counts") or {}
    rec = s.get("reconstruction") or {}
    fr = s.get("frames") or [None, None]
    fps = s.get("fps")
    rows = [("skeleton", f"{s.get('skeleton')} ({c.get('joints')} joints)"),
            ("source", str(s.get("source"))),
            ("frames", f"{c.get('frames')} ({fr[0]}..{fr[-1]}) at {num(fps, 4)} frames/s"
                       + (f" = {num(c.get('frames') / fps, 3)} s" if finite(fps) and fps
                          and c.get("frames") else "")),
            ("cameras, detections", f"{c.get('cameras')} cameras, {c.get('detections')} "
                                    "joint detections used"),
            ("reconstruction", f"{rec.get('solver')}, {rec.get('iterations')} iterations, "
                               f"{num(rec.get('seconds'), 3)} s, energy "
                               f"{num(rec.get('energy'), 5)} (px^2, robust)")]
    gaps = s.get("gaps")
    if gaps:
        rows.append(("gaps", f"{gaps.get('total')} of {gaps.get('joint_frames')} joint-frames "
                             "(fewer than two cameras agree): empty in joints3d.csv"))
    if finite(s.get("bone_cv_mean")):
        rows.append(("bone length CV", f"{100 * s['bone_cv_mean']:.1f} % (mean over the limbs)"))
    acc = s.get("accuracy")
    if acc:
        rows += [("MPJPE vs truth", f"{100 * acc.get('mpjpe', np.nan):.2f} cm (SIMULATED truth)"
                  if L == "m" else f"{num(acc.get('mpjpe'), 3)} {L} (SIMULATED truth)"),
                 ("knee flexion error", f"{num(acc.get('knee_flexion_mae'), 3)} deg (mean abs)"),
                 ("speed error", f"{num(acc.get('speed_mae'), 3)} {L}/s (mean abs)")]
    if s.get("figures") is False:               # photogram mocap --no-figures
        rows.append(("figures", "not drawn (photogram mocap --no-figures): no trajectory, "
                                "angles, reprojection or skeleton figures in this report"))
    doc.pairs(rows, title="Run")


def _metrics(doc, data, L):
    m = _csv(data, "metrics.csv")
    if m is None or m.empty:
        return
    rows = []
    for k, u in METRIC_UNITS.items():
        if k not in m.columns:
            continue
        v = m[k].to_numpy(float)
        v = v[np.isfinite(v)]
        if not len(v):
            continue
        u = u.replace("L", L)
        rows.append((k.replace("_", " "), u, num(v.mean(), 4), num(v.min(), 4), num(v.max(), 4),
                     f"{len(v)} of {len(m)}"))
    doc.table(["metric", "unit", "mean", "min", "max", "frames"], rows, size=7.5,
              title="Metrics over the run (metrics.csv, per frame)")


def _cameras(doc, data, s, rp, flagged):
    from photogram.mocap.evaluation.checks import OUTLIER_FACTOR, OUTLIER_MIN_PX

    if rp is None or rp.empty:
        return
    doc.start_section("Motion capture: cameras", intro=(
        "Per camera the reprojection errors of the detections used (px): the median, the "
        "median residual vector (detection - projection, x right, y down; near zero for "
        "random error, about the median's size for a static bias), mean, 90th percentile, "
        "and the share of the frames in which the camera has at least one detection used. "
        f"Rule: a camera stands out when its median error is above {OUTLIER_FACTOR:g} x the "
        f"median of the other cameras' medians and at least {OUTLIER_MIN_PX:g} px above it."))
    n_frames = int((s.get("counts") or {}).get("frames") or 0)
    det = _csv(data, "detections.csv")
    doc.table(["camera", "frames tracked", "median", "median vector (dx, dy)", "mean", "p90",
               "detections", "residuals"], camera_rows(rp, det, n_frames, flagged), size=7.5,
              title="Reprojection per camera (px)")
    med = rp.median_px.to_numpy(float)
    vec = rp[["median_dx_px", "median_dy_px"]].to_numpy(float) \
        if {"median_dx_px", "median_dy_px"} <= set(rp.columns) else None
    ax1, ax2 = doc.axes(3.0, ncols=2, gap=0.3)
    names = [str(c) for c in rp.camera]
    x = np.arange(len(names))
    ax1.bar(x, med, color=["tab:red" if n in flagged else "tab:blue" for n in names])
    for n, i in zip(names, x):
        rest = np.delete(med, i)
        rest = rest[np.isfinite(rest)]
        if len(rest) >= 2:
            lim = max(OUTLIER_FACTOR * np.median(rest), np.median(rest) + OUTLIER_MIN_PX)
            ax1.plot([i - 0.4, i + 0.4], [lim, lim], color="0.2", lw=1.0)
    ax1.set_xticks(x, names, fontsize=7)
    decorate(ax1, "median error; line: the limit of the rule", None, "median error [px]")
    ax1.grid(True, axis="y", lw=0.3)
    if vec is not None:
        lim = max(1.0, float(np.nanmax(np.abs(vec))) * 1.3) if np.any(np.isfinite(vec)) else 1
        for (dx, dy), n in zip(vec, names):
            if np.isfinite(dx) and np.isfinite(dy):
                colour = "tab:red" if n in flagged else "tab:blue"
                if getattr(ax2, "native", False):
                    ax2.arrow(0.0, 0.0, dx, dy, color=colour)
                else:
                    ax2.annotate("", (dx, dy), (0, 0), arrowprops=dict(arrowstyle="->",
                                                                       color=colour))
                ax2.annotate(n, (dx, dy), textcoords="offset points", fontsize=7,
                             xytext=(4 if dx >= 0 else -4, -4 if dy >= 0 else 4),
                             ha="left" if dx >= 0 else "right",
                             va="top" if dy >= 0 else "bottom")
        ax2.set_xlim(-lim, lim)
        ax2.set_ylim(lim, -lim)                     # image y down
        ax2.set_aspect("equal")
        decorate(ax2, "median residual vector", "dx [px]", "dy [px] (down)")
        ax2.grid(True, lw=0.3)
    ref = (s.get("reference") or {}).get("reprojection") or {}
    if ref:
        doc.table(["camera", "ours median", "reference median", "detections"],
                  [(c, num(v.get("ours_median_px"), 3), num(v.get("reference_median_px"), 3),
                    v.get("n")) for c, v in ref.items()],
                  title="Against the reference's 3D points (summary.json reference; same "
                        "detections, confidence >= "
                        f"{(s.get('reference') or {}).get('confidence_threshold')}), px",
                  size=7.5)
    tracking = s.get("tracking") or {}
    if tracking:
        doc.table(["camera", "frames", "tracked", "lost", "longest loss", "re-acquired",
                   "other person"],
                  [(c, t.get("frames"), t.get("tracked"), t.get("lost"), t.get("longest_loss"),
                    t.get("reacquired"), t.get("other_person")) for c, t in tracking.items()],
                  title="Tracking per camera (frames)", size=7.5)


def _bones(doc, data, s, L):
    j = _csv(data, "joints3d.csv")
    limbs = list((s.get("limb_lengths") or {}))
    if j is None or not limbs:
        return
    rows = bone_stability(j, limbs)
    if not rows:
        return
    doc.start_section("Motion capture: bone lengths", intro=(
        f"The length of every bone over the frames of joints3d.csv ({L}): a rigid skeleton "
        "keeps it constant, so sd and range measure how stable the reconstruction is. "
        "'model': the limb length the reconstruction estimated with the joints "
        "(summary.json limb_lengths)."))
    model = s.get("limb_lengths") or {}
    doc.table(["bone", "frames", f"model [{L}]", f"mean [{L}]", f"sd [{L}]", f"min [{L}]",
               f"max [{L}]", f"range [{L}]", "cv"],
              [(r["limb"], r["frames"], num(model.get(r["limb"]), 4), num(r["mean"], 4),
                num(r["sd"], 2), num(r["min"], 4), num(r["max"], 4), num(r["range"], 2),
                f"{100 * r['cv']:.1f} %") for r in rows], size=7,
              title=f"Bone-length stability: all {len(rows)} bones")
    ax, = doc.axes(2.8, pad_bottom=1.1)
    x = np.arange(len(rows))
    ax.bar(x, [100 * r["cv"] for r in rows], color="tab:blue")
    ax.set_xticks(x, [r["limb"] for r in rows], rotation=60, ha="right", fontsize=6)
    decorate(ax, "coefficient of variation of each bone's length", None, "sd / mean [%]")
    ax.grid(True, axis="y", lw=0.3)


def _figures(doc, data):
    from photogram.report.data import read_image

    present = [(f, t, h) for f, t, h in _FIGURES if data.has(f)]
    if not present:
        return
    doc.start_section("Motion capture: figures", intro=(
        "The figures photogram mocap wrote into the results folder (PNG), as they are."))
    for name, title, most in present:
        img = read_image(data.folder / name)
        h, w = img.shape[:2]
        height = min(doc.width * h / w, most)
        doc.ensure(height + 0.4)
        doc.subheading(f"{title} ({name})")
        doc.image(img, height)
