"""Parameter blocks of a bundle adjustment and their column layout.

Unknowns come in blocks: the interior orientation of each camera (its model's
parameters), the exterior orientation of each station (6: ``dX0`` and a small
rotation ``delta`` with ``R = expm([delta]x) R0``) and each object point (3).

Columns are numbered in one vector: first the *reduced* columns (cameras,
stations and the points that are coupled to other points by constraints),
then the *eliminated* points, 3 columns each, which the solver removes by the
Schur complement. Fixed parameters keep their columns (their Jacobian columns
are zeroed and their diagonal set to one), so the structure never changes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.geometry import small_rotation

STATION_SIZE = 6


@dataclass
class State:
    """Current values of all parameter blocks."""

    points: np.ndarray                 # (n_p, 3)
    R: np.ndarray                      # (n_s, 3, 3) world-to-camera
    X0: np.ndarray                     # (n_s, 3)
    io: list[np.ndarray] = field(default_factory=list)  # per camera (p_k,)

    def copy(self) -> "State":
        return State(self.points.copy(), self.R.copy(), self.X0.copy(),
                     [v.copy() for v in self.io])

    def updated(self, layout: "Layout", dx: np.ndarray) -> "State":
        """The state moved by the increment ``dx`` (one value per column)."""
        io = [v + dx[cols] for v, cols in zip(self.io, layout.camera_cols)]
        io += [v.copy() for v in self.io[len(io):]]
        st = dx[layout.station_cols]
        turned = np.flatnonzero(np.any(st[:, 3:] != 0.0, axis=1))
        if len(turned) == len(st):
            R = small_rotation(st[:, 3:]) @ self.R
        else:                      # a zero increment leaves R as it is (exactly)
            R = self.R.copy()
            if len(turned):
                R[turned] = small_rotation(st[turned, 3:]) @ self.R[turned]
        points = dx[layout.point_cols]         # a fresh array: the sum goes into it
        points += self.points
        out = State(points, R, self.X0 + st[:, :3], io)
        if layout.derived is not None:
            out.compose(layout.derived)
        return out

    def compose(self, derived) -> None:
        """Set the derived stations (a rig's images, ``derived = (station,
        frame, sensor)`` index arrays) to the composition of their frame's
        and their sensor's pose (:mod:`photogram.adjust.rig_blocks` eq. (1):
        ``R = R_s R_f``, ``X0 = X0_f + R_f^T X0_s``)."""
        d, f, s = derived
        Rf = self.R[f]
        X0 = self.X0[f] + np.einsum("nji,nj->ni", Rf, self.X0[s])
        self.R[d] = self.R[s] @ Rf
        self.X0[d] = X0


class Layout:
    """Column numbering of the unknowns.

    Parameters
    ----------
    camera_sizes : sequence of int
        Number of interior parameters of each camera.
    n_stations, n_points : int
    reduced_points : (n_p,) bool
        Points kept in the reduced system (coupled to other points).
    free : dict
        ``camera``: list of (p_k,) bool, ``station``: (n_s, 6) bool,
        ``point``: (n_p, 3) bool.
    camera_columns : list of (p_k,) int, optional
        Shared interior parameters (:mod:`photogram.adjust.interior_map`):
        the column of each parameter of each interior block (an "io
        instance": a camera, or a camera at one station), numbered
        ``0 .. n_camera_columns - 1``; blocks that share a parameter (a
        camera's stations, tied cameras, ``fy = fx``) name the same column.
        Default: every camera its own consecutive columns (``camera_sizes``).
    """

    #: rig images whose stations are composed, ``(station, frame, sensor)``
    #: index arrays (:mod:`photogram.adjust.build_rigs`), or None
    derived = None

    def __init__(self, camera_sizes, n_stations, n_points, reduced_points, free,
                 camera_columns=None, n_camera_columns=None):
        reduced_points = np.asarray(reduced_points, dtype=bool)
        self.camera_cols = []
        col = 0
        if camera_columns is not None:
            self.camera_cols = [np.asarray(c, dtype=int) for c in camera_columns]
            col = int(n_camera_columns)
        for p in camera_sizes if camera_columns is None else ():
            self.camera_cols.append(np.arange(col, col + p))
            col += p
        self.n_camera_columns = col
        self.station_cols = col + np.arange(n_stations * STATION_SIZE).reshape(-1, STATION_SIZE)
        col += n_stations * STATION_SIZE
        self.point_cols = np.zeros((n_points, 3), dtype=int)
        n_red_pts = int(reduced_points.sum())
        self.point_cols[reduced_points] = col + np.arange(3 * n_red_pts).reshape(-1, 3)
        col += 3 * n_red_pts
        self.n_reduced = col
        elim = ~reduced_points
        self.elim_index = np.full(n_points, -1)
        self.elim_index[elim] = np.arange(int(elim.sum()))
        self.n_eliminated = int(elim.sum())
        self.point_cols[elim] = col + np.arange(3 * self.n_eliminated).reshape(-1, 3)
        self.n_columns = col + 3 * self.n_eliminated
        self.reduced_points = reduced_points
        self.free = np.zeros(self.n_columns, dtype=bool)
        for cols, mask in zip(self.camera_cols, free["camera"]):
            self.free[cols] = mask
        self.free[self.station_cols] = np.asarray(free["station"], dtype=bool)
        self.free[self.point_cols] = np.asarray(free["point"], dtype=bool)

    @property
    def n_free(self) -> int:
        return int(self.free.sum())
