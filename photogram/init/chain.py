"""The approximation chain: approximate values for every station and point.

Steps 1B and 2A of the ski-jump paper. Starting from the image observations,
the cameras' interior orientation and whatever is known (control and check
points, given approximations of stations and points):

1. stations that see at least 4 known points (planar or not) are resected:
   direct solution (:func:`photogram.init.resection.resect`) on ideal image
   coordinates, then least squares with the full camera model
   (:func:`photogram.init.resection.refine_resection`);
2. if no station can be resected and none is given, the best stereo pair
   (most common points, widest intersection angles) is relatively oriented
   (:func:`photogram.init.relative.relative_orientation`) and its points
   intersected; the chain then works in that model frame until at least 3
   known points have been intersected in it, when a Helmert transformation
   (:func:`photogram.init.helmert.helmert`) brings everything into the
   control frame;
3. points seen from at least 2 oriented stations are intersected
   (:func:`photogram.init.intersection.intersect_points`);
4. steps 1 and 3 repeat until nothing changes; finally every intersected
   point is re-intersected with all its oriented rays and every resected
   station re-resected with all its located points (one polishing pass).

Approximations given in the project (stations with finite position and
angles, points with finite coordinates) are kept as they are. The
:class:`ChainReport` says how every station and point was reached, and why
the others could not be.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.init.intersection import intersect_points, project_ideal

__all__ = ["ChainReport", "approximate", "to_ideal", "camera_setup"]


# ---------------------------------------------------------------------------
# ideal coordinates


def _model_of(camera, model):
    from photogram.geometry import camera_model
    if model is None:
        return camera_model(camera.model)
    if isinstance(model, str):
        return camera_model(model)
    return model


def _principal_distance(model, io) -> float:
    names = list(model.parameter_names)
    for key in ("c", "fx", "f"):
        if key in names:
            return float(io[names.index(key)])
    return 1.0


def camera_setup(project, model=None, camera_values=None) -> dict:
    """Camera model, interior orientation and principal distance of every
    camera of ``project``.

    Parameters
    ----------
    project : Project
    model : None, str or camera model
        None: each camera's own model; otherwise used for all cameras (its
        parameters must match the cameras' parameter count).
    camera_values : dict, optional
        Camera name -> interior orientation array overriding
        ``Camera.values()``.

    Returns
    -------
    dict
        Camera name -> ``(model, io, c)``.

    Raises
    ------
    InputError
        Unknown model, parameter count mismatch, non-positive principal
        distance.
    """
    out = {}
    for name, cam in project.cameras.items():        # loop over cameras
        m = _model_of(cam, model)
        io = np.asarray(camera_values[name] if camera_values and name in camera_values
                        else cam.values(), dtype=float)
        if io.shape != (len(m.parameter_names),):
            raise InputError(
                f"camera {name}: {io.size} interior-orientation values, model "
                f"{m.name!r} needs {len(m.parameter_names)}",
                hint="parameters in order: " + ", ".join(m.parameter_names))
        c = _principal_distance(m, io)
        if not (np.isfinite(c) and c > 0):
            raise InputError(f"camera {name}: principal distance must be positive, got {c:g}")
        out[name] = (m, io, c)
    return out


def to_ideal(project, camera_values=None, model=None) -> tuple[np.ndarray, np.ndarray]:
    """Ideal image coordinates of all image-point observations.

    Measured coordinates are corrected with the camera model
    (``model.correct(xy, io)`` for "brown": distortion, affinity removed,
    reduced to the principal point, y down) so that the ideal collinearity
    equations ``x̄ = -c Xc_x/Xc_z``, ``ȳ = c Xc_y/Xc_z`` hold; models
    without ``correct`` use ``c * model.image_to_ray(xy, io)``.

    Parameters
    ----------
    project : Project
    camera_values : dict, optional
        Camera name -> interior orientation (default ``Camera.values()``).
    model : None, str or camera model
        See :func:`camera_setup`.

    Returns
    -------
    xy_ideal : ndarray (n_obs, 2)
        Reduced to the principal point.
    c : ndarray (n_obs,)
        Principal distance of each observation's camera.
    """
    setup = camera_setup(project, model, camera_values)
    obs = project.image_points
    st_cam = np.array(project.stations.camera, dtype=object)
    xy = np.full((len(obs), 2), np.nan)
    c = np.full(len(obs), np.nan)
    cam_of_obs = st_cam[obs.station] if len(obs) else np.zeros(0, dtype=object)
    for name, (m, io, cc) in setup.items():          # loop over cameras
        rows = np.nonzero(cam_of_obs == name)[0]
        if not len(rows):
            continue
        if hasattr(m, "correct"):
            xy[rows] = m.correct(obs.xy[rows], io)
        else:
            xy[rows] = cc * m.image_to_ray(obs.xy[rows], io)
        c[rows] = cc
    return xy, c


# ---------------------------------------------------------------------------
# report


def _f(x):
    """JSON-friendly float (None for NaN)."""
    x = float(x)
    return x if np.isfinite(x) else None


@dataclass
class ChainReport:
    """What the approximation chain reached, how, and what it could not.

    Attributes
    ----------
    frame : str
        ``"control"`` (the project's object frame, fixed by control/given
        points or given stations), ``"model"`` (the arbitrary frame of a
        relative orientation: left camera at the origin with ``R = I``,
        baseline ``|b_x| = 1``) or ``"none"`` (nothing reached).
    stations : dict
        Station name -> dict with ``how`` ("given", "resection",
        "relative orientation"), ``round`` and details (points used,
        residual RMS in image units).
    points : dict
        Point id -> dict with ``how`` ("control", "given", "intersection"),
        ``round``, ``rays``, ``max_angle_deg``.
    unreached_stations, unreached_points : dict
        Name -> reason.
    relative_orientation : dict or None
        The pair, number of points, sigma0 and candidates tried.
    helmert : dict or None
        The transformation into the control frame (points, scale, RMS).
    rounds : int
    messages : list of str
    """

    frame: str = "none"
    stations: dict = field(default_factory=dict)
    points: dict = field(default_factory=dict)
    unreached_stations: dict = field(default_factory=dict)
    unreached_points: dict = field(default_factory=dict)
    relative_orientation: dict | None = None
    helmert: dict | None = None
    rounds: int = 0
    messages: list = field(default_factory=list)

    @property
    def complete(self) -> bool:
        """True when every station and point was reached."""
        return not self.unreached_stations and not self.unreached_points

    def to_dict(self) -> dict:
        """A JSON-serialisable dict (for summary.json)."""
        return {
            "frame": self.frame,
            "rounds": int(self.rounds),
            "complete": self.complete,
            "counts": {
                "stations_reached": len(self.stations),
                "stations_unreached": len(self.unreached_stations),
                "points_reached": len(self.points),
                "points_unreached": len(self.unreached_points),
                "stations_by_method": _count(self.stations),
                "points_by_method": _count(self.points),
            },
            "stations": {k: dict(v) for k, v in self.stations.items()},
            "points": {k: dict(v) for k, v in self.points.items()},
            "unreached_stations": dict(self.unreached_stations),
            "unreached_points": dict(self.unreached_points),
            "relative_orientation": self.relative_orientation,
            "helmert": self.helmert,
            "messages": list(self.messages),
        }

    def summary(self) -> str:
        """A few lines for the console."""
        d = self.to_dict()["counts"]
        lines = [f"approximation chain ({self.frame} frame, {self.rounds} rounds): "
                 f"{d['stations_reached']} stations {d['stations_by_method']}, "
                 f"{d['points_reached']} points {d['points_by_method']}"]
        lines += [f"  {v}" for v in self.unreached_stations.values()]
        lines += [f"  {v}" for v in self.unreached_points.values()]
        lines += [f"  {m}" for m in self.messages]
        return "\n".join(lines)


def _count(d: dict) -> dict:
    out: dict = {}
    for v in d.values():
        out[v["how"]] = out.get(v["how"], 0) + 1
    return out


# ---------------------------------------------------------------------------
# the chain


class _State:
    """Orientations and coordinates in one frame."""

    def __init__(self, n_st: int, n_pt: int):
        self.R = np.full((n_st, 3, 3), np.nan)
        self.X0 = np.full((n_st, 3), np.nan)
        self.X = np.full((n_pt, 3), np.nan)
        self.st_info: dict[int, dict] = {}
        self.pt_info: dict[int, dict] = {}

    def oriented(self):
        return np.isfinite(self.X0).all(1) & np.isfinite(self.R).all((1, 2))

    def located(self):
        return np.isfinite(self.X).all(1)


class _Chain:
    def __init__(self, project, model, min_points, min_angle_deg, max_rounds, max_pairs,
                 sigma_image):
        from photogram.geometry import matrix_to_opk, opk_to_matrix
        self._opk, self._mat = matrix_to_opk, opk_to_matrix
        self.p = project
        self.st = project.stations
        self.pts = project.points
        self.obs = project.image_points
        self.n_st, self.n_pt = len(self.st), len(self.pts)
        self.setup = camera_setup(project, model)
        self.xy_ideal, self.c = to_ideal(project, model=model)
        self.min_points = int(min_points)
        self.min_angle = float(min_angle_deg)
        self.max_rounds = int(max_rounds)
        self.max_pairs = int(max_pairs)
        self.sigma_image = sigma_image
        self.report = ChainReport()
        self.round = 0
        self.fail_station: dict[int, str] = {}
        self.fail_point: dict[int, str] = {}
        o = self.obs
        ok = np.isfinite(o.xy).all(1) & np.isfinite(self.xy_ideal).all(1)
        self.use = np.nonzero(ok)[0]                     # usable observation rows
        order = np.argsort(o.station[self.use], kind="stable")
        rows = self.use[order]
        counts = np.bincount(o.station[rows], minlength=self.n_st)
        self.rows_of_station = np.split(rows, np.cumsum(counts)[:-1])
        # what is known in the project frame
        xyz = np.asarray(self.pts.xyz, dtype=float).reshape(-1, 3)
        self.known = np.isfinite(xyz).all(1)
        pos = np.asarray(self.st.position, dtype=float).reshape(-1, 3)
        ang = np.asarray(self.st.angles, dtype=float).reshape(-1, 3)
        self.given_station = np.isfinite(pos).all(1) & np.isfinite(ang).all(1)

    # -- naming -------------------------------------------------------------
    def sname(self, s) -> str:
        return str(self.st.names[s])

    def pname(self, p) -> str:
        return str(self.pts.ids[p])

    # -- steps --------------------------------------------------------------
    def world_state(self) -> _State:
        S = _State(self.n_st, self.n_pt)
        xyz = np.asarray(self.pts.xyz, dtype=float).reshape(-1, 3)
        S.X[self.known] = xyz[self.known]
        kind = np.asarray(self.pts.kind, dtype=object)
        for p in np.nonzero(self.known)[0]:
            S.pt_info[p] = {"how": "control" if kind[p] in ("control", "check") else "given",
                            "round": 0}
        g = np.nonzero(self.given_station)[0]
        if len(g):
            S.R[g] = self._mat(np.asarray(self.st.angles, dtype=float)[g])
            S.X0[g] = np.asarray(self.st.position, dtype=float)[g]
            for s in g:
                S.st_info[s] = {"how": "given", "round": 0}
        return S

    def resect_station(self, S: _State, s: int, rows: np.ndarray, start=None):
        """Resect station s from the located points of ``rows``; returns
        (R, X0, info) or raises GeometryError."""
        from photogram.init.resection import refine_resection, resect
        o = self.obs
        pt = o.point[rows]
        Xp = S.X[pt]
        cam = self.st.camera[s]
        m, io, c = self.setup[cam]
        if start is None:
            pe = resect(Xp, self.xy_ideal[rows], c)
            R0, X00 = pe.R, pe.X0
        else:
            R0, X00 = start
        sig = o.sigma[rows] if self.sigma_image is None else None
        if sig is not None and not np.all(np.isfinite(sig) & (sig > 0)):
            sig = None
        rr = refine_resection(Xp, o.xy[rows], m, io, self._opk(R0), X00, sigma=sig)
        R = np.asarray(rr.R, dtype=float)
        X0 = np.asarray(rr.X0, dtype=float)
        if not (np.isfinite(R).all() and np.isfinite(X0).all()):
            raise GeometryError("resection gave non-finite orientation")
        res = project_ideal(Xp, R, X0, c) - self.xy_ideal[rows]
        rms = float(np.sqrt(np.mean(res ** 2)))
        info = {"points": int(len(rows)), "rms": _f(rms), "converged": bool(rr.converged)}
        return R, X0, info

    def resect_round(self, S: _State, how: str = "resection") -> bool:
        changed = False
        located = S.located()
        oriented = S.oriented()
        for s in range(self.n_st):                      # loop over stations
            if oriented[s]:
                continue
            rows = self.rows_of_station[s]
            rows = rows[located[self.obs.point[rows]]]
            if len(rows) < self.min_points:
                continue
            try:
                R, X0, info = self.resect_station(S, s, rows)
            except GeometryError as e:
                self.fail_station[s] = f"resection failed: {e.what}"
                continue
            S.R[s], S.X0[s] = R, X0
            S.st_info[s] = {"how": how, "round": self.round, **info}
            self.fail_station.pop(s, None)
            changed = True
        return changed

    def rays(self, S: _State, point_mask: np.ndarray):
        """Observation rows of oriented stations and points in ``point_mask``."""
        o = self.obs
        rows = self.use[S.oriented()[o.station[self.use]] & point_mask[o.point[self.use]]]
        return rows

    def intersect_round(self, S: _State, targets: np.ndarray) -> bool:
        """Intersect the points of ``targets`` (bool mask) that have >= 2
        oriented rays; returns True if any new point was located."""
        rows = self.rays(S, targets)
        if not len(rows):
            return False
        o = self.obs
        st = o.station[rows]
        res = intersect_points(o.point[rows], self.xy_ideal[rows], S.R[st], S.X0[st],
                               self.c[rows], min_angle_deg=self.min_angle, strict=False,
                               point_ids=self.pts.ids)
        changed = False
        ok = res.valid & (res.behind == 0) & np.isfinite(res.X).all(1)
        for k in np.nonzero(~ok)[0]:                      # loop over failures only
            p = int(res.point_index[k])
            if res.reason[k] is not None:
                self.fail_point[p] = res.reason[k]
            elif res.behind[k]:
                self.fail_point[p] = (f"point {self.pname(p)}: intersection lies behind "
                                      f"{res.behind[k]} of its {res.n_rays[k]} cameras "
                                      f"(wrong point number?)")
        new = ok & ~S.located()[res.point_index]
        idx = res.point_index[ok]
        S.X[idx] = res.X[ok]
        for k in np.nonzero(ok)[0]:                       # bookkeeping per point
            p = int(res.point_index[k])
            info = S.pt_info.get(p)
            if info is None or info.get("how") == "intersection":
                S.pt_info[p] = {"how": "intersection",
                                "round": info["round"] if info else self.round,
                                "rays": int(res.n_rays[k]),
                                "max_angle_deg": _f(np.degrees(res.max_angle[k])),
                                "sigma0": _f(res.sigma0[k])}
            self.fail_point.pop(p, None)
        changed = bool(new.any())
        return changed

    def run(self, S: _State, world: bool) -> None:
        """Resect / intersect until nothing changes; in the model frame stop
        as soon as a Helmert transformation into the control frame works."""
        if not world and self.try_helmert(S):
            return
        while self.round < self.max_rounds:
            self.round += 1
            changed = self.resect_round(S)
            changed |= self.intersect_round(S, ~S.located())
            if not changed:
                self.round -= 1
                return
            if not world and self.try_helmert(S):
                return

    # -- relative orientation ------------------------------------------------
    def best_pair(self):
        """Relative orientation of the best pair; returns (a, b, result, info)
        or None."""
        from photogram.init.relative import relative_orientation
        o = self.obs
        rows = self.use
        import scipy.sparse as sp
        A = sp.csr_matrix((np.ones(len(rows)), (o.station[rows], o.point[rows])),
                          shape=(self.n_st, self.n_pt))
        A.data[:] = 1.0                                 # duplicates count once
        common = sp.triu(A @ A.T, k=1).tocoo()          # points common to two stations
        cnt = np.rint(common.data).astype(int)
        order = np.lexsort((common.col, common.row, -cnt))
        tried = []
        best = None
        for k in order[: self.max_pairs]:               # loop over candidate pairs
            a, b, n = int(common.row[k]), int(common.col[k]), int(cnt[k])
            if n < 5:
                break
            ra = self.rows_of_station[a]
            rb = self.rows_of_station[b]
            pa, pb = o.point[ra], o.point[rb]
            shared, ia, ib = np.intersect1d(pa, pb, return_indices=True)
            ca = self.setup[self.st.camera[a]][2]
            cb = self.setup[self.st.camera[b]][2]
            try:
                import warnings
                with warnings.catch_warnings(record=True) as w:
                    warnings.simplefilter("always")
                    res = relative_orientation(self.xy_ideal[ra[ia]], self.xy_ideal[rb[ib]],
                                               ca, cb, sigma_image=self.sigma_image)
            except GeometryError as e:
                tried.append({"pair": [self.sname(a), self.sname(b)], "points": n,
                              "error": e.what})
                continue
            med = float(np.median(res.max_angle))
            score = n * min(med, np.pi / 6)
            tried.append({"pair": [self.sname(a), self.sname(b)], "points": n,
                          "median_angle_deg": _f(np.degrees(med)), "sigma0": _f(res.sigma0),
                          "ambiguous": bool(res.ambiguous), "score": _f(score)})
            if res.ambiguous:
                score *= 0.5
            if best is None or score > best[0]:
                best = (score, a, b, shared, res, med)
        if best is None:
            return None, tried
        return best[1:], tried

    def start_model(self):
        """Relative orientation of the best pair as the model frame."""
        found, tried = self.best_pair()
        if found is None:
            why = ("no pair of stations shares 5 points" if not tried else
                   "no pair could be relatively oriented: " +
                   "; ".join(f"{t['pair'][0]}-{t['pair'][1]}: {t.get('error')}" for t in tried))
            self.report.messages.append(why)
            return None
        a, b, shared, res, med = found
        self.round += 1
        S = _State(self.n_st, self.n_pt)
        S.R[a], S.X0[a] = np.eye(3), np.zeros(3)
        S.R[b], S.X0[b] = res.R2, res.X0_2
        for s, k in ((a, 0), (b, 1)):
            S.st_info[s] = {"how": "relative orientation", "round": self.round,
                            "points": int(len(shared)), "rms": _f(res.sigma0)}
        front = np.isfinite(res.X).all(1)
        S.X[shared[front]] = res.X[front]
        for p, ang in zip(shared[front], res.max_angle[front]):
            S.pt_info[int(p)] = {"how": "intersection", "round": self.round, "rays": 2,
                                 "max_angle_deg": _f(np.degrees(ang)), "sigma0": None}
        self.report.relative_orientation = {
            "pair": [self.sname(a), self.sname(b)], "points": int(len(shared)),
            "sigma0": _f(res.sigma0), "median_angle_deg": _f(np.degrees(med)),
            "ambiguous": bool(res.ambiguous), "notes": list(res.notes),
            "baseline_component": "xyz"[res.fixed_component], "pairs_tried": tried}
        if res.ambiguous:
            self.report.messages.append(
                f"relative orientation of {self.sname(a)}-{self.sname(b)} may be ambiguous: "
                + "; ".join(res.notes))
        return S

    def try_helmert(self, S: _State) -> bool:
        """Transform the model state S into the control frame in place once
        >= 3 known points are located in it. Returns True on success."""
        from photogram.init.helmert import helmert
        common = np.nonzero(S.located() & self.known)[0]
        if len(common) < 3:
            return False
        xyz = np.asarray(self.pts.xyz, dtype=float).reshape(-1, 3)
        try:
            h = helmert(S.X[common], xyz[common])
        except GeometryError as e:
            self.report.messages.append(f"Helmert transformation postponed: {e.what}")
            return False
        loc = S.located()
        S.X[loc] = h.apply(S.X[loc])
        ori = S.oriented()
        S.X0[ori] = h.apply(S.X0[ori])
        S.R[ori] = S.R[ori] @ h.R.T
        # known points keep their coordinates
        S.X[self.known] = xyz[self.known]
        kind = np.asarray(self.pts.kind, dtype=object)
        for p in np.nonzero(self.known)[0]:
            S.pt_info[p] = {"how": "control" if kind[p] in ("control", "check") else "given",
                            "round": 0}
        rms = float(np.sqrt(np.mean(h.residuals ** 2)))
        self.report.helmert = {
            "points": [self.pname(p) for p in common], "scale": _f(h.scale),
            "rms": _f(rms), "max_residual": _f(np.abs(h.residuals).max()),
            "round": self.round}
        self.report.messages.append(
            f"model brought into the control frame by a Helmert transformation on "
            f"{len(common)} points (rms {rms:.3g})")
        return True

    # -- polishing -----------------------------------------------------------
    def polish(self, S: _State) -> None:
        """Re-intersect every intersected point with all its oriented rays,
        re-resect every resected station with all its located points."""
        inter = np.array([S.pt_info.get(p, {}).get("how") == "intersection"
                          for p in range(self.n_pt)], dtype=bool)
        if inter.any():
            self.intersect_round(S, inter)
        located = S.located()
        for s in range(self.n_st):                       # loop over stations
            info = S.st_info.get(s)
            if info is None or info["how"] == "given":
                continue
            rows = self.rows_of_station[s]
            rows = rows[located[self.obs.point[rows]]]
            if len(rows) < self.min_points:
                continue
            try:
                R, X0, new = self.resect_station(S, s, rows, start=(S.R[s], S.X0[s]))
            except GeometryError:
                continue
            S.R[s], S.X0[s] = R, X0
            info.update({"points": new["points"], "rms": new["rms"], "polished": True})
        if inter.any():
            self.intersect_round(S, inter)

    # -- final bookkeeping ---------------------------------------------------
    def finish(self, S: _State):
        o = self.obs
        rep = self.report
        ori = S.oriented()
        loc = S.located()
        for s in range(self.n_st):
            if ori[s]:
                rep.stations[self.sname(s)] = S.st_info.get(s, {"how": "?", "round": 0})
                continue
            rows = self.rows_of_station[s]
            if not len(rows):
                rep.unreached_stations[self.sname(s)] = (
                    f"station {self.sname(s)}: no (usable) image points")
                continue
            k = int(loc[o.point[rows]].sum())
            if k < self.min_points:
                rep.unreached_stations[self.sname(s)] = (
                    f"station {self.sname(s)}: sees only {k} oriented point"
                    f"{'s' if k != 1 else ''}, needs {self.min_points}")
            else:
                rep.unreached_stations[self.sname(s)] = (
                    f"station {self.sname(s)}: " + self.fail_station.get(s, "not reached"))
        n_obs = np.bincount(o.point[self.use], minlength=self.n_pt) if len(self.use) \
            else np.zeros(self.n_pt, dtype=int)
        n_ori = np.bincount(o.point[self.use], weights=ori[o.station[self.use]],
                            minlength=self.n_pt).astype(int) if len(self.use) \
            else np.zeros(self.n_pt, dtype=int)
        for p in range(self.n_pt):
            if loc[p]:
                rep.points[self.pname(p)] = S.pt_info.get(p, {"how": "?", "round": 0})
            elif n_obs[p] == 0:
                rep.unreached_points[self.pname(p)] = (
                    f"point {self.pname(p)}: not measured in any image")
            elif n_ori[p] < 2:
                rep.unreached_points[self.pname(p)] = (
                    f"point {self.pname(p)}: seen from {n_ori[p]} oriented station"
                    f"{'s' if n_ori[p] != 1 else ''} (measured in {n_obs[p]} image"
                    f"{'s' if n_obs[p] != 1 else ''}), needs 2")
            else:
                rep.unreached_points[self.pname(p)] = self.fail_point.get(
                    p, f"point {self.pname(p)}: not reached")
        rep.rounds = self.round


def approximate(project, model=None, *, min_points: int = 4, min_angle_deg: float = 1.0,
                max_rounds: int = 1000, max_pairs: int = 6, polish: bool = True,
                sigma_image: float | None = None):
    """Approximate values of every station and point (paper steps 1B, 2A).

    Parameters
    ----------
    project : Project
        Image points, cameras (interior orientation used as it is) and
        whatever is known: control/check points and any point with finite
        coordinates; stations with finite position and angles.
    model : None, str or camera model
        Camera model for all cameras (default: each camera's own).
    min_points : int
        Located points a station must see to be resected (>= 4: the
        direct solution needs 4 for a unique answer, planar or not).
    min_angle_deg : float
        Smallest acceptable intersection angle of a point (degrees).
    max_rounds : int
        Safety limit of resection/intersection rounds.
    max_pairs : int
        Pairs (by number of common points) tried for a relative orientation.
    polish : bool
        Finish with one pass of re-intersection with all rays and
        re-resection with all located points.
    sigma_image : float, optional
        A-priori image sigma for the relative orientation's zero-baseline
        test and the resection weights (default: per-observation sigmas).

    Returns
    -------
    project : Project
        A copy with ``stations.position``/``angles`` and ``points.xyz``
        filled where reached (given values unchanged).
    report : ChainReport

    Raises
    ------
    InputError
        Inconsistent cameras (unknown model, wrong parameter count).
    """
    if min_points < 4:
        raise InputError(f"min_points must be at least 4, got {min_points}")
    ch = _Chain(project, model, min_points, min_angle_deg, max_rounds, max_pairs, sigma_image)
    rep = ch.report
    S = ch.world_state()
    world = True
    ch.run(S, world=True)
    if not S.oriented().any():
        M = ch.start_model()
        if M is not None:
            # model frame: the project's coordinates are unusable until Helmert
            ch.run(M, world=False)
            S = M
            if rep.helmert is not None:
                ch.run(S, world=True)
            else:
                world = False
    if polish and S.oriented().any():
        ch.polish(S)
    if world:
        rep.frame = "control" if (S.oriented().any()) else "none"
    else:
        rep.frame = "model"
        if ch.known.any():
            rep.messages.append(
                f"only {int((S.located() & ch.known).sum())} known point(s) located in the "
                f"model: it stays in the relative-orientation frame (needs 3 for a Helmert "
                f"transformation); given coordinates are kept but are in another frame")
    ch.finish(S)
    out = _updated_project(project, S, ch)
    return out, rep


def _updated_project(project, S: _State, ch: _Chain):
    from photogram.geometry import matrix_to_opk
    st = project.stations
    pos = np.array(st.position, dtype=float).reshape(-1, 3).copy()
    ang = np.array(st.angles, dtype=float).reshape(-1, 3).copy()
    ori = S.oriented() & ~ch.given_station
    if ori.any():
        pos[ori] = S.X0[ori]
        ang[ori] = np.asarray(matrix_to_opk(S.R[ori]), dtype=float)
    xyz = np.array(project.points.xyz, dtype=float).reshape(-1, 3).copy()
    loc = S.located() & ~ch.known
    xyz[loc] = S.X[loc]
    stations = dataclasses.replace(st, position=pos, angles=ang)
    points = dataclasses.replace(project.points, xyz=xyz)
    return dataclasses.replace(project, stations=stations, points=points)
