"""Image points of a rigid object seen at many unknown poses: a calibration
board waved through a multi-camera volume (Ceres' residual block with three
parameter blocks: camera station, board pose, interior orientation).

The board's points ``p`` are known in the board's own frame. Each board
pose ``b`` is held as a *station* of the state (``R_b`` world-to-board,
``X0_b`` the board's origin in the world), so that the engine updates it as
any exterior orientation (``R = expm([delta]x) R0``). A board point in the
world is

    X = R_b^T p + X0_b

and its image in camera station ``c`` is the camera model's projection of
``X`` (the collinearity equations, ski-jump paper appendix A, through the
model's own ``residuals_rotation``). The Jacobians by chain rule, nothing
neglected:

* camera station ``c``: the model's own (``X0``, rotation);
* board pose ``b``: ``dX/dX0_b = I`` and, with ``R_b^T = R_b0^T
  expm(-[delta]x)``, ``dX/d delta_b = R_b^T [p]x`` (``-delta x p = p x
  delta``), each multiplied by the model's ``dr/dX``;
* interior orientation: the model's own.

This is what Zhang's calibration, OpenCV's ``stereoCalibrate`` and
aniposelib's bundle adjustment solve for a board; here the whole rig is one
adjustment with covariance.
"""

from __future__ import annotations

import numpy as np

from photogram.adjust.residual_blocks import ResidualBlock

__all__ = ["BoardPointBlock"]


def _cross_matrix(p: np.ndarray) -> np.ndarray:
    """``[p]x`` (n, 3, 3) with ``[p]x v = p x v``."""
    z = np.zeros(len(p))
    return np.stack([np.stack([z, -p[:, 2], p[:, 1]], -1),
                     np.stack([p[:, 2], z, -p[:, 0]], -1),
                     np.stack([-p[:, 1], p[:, 0], z], -1)], axis=1)


class BoardPointBlock(ResidualBlock):
    """Image points of board points (known in the board frame) at unknown
    board poses.

    Parameters
    ----------
    model : camera model (all cameras of the block share it)
    cameras : (K,) int, the cameras (indices into ``state.io``) of the block
    camera : (N,) int, index into ``cameras`` per observation
    station : (N,) int, the observing camera's station
    pose : (N,) int, the station index of the board pose
    board_xyz : (N, 3) the point in the board frame
    xy : (N, 2) measured image coordinates
    sigma : (N,) a-priori sigma (image unit)
    layout : Layout
    """

    name = "board points"
    group = "image points"
    dim = 2
    observed = "xy"

    def __init__(self, model, cameras, camera, station, pose, board_xyz, xy, sigma, layout,
                 labels=None):
        self.model = model
        self.cameras = np.asarray(cameras)
        self.camera = np.asarray(camera)
        self.station = np.asarray(station)
        self.pose = np.asarray(pose)
        self.board_xyz = np.asarray(board_xyz, dtype=float)
        self.xy = np.asarray(xy, dtype=float)
        self.sigma = np.repeat(np.asarray(sigma, dtype=float)[:, None], 2, axis=1)
        cam_cols = np.stack([layout.camera_cols[k] for k in self.cameras])
        self.slot_cols = [layout.station_cols[self.station], layout.station_cols[self.pose],
                          cam_cols[self.camera]]
        self._px = _cross_matrix(self.board_xyz)
        self.labels = labels

    def world_points(self, state) -> np.ndarray:
        """``X = R_b^T p + X0_b`` (N, 3)."""
        Rb = state.R[self.pose]
        return np.einsum("nji,nj->ni", Rb, self.board_xyz) + state.X0[self.pose]

    def evaluate(self, state, jacobians=True):
        """Unweighted residuals (N, 2) and the Jacobians by the camera
        station (N, 2, 6), the board pose (N, 2, 6) and the interior
        orientation (N, 2, p)."""
        io_cams = np.stack([state.io[k] for k in self.cameras])
        io = io_cams[self.camera]
        R, X0 = state.R[self.station], state.X0[self.station]
        X = self.world_points(state)
        kw = {}
        if hasattr(self.model, "correction_terms"):
            kw["correction"] = self.model.correction_terms(self.xy, io, io_jacobian=jacobians)
        if not jacobians:
            e = self.model.residuals_rotation(self.xy, X, R, X0, io, jacobians=False, **kw)
            return e, None
        e, jac = self.model.residuals_rotation(self.xy, X, R, X0, io, **kw)
        station = np.concatenate([jac["X0"], jac["rotation"]], axis=2)
        J_X = jac["X"]                                           # (N, 2, 3)
        RbT = np.swapaxes(state.R[self.pose], 1, 2)
        dX_ddelta = RbT @ self._px                               # (N, 3, 3)
        pose = np.concatenate([J_X, J_X @ dX_ddelta], axis=2)
        return e, [station, pose, jac["io"]]
