"""`photogram calibrate BOARD.prj` on a board project (one with ``[board]``):
a multi-camera rig calibrated from a board seen in videos or image folders
(issue 20, docs/board-calibration.md).

Writes into the output folder (whole or not at all):

* ``Calib.toml``: the cameras in Pose2Sim's / anipose's calibration format
  (OpenCV K, distortion, Rodrigues rotation, translation), which
  ``photogram mocap`` reads with ``calibration = "..."``;
* ``cameras.csv``: per camera every interior parameter and the projection
  centre and rotation with their a-posteriori sigmas, the reprojection RMS,
  the median residual vector, frames and corners used, OpenCV's
  single-camera RMS (the start);
* ``board_poses.csv``: every board pose (Rodrigues vector and translation,
  board to world);
* ``residuals.csv``: every corner with its residual (px);
* ``summary.json``, ``log.txt``.
"""

from __future__ import annotations

import json
import logging
import time

import numpy as np

from photogram.errors import InputError
from photogram.project.atomic import atomic_write_text

log = logging.getLogger("photogram")

__all__ = ["rig_and_write", "run"]


def _target(settings):
    from photogram.io.targets import parse_target
    try:
        return parse_target(settings.target)
    except InputError as exc:
        raise settings.error("target", f"target in [board]: {exc.what}", hint=exc.hint) from None


def calibrate_board_project(project):
    """Detections, frame choice and the rig adjustment of a board project;
    returns ``(result, frames)`` (:class:`photogram.rig.RigResult` and what
    :func:`photogram.rig.frames.read_rig` returned)."""
    from photogram.rig import calibrate_rig
    from photogram.rig.frames import read_rig
    bs = project.board
    target = _target(bs)
    t0 = time.perf_counter()
    frames = read_rig(bs.cameras, target, step=bs.step, min_sharpness=bs.min_sharpness,
                      max_frames=bs.max_frames, keep=(bs.floor,) if bs.floor else ())
    t1 = time.perf_counter()
    if bs.floor is not None and not any(bs.floor in d for d in frames["detections"].values()):
        raise bs.error("floor", f"floor = {bs.floor!r} in [board]: no camera finds the board "
                                "in that frame",
                       hint="give the frame number (video) or image name (without suffix) "
                            "where the board lies on the floor and is seen")
    scene = None
    if bs.scene is not None:
        from photogram.rig import SceneControl
        scene = SceneControl(bs.scene["points"], bs.scene["image_points"],
                             bs.scene["sigma_image"])
    result = calibrate_rig(frames["detections"], frames["image_sizes"], target,
                           model=bs.model, fix_k3=bs.fix_k3, floor_frame=bs.floor,
                           scene=scene, sigma_image=bs.sigma_image,
                           min_corners=bs.min_corners)

    result.summary["timings"] = {"detection_s": t1 - t0,
                                 "adjustment_s": time.perf_counter() - t1}
    return result, frames


def _cameras_table(result, length_unit):
    import pandas as pd
    from photogram.geometry import camera_model
    rows = []
    for name, c in result.cameras.items():
        row = {"camera": name, "model": c.model, "width": c.image_size[0],
               "height": c.image_size[1]}
        names = camera_model(c.model).parameter_names
        vals = dict(zip(names, [c.K[0, 0], c.K[1, 1], c.K[0, 2], c.K[1, 2], *c.dist]))
        for k in names:
            row[k], row[f"s_{k}"] = vals[k], c.sigmas[k]
        C = c.centre
        for k, v in zip(("X0", "Y0", "Z0"), C):
            row[k], row[f"s_{k}"] = v, c.sigmas[k]
        for k in ("rx", "ry", "rz"):
            row[f"s_{k}_deg"] = c.sigmas[k]
        row.update(rms_px=c.rms_px, median_dx=c.median_residual[0],
                   median_dy=c.median_residual[1], frames=c.n_frames, corners=c.n_points,
                   opencv_rms_px=result.start_rms[name])
        rows.append(row)
    return pd.DataFrame(rows)


def _board_table(result):
    import pandas as pd

    from photogram.geometry import matrix_to_rodrigues
    rows = []
    for f, (R, t) in result.board_poses.items():
        r = matrix_to_rodrigues(R)
        rows.append({"frame": f, "rx": r[0], "ry": r[1], "rz": r[2], "tx": t[0], "ty": t[1],
                     "tz": t[2], "floor": f == result.floor_frame})
    return pd.DataFrame(rows)


