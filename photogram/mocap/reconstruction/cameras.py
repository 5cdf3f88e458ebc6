"""Cameras of a motion-capture project: fixed positions, rotations (and
interior orientation) per frame.

Conventions are the library's (docs/camera-models.md): world-to-camera R,
photogrammetric camera frame looking along -z, image y down. A pan-tilt-zoom
camera has one projection centre ``X0`` and a rotation (and possibly a
principal distance) per frame; a fixed camera has one of each, broadcast
over the frames.

The reconstruction works in *ideal* coordinates: every detection is
undistorted once (``model.image_to_ray``: the ideal projection with c = 1,
``t = (-Xc_x/Xc_z, Xc_y/Xc_z)``), and residuals are scaled back to
pixel-equivalents by the local scale of the camera model at the principal
point (fx, fy for the OpenCV model). This is exact without distortion and a
first-order approximation with it (Pose2Sim's cameras have |k1| < 1e-3);
reported reprojection errors always use the full model
(:meth:`MocapCameras.project`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from photogram.errors import InputError
from photogram.geometry import camera_model

__all__ = ["MocapCameras"]


@dataclass
class MocapCameras:
    """C cameras, possibly moving (rotation and interior orientation per frame).

    ``R`` is (1 or F, C, 3, 3); ``io[c]`` is (1 or F, p_c) in the parameter
    order of ``models[c]``; ``X0`` (C, 3); ``image_size`` (C, 2) width,
    height in px (NaN: unknown).
    """

    names: list[str]
    models: list[str]
    io: list[np.ndarray]
    X0: np.ndarray
    R: np.ndarray
    image_size: np.ndarray

    def __post_init__(self):
        self.X0 = np.asarray(self.X0, dtype=float).reshape(-1, 3)
        self.R = np.asarray(self.R, dtype=float)
        if self.R.ndim == 3:
            self.R = self.R[None]
        self.io = [np.atleast_2d(np.asarray(p, dtype=float)) for p in self.io]
        self.image_size = np.asarray(self.image_size, dtype=float).reshape(-1, 2)
        C = len(self.names)
        if not (len(self.models) == len(self.io) == len(self.X0) == self.R.shape[1]
                == len(self.image_size) == C):
            raise InputError("inconsistent camera arrays")

    @property
    def n_cameras(self) -> int:
        return len(self.names)

    @property
    def n_frames(self) -> int | None:
        """Frames of the per-frame arrays (None: all fixed)."""
        lengths = {self.R.shape[0]} | {p.shape[0] for p in self.io}
        lengths.discard(1)
        return lengths.pop() if lengths else None

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise InputError(f"unknown camera {name!r}",
                             hint="cameras: " + ", ".join(self.names)) from None

    def select_frames(self, frames: np.ndarray) -> "MocapCameras":
        """The cameras at the given frame indices (fixed arrays unchanged)."""
        frames = np.asarray(frames, dtype=int)
        R = self.R if self.R.shape[0] == 1 else self.R[frames]
        io = [p if p.shape[0] == 1 else p[frames] for p in self.io]
        return replace(self, R=R, io=io)

    def select_cameras(self, names) -> "MocapCameras":
        idx = [self.index(n) for n in names]
        return MocapCameras([self.names[i] for i in idx], [self.models[i] for i in idx],
                            [self.io[i] for i in idx], self.X0[idx], self.R[:, idx],
                            self.image_size[idx])

    def rotations(self, n_frames: int) -> np.ndarray:
        """(F, C, 3, 3)"""
        return np.broadcast_to(self.R, (n_frames,) + self.R.shape[1:])

    def _io_rows(self, c: int, n_frames: int) -> np.ndarray:
        return np.broadcast_to(self.io[c], (n_frames, self.io[c].shape[1]))

    # ------------------------------------------------------------------
    def pixel_scale(self, n_frames: int) -> np.ndarray:
        """(F, C, 2): pixels per unit of ideal coordinates at the principal
        point (fx, fy for the OpenCV model), from the model itself."""
        out = np.empty((n_frames, self.n_cameras, 2))
        eps = 1e-6
        for c, name in enumerate(self.models):
            m = camera_model(name)
            io = self._io_rows(c, n_frames)
            zero = m.ray_to_image(np.zeros((n_frames, 2)), io)
            out[:, c, 0] = (m.ray_to_image(np.tile([eps, 0.0], (n_frames, 1)), io)[:, 0]
                            - zero[:, 0]) / eps
            out[:, c, 1] = (m.ray_to_image(np.tile([0.0, eps], (n_frames, 1)), io)[:, 1]
                            - zero[:, 1]) / eps
        return out

    def to_rays(self, xy: np.ndarray) -> np.ndarray:
        """Ideal coordinates (F, C, J, 2) of image points (F, C, J, 2); NaN
        stays NaN."""
        xy = np.asarray(xy, dtype=float)
        F, C, J = xy.shape[:3]
        out = np.full(xy.shape, np.nan)
        for c, name in enumerate(self.models):
            m = camera_model(name)
            io = np.repeat(self._io_rows(c, F), J, axis=0)
            pts = xy[:, c].reshape(-1, 2)
            ok = np.all(np.isfinite(pts), axis=1)
            if ok.any():
                t = np.full(pts.shape, np.nan)
                t[ok] = m.image_to_ray(pts[ok], io[ok])
                out[:, c] = t.reshape(F, J, 2)
        return out

    def camera_points(self, X: np.ndarray) -> np.ndarray:
        """Camera coordinates (F, C, J, 3) of points X (F, J, 3)."""
        X = np.asarray(X, dtype=float)
        R = self.rotations(X.shape[0])
        d = X[:, None, :, :] - self.X0[None, :, None, :]
        return np.einsum("fcab,fcjb->fcja", R, d)

    def project(self, X: np.ndarray) -> np.ndarray:
        """Image coordinates (F, C, J, 2) of points X (F, J, 3) with the full
        camera models; NaN for NaN points and points behind a camera."""
        Xc = self.camera_points(X)
        F, C, J = Xc.shape[:3]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.stack([-Xc[..., 0] / Xc[..., 2], Xc[..., 1] / Xc[..., 2]], -1)
        t[~(Xc[..., 2] < 0)] = np.nan
        out = np.full(t.shape, np.nan)
        for c, name in enumerate(self.models):
            m = camera_model(name)
            io = np.repeat(self._io_rows(c, F), J, axis=0)
            tc = t[:, c].reshape(-1, 2)
            ok = np.all(np.isfinite(tc), axis=1)
            if ok.any():
                xy = np.full(tc.shape, np.nan)
                xy[ok] = m.ray_to_image(tc[ok], io[ok])
                out[:, c] = xy.reshape(F, J, 2)
        return out

    def centre(self) -> np.ndarray:
        """Mean projection centre (the paper's initial position)."""
        return self.X0.mean(axis=0)
