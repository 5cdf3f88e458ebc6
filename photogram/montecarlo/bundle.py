"""A lean bundle adjustment for Monte-Carlo runs.

The engine (:mod:`photogram.adjust`) is general and builds its problem from a
project; a Monte-Carlo simulation solves the *same* small network a thousand
times with new observations. :class:`LeanBundle` is built once from a project
whose stations and points hold the true (or adjusted) values, and then only
takes new observations:

* the collinearity residuals of the Brown (correction) model in one
  vectorized evaluation: ``r = C(xy; io) - ideal(R (X - X0); c)``, with the
  same parameters as the engine (``R = expm([delta]x) R0``, so ``dXc/ddelta =
  -[Xc]x``); with the interior orientation fixed, ``C`` is computed once per
  solve;
* reference coordinates (datum ``weighted``; ``control`` holds them fixed),
  station priors (appendix D.2), interior priors, distances and verticality
  (eq. (3)) as the engine has them (:mod:`photogram.adjust.residual_blocks`);
* the free-network datum by inner constraints over all points (6 conditions
  with a distance, else 7), bordered;
* dense normal equations, Jacobi-scaled (the networks a Monte-Carlo run
  repeats have a few hundred unknowns at most).

``linearize`` gives what first-order propagation needs: the whitened
Jacobian, the cofactor matrix and the sensitivity to the (fixed) interior
orientation.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la

from photogram.errors import GeometryError, InputError
from photogram.geometry import (angle_increment_map, camera_model, opk_to_matrix, skew,
                                small_rotation)
from photogram.montecarlo.lean_state import (BundleInputs, BundleState, correct_brown,
                                              image_residuals)

#: the sigma (length unit or radian) a prior of sigma 0 ("fixed") gets in
#: the lean bundle, whose columns are per point and station: held to 1e-9
FIXED_SIGMA = 1e-9

__all__ = ["LeanBundle", "BundleInputs", "BundleState", "correct_brown", "image_residuals"]


class LeanBundle:
    """Dense Gauss-Newton bundle adjustment of one project, built once.

    Parameters
    ----------
    project : Project
        Cameras (brown model), stations and points with finite values (the
        truth or the adjusted solution: the start of every solve and the
        point of linearization); observations, priors, constraints and
        ``[adjustment]`` settings as the engine reads them.
    fix_interior : bool
        Hold every interior parameter fixed (``orient``); otherwise the
        parameters free in the project are estimated (``calibrate``).
    """

    def __init__(self, project, *, fix_interior: bool):
        self.camera_names = list(project.cameras)
        cams = [project.cameras[n] for n in self.camera_names]
        bad = [c.name for c in cams if c.model != "brown"]
        if bad:
            raise InputError(f"photogram montecarlo supports the brown camera model only, "
                             f"not {project.cameras[bad[0]].model} (camera {bad[0]})",
                             file=project.path,
                             hint="convert the camera to the brown model")
        self.model = camera_model("brown")
        self.parameter_names = list(self.model.parameter_names)
        p = len(self.parameter_names)
        st, pts, obs = project.stations, project.points, project.image_points
        self.station_names = list(st.names)
        self.point_ids = list(pts.ids)
        self.units = project.units
        self.path = project.path
        adj = project.adjustment
        self.datum = adj.datum
        K, S, P = len(cams), len(st), len(pts)
        cam_index = {n: i for i, n in enumerate(self.camera_names)}
        self.station_camera = np.array([cam_index[c] for c in st.camera], dtype=int)
        self.obs_station = np.asarray(obs.station, dtype=int)
        self.obs_point = np.asarray(obs.point, dtype=int)
        self.obs_camera = self.station_camera[self.obs_station]
        default = np.array([adj.sigma_image[n] if isinstance(adj.sigma_image, dict)
                            else adj.sigma_image for n in self.camera_names], dtype=float)
        sig = np.asarray(obs.sigma, dtype=float)
        self.obs_sigma = np.where(np.isfinite(sig), sig, default[self.obs_camera])
        self.start = BundleState(np.array([c.values() for c in cams], dtype=float),
                                 opk_to_matrix(st.angles), st.position.astype(float).copy(),
                                 pts.xyz.astype(float).copy())
        seen = np.bincount(self.obs_point, minlength=P) > 0
        kinds = np.asarray(pts.kind, dtype=object)
        self.control = np.flatnonzero(kinds == "control")
        pidx = pts.index()
        self.dist = [(pidx[d.point_a], pidx[d.point_b], d.value, d.sigma) for d in project.distances]
        self.vert = [(pidx[v.top], pidx[v.bottom], v.sigma) for v in project.verticals]
        coupled = np.zeros(P, dtype=bool)
        for a, b, *_ in self.dist + self.vert:
            coupled[[a, b]] = True
        free_pt = seen | coupled
        if self.datum == "weighted":
            free_pt[self.control] = True
        if self.datum == "control":
            free_pt[self.control] = False
        used = free_pt.copy()
        if not np.all(np.isfinite(self.start.X[used | seen])):
            raise InputError("montecarlo: the truth has points without coordinates",
                             file=project.path, hint="adjust the project first")
        self.free_points = np.flatnonzero(free_pt)

        # ---- columns ---------------------------------------------------
        io_free = np.zeros((K, p), dtype=bool)
        if not fix_interior:
            io_free = np.array([c.free_mask() for c in cams], dtype=bool)
        self.io_free = io_free
        n = 0
        self.io_cols = np.full((K, p), -1)
        self.io_cols[io_free] = np.arange(int(io_free.sum()))
        n += int(io_free.sum())
        self.station_cols = n + np.arange(6 * S).reshape(S, 6)
        n += 6 * S
        self.point_cols = np.full((P, 3), -1)
        self.point_cols[self.free_points] = n + np.arange(3 * len(self.free_points)).reshape(-1, 3)
        n += 3 * len(self.free_points)
        self.n = n
        dummy = n                                       # fixed parameters go here

        def cols(a):
            return np.where(a >= 0, a, dummy)

        # ---- rows and their sources -----------------------------------
        rows, sources = 0, []
        N = len(self.obs_point)
        self.img_rows = np.arange(2 * N).reshape(N, 2)
        self.img_cols = np.concatenate([
            cols(self.point_cols[self.obs_point]),
            self.station_cols[self.obs_station],
            cols(self.io_cols[self.obs_camera])], axis=1)          # (N, 9 + p)
        self.fixed_io = not io_free.any()
        rows += 2 * N
        sources += ["image"] * (2 * N)

        self.n_ref = len(self.control) if self.datum == "weighted" else 0
        self.ref_sigma = np.zeros((0, 3))
        if self.n_ref:
            s = pts.sigma[self.control].astype(float)
            if adj.sigma_control is not None:
                s = np.where(np.isfinite(s), s, adj.sigma_control)
            if not np.all(np.isfinite(s) & (s >= 0)):
                raise InputError("weighted datum: a control point has no sigma",
                                 file=project.path, hint="give sX sY sZ or sigma_control")
            self.ref_sigma = np.where(s == 0, FIXED_SIGMA, s)      # 0: fixed
            self.ref_rows = rows + np.arange(3 * self.n_ref).reshape(-1, 3)
            self.ref_cols = cols(self.point_cols[self.control])
            rows += 3 * self.n_ref
            sources += ["reference"] * (3 * self.n_ref)

        sp = np.hstack([st.position_sigma, st.angle_sigma]).astype(float)
        sp = np.where(sp == 0, FIXED_SIGMA, sp)                      # 0: fixed
        sp = np.where(np.isfinite(sp) & (sp > 0), sp, np.inf)
        self.prior_stations = np.flatnonzero(np.isfinite(sp).any(1))
        self.prior_sigma = sp[self.prior_stations]
        self.prior_rows = rows + np.arange(6 * len(self.prior_stations)).reshape(-1, 6)
        rows += 6 * len(self.prior_stations)
        sources += ["reference"] * (6 * len(self.prior_stations))

        ip = [(k, j, par.value, par.sigma) for k, c in enumerate(cams)
              for j, par in enumerate(c.parameters.values())
              if io_free[k, j] and par.sigma is not None and np.isfinite(par.sigma) and par.sigma > 0]
        self.ip_k = np.array([x[0] for x in ip], dtype=int)
        self.ip_j = np.array([x[1] for x in ip], dtype=int)
        self.ip_value = np.array([x[2] for x in ip], dtype=float)
        self.ip_sigma = np.array([x[3] for x in ip], dtype=float)
        self.ip_rows = rows + np.arange(len(ip))
        rows += len(ip)
        sources += ["interior"] * len(ip)

        self.d_a = np.array([d[0] for d in self.dist], dtype=int)
        self.d_b = np.array([d[1] for d in self.dist], dtype=int)
        self.d_value = np.array([d[2] for d in self.dist], dtype=float)
        self.d_sigma = np.array([d[3] for d in self.dist], dtype=float)
        self.d_rows = rows + np.arange(len(self.dist))
        rows += len(self.dist)
        sources += ["constraints"] * len(self.dist)

        self.v_t = np.array([v[0] for v in self.vert], dtype=int)
        self.v_b = np.array([v[1] for v in self.vert], dtype=int)
        self.v_sigma = np.array([v[2] for v in self.vert], dtype=float)
        self.v_rows = rows + np.arange(2 * len(self.vert)).reshape(-1, 2)
        rows += 2 * len(self.vert)
        sources += ["constraints"] * (2 * len(self.vert))
        self.m = rows
        self.sources = np.array(sources, dtype=object)

        self.G = None
        if self.datum == "free":
            chosen = None
            if adj.inner_constraints:
                chosen = np.array([pidx[q] for q in adj.inner_constraints if q in pidx])
            self.G = self._inner_constraints(chosen, scale=not self.dist)
        self.max_iterations = 30
        self.tolerance = 1e-10
        self.inputs = BundleInputs(
            xy=np.asarray(obs.xy, dtype=float).copy(),
            reference=pts.xyz[self.control].astype(float).copy() if self.n_ref
            else np.zeros((0, 3)),
            station_prior=np.hstack([st.position, st.angles])[self.prior_stations].astype(float),
            interior_prior=self.ip_value.copy(),
            distances=self.d_value.copy(),
            verticals=np.zeros((len(self.vert), 2)))

    # ------------------------------------------------------------------
    def input_sigmas(self) -> BundleInputs:
        """The a-priori sigma of every observation, shaped as the inputs."""
        return BundleInputs(
            xy=np.repeat(self.obs_sigma[:, None], 2, axis=1), reference=self.ref_sigma,
            station_prior=np.where(np.isfinite(self.prior_sigma), self.prior_sigma, 0.0),
            interior_prior=self.ip_sigma, distances=self.d_sigma,
            verticals=np.repeat(self.v_sigma[:, None], 2, axis=1))

    def _inner_constraints(self, chosen, scale):
        """Similarity motions of the points (and projection centres and
        rotations), conditions over the chosen points only."""
        X, X0 = self.start.X, self.start.X0
        pts = self.free_points if chosen is None else np.intersect1d(chosen, self.free_points)
        allxyz = np.vstack([X[self.free_points], X0])
        centre = allxyz.mean(0)
        size = float(np.sqrt(np.mean(np.sum((allxyz - centre) ** 2, 1)))) or 1.0
        G = np.zeros((self.n, 7))
        d = (X[pts] - centre) / size
        T = np.zeros((len(pts), 3, 7))
        T[:, [0, 1, 2], [0, 1, 2]] = 1.0
        x, y, z = d[:, 0], d[:, 1], d[:, 2]
        T[:, 1, 3], T[:, 2, 3] = -z, y
        T[:, 0, 4], T[:, 2, 4] = z, -x
        T[:, 0, 5], T[:, 1, 5] = -y, x
        T[:, :, 6] = d
        G[self.point_cols[pts].ravel()] = T.reshape(-1, 7)
        return G if scale else G[:, :6]

    # ------------------------------------------------------------------
    def evaluate(self, state: BundleState, inputs: BundleInputs, C_fixed=None,
                 interior_jacobian: bool = False):
        """Whitened residuals r (m,) and Jacobian J (m, n); with
        ``interior_jacobian`` also the whitened ``dr/dio`` (m, K p) of all
        interior parameters (for the sensitivity to a fixed interior
        orientation)."""
        J = np.zeros((self.m, self.n + 1))
        r = np.zeros(self.m)
        st, pt, cam = self.obs_station, self.obs_point, self.obs_camera
        io = state.io[cam]
        if C_fixed is None or interior_jacobian or not self.fixed_io:
            C, dC = correct_brown(self.model, inputs.xy, io, jacobians=True)
        else:
            C, dC = C_fixed, None
        R = state.R[st]
        e, J_xc, Xc, t = image_residuals(C, state.X[pt], R, state.X0[st], io[:, 0])
        w = 1.0 / self.obs_sigma
        JX = -(J_xc @ R)
        Jd = J_xc @ skew(Xc)
        parts = [JX, -JX, Jd]
        jio = None
        if dC is not None:
            jio = dC.copy()
            jio[:, :, 0] -= t
            parts.append(jio)
        vals = np.concatenate(parts, axis=2) * w[:, None, None]
        ncol = vals.shape[2]
        J[self.img_rows[:, :, None], self.img_cols[:, None, :ncol]] = vals
        r[self.img_rows] = e * w[:, None]
        if self.n_ref:
            X = state.X[self.control]
            r[self.ref_rows] = (X - inputs.reference) / self.ref_sigma
            J[self.ref_rows, self.ref_cols] = 1.0 / self.ref_sigma
        if len(self.prior_stations):
            s = self.prior_stations
            ang, E = angle_increment_map(state.R[s])
            pr = inputs.station_prior
            e6 = np.zeros((len(s), 6))
            e6[:, :3] = state.X0[s] - pr[:, :3]
            e6[:, 3:] = np.angle(np.exp(1j * (ang - pr[:, 3:])))
            w6 = 1.0 / self.prior_sigma
            r[self.prior_rows] = e6 * w6
            Jp = np.zeros((len(s), 6, 6))
            Jp[:, :3, :3] = np.eye(3)
            Jp[:, 3:, 3:] = E
            J[self.prior_rows[:, :, None], self.station_cols[s][:, None, :]] = Jp * w6[:, :, None]
        if len(self.ip_k):
            r[self.ip_rows] = (state.io[self.ip_k, self.ip_j] - inputs.interior_prior) / self.ip_sigma
            J[self.ip_rows, self.io_cols[self.ip_k, self.ip_j]] = 1.0 / self.ip_sigma
        if len(self.d_a):
            d = state.X[self.d_a] - state.X[self.d_b]
            L = np.linalg.norm(d, axis=1)
            u = d / L[:, None] / self.d_sigma[:, None]
            r[self.d_rows] = (L - inputs.distances) / self.d_sigma
            ca = np.where(self.point_cols[self.d_a] >= 0, self.point_cols[self.d_a], self.n)
            cb = np.where(self.point_cols[self.d_b] >= 0, self.point_cols[self.d_b], self.n)
            J[self.d_rows[:, None], ca] = u
            J[self.d_rows[:, None], cb] = -u
        if len(self.v_t):
            d = state.X[self.v_t] - state.X[self.v_b]
            h = d[:, 2]
            ev = d[:, :2] / h[:, None]
            Jv = np.zeros((len(d), 2, 3))
            Jv[:, 0, 0] = 1.0 / h
            Jv[:, 1, 1] = 1.0 / h
            Jv[:, :, 2] = -ev / h[:, None]
            w2 = 1.0 / self.v_sigma[:, None]
            r[self.v_rows] = (ev - inputs.verticals) * w2
            ct = np.where(self.point_cols[self.v_t] >= 0, self.point_cols[self.v_t], self.n)
            cbm = np.where(self.point_cols[self.v_b] >= 0, self.point_cols[self.v_b], self.n)
            J[self.v_rows[:, :, None], ct[:, None, :]] = Jv * w2[:, :, None]
            J[self.v_rows[:, :, None], cbm[:, None, :]] = -Jv * w2[:, :, None]
        J = J[:, :self.n]
        if not interior_jacobian:
            return r, J
        K, p = state.io.shape
        Jio = np.zeros((self.m, K * p))
        idx = (self.obs_camera[:, None] * p + np.arange(p))         # (N, p)
        vals = jio * w[:, None, None]
        Jio[self.img_rows[:, :, None], idx[:, None, :]] = vals
        return r, J, Jio

    # ------------------------------------------------------------------
    def _scaled_solve(self, J, r):
        """Step and the Jacobi scaling (with the datum conditions)."""
        N = J.T @ J
        g = J.T @ r
        d = np.sqrt(np.diag(N))
        d = 1.0 / np.where(d > 0, d, 1.0)
        Ns = N * d[:, None] * d[None, :]
        if self.G is None:
            try:
                cho = la.cho_factor(Ns, check_finite=False)
            except la.LinAlgError:
                raise GeometryError("montecarlo: singular normal equations (datum defect?)",
                                    hint="check the datum of the adjustment project") from None
            return -d * la.cho_solve(cho, d * g, check_finite=False)
        G = self.G * d[:, None]
        k = G.shape[1]
        M = np.block([[Ns, G], [G.T, np.zeros((k, k))]])
        sol = np.linalg.solve(M, np.concatenate([-d * g, np.zeros(k)]))
        return d * sol[:self.n]

    def update(self, state: BundleState, dx) -> BundleState:
        new = state.copy()
        if self.io_free.any():
            new.io[self.io_free] += dx[self.io_cols[self.io_free]]
        sdx = dx[self.station_cols]
        new.X0 = new.X0 + sdx[:, :3]
        new.R = small_rotation(sdx[:, 3:]) @ new.R
        new.X[self.free_points] += dx[self.point_cols[self.free_points]]
        return new

    def _scale(self, state):
        size = float(np.max(np.abs(state.X[self.free_points]), initial=1.0))
        s = np.ones(self.n)
        s[self.station_cols[:, :3]] = size
        s[self.point_cols[self.free_points]] = size
        if self.io_free.any():
            s[self.io_cols[self.io_free]] = np.maximum(np.abs(state.io[self.io_free]), 1e-3)
        return s

    def solve(self, inputs: BundleInputs, io=None, start: BundleState | None = None, tol=None):
        """Adjust with ``inputs`` (and the fixed interior orientation ``io``,
        default the start's); returns ``(state, iterations)``.

        Raises
        ------
        GeometryError
            No convergence within ``max_iterations``.
        """
        state = (start or self.start).copy()
        if io is not None:
            state.io = np.array(io, dtype=float)
        C = None
        if self.fixed_io:
            from photogram.montecarlo.intersect import correct_fast
            C = correct_fast(inputs.xy, state.io[self.obs_camera])
        scale = self._scale(state)
        for it in range(1, self.max_iterations + 1):
            r, J = self.evaluate(state, inputs, C_fixed=C)
            dx = self._scaled_solve(J, r)
            if not np.all(np.isfinite(dx)):
                raise GeometryError("montecarlo: the adjustment diverged")
            state = self.update(state, dx)
            if np.max(np.abs(dx) / scale) < (tol or self.tolerance):
                return state, it
        raise GeometryError(f"montecarlo: the adjustment did not converge in "
                            f"{self.max_iterations} iterations")

    def linearize(self, state: BundleState, inputs: BundleInputs):
        """What first-order propagation needs at ``state``.

        Returns
        -------
        J : (m, n) whitened Jacobian
        Q : (n, n) cofactors of the unknowns (a-priori sigma0 = 1; with the
            datum conditions, the inner-constraint cofactors)
        Jio : (m, K p) whitened derivative of the residuals w.r.t. every
            interior parameter
        """
        _, J, Jio = self.evaluate(state, inputs, interior_jacobian=True)
        N = J.T @ J
        d = np.sqrt(np.diag(N))
        d = 1.0 / np.where(d > 0, d, 1.0)
        Ns = N * d[:, None] * d[None, :]
        if self.G is None:
            Q = np.linalg.inv(Ns)
        else:
            G = self.G * d[:, None]
            k = G.shape[1]
            M = np.block([[Ns, G], [G.T, np.zeros((k, k))]])
            Q = np.linalg.inv(M)[:self.n, :self.n]
        return J, Q * d[:, None] * d[None, :], Jio
