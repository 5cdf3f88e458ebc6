"""A lean, vectorized intersect step for Monte-Carlo runs.

The same estimators as ``photogram intersect`` (:mod:`photogram.jump.pipeline`),
for all exposures at once and without the checks, figures and per-line
Python loops:

* **points** (all jumper points of all exposures): Gauss-Newton on the
  collinearity residuals of the Brown correction model with the orientation
  fixed, one 3x3 normal matrix per point, from a given start (the truth);
* **image lines** (appendix C.2, step A, eq. (C11)): per (line, view) the
  weighted orthogonal regression in ideal coordinates with the weights of
  :func:`photogram.lines.fit_view_line` (the sigma across the line through the
  correction Jacobian, with the normal of the unweighted principal axis) --
  the limit the Gauss-Helmert iteration of :func:`fit_image_line` converges
  to, in closed form;
* **3D lines** (appendix C.2, step B, eqs. (C13)-(C14)): the planes through
  the projection centres, all lines of a batch at once: the initial line
  from the null space of the stacked (conditioned) planes (appendix C.3) or
  a given start, then Gauss-Newton in the 4 local parameters of
  :class:`photogram.lines.SpaceLine` with the weights (C14), the two points
  per view kept during the iteration, as :func:`intersect_line` does;
* the **stick model** by :func:`photogram.jump.stick.stick_model`
  (vectorized already).

Tests check every piece against the library functions it mirrors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import InputError
from photogram.geometry import camera_model, opk_to_matrix
from photogram.geometry.camera import ideal_projection
from photogram.jump.exposures import exposure_order as _exposure_order
from photogram.jump.exposures import split_id
from photogram.jump.stick import stick_model
from photogram.montecarlo.lines import (fit_lines_batch, initial_lines_batch,  # noqa: F401
                                        intersect_lines_batch, local_basis_batch)

__all__ = ["LeanIntersect", "IntersectOutput", "fit_lines_batch", "intersect_lines_batch",
           "local_basis_batch"]


def correct_fast(xy, io, jacobian=False):
    """The brown model's correction (:meth:`BrownModel.correct`) of measured
    ``xy`` with per-row ``io`` (n, 10), without the interior-orientation
    derivatives; with ``jacobian`` also ``dC/dxy`` (n, 2, 2)."""
    xb, yb = xy[:, 0] - io[:, 1], xy[:, 1] - io[:, 2]
    K1, K2, K3, P1, P2, B1, B2 = (io[:, i] for i in range(3, 10))
    u = (1.0 + B1) * xb - B2 * yb
    v = -yb
    r2 = u * u + v * v
    k = r2 * (K1 + r2 * (K2 + r2 * K3))
    U = u + u * k + P1 * (r2 + 2 * u * u) + 2 * P2 * u * v
    V = v + v * k + P2 * (r2 + 2 * v * v) + 2 * P1 * u * v
    C = np.stack([U, -V], -1)
    if not jacobian:
        return C
    kp = K1 + r2 * (2.0 * K2 + 3.0 * r2 * K3)
    a = 1 + k + 2 * u * u * kp + 6 * P1 * u + 2 * P2 * v      # dU/du
    b = 2 * u * v * kp + 2 * P1 * v + 2 * P2 * u               # dU/dv
    c = 2 * u * v * kp + 2 * P2 * u + 2 * P1 * v               # dV/du
    d = 1 + k + 2 * v * v * kp + 6 * P2 * v + 2 * P1 * u       # dV/dv
    # (U, -V) by (u, v), times d(u, v)/d(xb, yb) = [[1 + B1, -B2], [0, -1]]
    J = np.empty((len(xb), 2, 2))
    J[:, 0, 0] = a * (1.0 + B1)
    J[:, 0, 1] = -a * B2 - b
    J[:, 1, 0] = -c * (1.0 + B1)
    J[:, 1, 1] = c * B2 + d
    return C, J


def _segments(keys):
    """Order that sorts ``keys`` and the start of each group."""
    order = np.argsort(keys, kind="stable")
    k = keys[order]
    starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]]) if len(k) else np.zeros(0, int)
    return order, starts


@dataclass
class IntersectOutput:
    P: np.ndarray          # (E, 4, 3) jumper points
    X: np.ndarray          # (n_points, 3) every point of the project
    line_P: np.ndarray     # (E, 2, 3) a point of each ski line
    line_D: np.ndarray     # (E, 2, 3) its unit direction (as estimated)
    model: object          # StickModel


class LeanIntersect:
    """The intersect step of one project, built once.

    Parameters
    ----------
    project : Project
        The intersect project (moving points ``P1@001``, ski lines
        ``L1@001``, ``[intersect]`` settings).
    camera_names, station_names : list of str
        Order of the cameras and stations of the orientation passed to
        :meth:`solve` (those of the adjustment step).
    """

    def __init__(self, project, camera_names, station_names):
        self.model = camera_model("brown")
        cfg = project.intersect
        self.cfg = cfg
        self.length_unit = project.units.length
        for n, cam in project.cameras.items():
            if cam.model != "brown":
                raise InputError(f"photogram montecarlo supports the brown camera model only "
                                 f"(camera {n})", file=project.path)
        cam_of = {}
        st = project.stations
        s_index = {n: i for i, n in enumerate(station_names)}
        c_index = {n: i for i, n in enumerate(camera_names)}
        missing = [n for n in st.names if n not in s_index]
        if missing:
            raise InputError(f"station(s) {', '.join(missing)} of the intersect project are not "
                             f"in the adjustment project", file=project.path,
                             hint="both projects must name the same stations")
        for n, cname in zip(st.names, st.camera):
            if cname not in c_index:
                raise InputError(f"camera {cname} of the intersect project is not in the "
                                 f"adjustment project", file=project.path)
            cam_of[s_index[n]] = c_index[cname]
        local_to_global = np.array([s_index[n] for n in st.names], dtype=int)
        self.station_camera = np.zeros(len(station_names), dtype=int)
        for s, k in cam_of.items():
            self.station_camera[s] = k
        sig = project.adjustment.sigma_image
        cam_sigma = {n: (sig[c] if isinstance(sig, dict) else sig)
                     for n, c in zip(st.names, st.camera)}
        # ---- points ------------------------------------------------------
        ip = project.image_points
        self.point_ids = list(project.points.ids)
        self.p_station = local_to_global[np.asarray(ip.station, dtype=int)]
        self.p_point = np.asarray(ip.point, dtype=int)
        self.p_camera = self.station_camera[self.p_station]
        default = np.array([cam_sigma[st.names[s]] for s in ip.station], dtype=float)
        self.p_sigma = np.where(np.isfinite(ip.sigma), ip.sigma, default)
        self.n_points = len(self.point_ids)
        if np.any(np.bincount(self.p_point, minlength=self.n_points) < 2):
            bad = [self.point_ids[i] for i in
                   np.flatnonzero(np.bincount(self.p_point, minlength=self.n_points) < 2)]
            raise InputError(f"point(s) {', '.join(bad[:5])} have fewer than 2 rays",
                             file=project.path)
        self._p_order = np.argsort(self.p_point, kind="stable")
        self._p_starts = np.flatnonzero(np.r_[True, np.diff(self.p_point[self._p_order]) != 0])
        pidx = {n: i for i, n in enumerate(self.point_ids)}
        moving = [split_id(i) for i in self.point_ids if "@" in i]
        self.exposures, frames = _exposure_order([e for _, e in moving])
        if not self.exposures:
            raise InputError("montecarlo: the intersect project has no exposures",
                             file=project.path)
        E = len(self.exposures)
        self.times = (frames - frames[0]) / cfg.fps
        self.jumper_index = np.full((E, 4), -1)
        for k, name in enumerate(cfg.points):
            for e, ex in enumerate(self.exposures):
                self.jumper_index[e, k] = pidx.get(f"{name}@{ex}", -1)
        if np.any(self.jumper_index < 0):
            raise InputError("montecarlo: every exposure needs all four jumper points",
                             file=project.path)
        # ---- lines -------------------------------------------------------
        il = project.image_lines
        lab = np.asarray(il.line, dtype=object)
        self.l_station = local_to_global[np.asarray(il.station, dtype=int)]
        default = np.array([cam_sigma[st.names[s]] for s in il.station], dtype=float)
        self.l_sigma = np.where(np.isfinite(il.sigma), il.sigma, default)
        labels = list(dict.fromkeys(lab.tolist()))
        line_of = {}
        for j, ski in enumerate(cfg.skis):
            for e, ex in enumerate(self.exposures):
                line_of[f"{ski}@{ex}"] = e * 2 + j
        unknown = [x for x in labels if x not in line_of]
        if unknown:
            raise InputError(f"montecarlo: image line(s) {', '.join(unknown[:3])} are not "
                             f"ski lines of an exposure", file=project.path)
        line_no = np.array([line_of[x] for x in lab], dtype=int)
        self.l_line = line_no
        self.n_lines = 2 * E
        # groups (line, station): rows kept in measurement order
        S = len(station_names)
        gkey = line_no * S + self.l_station
        uniq, self.l_group = np.unique(gkey, return_inverse=True)
        self.n_groups = len(uniq)
        g_line, g_station = uniq // S, uniq % S
        views = np.bincount(g_line, minlength=self.n_lines)
        if np.any(views < 2) or np.any(views != views[0]):
            raise InputError("montecarlo: every ski line must be measured in the same number "
                             "(>= 2) of images", file=project.path)
        self.k = int(views[0])
        order = np.lexsort((g_station, g_line))
        self.g_index = order.reshape(self.n_lines, self.k)          # group of (line, view)
        self.g_station = g_station[self.g_index]                     # (L, k)
        self.l_camera = self.station_camera[self.l_station]
        self.inputs_points = np.asarray(ip.xy, dtype=float).copy()
        self.inputs_lines = np.asarray(il.xy, dtype=float).copy()
        self.max_iterations = 20
        self.tolerance = 1e-11

    # ------------------------------------------------------------------
    def intersect_points(self, io, R, X0, xy, start, covariance=False, tol=None):
        """All points by Gauss-Newton from ``start`` (n_points, 3)."""
        st, pt, cam = self.p_station, self.p_point, self.p_camera
        C = correct_fast(xy, io[cam])
        X = np.array(start, dtype=float)
        Rs, X0s, c = R[st], X0[st], io[cam, 0]
        w = 1.0 / self.p_sigma
        order, starts = self._p_order, self._p_starts
        for _ in range(self.max_iterations):
            Xc = np.einsum("nij,nj->ni", Rs, X[pt] - X0s)
            ideal, Jxc, _ = ideal_projection(Xc, c, jacobians=True)
            r = (C - ideal) * w[:, None]
            JX = -(Jxc @ Rs) * w[:, None, None]
            Jt = np.swapaxes(JX, 1, 2)
            A = np.add.reduceat((Jt @ JX)[order], starts, axis=0)
            b = np.add.reduceat((Jt @ r[..., None])[order], starts, axis=0)
            dx = -np.linalg.solve(A, b)[..., 0]
            X += dx
            if np.abs(dx).max() <= (tol or self.tolerance) * (1.0 + np.abs(X).max()):
                break
        if covariance:
            return X, np.linalg.inv(A)
        return X

    def triangulate(self, io, R, X0, xy):
        """Closed-form start: the point nearest to its rays (least squares)."""
        st, pt, cam = self.p_station, self.p_point, self.p_camera
        C = self.model.correct(xy, io[cam])
        dc = np.stack([C[:, 0], -C[:, 1], -io[cam, 0]], -1)
        d = np.einsum("nji,nj->ni", R[st], dc)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        M = np.eye(3) - d[:, :, None] * d[:, None, :]
        n = self.n_points
        A = np.zeros((n, 3, 3))
        b = np.zeros((n, 3))
        Mb = np.einsum("nij,nj->ni", M, X0[st])
        for q in range(9):
            A[:, q // 3, q % 3] = np.bincount(pt, weights=M[:, q // 3, q % 3], minlength=n)
        for q in range(3):
            b[:, q] = np.bincount(pt, weights=Mb[:, q], minlength=n)
        return np.linalg.solve(A, b[..., None])[..., 0]

    def fit_lines(self, io, xy):
        xi, J = correct_fast(xy, io[self.l_camera], jacobian=True)
        return fit_lines_batch(xi, J, self.l_sigma, self.l_group, self.n_groups)

    def intersect_lines(self, io, R, X0, xy, start=None, covariance=False, tol=None):
        l, cov_l, ends = self.fit_lines(io, xy)
        g = self.g_index
        Rv, X0v = R[self.g_station], X0[self.g_station]
        cv = io[self.station_camera[self.g_station], 0]
        return intersect_lines_batch(l[g], cov_l[g], ends[g], Rv, X0v, cv, start=start,
                                     max_iterations=self.max_iterations,
                                     tol=tol or self.tolerance, covariance=covariance)

    def stick(self, P, line_P, line_D, cov_points=None, cov_dirs=None):
        cfg = self.cfg
        return stick_model(P, line_D[:, 0], line_D[:, 1], fps=cfg.fps, times=self.times,
                           length_unit=self.length_unit, ski_length=cfg.ski_length,
                           binding_fraction=cfg.binding_fraction, c1=line_P[:, 0],
                           c2=line_P[:, 1], forward="flight", cov_points=cov_points,
                           cov_dirs=cov_dirs)

    def solve(self, io, R, X0, xy_points, xy_lines, start_points, start_lines=None, tol=None):
        """The whole step for one orientation and one set of observations."""
        X = self.intersect_points(io, R, X0, xy_points, start_points, tol=tol)
        LP, LD = self.intersect_lines(io, R, X0, xy_lines, start_lines, tol=tol)
        E = len(self.exposures)
        P = X[self.jumper_index]
        line_P, line_D = LP.reshape(E, 2, 3), LD.reshape(E, 2, 3)
        return IntersectOutput(P, X, line_P, line_D, self.stick(P, line_P, line_D))

    def orientation_of(self, angles_or_R, X0):
        R = angles_or_R if np.ndim(angles_or_R) == 3 else opk_to_matrix(angles_or_R)
        return np.asarray(R, dtype=float), np.asarray(X0, dtype=float)
