"""The results folder of ``photogram mocap`` (all files written atomically).

=======================  ==========================================================
file                     content
=======================  ==========================================================
``joints3d.csv``         frame, time, ``<joint>_X/_Y/_Z`` (project length unit, world
                         axes, Z up; empty: a gap, fewer than two cameras)
``joints3d.trc``         the same for OpenSim (Y up: ``(X, Y, Z)`` is written as
                         ``(Y, Z, X)``, photogram.io.trc; gaps ``NaN``)
``joints3d.c3d``         the same as C3D points (world axes, Z up, mm; gaps invalid,
                         residual -1; needs the ``c3d`` package, skipped without it)
``metrics.csv``          per frame: CoM, speed, knee and hip flexion, lean,
                         outside leg, fore/aft angle and distance (empty where
                         a joint they need is a gap), ``gap_joints``
``angles.mot``           the angles of metrics.csv for OpenSim (degrees, NaN gaps)
``camera_rotations.mot`` pan-tilt cameras: pan, tilt, roll per camera and frame
                         (degrees about the world's up axis; mocap/files.py)
``detections.csv``       the tracked 2D detections used (long format) and the boxes
``reprojection.csv``     per camera: median, median residual vector (x, y), mean,
                         90th percentile (px), count
``bones.csv``            per limb: mean length, standard deviation, CV
``summary.json``         settings, counts, solver, timings, ``gaps`` (how many
                         joint-frames and why), accuracy (truth), comparison
                         with the reference
``*.png``                trajectory, angles, speed, reprojection errors, skeletons
                         (not with ``figures=False``, ``--no-figures``)
``log.txt``              the log of the run
=======================  ==========================================================
"""

from __future__ import annotations

import io
import json
import warnings
from pathlib import Path

import numpy as np

import photogram
from photogram.io.trc import write_trc
from photogram.mocap.files import write_joints
from photogram.project.atomic import atomic_write_bytes, atomic_write_text
from photogram.project.results import to_json_safe
from photogram.project.tables import format_table

__all__ = ["write_outputs", "summary"]


def _fig(size):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    return atomic_write_bytes(path, buf.getvalue())


def summary(result, project, figures: bool = True) -> dict:
    """The content of summary.json; ``figures``: whether the PNG figures
    were drawn (``--no-figures``: not)."""
    rec = result.reconstruction
    ms = project.mocap
    b = result.biomechanics
    out = {
        "status": "ok", "software_version": photogram.__version__,
        "project": {"name": project.name, "path": str(project.path) if project.path else None,
                    "length_unit": project.units.length, "angle_unit": "deg",
                    "image_unit": "px"},
        "command": "mocap", "skeleton": result.skeleton.name, "source": result.info["source"],
        "fps": result.fps, "frames": [int(result.frames[0]), int(result.frames[-1])],
        "counts": {"frames": len(result.frames), "cameras": result.cameras.n_cameras,
                   "joints": result.skeleton.n_joints,
                   "detections": int(np.sum(np.nan_to_num(result.observations[..., 2]) > 0)),
                   "runs": len(result.breaks) + 1},
        "reconstruction": {"solver": rec.solver, "energy": rec.energy,
                           "iterations": rec.iterations, "seconds": rec.seconds,
                           "windows": rec.n_windows, "stages": rec.stages,
                           "settings": dict(ms.reconstruction),
                           "filter": result.info.get("filter")},
        "limb_lengths": {f"{a}-{b_}": float(v) for (a, b_), v in
                         zip(result.skeleton.limbs, rec.limb_lengths)},
        "reprojection": result.reprojection,
        "bone_cv_mean": float(np.nanmean([v[2] for v in result.bones.values()]))
        if result.bones else None,
        "metrics_mean": {k: float(np.nanmean(b[k])) for k in b if k != "outside"
                         and np.any(np.isfinite(b[k]))},
        "axes": "world, Z up, project length unit; TRC: Y up (Y, Z, X)",
        "timings": result.info.get("timings", {}),
        "warnings": list(project.warnings),
        "figures": bool(figures),
    }
    if rec.gaps is not None:                    # joint-frames fewer than 2 cameras see
        out["gaps"] = rec.gaps.summary(result.skeleton.joints)
    if "tracking" in result.info:               # per camera: tracked, lost, re-acquired
        out["tracking"] = result.info["tracking"]
    if "people" in result.info:                 # the multi-view choice (section 5)
        out["people"] = result.info["people"]
    if result.info.get("rotation") == "estimate":
        out["rotation"] = _rotation_summary(result)
    if "sync" in result.info:
        out["synchronisation"] = result.info["sync"]
    if result.accuracy is not None:
        out["accuracy"] = result.accuracy
    if result.reference is not None:
        out["reference"] = result.reference
    return to_json_safe(out)


