"""Cameras aimed at a target: the world-to-camera rotation of a camera at
``X0`` looking at a point, in the photogrammetric camera frame (looking
along -z, y up; docs/camera-models.md).

Used by the simulators (:mod:`photogram.simulation`) and by the motion
capture's start with unknown rotations (cameras aimed at the athlete).
"""

from __future__ import annotations

import numpy as np

__all__ = ["look_at"]


def look_at(X0, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """World-to-camera R of cameras at ``X0`` (n,3) looking at ``target``.

    The photogrammetric camera looks along its -z axis with y up, so the
    rows of R are the camera axes in world coordinates: z = -(viewing
    direction), x = up x z normalised... chosen so that world "up" appears
    up in the image (y up in the camera, i.e. toward smaller row numbers).
    """
    X0 = np.atleast_2d(np.asarray(X0, dtype=float))
    target = np.broadcast_to(np.asarray(target, dtype=float), X0.shape)
    up = np.broadcast_to(np.asarray(up, dtype=float), X0.shape)
    view = target - X0
    z = -view / np.linalg.norm(view, axis=1, keepdims=True)
    x = np.cross(up, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)
