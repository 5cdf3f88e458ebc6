"""A multi-camera rig calibrated from a board: one bundle adjustment of
every camera's interior and exterior orientation and every board pose.

Unknowns: per camera the ``opencv`` model's fx fy cx cy k1 k2 p1 p2 (k3
free on request) and its exterior orientation (6); per board pose 6. The
board's points are known in its own frame (the target's geometry gives the
scale); frames where several cameras see the board tie the cameras
together, frames seen by one camera still inform its interior orientation.
The residual block is :class:`photogram.adjust.board_blocks.BoardPointBlock`.

**Datum** (:mod:`photogram.rig.datum`): the board at one pose, the
*floor pose* (the board laid on the floor, or the pose seen by the most
cameras when none is given), held fixed, world Z up out of the board; or
scene points of known coordinates marked in the images (control points,
no board pose held).

**Gross errors**: views (a camera's detection in a frame) far off the
others are left out and the rig solved again (:func:`_solve`).

**Statistics.** sigma0 from the residuals; every sigma is a-posteriori
(sigma0 times the cofactor's root, as OpenCV's ``stdDeviations`` and DBAT
report); per camera the reprojection RMS, the median residual vector and
the sigma of its projection centre; the weakest camera is the one whose
centre is least determined (largest ``sqrt(trace)`` of its 3 x 3
covariance).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError
from photogram.geometry.camera import FLIP_YZ
from photogram.rig.datum import SceneControl

__all__ = ["RigCamera", "RigResult", "SceneControl", "calibrate_rig", "INTERIOR", "MODELS"]

INTERIOR = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
MODELS = ("opencv", "opencv_fisheye")


@dataclass
class RigCamera:
    """One calibrated camera, OpenCV convention (``x = K dist(R X + t)``)."""

    name: str
    K: np.ndarray
    dist: np.ndarray                 # k1 k2 p1 p2 k3 (opencv) or k1 k2 k3 k4 (fisheye)
    R: np.ndarray                    # world -> camera
    t: np.ndarray
    image_size: tuple
    sigmas: dict = field(default_factory=dict)   # parameter -> a-posteriori sigma
    rms_px: float = float("nan")
    median_residual: tuple = (float("nan"), float("nan"))
    n_frames: int = 0
    n_points: int = 0
    model: str = "opencv"

    @property
    def centre(self) -> np.ndarray:
        """The projection centre in the world, ``-R^T t``."""
        return -self.R.T @ self.t

    @property
    def centre_sigma(self) -> float:
        """``sqrt(sX^2 + sY^2 + sZ^2)`` of the projection centre."""
        return float(np.sqrt(sum(self.sigmas.get(k, np.nan) ** 2 for k in ("X0", "Y0", "Z0"))))


@dataclass
class RigResult:
    cameras: dict                    # name -> RigCamera
    board_poses: dict                # frame -> (R_bw, t_bw): X_world = R_bw p + t_bw
    floor_frame: object
    sigma0: float
    redundancy: int
    iterations: int
    status: str
    weakest: str
    start_rms: dict                  # camera -> OpenCV's single-camera RMS (px)
    covariance: np.ndarray = None    # of the free columns (a-posteriori)
    summary: dict = field(default_factory=dict)


def _floor(init, detections, floor_frame):
    if floor_frame is not None:
        if floor_frame not in init["T_wb"]:
            raise InputError(f"the floor frame {floor_frame!r} has no board detection",
                             hint="give a frame where the board lies on the floor and is found")
        return floor_frame
    seen = {f: [c for c in detections if f in detections[c]] for f in init["T_wb"]}
    return max(seen, key=lambda f: (len(seen[f]), sum(len(detections[c][f][0])
                                                      for c in seen[f])))


def _checked(detections, board, min_corners):
    dets = {c: {f: (np.asarray(ids, int).ravel(), np.asarray(xy, float).reshape(-1, 2))
                for f, (ids, xy) in fr.items() if len(ids) >= min_corners}
            for c, fr in detections.items()}
    for c, fr in dets.items():
        if not fr:
            raise InputError(f"camera {c}: the board is never found with {min_corners} or more "
                             "corners", hint="check the board description and that this camera "
                                             "sees the board; or leave the camera out")
        bad = [f for f, (ids, _) in fr.items() if ids.min() < 0 or ids.max() >= len(board)]
        if bad:
            raise InputError(f"camera {c}, frame {bad[0]}: corner ids outside the board's "
                             f"0..{len(board) - 1}", hint="the board description does not "
                                                          "match the detections")
    return dets


def _check_scene(scene, names):
    for c in scene.observations:
        if c not in names:
            raise InputError(f"the scene's image points name camera {c!r}, which the rig does "
                             "not have", hint="cameras of the rig: " + ", ".join(names))
        for p in scene.observations[c]:
            if p not in scene.points:
                raise InputError(f"the scene's image points of camera {c} name point {p!r}, "
                                 "which has no coordinates",
                                 hint="give its X, Y, Z in the scene's points table")


class _Rig:
    """The adjustment problem of a rig (built once; views can be switched
    off and the problem solved again)."""

    def __init__(self, dets, board, image_sizes, init, W, model, fix_k3, sigma_image,
                 fixed_frame, scene):
        from photogram.adjust.board_blocks import BoardPointBlock
        from photogram.adjust.residual_blocks import ImagePointBlock, PointPriorBlock
        from photogram.adjust.solver import Problem
        from photogram.adjust.state import Layout, State
        from photogram.geometry import camera_model
        from photogram.rig.initial import _inv, planar_view_ok
        self.names = names = list(dets)
        # a board pose is kept while one of its views alone determines it
        # (corners not along one line): views or corners left out may leave
        # a pose seen by 4 collinear corners, which would make the normal
        # equations singular
        self.frames = frames = [f for f in init["T_wb"]
                                if any(f in d and planar_view_ok(board[d[f][0]], d[f][1])
                                       for d in dets.values())]
        n_c, n_b = len(names), len(frames)
        self.n_c = n_c
        Winv = _inv(W)
        R = np.zeros((n_c + n_b, 3, 3))
        X0 = np.zeros((n_c + n_b, 3))
        for i, c in enumerate(names):
            T = init["T_cw"][c] @ Winv                     # world -> camera (OpenCV)
            R[i] = FLIP_YZ @ T[:3, :3]
            X0[i] = -T[:3, :3].T @ T[:3, 3]
        for j, f in enumerate(frames):
            T = W @ init["T_wb"][f]                        # board -> world
            R[n_c + j] = T[:3, :3].T
            X0[n_c + j] = T[:3, 3]
        io = [np.r_[init["K"][c][0, 0], init["K"][c][1, 1], init["K"][c][0, 2],
                    init["K"][c][1, 2], init["dist"][c]] for c in names]
        self.model = camera_model(model)
        self.names_io = self.model.parameter_names
        free_io = np.ones(len(self.names_io), dtype=bool)
        if model == "opencv" and fix_k3:
            free_io[8] = False
            for v in io:
                v[8] = 0.0
        station_free = np.ones((n_c + n_b, 6), dtype=bool)
        if fixed_frame is not None:
            station_free[n_c + frames.index(fixed_frame)] = False
        sc_names = list(scene.points) if scene is not None else []
        self.scene_names = sc_names
        sc_xyz = np.array([scene.points[p][0] for p in sc_names], float).reshape(-1, 3)
        sc_sig = np.array([scene.points[p][1] for p in sc_names], float)
        point_free = np.repeat((sc_sig > 0)[:, None], 3, axis=1)
        self.layout = layout = Layout(
            [len(self.names_io)] * n_c, n_c + n_b, len(sc_names), np.zeros(len(sc_names), bool),
            {"camera": [free_io.copy() for _ in names], "station": station_free,
             "point": point_free})
        cam, pose, pts, xy, labels = [], [], [], [], []
        fidx = {f: j for j, f in enumerate(frames)}
        for i, c in enumerate(names):
            for f, (ids, p) in dets[c].items():
                if f not in fidx:       # a board pose no camera's start placed
                    continue            # (its only views were left out of the start)
                cam += [i] * len(ids)
                pose += [n_c + fidx[f]] * len(ids)
                pts.append(board[ids])
                xy.append(p)
                labels += [(c, f, int(k)) for k in ids]
        self.cam = np.asarray(cam)
        self.labels = labels
        self.board_block = BoardPointBlock(
            self.model, np.arange(n_c), self.cam, self.cam, np.asarray(pose), np.vstack(pts),
            np.vstack(xy), np.full(len(cam), sigma_image), layout, labels)
        blocks = [self.board_block]
        self.scene_block = None
        if sc_names:
            rows = [(names.index(c), sc_names.index(p), xy_)
                    for c, obs in scene.observations.items() for p, xy_ in obs.items()]
            ci = np.array([r[0] for r in rows])
            self.scene_block = ImagePointBlock(
                self.model, np.arange(n_c), ci, ci, np.array([r[1] for r in rows]),
                np.array([r[2] for r in rows], float), np.full(len(rows), scene.sigma_image),
                layout, labels=[(names[r[0]], sc_names[r[1]]) for r in rows])
            blocks.append(self.scene_block)
            weighted = np.flatnonzero(sc_sig > 0)
            if len(weighted):
                blocks.append(PointPriorBlock(weighted, sc_xyz[weighted],
                                              np.repeat(sc_sig[weighted, None], 3, 1), layout))
        state = State(sc_xyz.copy(), R, X0, io)
        self.problem = Problem(state, layout, blocks)

    def view_rms(self):
        """RMS (px) of every (camera, frame) view of the board."""
        if not hasattr(self, "_views"):
            keys = [(lab[0], lab[1]) for lab in self.labels]
            self._view_keys = list(dict.fromkeys(keys))
            index = {k: i for i, k in enumerate(self._view_keys)}
            self._views = np.array([index[k] for k in keys])
        e, _ = self.board_block.evaluate(self.problem.state, jacobians=False)
        n = len(self._view_keys)
        ss = np.bincount(self._views, np.sum(e * e, axis=1), minlength=n)
        cnt = np.bincount(self._views, minlength=n)
        return {k: float(np.sqrt(ss[i] / cnt[i])) for i, k in enumerate(self._view_keys)}


def _solve(build, dets, max_iterations, reject_px, corner_sigma=5.0, min_corner_px=0.3,
           keep_frame=None, max_rounds=4):
    """Build the rig from the detections and solve; views (a camera's
    detection in a frame) whose RMS exceeds ``reject_px`` and 5 times the
    median view RMS are left out and the rig built and solved again (a
    wrongly numbered or mis-detected board; a board pose no camera sees
    any more goes with them; a view that would cut a camera off stays:
    :func:`removable_views`), at most ``max_rounds`` times. Returns the
    rig, the solver summary and the views left out with their RMS."""
    from photogram.adjust.solver import SolverOptions, solve
    rejected, rejected_corners = {}, 0

    def without(d, bad):
        return {c: {f: v for f, v in fr.items() if (c, f) not in bad} for c, fr in d.items()}
    if reject_px > 0:           # gross errors at the start values (10 times looser)
        rms = build(dets).view_rms()
        med = float(np.median(list(rms.values())))
        bad = removable_views(dets, {k: v for k, v in rms.items()
                                     if v > max(10 * reject_px, 10 * med)}, keep_frame)
        rejected.update(bad)
        dets = without(dets, bad)
    for round_ in range(max_rounds + 1):
        rig = build(dets)
        s = solve(rig.problem, SolverOptions(max_iterations=max_iterations, tolerance=1e-10))
        last = reject_px <= 0 or round_ == max_rounds
        if s.status != "converged" and last:
            raise InputError(f"the rig adjustment did not converge ({s.status}: {s.message})",
                             hint="check the detections (a wrong board description) or give "
                                  "more frames seen by several cameras")
        if reject_px <= 0:
            break
        rms = rig.view_rms()
        med = float(np.median(list(rms.values())))
        bad = removable_views(dets, {k: v for k, v in rms.items() if v > max(reject_px, 5 * med)},
                              keep_frame)
        if not bad and s.status == "converged":
            dets, n_out = _without_corners(rig, dets, corner_sigma, min_corner_px)
            if not n_out:
                break
            rejected_corners += n_out
            continue
        rejected.update(bad)
        dets = without(dets, bad)
    return rig, s, rejected, rejected_corners


def _cameras_connected(views: dict) -> bool:
    """Whether the cameras form one group through shared frames (``views``:
    camera -> set of frames)."""
    names = list(views)
    reached, todo = {names[0]}, [names[0]]
    while todo:
        c = todo.pop()
        for d in names:
            if d not in reached and views[c] & views[d]:
                reached.add(d)
                todo.append(d)
    return len(reached) == len(names)


def removable_views(dets: dict, candidates: dict, keep_frame=None) -> dict:
    """The views of ``candidates`` ((camera, frame) -> RMS) that can be left
    out, the largest RMS first, while every camera keeps 3 views, the
    cameras stay tied together by shared frames and ``keep_frame`` (the
    floor pose) stays seen: a view that would cut a camera off is kept
    (seen on a rendered harsh set, where a poor start put all the views a
    camera shared with the others over the start's threshold)."""
    views = {c: set(fr) for c, fr in dets.items()}
    out = {}
    for (c, f), rms in sorted(candidates.items(), key=lambda kv: -kv[1]):
        trial = dict(views)
        trial[c] = views[c] - {f}
        if len(trial[c]) < 3 or not _cameras_connected(trial):
            continue
        if keep_frame is not None and not any(keep_frame in v for v in trial.values()):
            continue
        views, out[(c, f)] = trial, rms
    return out


def _without_corners(rig, dets, k_sigma, min_px):
    """The detections without the corners whose residual norm exceeds
    ``k_sigma`` times the camera's robust scale (the median norm over
    1.1774: a 2D Gaussian's norm is Rayleigh distributed) and ``min_px``:
    single corners that a detector placed off (OpenCV's ChArUco refinement
    puts some corners of oblique views 1-3 px off). Returns the detections
    and the number of corners left out."""
    if k_sigma <= 0:
        return dets, 0
    e, _ = rig.board_block.evaluate(rig.problem.state, jacobians=False)
    norm = np.linalg.norm(e, axis=1)
    cams = np.array([lab[0] for lab in rig.labels])
    drop = set()
    for c in rig.names:
        m = cams == c
        scale = float(np.median(norm[m])) / 1.1774
        out = np.flatnonzero(m & (norm > max(k_sigma * scale, min_px)))
        drop |= {rig.labels[i] for i in out}
    if not drop:
        return dets, 0
    new = {}
    for c, fr in dets.items():
        new[c] = {}
        for f, (ids, xy) in fr.items():
            keep = np.array([(c, f, int(i)) not in drop for i in ids])
            if keep.sum() >= 4:
                new[c][f] = (ids[keep], xy[keep])
    return new, len(drop)


def calibrate_rig(detections: dict, image_sizes: dict, target, *, model: str = "opencv",
                  fix_k3: bool = True, floor_frame=None, scene: SceneControl | None = None,
                  sigma_image: float = 0.5, max_iterations: int = 50, min_corners: int = 6,
                  reject_px: float = 3.0, corner_sigma: float = 5.0,
                  min_corner_px: float = 0.3) -> RigResult:
    """Calibrate every camera of a rig from board detections (module doc).

    Parameters
    ----------
    detections : dict camera -> dict frame -> (ids (n,), xy (n, 2))
        Board corners (OpenCV's pixel convention: pixel centres at integer
        coordinates); ``ids`` index ``target.object_points()``.
    image_sizes : dict camera -> (w, h)
    target : photogram.io.targets.Target (or its description string)
    model : "opencv" (pinhole with Brown-Conrady distortion) or
        "opencv_fisheye" (Kannala-Brandt k1..k4, OpenCV's fisheye model)
    fix_k3 : hold k3 at 0 (a few board poses rarely separate k1, k2, k3;
        the opencv model only)
    floor_frame : the frame whose board pose defines the world
        (:mod:`photogram.rig.datum`); None: the pose seen by the most cameras
    scene : control points and their image points instead of the floor
        (:class:`photogram.rig.datum.SceneControl`)
    sigma_image : a-priori sigma of a corner (px); the reported sigmas are
        a-posteriori and do not depend on it
    min_corners : detections with fewer corners are left out
    reject_px : a view whose RMS exceeds this and 5 times the median view
        RMS is left out (0: never)
    corner_sigma, min_corner_px : then a single corner whose residual
        exceeds ``corner_sigma`` times its camera's robust scale and
        ``min_corner_px`` is left out (``corner_sigma`` 0: never)

    Returns
    -------
    RigResult
    """
    from photogram.io.targets import parse_target
    from photogram.rig.datum import floor_transform, scene_transform
    from photogram.rig.initial import initial_rig
    from photogram.stats.covariance import cofactors

    if isinstance(target, str):
        target = parse_target(target)
    if model not in MODELS:
        raise InputError(f"unknown camera model {model!r} for a rig",
                         hint="opencv or opencv_fisheye")
    if scene is not None and floor_frame is not None:
        raise InputError("a rig's world comes from the floor frame or from scene points, not "
                         "both", hint="give one of them")
    board = target.object_points()
    dets = _checked(detections, board, min_corners)
    if scene is not None:
        _check_scene(scene, list(dets))
    fisheye = model == "opencv_fisheye"
    init = initial_rig(dets, board, image_sizes, fix_k3=fix_k3, fisheye=fisheye)
    if scene is not None:
        f0, W = None, scene_transform(scene, init, fisheye)
    else:
        f0 = _floor(init, dets, floor_frame)
        W = floor_transform(init["T_wb"][f0])

    def build(d):
        return _Rig(d, board, image_sizes, init, W, model, fix_k3, sigma_image, f0, scene)
    rig, s, rejected, n_corners = _solve(build, dets, max_iterations, reject_px,
                                         corner_sigma, min_corner_px, f0)
    result = _result(rig, s, rejected, image_sizes, init, f0, cofactors(rig.problem))
    result.summary["rejected_corners"] = n_corners
    return result


def _result(rig, s, rejected, image_sizes, init, f0, cof) -> RigResult:
    state, layout, names, n_c = rig.problem.state, rig.layout, rig.names, rig.n_c
    Q = cof.Qcc * s.sigma0 ** 2
    e, _ = rig.board_block.evaluate(state, jacobians=False)
    active = rig.problem.active[0]
    cams = {}
    for i, c in enumerate(names):
        v = state.io[i]
        K = np.array([[v[0], 0, v[2]], [0, v[1], v[3]], [0, 0, 1.0]])
        R_cv = FLIP_YZ @ state.R[i]
        t = -R_cv @ state.X0[i]
        sig = {n: float(np.sqrt(max(Q[k, k], 0.0)))
               for n, k in zip(rig.names_io, layout.camera_cols[i])}
        sc = layout.station_cols[i]
        for n, k in zip(("X0", "Y0", "Z0"), sc[:3]):
            sig[n] = float(np.sqrt(max(Q[k, k], 0.0)))
        for n, k in zip(("rx", "ry", "rz"), sc[3:]):
            sig[n] = float(np.degrees(np.sqrt(max(Q[k, k], 0.0))))   # rotation, deg
        m = (rig.cam == i) & active
        r = e[m]
        n_frames = len({lab[1] for lab, a in zip(rig.labels, m) if a})
        cams[c] = RigCamera(c, K, v[4:].copy(), R_cv, t, tuple(image_sizes[c]), sig,
                            float(np.sqrt(np.mean(np.sum(r ** 2, 1)))),
                            tuple(float(x) for x in np.median(r, axis=0)),
                            n_frames, int(m.sum()), rig.model.name)
    boards = {f: (state.R[n_c + j].T.copy(), state.X0[n_c + j].copy())
              for j, f in enumerate(rig.frames)}
    weakest = max(names, key=lambda c: cams[c].centre_sigma)
    summary = {"observations": int(2 * active.sum()), "board_poses": len(rig.frames),
               "cameras": n_c, "rejected_views": {f"{c} {f}": v for (c, f), v in
                                                  rejected.items()}}
    if rig.scene_block is not None:
        es, _ = rig.scene_block.evaluate(state, jacobians=False)
        summary["scene_rms_px"] = float(np.sqrt(np.mean(np.sum(es ** 2, 1))))
        summary["scene_points"] = {p: [float(x) for x in state.points[k]]
                                   for k, p in enumerate(rig.scene_names)}
    return RigResult(cams, boards, f0, float(s.sigma0), int(s.redundancy), int(s.iterations),
                     s.status, weakest, init["rms"], Q, summary)
