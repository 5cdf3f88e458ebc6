"""Residual blocks: one class per observation type, vectorized over all its
observations (Ceres' residual blocks).

A block has ``name``, ``dim`` (residuals per observation), ``sigma`` (N, dim)
a-priori standard deviations, ``records`` (labels for reports) and
``slot_cols`` (one (N, s) column array per parameter block it touches). Its
``evaluate(state)`` returns the *unweighted* residuals e (N, dim) and one
Jacobian (N, dim, s) per slot; the solver whitens them with the sigmas,
variance factors and robust weights.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from photogram.geometry import angle_increment_map
from photogram.geometry.camera import ideal_projection


class ResidualBlock:
    name = "residual"
    dim = 1
    group = "other"           # variance-component group of every row

    def __len__(self) -> int:
        return len(self.sigma)

    def evaluate(self, state, jacobians=True):  # pragma: no cover - interface
        raise NotImplementedError

    #: the attribute holding the observed values (shape (N, ...)); None: the
    #: block observes nothing that a re-solve could replace
    observed = None

    def observations(self):
        """The observed values (a copy), or None."""
        return None if self.observed is None else np.array(getattr(self, self.observed))

    def set_observations(self, values):
        """Replace the observed values (same shape) to solve the problem again
        with new observations (Monte Carlo); the structure is unchanged."""
        old = getattr(self, self.observed)
        values = np.asarray(values, dtype=float)
        if values.shape != np.shape(old):
            raise ValueError(f"{self.name}: observations of shape {values.shape}, "
                             f"not {np.shape(old)}")
        setattr(self, self.observed, values.copy())


class ImagePointBlock(ResidualBlock):
    """Collinearity residuals of image points of cameras sharing one model
    (ski-jump paper, appendix A; the residual form is the model's own).

    Parameters
    ----------
    model : camera model
    cameras : (K,) int, the cameras (indices into ``state.io``) of this block
    camera : (N,) int, index into ``cameras`` per observation
    station, point : (N,) int
    xy : (N, 2) measured image coordinates
    sigma : (N,) a-priori sigma (image unit)
    layout : Layout
    """

    name = "image points"
    dim = 2
    observed = "xy"

    def __init__(self, model, cameras, camera, station, point, xy, sigma, layout, labels=None):
        self.model = model
        self.cameras = np.asarray(cameras)
        self.camera = np.asarray(camera)
        self.station = np.asarray(station)
        self.point = np.asarray(point)
        self.xy = np.asarray(xy, dtype=float)
        self.sigma = np.repeat(np.asarray(sigma, dtype=float)[:, None], 2, axis=1)
        cam_cols = np.stack([layout.camera_cols[k] for k in self.cameras])
        self.slot_cols = [layout.point_cols[self.point],
                          layout.station_cols[self.station],
                          cam_cols[self.camera]]
        self.labels = labels

    def evaluate(self, state, jacobians=True, fixed_io=False, fixed_stations=False):
        """Residuals and Jacobians (X, station, io). ``fixed_io`` /
        ``fixed_stations``: the caller holds every interior parameter /
        station of the block fixed and needs no Jacobian by them (a
        correction model then returns None for them and skips dC/dio)."""
        indexed = getattr(self.model, "residuals_indexed", None)
        if indexed is not None:
            out = indexed(self.xy, state.points, state.R, state.X0,
                          np.stack([state.io[k] for k in self.cameras]),
                          self.point, self.station, self.camera, jacobians,
                          kernel=_compiled_rows(self.model, len(self.point)))
            if out is not None:
                return out
        io_cams = np.stack([state.io[k] for k in self.cameras])
        io = io_cams[self.camera]
        R = state.R[self.station]
        X = state.points[self.point]
        X0 = state.X0[self.station]
        kw = {}
        if hasattr(self.model, "correction_terms"):
            need = jacobians and not fixed_io
            kw["correction"] = self._correction_terms(io_cams, io, need)
            if fixed_stations:
                kw["stations"] = False
        # the state holds R: the models' rotation-matrix path (no angles)
        if not jacobians:
            e = self.model.residuals_rotation(self.xy, X, R, X0, io, jacobians=False, **kw)
            return e, None
        e, jac = self.model.residuals_rotation(self.xy, X, R, X0, io, **kw)
        station = None if jac["X0"] is None else np.concatenate([jac["X0"], jac["rotation"]],
                                                                 axis=2)
        return e, [jac["X"], station, jac["io"]]


    def _correction_terms(self, io_cams, io, io_jacobian):
        """A correction model's (brown) ``C(xy, io)`` and ``dC/dio`` (None
        without ``io_jacobian``). They stay while the observations and the
        interior orientation do (orient, intersect, Monte-Carlo runs):
        computed once, not per iteration."""
        key = (self.xy.tobytes(), io_cams.tobytes())
        if getattr(self, "_correction_key", None) != key or \
                (io_jacobian and self._correction[1] is None):
            self._correction = self.model.correction_terms(self.xy, io, io_jacobian=io_jacobian)
            self._correction_key = key
        return self._correction if io_jacobian else (self._correction[0], None)

    def points_only(self, state):
        """The residuals as a function of the object points alone, every
        station and interior parameter held at ``state``'s values (an
        intersection; Ceres' constant parameter blocks): a function
        ``f(points) -> (e (N, 2), dE/dX (N, 2, 3))`` that computes what does
        not depend on the points once. The same numbers as
        ``evaluate(state with those points, fixed_io=True,
        fixed_stations=True)`` (its residual and point Jacobian)."""
        if getattr(self.model, "residuals_indexed", None) is not None or \
                not hasattr(self.model, "correction_terms"):
            def general(points):
                e, Js = self.evaluate(replace(state, points=points), True, fixed_io=True,
                                      fixed_stations=True)
                return e, Js[0]
            return general
        io_cams = np.stack([state.io[k] for k in self.cameras])
        io = io_cams[self.camera]
        C = self._correction_terms(io_cams, io, False)[0]
        R, X0, c = state.R[self.station], state.X0[self.station], io[:, 0]
        point = self.point

        def collinearity(points):
            # as BrownModel.residuals_rotation: e = C - ideal(R (X - X0)),
            # dE/dX = -(d ideal / d Xc) R (appendix A)
            Xc = np.einsum("nij,nj->ni", R, points[point] - X0)
            ideal, J_xc, _ = ideal_projection(Xc, c, jacobians=True)
            return C - ideal, -J_xc @ R
        return collinearity


def _compiled_rows(model, n_rows):
    """The engine's compiled version of a camera model's row kernel
    (``model.row_kernel``, the name of a function in
    :mod:`photogram.adjust._numba_kernels`) when the compiled kernels are in
    use for ``n_rows`` rows, else None (the model's own numpy rows). The
    engine chooses; the camera model (geometry, below the engine) only names
    the kernel."""
    name = getattr(model, "row_kernel", None)
    if name is None:
        return None
    from photogram.adjust import kernels
    return getattr(kernels.compiled(), name) if kernels.active(n_rows) else None


class PointPriorBlock(ResidualBlock):
    """Reference coordinates as weighted observations (appendix D.1,
    eq. (D3b)): ``e = X - X_ref``."""

    name = "control coordinates"
    dim = 3
    group = "control"
    observed = "xyz"

    def __init__(self, point, xyz, sigma, layout):
        self.point = np.asarray(point)
        self.xyz = np.asarray(xyz, dtype=float)
        self.sigma = np.asarray(sigma, dtype=float)
        self.slot_cols = [layout.point_cols[self.point]]

    def evaluate(self, state, jacobians=True):
        e = state.points[self.point] - self.xyz
        J = np.broadcast_to(np.eye(3), (len(e), 3, 3)).copy()
        return e, [J]


class StationPriorBlock(ResidualBlock):
    """Approximate exterior orientations as weighted observations with a
    guessed accuracy (appendix D.2). Angles in radians; angle residuals are
    wrapped to (-pi, pi]."""

    name = "station priors"
    dim = 6
    group = "station priors"

    def __init__(self, station, position, angles, sigma, layout):
        self.station = np.asarray(station)
        self.position = np.asarray(position, dtype=float)
        self.angles = np.asarray(angles, dtype=float)
        self.sigma = np.asarray(sigma, dtype=float)   # (N, 6); inf = no prior
        self.slot_cols = [layout.station_cols[self.station]]

    def observations(self):
        """(N, 6): X0 Y0 Z0 and the angles (radians) observed."""
        return np.hstack([self.position, self.angles])

    def set_observations(self, values):
        values = np.asarray(values, dtype=float)
        if values.shape != (len(self.station), 6):
            raise ValueError(f"{self.name}: observations of shape {values.shape}, "
                             f"not {(len(self.station), 6)}")
        self.position, self.angles = values[:, :3].copy(), values[:, 3:].copy()

    def evaluate(self, state, jacobians=True):
        n = len(self.station)
        ang, E = angle_increment_map(state.R[self.station])
        e = np.zeros((n, 6))
        e[:, :3] = np.where(np.isfinite(self.position), state.X0[self.station] - self.position, 0.0)
        d = np.angle(np.exp(1j * (ang - self.angles)))
        e[:, 3:] = np.where(np.isfinite(self.angles), d, 0.0)
        J = np.zeros((n, 6, 6))
        J[:, :3, :3] = np.eye(3)
        J[:, 3:, 3:] = E
        return e, [J]


class InteriorPriorBlock(ResidualBlock):
    """Weighted interior-orientation priors: ``e = io_k - value_k``."""

    name = "interior priors"
    dim = 1
    group = "interior priors"
    observed = "value"

    def __init__(self, camera, parameter, value, sigma, layout):
        self.camera = np.asarray(camera)
        self.parameter = np.asarray(parameter)
        self.value = np.asarray(value, dtype=float)
        self.sigma = np.asarray(sigma, dtype=float)[:, None]
        cols = np.array([layout.camera_cols[k][j] for k, j in zip(self.camera, self.parameter)])
        self.slot_cols = [cols.reshape(-1, 1)]

    def evaluate(self, state, jacobians=True):
        current = np.array([state.io[k][j] for k, j in zip(self.camera, self.parameter)])
        e = (current - self.value)[:, None]
        return e, [np.ones((len(e), 1, 1))]


class DistanceBlock(ResidualBlock):
    """Measured distances between two points (scale bars, rods):
    ``e = |X_a - X_b| - d``."""

    name = "distances"
    dim = 1
    group = "distances"
    observed = "value"

    def __init__(self, a, b, value, sigma, layout):
        self.a, self.b = np.asarray(a), np.asarray(b)
        self.value = np.asarray(value, dtype=float)
        self.sigma = np.asarray(sigma, dtype=float)[:, None]
        self.slot_cols = [layout.point_cols[self.a], layout.point_cols[self.b]]

    def evaluate(self, state, jacobians=True):
        d = state.points[self.a] - state.points[self.b]
        length = np.linalg.norm(d, axis=1)
        u = (d / length[:, None])[:, None, :]
        return (length - self.value)[:, None], [u, -u]


class VerticalBlock(ResidualBlock):
    """Rod verticality (ski-jump paper, eq. (3)): the horizontal offsets of
    the top from the bottom point per unit height are observed as zero,
    ``e = ((X_t - X_b)/(Z_t - Z_b), (Y_t - Y_b)/(Z_t - Z_b))`` with sigma a
    slope ratio (1:100 -> 0.01). The observed slopes ``value`` (N, 2) are
    zero (a vertical rod) unless replaced (``set_observations``, Monte
    Carlo): ``e = slope - value``."""

    name = "verticality"
    dim = 2
    group = "verticality"
    observed = "value"

    def __init__(self, top, bottom, sigma, layout, value=None):
        self.top, self.bottom = np.asarray(top), np.asarray(bottom)
        self.sigma = np.repeat(np.asarray(sigma, dtype=float)[:, None], 2, axis=1)
        self.slot_cols = [layout.point_cols[self.top], layout.point_cols[self.bottom]]
        self.value = (np.zeros((len(self.top), 2)) if value is None
                      else np.asarray(value, dtype=float).reshape(-1, 2))

    def evaluate(self, state, jacobians=True):
        d = state.points[self.top] - state.points[self.bottom]
        h = d[:, 2]
        slope = d[:, :2] / h[:, None]
        J = np.zeros((len(d), 2, 3))
        J[:, 0, 0] = 1.0 / h
        J[:, 1, 1] = 1.0 / h
        J[:, :, 2] = -slope / h[:, None]
        return slope - self.value, [J, -J]
