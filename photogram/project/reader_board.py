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

BOARD_KEYS = ("target", "cameras", "floor", "model", "step", "max_frames", "fix_k3",
              "min_corners", "sigma_image", "min_sharpness")
BOARD_MODELS = ("opencv", "opencv_fisheye")
_ALLOWED = ("project", "output", "board")


@dataclass
class BoardSettings:
    """``[board]`` with absolute paths (module doc)."""

    target: str
    cameras: dict                     # camera -> video file or image folder
    floor: str | None = None          # frame id (a video's frame number as text, or a stem)
    model: str = "opencv"             # or "opencv_fisheye"
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
    return BoardSettings(
        target=target, cameras=cameras, floor=floor,
        model=sec.string("model", "opencv", choices=BOARD_MODELS),
        step=sec.number("step", 0.2, positive=True),
        max_frames=sec.integer("max_frames", 150, minimum=3),
        fix_k3=sec.boolean("fix_k3", True),
        min_corners=sec.integer("min_corners", 6, minimum=4),
        sigma_image=sec.number("sigma_image", 0.5, positive=True),
        min_sharpness=sec.number("min_sharpness", 0.3, nonnegative=True, below=1.0),
        lines={k: sec.source.line_of(sec.keypath + (k,)) for k in sec.data}, source=sec)


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
