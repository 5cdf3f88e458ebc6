"""Writing a rendered multi-camera set, and detecting its boards."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from photogram.simulation.board_rig.geometry import (BoardPoses, RigRenderSettings,
                                                     board_poses, true_corners)
from photogram.simulation.board_rig.render import (_texture, face_seen, render_rig,
                                                   render_view)


def _toml_array(a) -> str:
    a = np.asarray(a, float)
    if a.ndim == 1:
        return "[" + ", ".join(repr(float(x)) for x in a) + "]"
    return "[" + ", ".join(_toml_array(r) for r in a) + "]"


def cameras_toml(cameras) -> str:
    """The true cameras as TOML: one table per camera with ``size`` (w, h),
    ``matrix`` (K), ``distortions`` (k1 k2 p1 p2 k3), ``rotation`` (R, 3 x 3)
    and ``translation`` (t), OpenCV's convention ``x_cam = R X + t``."""
    out = ["# true cameras (photogram.simulation.board_rig); x_cam = R X_world + t, "
           "pixel centres at integers\n"]
    for c in cameras:
        out.append(f"[{c.name}]\nname = \"{c.name}\"\nsize = [{c.image_size[0]}, "
                   f"{c.image_size[1]}]\nmatrix = {_toml_array(c.K)}\n"
                   f"distortions = {_toml_array(c.dist)}\nrotation = {_toml_array(c.R)}\n"
                   f"translation = {_toml_array(c.t)}\n")
    return "\n".join(out)


def write_rig_set(folder, cameras, poses: BoardPoses, target, settings: RigRenderSettings,
                  *, video: bool = False, fps: float = 30.0, images: dict | None = None) -> Path:
    """Render (unless ``images`` are given) and write a set into ``folder``.

    Files: ``camNN/000000.png ...`` (one folder per camera, file k = pose k)
    or, with ``video``, ``camNN.avi`` (MJPG via ``cv2.VideoWriter``, which
    re-encodes the frames); ``truth/cameras.toml`` (:func:`cameras_toml`),
    ``truth/board_poses.csv`` (frame, R_bw row by row r00..r22, t_bw, v,
    w; frame 0 on the floor), ``truth/corners.csv`` (camera, frame, id, x,
    y, visible: :func:`true_corners`) and ``truth/settings.json`` (the
    settings, the target, the texture margin used).

    Raises
    ------
    FileExistsError
        ``folder`` exists and is not empty (never overwrites).
    """
    import cv2
    import pandas as pd
    folder = Path(folder)
    if folder.exists() and any(folder.iterdir()):
        raise FileExistsError(f"{folder} exists and is not empty: give a new folder")
    images = images if images is not None else render_rig(cameras, poses, target, settings)
    (folder / "truth").mkdir(parents=True, exist_ok=True)
    for cam in cameras:
        frames = images[cam.name]
        if video:
            vw = cv2.VideoWriter(str(folder / f"{cam.name}.avi"),
                                 cv2.VideoWriter_fourcc(*"MJPG"), fps, cam.image_size, True)
            for f in frames:
                vw.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
            vw.release()
        else:
            (folder / cam.name).mkdir()
            for k, f in enumerate(frames):
                cv2.imwrite(str(folder / cam.name / f"{k:06d}.png"), f)
    (folder / "truth" / "cameras.toml").write_text(cameras_toml(cameras))
    table = {"frame": np.arange(len(poses))}
    for i in range(3):
        for j in range(3):
            table[f"r{i}{j}"] = poses.R[:, i, j]
    for name, arr in (("t", poses.t), ("v", poses.v), ("w", poses.w)):
        for i, ax in enumerate("xyz"):
            table[f"{name}{ax}"] = arr[:, i]
    pd.DataFrame(table).to_csv(folder / "truth" / "board_poses.csv", index=False,
                               float_format="%.9g")
    rows = []
    for i, cam in enumerate(cameras):
        for k in range(len(poses)):
            xy, vis = true_corners(cam, poses[k], target, settings, key=(i, k))
            rows.append(pd.DataFrame({"camera": cam.name, "frame": k,
                                      "id": np.arange(len(xy)), "x": xy[:, 0],
                                      "y": xy[:, 1], "visible": vis}))
    pd.concat(rows).to_csv(folder / "truth" / "corners.csv", index=False, float_format="%.4f")
    meta = {"settings": asdict(settings), "margin_used": _texture(target, settings.margin)[2],
            "target": f"{target.kind}:{target.cols}x{target.rows}:{target.size}:"
                      f"{target.marker}:{target.dictionary}",
            "floor_pose": 0}
    (folder / "truth" / "settings.json").write_text(json.dumps(meta, indent=1) + "\n")
    return folder


def detect_rendered(cameras, poses: BoardPoses, target, settings: RigRenderSettings) -> dict:
    """:func:`detect_rig` of :func:`render_rig`'s views, each view rendered,
    detected and dropped in turn (one image in memory instead of all: 110 MB
    for 4 cameras and 30 poses at 1280 x 720); the same detections. Views
    that show nothing of the board's printed face (:func:`face_seen`: its
    back towards the camera, or outside the image: 53 of the 240 views of
    tests/test_rig_rendered.py's two sets, none of them detected when
    rendered) are not rendered: no board can be detected in them."""
    from photogram.io.targets import detect
    out = {}
    for i, cam in enumerate(cameras):
        out[cam.name] = {}
        for k in range(len(poses)):
            if not face_seen(cam, poses[k], target, settings):
                continue
            hit = detect(render_view(cam, poses[k], target, settings, key=(i, k)), target)
            if hit is not None:
                out[cam.name][k] = hit
    return out


def detect_rig(cameras, images: dict, target) -> dict:
    """The board detected in every rendered view (``photogram.io.targets.detect``):
    ``{camera: {pose index: (ids, xy)}}``, the input of
    :func:`photogram.rig.calibrate_rig`."""
    from photogram.io.targets import detect
    out = {}
    for c in cameras:
        out[c.name] = {}
        for k, img in enumerate(images[c.name]):
            hit = detect(img, target)
            if hit is not None:
                out[c.name][k] = hit
    return out
