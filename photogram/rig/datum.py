"""The world of a rig: the board laid on the floor, or scene points of known
coordinates (Pose2Sim's "scene" extrinsics: points marked in the cameras'
images).

* **Floor**: the board at one frame, held fixed. World X = the board's x
  axis (along the first row of corners), Y = -y, Z = -z: up, out of a
  board lying face up (OpenCV's board frame has z into the board). A
  minimum datum: six fixed parameters.
* **Scene**: control points ``point, X, Y, Z[, sigma]`` (world, the
  project's length unit; ``sigma`` 0 or absent: fixed) and their marked
  image points ``camera, point, x, y`` (px). The points enter the
  adjustment as image observations of fixed (or weighted) object points,
  no board pose is held: the control defines the world and the board
  still gives the rig its shape and scale. The start: the points
  triangulated in the start rig's frame, then the rigid part of the
  similarity (Horn/Umeyama, :func:`photogram.init.helmert.helmert`) onto
  their coordinates.

Transforms are 4 x 4 homogeneous matrices in OpenCV's convention.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError

__all__ = ["FLOOR", "SceneControl", "floor_transform", "scene_transform", "rays"]

#: board frame -> world axes of a board lying face up
FLOOR = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass
class SceneControl:
    """Control points and their marked image points."""

    points: dict                                   # name -> (xyz (3,), sigma)
    observations: dict = field(default_factory=dict)   # camera -> {name: xy (2,)}
    sigma_image: float = 1.0                       # px, of a marked (clicked) point


def floor_transform(T_wb_floor: np.ndarray) -> np.ndarray:
    """Start world -> floor world (module doc)."""
    from photogram.rig.initial import _inv
    return FLOOR @ _inv(T_wb_floor)


def rays(camera_K, camera_dist, T_cw, xy, fisheye: bool = False):
    """Centre (3,) and unit directions (n, 3) in the world of image points
    (n, 2) of a camera (undistorted with OpenCV)."""
    import cv2
    xy = np.asarray(xy, float).reshape(-1, 1, 2)
    if fisheye:
        u = cv2.fisheye.undistortPoints(xy, camera_K, np.asarray(camera_dist, float)[:4])
    else:
        u = cv2.undistortPoints(xy, camera_K, np.asarray(camera_dist, float))
    u = u.reshape(-1, 2)
    R, t = T_cw[:3, :3], T_cw[:3, 3]
    d = np.c_[u, np.ones(len(u))] @ R                       # R^T [u, 1]
    return -R.T @ t, d / np.linalg.norm(d, axis=1, keepdims=True)


def _closest_point(centres, directions):
    """The point nearest (least squares) to lines (centre, unit direction)."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for C, d in zip(centres, directions):
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ C
    return np.linalg.solve(A, b)


def scene_transform(scene: SceneControl, init: dict, fisheye: bool = False) -> np.ndarray:
    """Start world -> scene world: the marked points triangulated from the
    start cameras, then the rigid part of the similarity onto their
    coordinates. InputError when fewer than 3 points are marked in 2 or
    more cameras, or they are collinear."""
    from photogram.init.helmert import helmert
    src, dst, names = [], [], []
    for name, (xyz, _) in scene.points.items():
        seen = [c for c, obs in scene.observations.items() if name in obs and c in init["T_cw"]]
        if len(seen) < 2:
            continue
        cs, ds = [], []
        for c in seen:
            C, d = rays(init["K"][c], init["dist"][c], init["T_cw"][c],
                        scene.observations[c][name], fisheye)
            cs.append(C)
            ds.append(d[0])
        src.append(_closest_point(cs, ds))
        dst.append(np.asarray(xyz, float))
        names.append(name)
    if len(src) < 3:
        raise InputError(f"the scene has {len(src)} point(s) marked in 2 or more cameras; the "
                         "world needs 3 or more, not on one line",
                         hint="mark more scene points, each in at least two cameras, or give "
                              "[board] floor instead")
    try:
        h = helmert(np.array(src), np.array(dst))
    except Exception as exc:          # collinear points (the initialiser's own error)
        raise InputError(f"the scene points cannot fix the world: {exc}",
                         hint="mark points that are not on one line") from None
    T = np.eye(4)
    T[:3, :3] = h.R
    T[:3, 3] = h.t + (h.scale - 1.0) * h.R @ np.mean(src, axis=0)   # rigid, about the centroid
    return T
