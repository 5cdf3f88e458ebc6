"""A multi-camera rig calibrated from a board: one bundle adjustment of
every camera's interior and exterior orientation and every board pose.

Unknowns: per camera the ``opencv`` model's fx fy cx cy k1 k2 p1 p2 (k3
free on request) and its exterior orientation (6); per board pose 6. The
board's points are known in its own frame (the target's geometry gives the
scale); frames where several cameras see the board tie the cameras
together, frames seen by one camera still inform its interior orientation.
The residual block is :class:`photogram.adjust.board_blocks.BoardPointBlock`.

**Datum.** The world is the board at one pose, the *floor pose* (the board
laid on the floor, or the pose seen by the most cameras when none is
given), held fixed: ``X = x_b``, ``Y = -y_b``, ``Z = -z_b`` with ``x_b,
y_b`` the board's axes (OpenCV's board frame: x along the first row of
corners, y down the columns, z into the board), so that the world's Z
points up out of a board lying face up. Six fixed parameters: a minimum
datum, the sigmas are those of the cameras relative to that board pose.

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

__all__ = ["RigCamera", "RigResult", "calibrate_rig", "INTERIOR"]

INTERIOR = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
MODELS = ("opencv", "opencv_fisheye")
_F4 = np.diag([1.0, -1.0, -1.0, 1.0])


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


def calibrate_rig(detections: dict, image_sizes: dict, target, *, model: str = "opencv",
                  fix_k3: bool = True, floor_frame=None, sigma_image: float = 0.5,
                  max_iterations: int = 50, min_corners: int = 6) -> RigResult:
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
    floor_frame : the frame whose board pose defines the world (module doc)
    sigma_image : a-priori sigma of a corner (px); the reported sigmas are
        a-posteriori and do not depend on it
    min_corners : detections with fewer corners are left out

    Returns
    -------
    RigResult
    """
    from photogram.adjust.board_blocks import BoardPointBlock
    from photogram.adjust.solver import Problem, SolverOptions, solve
    from photogram.adjust.state import Layout, State
    from photogram.geometry import camera_model
    from photogram.io.targets import parse_target
    from photogram.rig.initial import _inv, initial_rig
    from photogram.stats.covariance import cofactors

    if isinstance(target, str):
        target = parse_target(target)
    board = target.object_points()
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
    if model not in MODELS:
        raise InputError(f"unknown camera model {model!r} for a rig",
                         hint="opencv or opencv_fisheye")
    fisheye = model == "opencv_fisheye"
    init = initial_rig(dets, board, image_sizes, fix_k3=fix_k3, fisheye=fisheye)
    names = list(dets)
    f0 = _floor(init, dets, floor_frame)
    # world' = the floor board's frame, Z up (module doc)
    W = _F4 @ _inv(init["T_wb"][f0])                   # old world -> new world
    Winv = _inv(W)
    frames = list(init["T_wb"])
    n_c, n_b = len(names), len(frames)
    R = np.zeros((n_c + n_b, 3, 3))
    X0 = np.zeros((n_c + n_b, 3))
    for i, c in enumerate(names):
        T = init["T_cw"][c] @ Winv                     # new world -> camera (OpenCV)
        R[i] = FLIP_YZ @ T[:3, :3]
        X0[i] = -T[:3, :3].T @ T[:3, 3]
    for j, f in enumerate(frames):
        T = W @ init["T_wb"][f]                        # board -> new world
        R[n_c + j] = T[:3, :3].T
        X0[n_c + j] = T[:3, 3]
    io = [np.r_[init["K"][c][0, 0], init["K"][c][1, 1], init["K"][c][0, 2],
                init["K"][c][1, 2], init["dist"][c]] for c in names]
    cam_model = camera_model(model)
    names_io = cam_model.parameter_names
    free_io = np.ones(len(names_io), dtype=bool)
    if not fisheye and fix_k3:
        free_io[8] = False
        for v in io:
            v[8] = 0.0
    station_free = np.ones((n_c + n_b, 6), dtype=bool)
    station_free[n_c + frames.index(f0)] = False
    layout = Layout([len(names_io)] * n_c, n_c + n_b, 0, np.zeros(0, bool),
                    {"camera": [free_io.copy() for _ in names], "station": station_free,
                     "point": np.zeros((0, 3), bool)})
    cam, pose, pts, xy, labels = [], [], [], [], []
    fidx = {f: j for j, f in enumerate(frames)}
    for i, c in enumerate(names):
        for f, (ids, p) in dets[c].items():
            cam += [i] * len(ids)
            pose += [n_c + fidx[f]] * len(ids)
            pts.append(board[ids])
            xy.append(p)
            labels += [(c, f, int(k)) for k in ids]
    cam = np.asarray(cam)
    block = BoardPointBlock(cam_model, np.arange(n_c), cam, cam, np.asarray(pose),
                            np.vstack(pts), np.vstack(xy), np.full(len(cam), sigma_image),
                            layout, labels)
    state = State(np.zeros((0, 3)), R, X0, io)
    problem = Problem(state, layout, [block])
    s = solve(problem, SolverOptions(max_iterations=max_iterations, tolerance=1e-10))
    if s.status not in ("converged",):
        raise InputError(f"the rig adjustment did not converge ({s.status}: {s.message})",
                         hint="check the detections (a wrong board description) or give more "
                              "frames seen by several cameras")
    state = problem.state
    cof = cofactors(problem)
    s0sq = s.sigma0 ** 2
    Q = cof.Qcc * s0sq
    e, _ = block.evaluate(state, jacobians=False)
    cams = {}
    for i, c in enumerate(names):
        v = state.io[i]
        K = np.array([[v[0], 0, v[2]], [0, v[1], v[3]], [0, 0, 1.0]])
        R_cv = FLIP_YZ @ state.R[i]
        t = -R_cv @ state.X0[i]
        cols = layout.camera_cols[i]
        sig = {n: float(np.sqrt(max(Q[k, k], 0.0))) for n, k in zip(names_io, cols)}
        sc = layout.station_cols[i]
        for n, k in zip(("X0", "Y0", "Z0"), sc[:3]):
            sig[n] = float(np.sqrt(max(Q[k, k], 0.0)))
        for n, k in zip(("rx", "ry", "rz"), sc[3:]):
            sig[n] = float(np.degrees(np.sqrt(max(Q[k, k], 0.0))))   # rotation, deg
        m = cam == i
        r = e[m]
        cams[c] = RigCamera(c, K, v[4:].copy(), R_cv, t, tuple(image_sizes[c]), sig,
                            float(np.sqrt(np.mean(np.sum(r ** 2, 1)))),
                            tuple(float(x) for x in np.median(r, axis=0)),
                            len(dets[c]), int(m.sum()), model)
    boards = {}
    for j, f in enumerate(frames):
        Rb = state.R[n_c + j]
        boards[f] = (Rb.T.copy(), state.X0[n_c + j].copy())
    weakest = max(names, key=lambda c: cams[c].centre_sigma)
    return RigResult(cams, boards, f0, float(s.sigma0), int(s.redundancy), int(s.iterations),
                     s.status, weakest, init["rms"], Q,
                     {"observations": int(2 * len(cam)), "board_poses": n_b,
                      "cameras": n_c})
