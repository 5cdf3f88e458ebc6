"""The adjustment step of a Monte-Carlo chain: the engine's problem, built
once, re-solved with new observations.

:class:`EngineBundle` builds the engine :class:`~photogram.adjust.solver.Problem`
of the truth project once (:func:`photogram.adjust.build.build_problem`: the
same parameter blocks, residual blocks, weights and datum as ``photogram
orient``/``calibrate``, any camera model the engine has). A run only replaces
the observed values of its residual blocks (``Problem.set_observations``),
resets the state to the truth (with the drawn interior orientation for
``orient``) and solves with the engine's dense Gauss-Newton path
(:func:`photogram.adjust.dense.gauss_newton`), whose scatter indices are
computed once. :meth:`EngineBundle.linearize` gives what first-order
propagation needs from the same problem (:func:`photogram.adjust.dense.dense_cofactors`).

The random inputs of a run (:class:`BundleInputs`) keep the shapes and the
order they always had (the project's tables), so the same seeds give the same
perturbations: image coordinates (N, 2) in the order of the image points
table, reference coordinates of the control points (weighted datum), station
priors (every station with a finite prior sigma, 0 included), interior
priors, distances and verticality slopes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.adjust.build import build_problem, merged_image_blocks
from photogram.adjust.dense import (dense_cofactors, dense_structure, gauss_newton,
                                    parameter_scale)
from photogram.adjust.residual_blocks import (DistanceBlock, ImagePointBlock,
                                              InteriorPriorBlock, PointPriorBlock,
                                              StationPriorBlock, VerticalBlock)
from photogram.adjust.state import State
from photogram.errors import InputError
from photogram.geometry import camera_model, matrix_to_opk

__all__ = ["EngineBundle", "BundleInputs", "BundleState", "SOURCES"]

#: the kind of perturbation ([montecarlo] perturb) of each residual block type
SOURCES = ((ImagePointBlock, "image"), (PointPriorBlock, "reference"),
           (StationPriorBlock, "reference"), (InteriorPriorBlock, "interior"),
           (DistanceBlock, "constraints"), (VerticalBlock, "constraints"))


@dataclass
class BundleState:
    """Values of all unknowns; ``io`` (K, p_max) padded with zeros."""

    io: np.ndarray
    R: np.ndarray
    X0: np.ndarray
    X: np.ndarray

    def copy(self) -> "BundleState":
        return BundleState(self.io.copy(), self.R.copy(), self.X0.copy(), self.X.copy())

    @property
    def angles(self) -> np.ndarray:
        return matrix_to_opk(self.R)


@dataclass
class BundleInputs:
    """The observations of one run (shapes of the project's tables)."""

    xy: np.ndarray                 # (N, 2) image coordinates
    reference: np.ndarray          # (n_c, 3) reference coordinates of the control points
    station_prior: np.ndarray      # (n_s', 6) prior X0 Y0 Z0 omega phi kappa (radians)
    interior_prior: np.ndarray     # (n_ip,)
    distances: np.ndarray          # (n_d,)
    verticals: np.ndarray          # (n_v, 2) observed slopes (0 for a vertical rod)

    def copy(self) -> "BundleInputs":
        return BundleInputs(*(np.array(a, dtype=float, copy=True) for a in (
            self.xy, self.reference, self.station_prior, self.interior_prior,
            self.distances, self.verticals)))


def _source(block):
    for cls, kind in SOURCES:
        if isinstance(block, cls):
            return kind
    return "other"


class EngineBundle:
    """The adjustment step of a chain, built once from the truth project.

    Parameters
    ----------
    project : Project
        Cameras, stations and points with finite values (the truth: the
        start of every solve and the point of linearization).
    fix_interior : bool
        ``orient`` (interior fixed, drawn per run) or ``calibrate``.
    """

    def __init__(self, project, *, fix_interior: bool):
        adj = project.adjustment
        built = build_problem(project, fix_interior=fix_interior)
        if built.interior is not None:
            raise InputError("photogram montecarlo does not support shared interior "
                             "parameters (per_station, tie, shared) yet", file=project.path,
                             hint="remove per_station, tie and shared from the cameras of the "
                                  "calibrate step, or use orient (interior fixed)")
        if built.rigs is not None:
            raise InputError("photogram montecarlo does not support rigs ([rigs.NAME]) yet",
                             file=project.path,
                             hint="remove the [rigs] sections (the stations then are free)")
        self.built = built
        # one image block per camera model: the same residuals and weights
        pb = self.problem = merged_image_blocks(built.problem)
        self.camera_names = list(built.camera_names)
        cams = [project.cameras[n] for n in self.camera_names]
        self.models = [camera_model(c.model) for c in cams]
        self.parameter_names = [list(m.parameter_names) for m in self.models]
        self.n_params = np.array([len(p) for p in self.parameter_names], dtype=int)
        K, p = len(cams), int(self.n_params.max(initial=0))
        self.io_valid = np.arange(p)[None, :] < self.n_params[:, None]     # (K, p)
        st, pts, obs = project.stations, project.points, project.image_points
        self.station_names = list(st.names)
        self.point_ids = list(pts.ids)
        self.units = project.units
        self.path = project.path
        self.fix_interior = fix_interior
        self.station_camera = np.array([self.camera_names.index(c) for c in st.camera], dtype=int)
        self.obs_station = np.asarray(obs.station, dtype=int)
        self.obs_point = np.asarray(obs.point, dtype=int)
        lay = pb.layout
        self.layout = lay
        io = np.zeros((K, p))
        for k, v in enumerate(pb.state.io):
            io[k, :len(v)] = v
        self.start = BundleState(io, pb.state.R.copy(), pb.state.X0.copy(),
                                 pb.state.points.copy())
        self.truth_state = pb.state.copy()
        free_pt = lay.free[lay.point_cols].any(axis=1)
        self.free_points = np.flatnonzero(free_pt)
        if not np.all(np.isfinite(self.start.X[free_pt])):
            raise InputError("montecarlo: the truth has points without coordinates",
                             file=project.path, hint="adjust the project first")
        # columns (all columns of the layout; fixed ones give zero rows)
        self.n = lay.n_columns
        self.station_cols = lay.station_cols
        self.point_cols = lay.point_cols
        self.io_cols = np.full((K, p), -1)
        for k, cols in enumerate(lay.camera_cols):
            self.io_cols[k, :len(cols)] = cols
        self.io_free = np.zeros((K, p), dtype=bool)
        for k, cols in enumerate(lay.camera_cols):
            self.io_free[k, :len(cols)] = lay.free[cols]
        self.dense = dense_structure(pb)
        #: the parameter scale of the convergence test, at the truth
        self.scale = parameter_scale(pb, self.truth_state)
        self.sources = np.concatenate(
            [np.full(len(b) * b.dim, _source(b), dtype=object) for b in pb.blocks]
            or [np.zeros(0, dtype=object)])

        # ---- the blocks that take the run's observations ------------------
        self._image = [b for b in pb.blocks if isinstance(b, ImagePointBlock)]
        if sum(len(b) for b in self._image) != len(obs):
            raise InputError("montecarlo: every image point must be an observation of the "
                             "adjustment (groups, eccentric targets)", file=project.path)
        sig_xy = np.zeros((len(obs), 2))
        for b in self._image:
            sig_xy[b.rows] = b.sigma
        self._one = {cls: next((b for b in pb.blocks if type(b) is cls), None)
                     for cls in (PointPriorBlock, StationPriorBlock, InteriorPriorBlock,
                                 DistanceBlock, VerticalBlock)}
        kinds = np.asarray(pts.kind, dtype=object)
        self.control = np.flatnonzero(kinds == "control") if adj.datum == "weighted" \
            else np.zeros(0, dtype=int)
        self.n_ref = len(self.control)
        ref_sigma = np.zeros((0, 3))
        if self.n_ref:
            s = pts.sigma[self.control].astype(float).reshape(-1, 3)
            if adj.sigma_control is not None:
                s = np.where(np.isfinite(s), s, adj.sigma_control)
            ref_sigma = np.where(np.isfinite(s), s, 0.0)
        # station priors: every station with a finite sigma (0: fixed, no noise)
        sp = np.hstack([st.position_sigma, st.angle_sigma]).astype(float).reshape(-1, 6)
        self.prior_stations = np.flatnonzero(np.isfinite(sp).any(1))
        prior_sigma = np.where(np.isfinite(sp[self.prior_stations]), sp[self.prior_stations], 0.0)
        blk = self._one[StationPriorBlock]
        self._prior_rows = np.zeros(0, dtype=int)
        if blk is not None:
            where = {s: i for i, s in enumerate(self.prior_stations)}
            self._prior_rows = np.array([where[s] for s in blk.station], dtype=int)
        ip = self._one[InteriorPriorBlock]
        ip_sigma = ip.sigma[:, 0] if ip is not None else np.zeros(0)
        dist, vert = self._one[DistanceBlock], self._one[VerticalBlock]
        self.d_a = dist.a if dist is not None else np.zeros(0, dtype=int)
        self.d_b = dist.b if dist is not None else np.zeros(0, dtype=int)
        self.v_t = vert.top if vert is not None else np.zeros(0, dtype=int)
        self.v_b = vert.bottom if vert is not None else np.zeros(0, dtype=int)
        self.sigmas = BundleInputs(
            xy=sig_xy, reference=ref_sigma, station_prior=prior_sigma,
            interior_prior=ip_sigma,
            distances=dist.sigma[:, 0] if dist is not None else np.zeros(0),
            verticals=vert.sigma if vert is not None else np.zeros((0, 2)))
        self.ip_k = ip.camera if ip is not None else np.zeros(0, dtype=int)
        self.ip_j = ip.parameter if ip is not None else np.zeros(0, dtype=int)
        self.inputs = self.exact_inputs()
        self.max_iterations = 30
        self.tolerance = 1e-10

    # ------------------------------------------------------------------ inputs
    def exact_inputs(self, state: BundleState | None = None) -> BundleInputs:
        """The error-free observations of ``state`` (default the truth):
        projected image points, true reference coordinates, priors and
        constraints."""
        from photogram.montecarlo.truth import project_points
        s = self.start if state is None else state
        angles = matrix_to_opk(s.R)
        xy = project_points(self.models, s.io, angles, s.X0, s.X, self.station_camera,
                            self.obs_station, self.obs_point)
        d = s.X[self.v_t] - s.X[self.v_b]
        return BundleInputs(
            xy=xy, reference=s.X[self.control].copy(),
            station_prior=np.hstack([s.X0, angles])[self.prior_stations],
            interior_prior=s.io[self.ip_k, self.ip_j].copy(),
            distances=np.linalg.norm(s.X[self.d_a] - s.X[self.d_b], axis=1),
            verticals=d[:, :2] / d[:, 2:3] if len(d) else np.zeros((0, 2)))

    def input_sigmas(self) -> BundleInputs:
        """The a-priori sigma of every observation, shaped as the inputs."""
        return self.sigmas

    def set_inputs(self, inp: BundleInputs):
        """Put a run's observations into the problem's residual blocks."""
        for b in self._image:
            b.xy = inp.xy[b.rows]
        blk = self._one[PointPriorBlock]
        if blk is not None:
            blk.xyz = inp.reference[np.searchsorted(self.control, blk.point)]
        blk = self._one[StationPriorBlock]
        if blk is not None:
            v = inp.station_prior[self._prior_rows]
            blk.position, blk.angles = v[:, :3], v[:, 3:]
        for cls, value in ((InteriorPriorBlock, inp.interior_prior),
                           (DistanceBlock, inp.distances), (VerticalBlock, inp.verticals)):
            blk = self._one[cls]
            if blk is not None:
                blk.set_observations(value)

    def _engine_state(self, state: BundleState):
        return State(state.X.copy(), state.R.copy(), state.X0.copy(),
                     [np.array(state.io[k, :n], dtype=float)
                      for k, n in enumerate(self.n_params)])

    def _bundle_state(self, s) -> BundleState:
        io = np.zeros_like(self.start.io)
        for k, v in enumerate(s.io):
            io[k, :len(v)] = v
        return BundleState(io, s.R, s.X0, s.points)

    # ------------------------------------------------------------------ solve
    def solve(self, inputs: BundleInputs, io=None, start: BundleState | None = None, tol=None):
        """Adjust with ``inputs`` (and the fixed interior orientation ``io``,
        default the start's) by the engine; returns ``(state, iterations)``."""
        state = (start or self.start).copy()
        if io is not None:
            state.io = np.array(io, dtype=float)
        self.set_inputs(inputs)
        pb = self.problem
        pb.state = self._engine_state(state)
        it = gauss_newton(pb, tolerance=tol or self.tolerance,
                          max_iterations=self.max_iterations, scale=self.scale)
        return self._bundle_state(pb.state), it

    def linearize(self, state: BundleState, inputs: BundleInputs):
        """What first-order propagation needs at ``state``: the whitened
        Jacobian ``J`` (m, n) over all columns (zero for fixed ones), the
        cofactors ``Q`` (n, n; zero rows for fixed columns) and ``Jio``
        (m, K p) the whitened derivatives w.r.t. every interior parameter."""
        self.set_inputs(inputs)
        _, Jf, Qf, Jall = dense_cofactors(self.problem, self._engine_state(state))
        free = self.dense.free
        J = np.zeros((Jf.shape[0], self.n))
        J[:, free] = Jf
        Q = np.zeros((self.n, self.n))
        Q[np.ix_(free, free)] = Qf
        K, p = self.start.io.shape
        Jio = np.zeros((Jf.shape[0], K * p))
        for k in range(K):
            cols = self.layout.camera_cols[k]
            Jio[:, k * p:k * p + len(cols)] = Jall[:, cols]
        return J, Q, Jio