def _rotation_summary(result) -> dict:
    rec = result.reconstruction
    per = result.info.get("differences", {})
    cams = {}
    for c, name in enumerate(result.cameras.names):
        rd = per.get(name)
        cams[name] = {"pairs": int(len(rd.ok)) if rd is not None else 0,
                      "failed_pairs": int(np.sum(~rd.ok)) if rd is not None else None,
                      "median_inliers": float(np.median(rd.inliers))
                      if rd is not None and len(rd.ok) else None,
                      "used": bool(np.any(result.info["weights"][:, c] > 0))
                      if len(result.info["weights"]) else False}
    out = {"mode": "estimate", "cameras": cams,
           "bootstrap_last_change_m": rec.bootstrap_history[-1] if rec.bootstrap_history
           else None, "rotations_file": "rotations.csv"}
    for key in ("rotation_errors", "rotation_errors_bootstrap", "difference_errors_deg"):
        if key in result.info:
            out[key] = result.info[key]
    return out


def _detections_table(result) -> str:
    F, C, J, _ = result.observations.shape
    f, c, j = np.nonzero(np.nan_to_num(result.observations[..., 2]) > 0)
    o = result.observations[f, c, j]
    cols = {"frame": result.frames[f], "camera": np.array(result.cameras.names)[c],
            "joint": np.array(result.skeleton.joints)[j],
            "x": np.round(o[:, 0], 2), "y": np.round(o[:, 1], 2),
            "confidence": np.round(o[:, 2], 3)}
    return format_table(cols, comment="tracked detections used by the reconstruction (px)")


