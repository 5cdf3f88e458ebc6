"""Image points of cameras rigidly mounted on a rig (COLMAP's rigs and
frames, ``src/colmap/scene/frame.h``; Ceres style: one residual block with
four parameter blocks: object point, frame pose, sensor pose, interior
orientation).

A *frame* is one exposure of the rig: its pose ``f`` (``R_f`` world-to-rig,
``X0_f`` the rig's origin in the world) is one unknown station of the
state. A *sensor* is a camera of the rig: its pose ``s`` relative to the
rig (``R_s`` rig-to-camera, ``X0_s`` the camera's centre in the rig frame)
is another station, shared by every frame; the reference sensor is the
identity (a station held fixed at ``R = I``, ``X0 = 0``). Both are updated
as any exterior orientation (``R = expm([delta]x) R0``, ``X0 + dX0``).

A world point ``X`` in the rig frame and then in the camera::

    X_r = R_f (X - X0_f)
    x   = model(R_s, X0_s, io; X_r)        (the model's residuals_rotation)

The composed exterior orientation of the image is COLMAP's
``cam_from_world = sensor_from_rig * rig_from_world``::

    R = R_s R_f,    X0 = X0_f + R_f^T X0_s                         (1)

The Jacobians by chain rule, nothing neglected (``J_r = dr/dX_r`` the
model's own):

* sensor pose: the model's own (``X0``, rotation);
* frame pose: ``dX_r/dX0_f = -R_f`` and, with ``R_f = expm([d]x) R_f0``,
  ``dX_r/d d = d x X_r / d d = -[X_r]x``;
* object point: ``J_r R_f``;
* interior orientation: the model's own.
"""

from __future__ import annotations

import numpy as np

from photogram.adjust.board_blocks import _cross_matrix
from photogram.adjust.residual_blocks import ResidualBlock

__all__ = ["RigImagePointBlock", "composed_poses"]


def composed_poses(R_frame, X0_frame, R_sensor, X0_sensor):
    """The exterior orientation (R (n, 3, 3), X0 (n, 3)) of images taken
    by sensors ``(R_sensor, X0_sensor)`` in frames ``(R_frame, X0_frame)``,
    eq. (1) of the module docstring."""
    R = R_sensor @ R_frame
    X0 = X0_frame + np.einsum("nji,nj->ni", R_frame, X0_sensor)
    return R, X0


class RigImagePointBlock(ResidualBlock):
    """Collinearity residuals of image points taken by rig sensors (cameras
    sharing one model) in rig frames.

    Parameters
    ----------
    model : camera model
    cameras : (K,) int, the cameras (indices into ``state.io``) of the block
    camera : (N,) int, index into ``cameras`` per observation
    frame : (N,) int, the station index of the observation's frame pose
    sensor : (N,) int, the station index of the observing sensor's pose
    point : (N,) int
    xy : (N, 2) measured image coordinates
    sigma : (N,) a-priori sigma (image unit)
    layout : Layout
    """

    name = "image points"           # residuals, reliability and reports take it as one
    group = "image points"
    dim = 2
    observed = "xy"

    def __init__(self, model, cameras, camera, frame, sensor, point, xy, sigma, layout,
                 labels=None):
        self.model = model
        self.cameras = np.asarray(cameras)
        self.camera = np.asarray(camera)
        self.frame = np.asarray(frame)
        self.sensor = np.asarray(sensor)
        self.point = np.asarray(point)
        self.xy = np.asarray(xy, dtype=float)
        self.sigma = np.repeat(np.asarray(sigma, dtype=float)[:, None], 2, axis=1)
        cam_cols = np.stack([layout.camera_cols[k] for k in self.cameras])
        self.slot_cols = [layout.point_cols[self.point], layout.station_cols[self.frame],
                          layout.station_cols[self.sensor], cam_cols[self.camera]]
        self.labels = labels
        self.station = None             # the observing images' stations (set by the build)

    def rig_points(self, state) -> np.ndarray:
        """``X_r = R_f (X - X0_f)`` (N, 3)."""
        return np.einsum("nij,nj->ni", state.R[self.frame],
                         state.points[self.point] - state.X0[self.frame])

    def evaluate(self, state, jacobians=True):
        """Unweighted residuals (N, 2) and the Jacobians by the object point
        (N, 2, 3), the frame pose (N, 2, 6), the sensor pose (N, 2, 6) and
        the interior orientation (N, 2, p)."""
        io = np.stack([state.io[k] for k in self.cameras])[self.camera]
        Rs, X0s = state.R[self.sensor], state.X0[self.sensor]
        Xr = self.rig_points(state)
        kw = {}
        if hasattr(self.model, "correction_terms"):
            kw["correction"] = self.model.correction_terms(self.xy, io, io_jacobian=jacobians)
        if not jacobians:
            e = self.model.residuals_rotation(self.xy, Xr, Rs, X0s, io, jacobians=False, **kw)
            return e, None
        e, jac = self.model.residuals_rotation(self.xy, Xr, Rs, X0s, io, **kw)
        J_r = jac["X"]                                            # (N, 2, 3)
        Rf = state.R[self.frame]
        sensor = np.concatenate([jac["X0"], jac["rotation"]], axis=2)
        frame = np.concatenate([-J_r @ Rf, -J_r @ _cross_matrix(Xr)], axis=2)
        return e, [J_r @ Rf, frame, sensor, jac["io"]]
