"""The steps of the approximation chain (:mod:`photogram.init.chain`).

:class:`_State` holds the orientations and coordinates reached in one frame;
:class:`_Chain` does the steps on it: resection and intersection rounds,
the relative orientation of the best pair as a model frame, the Helmert
transformation of a model into the control frame, the polishing pass, and
the final bookkeeping of the :class:`~photogram.init.chain_report.ChainReport`.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError
from photogram.init.chain_report import ChainReport, _f
from photogram.init.ideal import camera_setup, to_ideal
from photogram.init.intersection import intersect_points
from photogram.init.rays import project_ideal


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
    def set_known(self, S: _State) -> None:
        """Known points at their project coordinates ("control" or "given")."""
        xyz = np.asarray(self.pts.xyz, dtype=float).reshape(-1, 3)
        S.X[self.known] = xyz[self.known]
        kind = np.asarray(self.pts.kind, dtype=object)
        for p in np.nonzero(self.known)[0]:
            S.pt_info[p] = {"how": "control" if kind[p] in ("control", "check") else "given",
                            "round": 0}

    def located_rows(self, s: int, located: np.ndarray) -> np.ndarray:
        """Usable observation rows of station s whose points are located."""
        rows = self.rows_of_station[s]
        return rows[located[self.obs.point[rows]]]

    def world_state(self) -> _State:
        S = _State(self.n_st, self.n_pt)
        self.set_known(S)
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
            rows = self.located_rows(s, located)
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
                names = sorted({self.sname(int(x)) for x in st[o.point[rows] == p]})
                self.fail_point[p] = f"{res.reason[k]} from stations {', '.join(names)}"
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
        self.set_known(S)                   # known points keep their coordinates
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
            rows = self.located_rows(s, located)
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