def write_outputs(result, project, folder: Path, log_text: str = "", *,
                  figures: bool = True) -> list[Path]:
    """Write the results folder (module docstring); ``figures=False``: without
    the PNG figures (batch runs), as summary.json says. Returns the files."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    sk, X = result.skeleton, result.reconstruction.joints
    unit = project.units.length
    written = [write_joints(folder / "joints3d.csv", result.frames, result.times, X, sk,
                            comment=f"3D joints ({unit}, world axes, Z up) of photogram mocap")]
    markers = {n: X[:, k] for k, n in enumerate(sk.joints)}
    times = result.times + 1.0 / result.fps
    written.append(write_trc(folder / "joints3d.trc", times, markers, units=unit,
                             data_rate=result.fps, frames=result.frames + 1))
    c3d = _write_c3d(folder / "joints3d.c3d", X, sk, result.fps, unit)
    if c3d is not None:
        written.append(c3d)
    b = result.biomechanics
    cols = {"frame": result.frames, "time": np.round(result.times, 6)}
    cols.update({k: (v if k == "outside" else np.round(v, 6)) for k, v in b.items()})
    cols["gap_joints"] = _gap_joints(result)
    written.append(atomic_write_text(folder / "metrics.csv", format_table(
        cols, comment="per-frame quantities of photogram mocap (docs/mocap.md, Metrics)")))
    from photogram.mocap.files import write_angles_mot, write_camera_rotations_mot
    written.append(write_angles_mot(folder / "angles.mot", result.times, b))
    if result.info.get("rotation") == "estimate" or result.cameras.R.shape[0] > 1:
        written.append(write_camera_rotations_mot(folder / "camera_rotations.mot",
                                                  result.times, result.cameras))
    written.append(atomic_write_text(folder / "detections.csv", _detections_table(result)))
    rp = result.reprojection
    written.append(atomic_write_text(folder / "reprojection.csv", format_table({
        "camera": list(rp), "median_px": [rp[c]["median_px"] for c in rp],
        "median_dx_px": [rp[c].get("median_dx_px") for c in rp],
        "median_dy_px": [rp[c].get("median_dy_px") for c in rp],
        "mean_px": [rp[c]["mean_px"] for c in rp], "p90_px": [rp[c]["p90_px"] for c in rp],
        "n": [rp[c]["n"] for c in rp]})))
    bones = result.bones
    if bones:
        written.append(atomic_write_text(folder / "bones.csv", format_table({
            "limb": list(bones), "mean": [round(v[0], 6) for v in bones.values()],
            "std": [round(v[1], 6) for v in bones.values()],
            "cv": [round(v[2], 6) for v in bones.values()]})))
    if result.info.get("rotation") == "estimate":
        from photogram.mocap.files import write_camera_frames
        written.append(write_camera_frames(
            folder / "rotations.csv", result.frames, result.cameras, project,
            comment="estimated rotations per camera and frame (world to camera; the layout "
                    "of camera_frames: usable as rotation = \"known\")"))
        per = result.info.get("differences") or {}
        if per:
            from photogram.mocap.motion.rotation_series import write_rotation_differences
            written.append(write_rotation_differences(folder / "rotation_differences.csv",
                                                      per, first_frame=int(result.frames[0])))
    if figures:
        written += _plots(result, folder, unit)
    written.append(atomic_write_text(folder / "summary.json", json.dumps(
        summary(result, project, figures), indent=2, allow_nan=False) + "\n"))
    written.append(atomic_write_text(folder / "log.txt", log_text))
    return written


def _gap_joints(result) -> list[str]:
    """Per frame the joints that are gaps (space separated; empty: none)."""
    gaps = result.reconstruction.gaps
    if gaps is None:
        return [""] * len(result.frames)
    names = np.array(result.skeleton.joints)
    return [" ".join(names[row]) for row in gaps.mask]


def _write_c3d(path: Path, X, sk, fps, unit):
    try:
        import c3d
    except ImportError:
        return None
    from photogram.project.model import LENGTH_UNITS
    scale = LENGTH_UNITS.get(unit, 1.0) * 1000.0          # to mm
    writer = c3d.Writer(point_rate=float(fps), point_units="mm  ")
    writer.set_point_labels([n.ljust(16)[:16] for n in sk.joints])
    for f in range(len(X)):
        pts = np.zeros((sk.n_joints, 5), np.float32)
        ok = np.all(np.isfinite(X[f]), axis=1)
        pts[ok, :3] = X[f][ok] * scale
        pts[~ok, 3] = -1.0                                  # residual -1: invalid point
        writer.add_frames([(pts, np.zeros((0, 0), np.float32))])
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)      # "No analog data found in file."
        writer.write(buf)
    return atomic_write_bytes(path, buf.getvalue())


# --------------------------------------------------------------------------
def _plots(result, folder: Path, unit: str = "m") -> list[Path]:
    import matplotlib.style
    out = []
    with matplotlib.style.context("default"):
        out.append(_plot_trajectory(result, folder / "trajectory.png", unit))
        out.append(_plot_series(result, folder / "angles.png", unit))
        out.append(_plot_reprojection(result, folder / "reprojection.png"))
        out.append(_plot_skeletons(result, folder / "skeletons.png"))
    return out


def _plot_trajectory(result, path, unit="m"):
    """The plan view of the centre of mass and the cameras; kept for the
    next call with the same cameras (:func:`_reused`)."""
    b, tb = result.biomechanics, result.truth_biomechanics
    X0 = result.cameras.X0
    names = tuple(result.cameras.names)

    def build():
        fig = _fig((8, 6))
        ax = fig.add_subplot(111)
        lines = [ax.plot(b["com_x"], b["com_y"], "-", color="tab:blue", lw=1.5,
                         label="CoM (reconstructed)")[0]]
        if tb is not None:
            lines.append(ax.plot(tb["com_x"], tb["com_y"], "--", color="black", lw=1,
                                 label="CoM (truth)")[0])
        lines.append(ax.plot(X0[:, 0], X0[:, 1], "^", color="tab:red", label="cameras")[0])
        notes = [ax.annotate(name, p[:2], textcoords="offset points", xytext=(4, 4),
                             fontsize=8) for name, p in zip(names, X0)]
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"X ({unit})")
        ax.set_ylabel(f"Y ({unit})")
        ax.set_title("plan view")
        ax.legend(loc="best", fontsize=8)
        ax.grid(alpha=0.3)
        return fig, (ax, lines, notes)

    def update(artists):
        ax, lines, notes = artists
        data = [(b["com_x"], b["com_y"])] + ([(tb["com_x"], tb["com_y"])] if tb is not None
                                             else []) + [(X0[:, 0], X0[:, 1])]
        for line, (x, y) in zip(lines, data):
            line.set_data(x, y)
        for note, p in zip(notes, X0):
            note.xy = p[:2]
        ax.relim()
        ax.autoscale_view()

    return _reused(("trajectory", unit, tb is None, names), build, update, path)


def _plot_series(result, path, unit="m"):
    """Joint angles and speed over time, four panels. The figure is kept
    for the next call with the same layout (:func:`_reused`): its axes and
    ticks are built once per process, the lines get the new data and the
    axes are scaled to it again (the same PNG, bit for bit, as a new
    figure: tests/test_mocap_figure_reuse.py)."""
    b, tb = result.biomechanics, result.truth_biomechanics
    t = result.times
    panels = [("knee flexion (deg)", ("knee_flexion_r", "knee_flexion_l")),
              ("hip flexion (deg)", ("hip_flexion_r", "hip_flexion_l")),
              ("lean (deg) / fore-aft (deg)", ("lean", "fore_aft_angle")),
              (f"CoM speed ({unit}/s)", ("speed",))]
    series = [(b[k], None if tb is None else tb[k]) for _, keys in panels for k in keys]

    def build():
        fig = _fig((9, 9))
        fig.subplots_adjust(left=0.08, right=0.98, bottom=0.06, top=0.98, hspace=0.2)
        colors = ("tab:red", "tab:blue")
        lines = []
        for i, (title, keys) in enumerate(panels):
            ax = fig.add_subplot(len(panels), 1, i + 1)
            for k, col in zip(keys, colors):
                lines.append(ax.plot(t, b[k], color=col, lw=1.2, label=k)[0])
                if tb is not None:
                    lines.append(ax.plot(t, tb[k], "--", color=col, lw=0.8,
                                         label=k + " (truth)")[0])
            ax.set_ylabel(title, fontsize=8)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="upper right", ncol=2)
        ax.set_xlabel("time (s)")
        return fig, lines

    def update(lines):
        data = [y for pair in series for y in pair if y is not None]
        for line, y in zip(lines, data):
            line.set_data(t, y)
        for ax in {line.axes for line in lines}:
            ax.relim()
            ax.autoscale_view()

    return _reused(("series", unit, tb is None), build, update, path)


def _plot_reprojection(result, path):
    """Box plots of the reprojection errors per camera; the axes kept for
    the next call with the same cameras (:func:`_reused`), the boxes drawn
    anew."""
    proj = result.cameras.project(result.reconstruction.joints)
    err = np.linalg.norm(proj - result.observations[..., :2], axis=-1)
    use = np.nan_to_num(result.observations[..., 2]) >= 0.3
    data = [err[:, c][use[:, c] & np.isfinite(err[:, c])] for c in range(err.shape[1])]
    names = tuple(result.cameras.names)

    def boxes(ax):
        drawn = ax.boxplot([d if len(d) else [np.nan] for d in data], showfliers=False)
        artists = [a for group in drawn.values() for a in group]
        ax.set_xticks(range(1, len(data) + 1), names)
        if result.reference is not None:
            ref = [result.reference["reprojection"][c]["reference_median_px"] for c in names]
            artists += ax.plot(range(1, len(data) + 1),
                               [np.nan if r is None else r for r in ref], "kx",
                               label="reference median")
            artists.append(ax.legend(fontsize=8))
        return artists

    def build():
        fig = _fig((8, 4))
        ax = fig.add_subplot(111)
        artists = boxes(ax)
        ax.set_ylabel("reprojection error (px)")
        ax.set_title("per camera (detections with confidence >= 0.3, whiskers 1.5 IQR)")
        ax.grid(alpha=0.3, axis="y")
        return fig, (ax, artists)

    def update(kept):
        ax, artists = kept
        for a in artists:
            a.remove()
        ax.relim()
        artists[:] = boxes(ax)

    return _reused(("reprojection", names, result.reference is None), build, update, path)


def _plot_skeletons(result, path):
    """Up to 8 skeletons side by side; the limbs of a panel are one line
    collection (184 single lines cost more than the rest of the figure) and
    the margins are fixed (tight_layout drew the figure twice). The figure
    is kept for the next call with the same panels (:func:`_reused`): the
    collections get the new limbs and the titles the new frames."""
    from matplotlib.collections import LineCollection
    X = result.reconstruction.joints
    sk = result.skeleton
    F = len(X)
    picks = np.unique(np.linspace(0, F - 1, min(F, 8)).astype(int))
    L = np.array(sk.limb_indices()).reshape(-1, 2)
    side = [sk.joints[a][:2] if sk.name == "ski24" else sk.joints[a][:1] for a in L[:, 0]]
    colors = ["tab:red" if s in ("r_", "R") else "tab:blue" if s in ("l_", "L") else "black"
              for s in side]
    shown = [bool(np.any(np.isfinite(X[f]))) for f in picks]

    def limbs(f):
        P = X[f]
        return (P - np.nanmean(P, axis=0))[:, [0, 2]][L]

    def build():
        fig = _fig((12, 2.8))
        fig.subplots_adjust(left=0.03, right=0.99, bottom=0.09, top=0.8, wspace=0.3)
        panels = []
        for i, f in enumerate(picks):
            ax = fig.add_subplot(1, len(picks), i + 1)
            if not shown[i]:
                continue
            coll = ax.add_collection(LineCollection(limbs(f), colors=colors, linewidths=1.2))
            ax.set_aspect("equal")
            title = ax.set_title(f"frame {result.frames[f]}", fontsize=8)
            ax.tick_params(labelsize=6)
            ax.set_xlim(-1.1, 1.1)
            ax.set_ylim(-1.1, 1.1)
            panels.append((coll, title))
        fig.suptitle("skeletons, side view (X-Z about the mean joint; right red, left blue)",
                     fontsize=9)
        return fig, panels

    def update(panels):
        for (coll, title), f in zip(panels, picks[np.array(shown, bool)]):
            coll.set_segments(limbs(f))
            title.set_text(f"frame {result.frames[f]}")

    return _reused(("skeletons", tuple(shown), tuple(colors), L.tobytes()), build, update,
                   path)


# figures kept for the next call with the same layout, by key; a figure is
# taken out while it is drawn, so that concurrent callers build their own
_REUSED: dict = {}


def _reused(key, build, update, path: Path) -> Path:
    """Draw a figure whose layout ``key`` names into ``path``: a new one
    from ``build() -> (fig, artists)``, or the one kept from an earlier call
    with the same key, after ``update(artists)`` has given it the data of
    this call. Building the axes and their ticks costs most of a small
    figure (matplotlib); a process that writes many results folders (a
    batch, the tests) builds each layout once."""
    entry = _REUSED.pop(key, None)
    if entry is None:
        entry = build()
    else:
        update(entry[1])
    out = _save(entry[0], path)
    while len(_REUSED) >= 8:                    # at most 8 kept (~2-4 MB each): the oldest go
        _REUSED.pop(next(iter(_REUSED)))
    _REUSED[key] = entry
    return out
