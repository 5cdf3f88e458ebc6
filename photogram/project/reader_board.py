"""The ``[board]`` section: a multi-camera rig calibrated from a board
(issue 20, docs/board-calibration.md).

A .prj with a ``[board]`` section is a board project: ``[project]`` and
``[output]`` as usual, and the board's images per camera; no other
sections (``photogram calibrate`` finds the cameras). Like anipose's
``[calibration]`` (board type, size, square and marker lengths) and
Pose2Sim's ``[calibration.calculate]`` (corners, square size, one frame
every N seconds), in one line per camera::

    [board]
    target = "charuco:7x5:0.08:0.06:DICT_5X5_100"
    cameras = { cam01 = "videos/cam01.avi", cam02 = "images/cam02" }
    floor = 0            # the frame (video) or image stem where the board lies on the floor
    # scene = { points = "scene.csv", image_points = "marks.csv" }   # or: the world from
    #                      # points of known coordinates marked in the images (not with floor)
    model = "opencv"     # or "opencv_fisheye" (OpenCV's fisheye model, Kannala-Brandt)
    step = 0.2           # videos: one frame every step seconds
    max_frames = 150     # at most this many frames, the sharpest covering the images best
    fix_k3 = true
    min_corners = 6
    sigma_image = 0.5    # px, a-priori (the reported sigmas are a-posteriori)

Frames are the same instant in every camera: a video's frame index, or an
image file's stem (``000012.png`` in every camera's folder). This module
checks types, choices and that files exist, every error with file and line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from photogram.errors import InputError
from photogram.project.model import Points, Project
from photogram.project.toml_source import Section, TomlSource

__all__ = ["BoardSettings", "read_board_project", "BOARD_KEYS"]

BOARD_KEYS = ("target", "cameras", "floor", "scene", "model", "step", "max_frames", "fix_k3",
              "min_corners", "sigma_image", "min_sharpness")
SCENE_KEYS = ("points", "image_points", "sigma_image")
BOARD_MODELS = ("opencv", "opencv_fisheye")
_ALLOWED = ("project", "output", "board")


@dataclass
class BoardSettings:
    """``[board]`` with absolute paths (module doc)."""

    target: str
    cameras: dict                     # camera -> video file or image folder
    floor: str | None = None          # frame id (a video's frame number as text, or a stem)
    model: str = "opencv"             # or "opencv_fisheye"
    scene: dict | None = None         # points {name: (xyz, sigma)}, image_points
                                      # {camera: {name: xy}}, sigma_image (px)
    step: float = 0.2
    max_frames: int = 150
    fix_k3: bool = True
    min_corners: int = 6
    sigma_image: float = 0.5
    min_sharpness: float = 0.3
    lines: dict = field(default_factory=dict)
    source: object = None             # the Section, for errors at a key's line

    def error(self, key, what, hint=None) -> InputError:
        return self.source.error(key, what, hint)


def _read_board(sec: Section, prj: Path) -> BoardSettings:
    sec.check_keys(BOARD_KEYS, required=("target", "cameras"))
    target = sec.string("target")        # parsed by the command (photogram.io.targets)
    cams = sec.data["cameras"]
    if not isinstance(cams, dict) or not cams:
        raise sec.error("cameras", f"cameras in {sec.label} must be a table camera = path",
                        hint='e.g. cameras = { cam01 = "videos/cam01.avi", cam02 = "cam02/" }')
    cameras = {}
    for name, value in cams.items():
        if not isinstance(value, str):
            raise sec.error("cameras", f"the images of {name} in {sec.label} must be a path "
                                       "(text)", hint=f'e.g. {name} = "videos/{name}.avi"')
        p = Path(value)
        full = p if p.is_absolute() else prj.parent / p
        if not (full.is_file() or full.is_dir()):
            raise sec.error("cameras", f"cameras in {sec.label}: {name}: video or image folder "
                                       f"{value} not found",
                            hint="paths are relative to the folder of the .prj file")
        cameras[name] = full
    if len(cameras) < 2:
        raise sec.error("cameras", f"{sec.label} needs at least 2 cameras, not {len(cameras)}",
                        hint="one camera alone: photogram import images FOLDER --target ...")
    floor = sec.ident("floor", None)
    scene = _read_scene(sec, prj, cameras) if "scene" in sec else None
    if scene is not None and floor is not None:
        raise sec.error("scene", f"{sec.label} gives both floor and scene",
                        hint="the world comes from one of them: the board on the floor, or "
                             "the scene points")
    return BoardSettings(
        target=target, cameras=cameras, floor=floor, scene=scene,
        model=sec.string("model", "opencv", choices=BOARD_MODELS),
        step=sec.number("step", 0.2, positive=True),
        max_frames=sec.integer("max_frames", 150, minimum=3),
        fix_k3=sec.boolean("fix_k3", True),
        min_corners=sec.integer("min_corners", 6, minimum=4),
        sigma_image=sec.number("sigma_image", 0.5, positive=True),
        min_sharpness=sec.number("min_sharpness", 0.3, nonnegative=True, below=1.0),
        lines={k: sec.source.line_of(sec.keypath + (k,)) for k in sec.data}, source=sec)


def _read_scene(sec: Section, prj: Path, cameras: dict) -> dict:
    """``scene = { points = "scene.csv", image_points = "marks.csv" }``:
    control points ``point, X, Y, Z[, sigma]`` (sigma 0 or empty: fixed)
    and their image points ``camera, point, x, y`` (px)."""
    import numpy as np

    from photogram.project.tables import read_table
    sc = sec.table("scene")
    sc.check_keys(SCENE_KEYS, required=("points", "image_points"))
    files = {}
    for key in ("points", "image_points"):
        text = sc.string(key)
        full = Path(text) if Path(text).is_absolute() else prj.parent / text
        if not full.is_file():
            raise sc.error(key, f"{key} in {sc.label}: file {text} not found",
                           hint="paths are relative to the folder of the .prj file")
        files[key] = full
    t = read_table(files["points"], required=("point", "X", "Y", "Z"), optional=("sigma",),
                   what="scene points table")
    names = t.text("point")
    xyz = np.stack([t.floats(c, required=True) for c in "XYZ"], 1)
    sig = np.nan_to_num(t.floats("sigma")) if t.has("sigma") else np.zeros(len(names))
    points = {}
    for i, n in enumerate(names):
        if n in points:
            raise t.error(i, f"scene point {n} is given twice", hint="one row per point")
        if sig[i] < 0:
            raise t.error(i, f"sigma of scene point {n} is negative",
                          hint="0 or empty: fixed; else its standard deviation")
        points[n] = (xyz[i], float(sig[i]))
    m = read_table(files["image_points"], required=("camera", "point", "x", "y"),
                   what="scene image points table")
    cams, pts = m.text("camera"), m.text("point")
    xy = np.stack([m.floats("x", required=True), m.floats("y", required=True)], 1)
    obs: dict = {}
    for i, (c, p) in enumerate(zip(cams, pts)):
        if c not in cameras:
            raise m.error(i, f"camera {c} is not one of [board] cameras",
                          hint="cameras: " + ", ".join(cameras))
        if p not in points:
            raise m.error(i, f"point {p} has no coordinates in {files['points'].name}",
                          hint="add it to the scene points table")
        if p in obs.setdefault(c, {}):
            raise m.error(i, f"point {p} is marked twice in camera {c}",
                          hint="one row per camera and point")
        obs[c][p] = xy[i]
    return {"points": points, "image_points": obs, "files": list(files.values()),
            "sigma_image": sc.number("sigma_image", 1.0, positive=True)}


def read_board_project(prj: Path, src: TomlSource, root: Section) -> Project:
    """Read a board project (module doc)."""
    from photogram.project.reader_sections import _read_output, _read_project_section
    for name in root.data:
        if name not in _ALLOWED:
            raise root.error(name, f"[{name}] has no meaning in a board project (one with "
                                   "[board])", hint="a board project has [project], [board] and "
                                                    "[output]; photogram calibrate finds the "
                                                    "cameras")
    project = Project(path=prj, sources={"project": prj})
    _read_project_section(root.table("project"), project)
    project.output = _read_output(root.table("output", required=False))
    project.points = Points()
    project.board = _read_board(root.table("board"), prj)
    return project