def _views(result):
    from photogram.io.exchange import View
    return [View(n, n, c.K, c.dist, c.R, c.t, c.image_size,
                 extra={"fisheye": c.model == "opencv_fisheye"})
            for n, c in result.cameras.items()]


def summary_of(result, frames, project) -> dict:
    cams = {n: {"rms_px": c.rms_px, "median_residual_px": list(c.median_residual),
                "frames": c.n_frames, "corners": c.n_points,
                "centre_sigma": c.centre_sigma,
                "frames_read": frames["per_camera"][n]["frames"],
                "blurred_left_out": len(frames["per_camera"][n]["blurred"]),
                "fps": frames["per_camera"][n]["fps"]}
            for n, c in result.cameras.items()}
    return {"command": "calibrate (board)", "status": result.status,
            "iterations": result.iterations, "sigma0": result.sigma0,
            "redundancy": result.redundancy, "floor_frame": result.floor_frame,
            "floor_given": project.board.floor is not None,
            "world": "scene" if project.board.scene is not None else "floor",
            "rejected_views": result.summary.get("rejected_views", {}),
            "scene_rms_px": result.summary.get("scene_rms_px"),
            "weakest_camera": result.weakest,
            "frames_chosen": len(frames["chosen"]), "board_poses": len(result.board_poses),
            "cameras": cams, "length_unit": project.units.length,
            "timings": result.summary.get("timings", {})}


def rig_and_write(project, output=None):
    """Calibrate a board project and write its results folder; returns
    ``(folder, result, summary)``."""
    from pathlib import Path

    from photogram.io.pose2sim import format_pose2sim
    from photogram.project.output_policy import project_inputs
    from photogram.project.results_folder import staged_results
    result, frames = calibrate_board_project(project)
    summary = summary_of(result, frames, project)
    folder = Path(output) if output else project.output_folder()
    with staged_results(folder, command="calibrate", inputs=project_inputs(project)) as stage:
        mean_rms = float(np.mean([c.rms_px for c in result.cameras.values()]))
        atomic_write_text(stage.path / "Calib.toml", format_pose2sim(_views(result),
                                                                      error=mean_rms))
        atomic_write_text(stage.path / "cameras.csv",
                          _cameras_table(result, project.units.length).to_csv(
                              index=False, float_format="%.10g"))
        atomic_write_text(stage.path / "board_poses.csv",
                          _board_table(result).to_csv(index=False, float_format="%.10g"))
        atomic_write_text(stage.path / "summary.json",
                          json.dumps(summary, indent=1, default=str) + "\n")
        atomic_write_text(stage.path / "log.txt", _log(result, summary))
    return folder, result, summary


def _log(result, summary) -> str:
    lines = [f"status: {result.status} after {result.iterations} iterations, sigma0 "
             f"{result.sigma0:.4f}, redundancy {result.redundancy}",
             (f"world: the scene points (RMS of their image points "
              f"{summary['scene_rms_px']:.3f} px)" if summary["world"] == "scene" else
              f"world: the board at frame {result.floor_frame}"
              + ("" if summary["floor_given"] else " (seen by the most cameras; give [board] "
                                                   "floor for the board on the floor)"))]
    lines += [f"left out: {v} (RMS {r:.2f} px)" for v, r in
              summary["rejected_views"].items()]
    for n, c in result.cameras.items():
        lines.append(f"{n}: {c.n_frames} frames, {c.n_points} corners, RMS {c.rms_px:.3f} px, "
                     f"median residual ({c.median_residual[0]:+.3f}, "
                     f"{c.median_residual[1]:+.3f}) px, fx {c.K[0, 0]:.2f} +- "
                     f"{c.sigmas['fx']:.2f}, centre sigma {c.centre_sigma:.4g}")
    lines.append(f"weakest camera: {result.weakest} (the least determined projection centre)")
    return "\n".join(lines) + "\n"


def run(project, args=None):
    """Command-line entry: calibrate, write, print one line."""
    folder, result, summary = rig_and_write(project)
    if not summary["floor_given"] and summary["world"] == "floor":
        log.warning("calibrate: no [board] floor frame given: the world is the board at frame "
                    "%s (seen by the most cameras)", result.floor_frame)
    if not getattr(args, "quiet", False):
        print(f"calibrate: {len(result.cameras)} cameras from {summary['board_poses']} board "
              f"poses, sigma0 {result.sigma0:.4f}, RMS "
              + ", ".join(f"{n} {c.rms_px:.2f}" for n, c in result.cameras.items())
              + f" px; weakest camera {result.weakest}; results in {folder}")
    return 0
