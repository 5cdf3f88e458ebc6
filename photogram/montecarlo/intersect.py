"""The intersect step of a Monte-Carlo chain, built once.

The same estimators as ``photogram intersect`` (:mod:`photogram.jump.pipeline`),
for all exposures at once:

* **points** (all jumper points of all exposures) by the engine: the
  problem of the intersect project (:func:`photogram.adjust.build.build_problem`
  with the orientation fixed, as ``photogram intersect`` builds it) is built
  once; a run puts its orientation into the state and its image
  coordinates into the image block and solves point by point
  (:func:`photogram.adjust.dense.gauss_newton`, 3x3 normal equations per
  point, :func:`photogram.adjust.dense.point_normals` for the cofactors);
* **image lines and 3D lines** by the line code of the commands,
  :mod:`photogram.lines.batch_image` and :mod:`photogram.lines.batch` (:func:`photogram.lines.fit_view_line` and
  :func:`photogram.lines.intersect_line` are its batches of one), here over
  all lines of a run at once, with the ideal coordinates of every camera
  model from :func:`photogram.lines.views.ideal_coordinates`;
* the **stick model** by :func:`photogram.jump.stick.stick_model`.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from photogram.adjust.build import build_problem, merged_image_blocks
from photogram.adjust.dense import gauss_newton, point_normals, pointwise_structure
from photogram.adjust.residual_blocks import ImagePointBlock
from photogram.adjust.state import State
from photogram.errors import InputError
from photogram.geometry import matrix_to_opk
from photogram.jump.exposures import exposure_order as _exposure_order
from photogram.jump.exposures import split_id
from photogram.jump.stick import stick_model
from photogram.lines.batch import intersect_lines_batch, local_basis_batch  # noqa: F401
from photogram.lines.batch_image import fit_lines_batch, fit_lines_padded, line_layout
from photogram.lines.views import ideal_coordinates

#: the image-line fit's stopping rule outside trials (that of photogram
#: intersect: :func:`photogram.lines.fit_image_line`)
IMAGE_LINE_TOLERANCE = 1e-13

__all__ = ["IntersectStep", "IntersectOutput", "local_basis_batch"]


@dataclass
class IntersectOutput:
    P: np.ndarray          # (E, 4, 3) jumper points
    X: np.ndarray          # (n_points, 3) every point of the project
    line_P: np.ndarray     # (E, 2, 3) a point of each ski line
    line_D: np.ndarray     # (E, 2, 3) its unit direction (as estimated)
    model: object          # StickModel


class IntersectStep:
    """The intersect step of one project, built once.

    Parameters
    ----------
    project : Project
        The intersect project (moving points ``P1@001``, ski lines
        ``L1@001``, ``[intersect]`` settings).
    bundle : EngineBundle
        The adjustment step: its cameras (models) and stations name the
        orientation passed to :meth:`solve`; its truth orientation is where
        the intersect problem is built.
    start_points : (n_points, 3), optional
        Approximate points (the truth of a simulation); default: the
        approximation chain of ``photogram intersect``.
    """

    def __init__(self, project, bundle, start_points=None):
        camera_names, station_names = bundle.camera_names, bundle.station_names
        self.models = bundle.models
        cfg = project.intersect
        self.cfg = cfg
        self.length_unit = project.units.length
        st = project.stations
        s_index = {n: i for i, n in enumerate(station_names)}
        c_index = {n: i for i, n in enumerate(camera_names)}
        missing = [n for n in st.names if n not in s_index]
        if missing:
            raise InputError(f"station(s) {', '.join(missing)} of the intersect project are not "
                             f"in the adjustment project", file=project.path,
                             hint="both projects must name the same stations")
        cam_of = {}
        for n, cname in zip(st.names, st.camera):
            if cname not in c_index:
                raise InputError(f"camera {cname} of the intersect project is not in the "
                                 f"adjustment project", file=project.path)
            cam_of[s_index[n]] = c_index[cname]
            k = c_index[cname]
            if project.cameras[cname].model != bundle.models[k].name:
                raise InputError(f"camera {cname}: model {project.cameras[cname].model} in the "
                                 f"intersect project, {bundle.models[k].name} in the "
                                 f"adjustment project", file=project.path)
        local_to_global = np.array([s_index[n] for n in st.names], dtype=int)
        self.local_to_global = local_to_global
        self.station_camera = np.zeros(len(station_names), dtype=int)
        for s, k in cam_of.items():
            self.station_camera[s] = k
        self.camera_global = np.array([c_index[n] for n in project.cameras], dtype=int)
        # ---- points: the engine problem of photogram intersect -----------
        ip = project.image_points
        self.point_ids = list(project.points.ids)
        self.p_station = local_to_global[np.asarray(ip.station, dtype=int)]
        self.p_point = np.asarray(ip.point, dtype=int)
        self.n_points = len(self.point_ids)
        counts = np.bincount(self.p_point, minlength=self.n_points)
        if np.any(counts < 2):
            bad = [self.point_ids[i] for i in np.flatnonzero(counts < 2)]
            raise InputError(f"point(s) {', '.join(bad[:5])} have fewer than 2 rays",
                             file=project.path)
        self._build_points(project, bundle, start_points)
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
        sig = project.adjustment.sigma_image
        cam_sigma = {n: (sig[c] if isinstance(sig, dict) else sig)
                     for n, c in zip(st.names, st.camera)}
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
        S = len(station_names)
        gkey = line_no * S + self.l_station
        uniq, self.l_group = np.unique(gkey, return_inverse=True)
        self.n_groups = len(uniq)
        self.l_layout = line_layout(self.l_group, self.n_groups)
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
        names = [m.name for m in self.models]
        self._l_rows = [(self.models[names.index(n)],
                         np.flatnonzero(np.isin(self.l_camera,
                                                [k for k, m in enumerate(names) if m == n])))
                        for n in dict.fromkeys(names)]        # one call per camera model
        self.inputs_lines = np.asarray(il.xy, dtype=float).copy()
        self._l_camera_padded = self.l_camera[self.l_layout[0].ravel()]
        self._l_sigma_padded = np.broadcast_to(self.l_sigma, self.l_camera.shape)[self.l_layout[0]]
        self.max_iterations = 20
        self.tolerance = 1e-11

    def _build_points(self, project, bundle, start_points):
        """The engine problem of the points at the truth orientation."""
        st = bundle.start
        prj = copy.deepcopy(project)
        for name, cam in prj.cameras.items():
            k = self.camera_names_index(bundle, name)
            for pname, v in zip(cam.parameters, st.io[k]):
                cam.parameters[pname].value = float(v)
        prj.stations.position = st.X0[self.local_to_global].copy()
        prj.stations.angles = matrix_to_opk(st.R[self.local_to_global])
        if start_points is not None:
            prj.points.xyz = np.asarray(start_points, dtype=float).copy()
        else:
            from photogram.bundle import approximate_if_needed
            prj = approximate_if_needed(prj, {"warnings": []})
        built = build_problem(prj, fix_interior=True, fix_stations=True)
        pb = merged_image_blocks(built.problem)
        if not pointwise_structure(pb).ok:
            raise InputError("montecarlo: the intersect project's points are coupled "
                             "(distances, verticality, a datum)", file=project.path)
        self.problem = pb
        self.state0 = pb.state.copy()
        self._image = [b for b in pb.blocks if isinstance(b, ImagePointBlock)]
        n = len(self.p_point)
        self.p_sigma = np.zeros(n)
        for b in self._image:
            self.p_sigma[b.rows] = b.sigma[:, 0]
        self.inputs_points = np.asarray(project.image_points.xy, dtype=float).copy()
        self.start_points = pb.state.points.copy()
        self._n_io = [len(v) for v in pb.state.io]
        self._in_order = [len(b.rows) == n and np.array_equal(b.rows, np.arange(n))
                          for b in self._image]

    @staticmethod
    def camera_names_index(bundle, name):
        return bundle.camera_names.index(name)

    # ------------------------------------------------------------------
    def intersect_points(self, io, R, X0, xy, start, covariance=False, tol=None):
        """All points by the engine from ``start`` (n_points, 3) with the
        orientation ``io`` (K, p), ``R``, ``X0`` of the adjustment step's
        cameras and stations and the image coordinates ``xy`` (rows of the
        image points table); with ``covariance`` also the cofactors (n, 3, 3)
        of every point (a-priori image sigmas)."""
        pb = self.problem
        l2g = self.local_to_global
        state = State(np.array(start, dtype=float), np.asarray(R, dtype=float)[l2g],
                      np.asarray(X0, dtype=float)[l2g],
                      [np.array(io[k, :n], dtype=float)
                       for k, n in zip(self.camera_global, self._n_io)])
        xy = np.asarray(xy, dtype=float)
        for b, in_order in zip(self._image, self._in_order):
            b.xy = xy.copy() if in_order else xy[b.rows]
        pb.state = state
        gauss_newton(pb, tolerance=tol or self.tolerance, max_iterations=self.max_iterations)
        X = pb.state.points.copy()
        if not covariance:
            return X
        points, A, _ = point_normals(pb, pb.state)
        cov = np.full((self.n_points, 3, 3), np.nan)
        cov[points] = np.linalg.inv(A)
        return X, cov

    def ideal(self, io, xy, rows_by_model, jacobians=False):
        """Ideal coordinates of image coordinates xy (camera per row) by
        :func:`photogram.lines.views.ideal_coordinates`."""
        if len(rows_by_model) == 1:                  # one camera model: no scatter
            model, rows = rows_by_model[0]
            return ideal_coordinates(model.name, xy, io[self.l_camera, :model.n_params],
                                     jacobians=jacobians)
        xi = np.zeros((len(xy), 2))
        J = np.zeros((len(xy), 2, 2)) if jacobians else None
        for model, rows in rows_by_model:
            if not len(rows):
                continue
            ior = io[self.l_camera[rows], :model.n_params]
            out = ideal_coordinates(model.name, xy[rows], ior, jacobians=jacobians)
            if jacobians:
                xi[rows], J[rows] = out
            else:
                xi[rows] = out
        return (xi, J) if jacobians else xi

    def fit_lines(self, io, xy, tol=None):
        """The image lines (the commands' Gauss-Helmert fit, eq. (C11));
        ``tol`` its stopping rule (default: the commands' 1e-13; a trial
        passes the trial tolerance, as for every other iteration of a run)."""
        tol = tol or IMAGE_LINE_TOLERANCE
        if len(self._l_rows) == 1:        # one camera model: straight into the padded layout
            src, mask = self.l_layout
            model = self._l_rows[0][0]
            xi, J = ideal_coordinates(model.name, xy[src.ravel()],
                                      io[self._l_camera_padded, :model.n_params],
                                      jacobians=True)
            return fit_lines_padded(xi.reshape(src.shape + (2,)), J.reshape(src.shape + (2, 2)),
                                    self._l_sigma_padded, mask, tol=tol)
        xi, J = self.ideal(io, xy, self._l_rows, jacobians=True)
        return fit_lines_batch(xi, J, self.l_sigma, self.l_group, self.n_groups,
                               layout=self.l_layout, tol=tol)

    def intersect_lines(self, io, R, X0, xy, start=None, covariance=False, tol=None):
        l, cov_l, ends = self.fit_lines(io, xy, tol=tol)
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
