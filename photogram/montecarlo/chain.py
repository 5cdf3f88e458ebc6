"""The chain one Monte-Carlo run repeats, and its first-order propagation.

A :class:`Chain` is built once (in the parent process) from the
``[montecarlo]`` settings: the truth world (:mod:`photogram.montecarlo.truth`),
the adjustment step on the engine
(:class:`~photogram.montecarlo.adjustment.EngineBundle`) and, if asked, the
intersect step (:class:`~photogram.montecarlo.intersect.IntersectStep`:
points by the engine, lines by :mod:`photogram.lines.batch`). It is small and
picklable; :meth:`Chain.trial` runs one simulation from one
:class:`numpy.random.SeedSequence`:

1. draw, in a fixed order and always all of them (a kind not perturbed is
   multiplied by 0, so every kind keeps its own numbers whatever else is
   perturbed): the image coordinates of the adjustment step, the reference
   coordinates (and station priors), the constraint observations, the
   interior orientation (``N(truth, covariance of the calibration)``), the
   image points and the points along the image lines of the intersect step;
2. adjust (interior fixed at the drawn values for ``orient``, estimated for
   ``calibrate``), starting from the truth;
3. intersect the jumper points and ski lines with that orientation, and the
   stick model;
4. return one vector: stations (X0 Y0 Z0 omega phi kappa), interior
   parameters, collected adjustment points, jumper points, stick-model
   parameters (angles wrapped to the truth +- pi).

:meth:`Chain.propagate` gives, for the same vector, the sigma of
first-order covariance propagation through the same chain (``sigma_prop``)
and :attr:`Chain.sigma_cmd` the sigma the commands report, computed by the
commands' own code at the setup (:mod:`photogram.montecarlo.reported`); see
docs/montecarlo.md.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.geometry import matrix_to_opk
from photogram.jump.definitions import ANGLE_PARAMETERS, PARAMETERS
from photogram.jump.stick import ANGLE_FACTORS
from photogram.montecarlo.adjustment import EngineBundle
from photogram.montecarlo.intersect import IntersectStep
from photogram.montecarlo.manifest import project_files

__all__ = ["Chain", "Outputs"]

_AXES = ("X", "Y", "Z")
#: relative step size at which a run's iterations stop (the setup and the
#: propagation iterate to 1e-10 and below)
TRIAL_TOLERANCE = 1e-6
_STATION = ("X0", "Y0", "Z0", "omega", "phi", "kappa")


@dataclass
class Outputs:
    """Names and metadata of the vector a trial returns."""

    names: list = field(default_factory=list)
    groups: list = field(default_factory=list)     # station, interior, point, jumper, stick
    units: list = field(default_factory=list)
    angle: list = field(default_factory=list)      # wrapped around the truth
    factor: list = field(default_factory=list)     # internal -> reported unit

    def add(self, names, group, unit, angle=False, factor=1.0):
        n = len(names)
        self.names += list(names)
        self.groups += [group] * n
        self.units += [unit] * n if isinstance(unit, str) else list(unit)
        self.angle += [angle] * n if isinstance(angle, bool) else list(angle)
        self.factor += [factor] * n if np.isscalar(factor) else list(factor)


def _sqrt_psd(C):
    """A factor L with L L^T = C (C symmetric PSD, any scaling)."""
    d = np.sqrt(np.clip(np.diag(C), 0, None))
    inv = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    w, V = np.linalg.eigh(C * inv[:, None] * inv[None, :])
    return d[:, None] * V * np.sqrt(np.clip(w, 0, None))[None, :]


def _wrap(x):
    return np.angle(np.exp(1j * x))


def _interior_covariance(settings, project, camera_names, parameter_names, files=None):
    from photogram.project.results_read import read_orientation_covariance
    folder = settings.interior_covariance
    if folder is None:
        srcs = {project.sources.get(f"cameras:{n}") for n in camera_names}
        srcs.discard(None)
        if len(srcs) != 1:
            raise InputError("perturb includes interior but the cameras do not come from one "
                             "calibration results folder", file=project.path,
                             hint="give [montecarlo] interior_covariance = \"../lab/results\"")
        folder = next(iter(srcs)).parent
    if files is not None:
        files.append(Path(folder) / "covariance.npz")
    try:
        labels, matrix = read_orientation_covariance(folder)
    except FileNotFoundError:
        raise InputError("no covariance.npz of the interior orientation", file=folder,
                         hint="run photogram calibrate on the lab project first") from None
    index = {lab: i for i, lab in enumerate(labels)}
    p_max = max((len(p) for p in parameter_names), default=0)
    want = [f"{c}.{names[j]}" if j < len(names) else None
            for c, names in zip(camera_names, parameter_names) for j in range(p_max)]
    sel = np.array([index.get(w, -1) for w in want])
    C = np.zeros((len(want), len(want)))
    ok = sel >= 0
    C[np.ix_(ok, ok)] = matrix[np.ix_(sel[ok], sel[ok])]
    return C


class Chain:
    """One Monte-Carlo chain (see the module docstring)."""

    def __init__(self, settings, *, project_reader=None):
        from photogram.montecarlo.reported import command_sigmas
        from photogram.montecarlo.truth import adjusted_result, simulation_truth
        from photogram.project import read_project
        read = project_reader or read_project
        self.settings = settings
        self.perturb = set(settings.perturb)
        self.fix_interior = settings.orient is not None
        prj1 = read(settings.orient or settings.calibrate)
        #: every file the runs depend on (their content is hashed into the
        #: manifest of the samples folder, photogram.montecarlo.manifest)
        self.input_files = project_files(prj1)
        self.units = prj1.units
        if settings.truth == "simulation":
            self.input_files += [Path(prj1.folder) / "truth" / f
                                 for f in ("cameras.csv", "stations.csv", "points.csv")]
            truth1 = simulation_truth(prj1)
            result1 = None
        else:
            result1 = adjusted_result(prj1, fix_interior=self.fix_interior)
            truth1 = result1.project
        b = EngineBundle(truth1, fix_interior=self.fix_interior)
        self.bundle = b
        K, p = b.start.io.shape
        self.shape_io = (K, p)
        # the exact observations of the truth (EngineBundle.exact_inputs)
        self.sig1 = b.input_sigmas()
        # interior orientation drawn from the calibration's covariance
        self.io_cov = np.zeros((K * p, K * p))
        if self.fix_interior:
            try:
                self.io_cov = _interior_covariance(settings, prj1, b.camera_names,
                                                   b.parameter_names, self.input_files)
            except InputError:
                if "interior" in self.perturb:
                    raise
        self.io_L = _sqrt_psd(self.io_cov) if self.io_cov.any() else np.zeros((K * p, 0))
        if self.fix_interior:
            self.io_random = np.flatnonzero(np.diag(self.io_cov) > 0)
        else:
            self.io_random = np.flatnonzero(b.io_free.ravel())
        self.collect = self._collected_points(truth1)
        self.intersect = None
        prj2 = None
        if settings.intersect is not None:
            prj2 = read(settings.intersect)
            self.input_files += project_files(prj2)
            if settings.truth == "simulation":
                self.input_files += [Path(prj2.folder) / "truth" / f
                                     for f in ("jumper_points.csv", "skis.csv")]
            self._setup_intersect(prj2)
        self.outputs = self._outputs()
        self.truth = self._evaluate_truth()
        #: what the commands report for every output (internal units, NaN:
        #: not reported), by the commands' own code (montecarlo.reported)
        self.sigma_cmd = command_sigmas(self, prj1, prj2, result1)

    # ------------------------------------------------------------------ setup
    def _collected_points(self, truth1):
        pats = self.settings.points
        if not pats:
            return np.zeros(0, dtype=int)
        ids = self.bundle.point_ids
        free = set(self.bundle.free_points.tolist())
        sel = [i for i, n in enumerate(ids) if i in free and any(fnmatch.fnmatchcase(n, q)
                                                                  for q in pats)]
        if not sel:
            raise InputError(f"[montecarlo] points {list(pats)} match no adjusted point",
                             file=self.settings_path, hint="use point ids, * as a wildcard")
        return np.array(sel, dtype=int)

    @property
    def settings_path(self):
        return getattr(self.settings, "path", None)

    def _setup_intersect(self, prj2):
        from photogram.montecarlo.truth import (line_observations, project_points,
                                                simulation_jump_truth)
        b = self.bundle
        li = IntersectStep(prj2, b)
        st = b.start
        io, R, X0 = st.io, st.R, st.X0
        E = len(li.exposures)
        if self.settings.truth == "simulation":
            P, LP, LD = simulation_jump_truth(prj2, li.exposures, li.cfg.points, li.cfg.skis)
            X = np.full((li.n_points, 3), np.nan)
            X[li.jumper_index] = P
            if not np.all(np.isfinite(X)):
                raise InputError("the intersect project has points that are not jumper points "
                                 "of the truth", file=prj2.path)
            LP, LD = LP.reshape(-1, 3), LD.reshape(-1, 3)
        else:
            X = li.intersect_points(io, R, X0, li.inputs_points, li.start_points)
            LP, LD = li.intersect_lines(io, R, X0, li.inputs_lines)
        xy_p = project_points(b.models, io, matrix_to_opk(R), X0, X, li.station_camera,
                              li.p_station, li.p_point)
        xy_l = line_observations(b.models, io, R, X0, li.station_camera, li.inputs_lines,
                                 li.l_station, li.l_line, LP, LD)
        li.inputs_points, li.inputs_lines = xy_p, xy_l
        # the exact observations give back the truth (up to the tolerance)
        X = li.intersect_points(io, R, X0, xy_p, X)
        LP, LD = li.intersect_lines(io, R, X0, xy_l, (LP, LD))
        self.intersect = li
        self.X2, self.LP2, self.LD2 = X, LP, LD
        self.n_exposures = E

    def _outputs(self):
        b, u = self.bundle, self.units
        out = Outputs()
        fa = ANGLE_FACTORS[u.angle]
        for s in b.station_names:
            out.add([f"{s}.{q}" for q in _STATION], "station",
                    [u.length] * 3 + [u.angle] * 3, [False] * 3 + [True] * 3,
                    [1.0] * 3 + [fa] * 3)
        K, p = self.shape_io
        for i in self.io_random:
            k = i // p
            cam, par = b.camera_names[k], b.parameter_names[k][i % p]
            dims = getattr(b.models[k], "parameter_dims", ()) or ()
            dim = dims[i % p] if len(dims) > i % p else 1
            unit = u.image if dim == 1 else ("1" if dim == 0 else f"{u.image}^{dim}")
            out.add([f"{cam}.{par}"], "interior", unit)
        for i in self.collect:
            out.add([f"{b.point_ids[i]}.{a}" for a in _AXES], "point", u.length)
        if self.intersect is not None:
            li = self.intersect
            for ex in li.exposures:
                for name in li.cfg.points:
                    out.add([f"{name}@{ex}.{a}" for a in _AXES], "jumper", u.length)
            for ex in li.exposures:
                for q in PARAMETERS:
                    ang = q in ANGLE_PARAMETERS
                    unit = u.angle if ang else (f"{u.length}/s" if q == "v" else u.length)
                    out.add([f"{q}@{ex}"], "stick", unit, ang, fa if ang else 1.0)
        out.factor = np.array(out.factor, dtype=float)
        out.angle = np.array(out.angle, dtype=bool)
        return out

    # ------------------------------------------------------------------ runs
    def _align(self, X):
        """Remove a translation and a rotation about Z (least squares onto
        the truth) from the collected points."""
        T = self.bundle.start.X[self.collect]
        ce, ct = X.mean(0), T.mean(0)
        a, t = X - ce, T - ct
        ang = np.arctan2(np.sum(a[:, 0] * t[:, 1] - a[:, 1] * t[:, 0]),
                         np.sum(a[:, 0] * t[:, 0] + a[:, 1] * t[:, 1]))
        c, s = np.cos(ang), np.sin(ang)
        out = a.copy()
        out[:, 0], out[:, 1] = c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1]
        return out + ct

    def _vector(self, io, state, out2):
        parts = [np.hstack([state.X0, matrix_to_opk(state.R)]).ravel(),
                 io.ravel()[self.io_random]]
        if len(self.collect):
            X = state.X[self.collect]
            if self.settings.align == "plan":
                X = self._align(X)
            parts.append(X.ravel())
        if out2 is not None:
            parts.append(out2.P.ravel())
            m = out2.model
            parts.append(np.stack([m.values[q] for q in PARAMETERS], axis=1).ravel())
        return np.concatenate(parts)

    def draws(self, rng):
        """The random inputs of one run (always all kinds, fixed order)."""
        b, f = self.bundle, self.perturb
        sig = self.sig1
        inp = b.inputs.copy()

        def noise(shape, s, kind):
            z = rng.standard_normal(shape)
            return z * s if kind in f else 0.0 * z

        inp.xy = inp.xy + noise(inp.xy.shape, sig.xy, "image")
        inp.reference = inp.reference + noise(inp.reference.shape, sig.reference, "reference")
        inp.station_prior = inp.station_prior + noise(inp.station_prior.shape,
                                                      sig.station_prior, "reference")
        inp.interior_prior = inp.interior_prior + noise(inp.interior_prior.shape,
                                                        sig.interior_prior, "interior")
        inp.distances = inp.distances + noise(inp.distances.shape, sig.distances, "constraints")
        inp.verticals = inp.verticals + noise(inp.verticals.shape, sig.verticals, "constraints")
        z = rng.standard_normal(self.io_L.shape[1])
        io = b.start.io + (self.io_L @ z).reshape(self.shape_io) * ("interior" in f)
        xy_p = xy_l = None
        if self.intersect is not None:
            li = self.intersect
            xy_p = li.inputs_points + noise(li.inputs_points.shape, li.p_sigma[:, None], "image")
            xy_l = li.inputs_lines + noise(li.inputs_lines.shape, li.l_sigma[:, None], "image")
        return inp, io, xy_p, xy_l

    def trial(self, seed) -> np.ndarray:
        """One run: the output vector (internal units: radians)."""
        rng = np.random.default_rng(seed)
        inp, io, xy_p, xy_l = self.draws(rng)
        b = self.bundle
        state, _ = b.solve(inp, io=io if self.fix_interior else None, tol=TRIAL_TOLERANCE)
        io_used = io if self.fix_interior else state.io
        out2 = None
        if self.intersect is not None:
            out2 = self.intersect.solve(io_used, state.R, state.X0, xy_p, xy_l, self.X2,
                                        (self.LP2, self.LD2), tol=TRIAL_TOLERANCE)
        v = self._vector(io_used, state, out2)
        a = self.outputs.angle
        v[a] = self.truth[a] + _wrap(v[a] - self.truth[a])
        return v

    def _evaluate_truth(self):
        b = self.bundle
        out2 = None
        if self.intersect is not None:
            li = self.intersect
            out2 = li.solve(b.start.io, b.start.R, b.start.X0, li.inputs_points,
                            li.inputs_lines, self.X2, (self.LP2, self.LD2))
        v = self._vector(b.start.io, b.start, out2)
        return v

    def report_units(self, values):
        """Internal values (..., n_out) in the reported units."""
        return values * self.outputs.factor

    # ------------------------------------------------------------ propagation
    def propagate(self):
        """``(sigma_prop, sigma_cmd)`` of every output (internal units)."""
        from photogram.montecarlo.propagation import propagate
        return propagate(self)
