"""Cameras, board poses and settings of the rendered multi-camera sets
(:mod:`photogram.simulation.board_rig`, whose doc says what is simulated)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np


VOLUME_CENTRE = np.array([0.0, 0.0, 1.0])
VOLUME_HALF = np.array([1.5, 1.5, 1.0])
TARGET_SPEC = "charuco:7x5:0.08:0.06:DICT_5X5_100"
#: Camera distances (m from the volume's centre) at which this board is
#: decoded: at 1280 x 720 px, cameras beyond ~4 m see 8 cm squares under
#: ~20 px (under 16 px at 45 deg) and cv2.aruco no longer reads the markers;
#: with the default 2-6 m, 4 cameras see few poses in pairs (docs).
USABLE_DISTANCE = (2.0, 4.0)
TEXELS_PER_SQUARE = 224          # 32 x 7: 5 exact mip levels, integer marker bits
MAX_LEVEL = 5
STRIP = 16                       # output rows rendered at a time (each over its own columns)


@dataclass(frozen=True, eq=False)
class RigCamera:
    """One camera of the rig (OpenCV model; ``x_cam = R X + t``)."""

    name: str
    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    image_size: tuple

    @property
    def centre(self) -> np.ndarray:
        """Projection centre in the world frame, ``-R^T t``."""
        return -self.R.T @ self.t


@dataclass
class BoardPoses:
    """Board-to-world poses ``X_world = R[k] X_board + t[k]`` with the
    velocities at mid-exposure: ``v`` (m/s, world), ``w`` (rad/s, world).
    Index 0 is the pose flat on the floor."""

    R: np.ndarray
    t: np.ndarray
    v: np.ndarray
    w: np.ndarray

    def __len__(self) -> int:
        return len(self.t)

    def __getitem__(self, k):
        return self.R[k], self.t[k], self.v[k], self.w[k]


@dataclass(frozen=True)
class RigRenderSettings:
    """How the views are rendered (module doc).

    Attributes
    ----------
    supersample : int          samples per pixel along each axis
    blur : float               Gaussian sigma (px) of the lens blur
    noise : float              sensor noise sigma (grey levels)
    jpeg_quality : int         0: no compression
    shutter : float            exposure (s) for the motion blur
    subframes : int            sub-poses averaged (1: no motion blur)
    white, black, back : float grey of the paper, the ink, the board's back
    margin : float             white paper around the squares (m)
    occlusion : float          fraction of views with a dark bar across the board
    partly_outside : float     fraction of poses placed on the image border of one
                               camera (used by :func:`board_poses`)
    seed : int                 noise, background and occluders
    """

    supersample: int = 3
    blur: float = 0.7
    noise: float = 1.5
    jpeg_quality: int = 95
    shutter: float = 1 / 500
    subframes: int = 3
    white: float = 215.0
    black: float = 25.0
    back: float = 150.0
    margin: float = 0.02
    occlusion: float = 0.0
    partly_outside: float = 0.0
    seed: int = 0


def normal_settings(seed: int = 0) -> RigRenderSettings:
    """Clean-ish views: noise 1.5, blur 0.7 px, JPEG 95, 1/500 s shutter."""
    return RigRenderSettings(seed=seed)


def harsh_settings(seed: int = 1) -> RigRenderSettings:
    """The set nothing was tuned on: noise 4, blur 1.0 px, JPEG 60, 1/100 s
    shutter (streaks of several px), lower contrast, a dark bar over the
    board in 15 % of the views, 10 % of the poses on an image border."""
    return replace(RigRenderSettings(), blur=1.0, noise=4.0, jpeg_quality=60, shutter=1 / 100,
                   subframes=7, white=185.0, black=45.0, occlusion=0.15, partly_outside=0.1,
                   seed=seed)


# ---------------------------------------------------------------- geometry

def _rotvec(r) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    r = np.asarray(r, float)
    a = np.linalg.norm(r)
    if a < 1e-15:
        return np.eye(3)
    k = r / a
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * Kx + (1 - math.cos(a)) * Kx @ Kx


def _look_at(eye, target, roll=0.0) -> np.ndarray:
    """World->camera rotation of an OpenCV camera (x right, y down, z along
    the view) at ``eye`` looking at ``target``, world Z up."""
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    R = np.array([x, np.cross(z, x), z])
    return _rotvec(R[2] * roll) @ R if roll else R


def _radial_invertible(dist, r_max: float) -> bool:
    """The radial distortion r -> r (1 + k1 r^2 + k2 r^4 + k3 r^6) rises
    steadily (slope > 0.5) up to ``r_max``: every pixel of the image has
    one undistorted ray (beyond the fold, e.g. k1 = -0.17 with k2, k3 < 0,
    the image corners have none and ``cv2.undistortPoints`` returns points
    20 px off)."""
    k1, k2, k3 = dist[0], dist[1], dist[4]
    r2 = np.linspace(0, r_max, 200) ** 2
    return bool(np.all(1 + 3 * k1 * r2 + 5 * k2 * r2 ** 2 + 7 * k3 * r2 ** 3 > 0.5))


def rig_cameras(n_cameras: int = 4, seed: int = 0, image_size=(1280, 720),
                distance=(2.0, 6.0)) -> list[RigCamera]:
    """Cameras around the capture volume (module doc), seeded.

    Azimuths evenly spread (jitter +-20 % of the spacing), so that adjacent
    cameras are ``360 / n`` deg apart on average.
    """
    rng = np.random.default_rng([seed, 1])
    w, h = image_size
    out = []
    for i in range(n_cameras):
        az = 2 * np.pi * (i + rng.uniform(-0.2, 0.2)) / n_cameras
        d = rng.uniform(*distance)
        height = rng.uniform(1.0, 3.0)
        dz = height - VOLUME_CENTRE[2]
        r = math.sqrt(max(d * d - dz * dz, 0.25))
        C = VOLUME_CENTRE + np.array([r * math.cos(az), r * math.sin(az), dz])
        aim = VOLUME_CENTRE + rng.uniform(-0.3, 0.3, 3)
        R = _look_at(C, aim, roll=math.radians(rng.uniform(-3, 3)))
        fx = rng.uniform(900, 1400) * w / 1280
        K = np.array([[fx, 0, (w - 1) / 2 + rng.uniform(-0.03, 0.03) * w],
                      [0, fx * (1 + rng.uniform(-0.005, 0.005)),
                       (h - 1) / 2 + rng.uniform(-0.03, 0.03) * h],
                      [0, 0, 1]])
        corner = math.hypot(max(K[0, 2], w - K[0, 2]) / K[0, 0],
                            max(K[1, 2], h - K[1, 2]) / K[1, 1])
        while True:
            dist = np.array([rng.uniform(-0.2, 0.1), rng.uniform(-0.05, 0.1),
                             rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3),
                             rng.uniform(-0.02, 0.02)])
            if _radial_invertible(dist, 1.5 * corner):
                break
        out.append(RigCamera(f"cam{i + 1:02d}", K, dist, R, -R @ C, (int(w), int(h))))
    return out


def _board_centre(target) -> np.ndarray:
    return np.array([target.cols * target.size / 2, target.rows * target.size / 2, 0.0])


def _facing(centre, front, roll, tilt_axis, tilt, target) -> tuple:
    """(R_bw, t_bw) of a board centred at ``centre`` whose printed face
    (its -z side) looks along ``front``, upright (board y down) before the
    roll about its normal and the tilt about ``tilt_axis``."""
    z = -np.asarray(front, float) / np.linalg.norm(front)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0, 0])
    R = np.column_stack([x, np.cross(z, x), z])
    R = _rotvec(np.asarray(tilt_axis) * tilt) @ R @ _rotvec([0, 0, roll])
    return R, centre - R @ _board_centre(target)


def floor_frame(poses: BoardPoses) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the frame ``photogram.rig`` reports its cameras in when
    pose 0 is its floor pose: ``X_world = R X_floor + t`` with the floor
    frame the board's axes made Z-up (x, -y, -z: :mod:`photogram.rig.datum`),
    at the board's origin."""
    return poses.R[0] @ np.diag([1.0, -1.0, -1.0]), poses.t[0]


def _image_ray(camera: RigCamera, uv) -> np.ndarray:
    """Unit world direction of the ray through the distorted pixels ``uv``."""
    xn = _undistort(camera, np.atleast_2d(np.asarray(uv, float)))
    d = np.column_stack([xn, np.ones(len(xn))]) @ camera.R
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _views_ok(cameras, R_bw, t_bw, target, min_edge: float) -> np.ndarray:
    """Per camera: every corner of the board is in front, in the image
    and the printed face is towards the camera, and the shortest projected
    square edge is at least ``min_edge`` px (cv2.aruco decodes the 5 x 5
    markers down to about 16 px squares, measured on these renders)."""
    cols, rows = target.cols - 1, target.rows - 1
    out = []
    for cam in cameras:
        xy, vis = true_corners(cam, (R_bw, t_bw), target)
        g = xy.reshape(rows, cols, 2)
        edge = min(np.linalg.norm(np.diff(g, axis=0), axis=2).min(),
                   np.linalg.norm(np.diff(g, axis=1), axis=2).min())
        out.append(bool(vis.all()) and edge >= min_edge)
    return np.array(out)


def _floor_pose(cameras, target) -> tuple[np.ndarray, np.ndarray]:
    """The floor pose: flat, printed face up, board x along world X (or
    -Y), centred on the floor point of a 0.25 m grid over the volume's floor
    that the most cameras see well (:func:`_views_ok`, then the larger
    sum of the shortest edges); on the world origin without cameras."""
    R0 = np.diag([1.0, -1.0, -1.0])
    c = _board_centre(target)
    if not cameras:
        return R0, -R0 @ c
    best, score = None, (-1, -1.0)
    for yaw in (0.0, np.pi / 2):
        R = _rotvec([0, 0, yaw]) @ R0
        for x in np.arange(-1.25, 1.26, 0.25):
            for y in np.arange(-1.25, 1.26, 0.25):
                t = np.array([x, y, 0.0]) - R @ c
                ok = _views_ok(cameras, R, t, target, 16.0)
                sc = (int(ok.sum()), -abs(x) - abs(y))
                if sc > score:
                    best, score = (R, t), sc
    return best


def _waved(rng, pair, target, centre=None) -> tuple[np.ndarray, np.ndarray]:
    """One waved pose shown to the cameras at ``pair`` (module doc): its
    centre uniform in the half of the volume nearer the pair (unless
    given), its face towards their midpoint, tilted up to 30 deg, rolled
    up to 45 deg."""
    look = (pair[0] + pair[1]) / 2
    if centre is None:
        u = rng.uniform(-1, 1, 3) * np.array([1.4, 1.4, 0.75])
        side = (look - VOLUME_CENTRE)[:2] / np.linalg.norm((look - VOLUME_CENTRE)[:2])
        if u[:2] @ side < 0:
            u[:2] = np.clip(u[:2] - 2 * (u[:2] @ side) * side, -1.4, 1.4)
        centre = VOLUME_CENTRE + u
    front = look - centre
    axis = np.cross(front, rng.normal(size=3))
    return _facing(centre, front, rng.uniform(-np.pi / 4, np.pi / 4),
                   axis / np.linalg.norm(axis), math.radians(rng.uniform(0, 30)), target)


def board_poses(n_poses: int = 60, seed: int = 0, cameras=None, target=None,
                partly_outside: float = 0.0, tries: int = 20) -> BoardPoses:
    """Board poses waved through the volume; pose 0 flat on the floor
    (module doc).

    Parameters
    ----------
    cameras : list of RigCamera, optional
        Pose k faces the midpoint of the cameras k and k + 1 (mod n, ordered
        by azimuth); without cameras, pose k faces an azimuth spread evenly
        and 2 m up, 4 m from the volume's centre.
    partly_outside : float
        Fraction of poses whose centre is placed on the image border of one
        camera (2-4 m from it): partly outside that camera's image.
    tries : int
        With cameras, a pose is drawn again (up to ``tries`` times, keeping
        the best) until at least two cameras see it whole with squares of
        16 px or more (:func:`_views_ok`): the person waving the board
        watches the live views. The floor pose is put where the most cameras
        see it (:func:`_floor_pose`).
    """
    from photogram.io.targets import parse_target
    target = target or parse_target(TARGET_SPEC)
    rng = np.random.default_rng([seed, 2])
    if cameras:
        centres = np.array([c.centre for c in cameras])
        off = centres - VOLUME_CENTRE
        order = np.argsort(np.arctan2(off[:, 1], off[:, 0]))
        eyes = centres[order]
    else:
        a = np.linspace(0, 2 * np.pi, 8, endpoint=False)
        eyes = np.column_stack([4 * np.cos(a), 4 * np.sin(a), np.full(8, 2.0)])
    n_eye = len(eyes)
    R = np.empty((n_poses, 3, 3))
    t = np.empty((n_poses, 3))
    R[0], t[0] = _floor_pose(cameras, target)
    border = set()
    if cameras and partly_outside > 0:
        k_out = max(1, int(round(partly_outside * (n_poses - 1))))
        border = set(rng.choice(np.arange(1, n_poses), k_out, replace=False).tolist())
    for k in range(1, n_poses):
        pair = (eyes[k % n_eye], eyes[(k + 1) % n_eye])
        if k in border:
            cam = cameras[order[k % n_eye]]
            w, h = cam.image_size
            side, a = rng.integers(4), rng.uniform(0.2, 0.8)
            uv = [(0.0, a * h), (w - 1.0, a * h), (a * w, 0.0), (a * w, h - 1.0)][side]
            centre = cam.centre + rng.uniform(2.0, 4.0) * _image_ray(cam, [uv])[0]
            R[k], t[k] = _waved(rng, pair, target, centre)
            continue
        best = -1
        for _ in range(tries if cameras else 1):
            Rk, tk = _waved(rng, pair, target)
            n_ok = int(_views_ok(cameras, Rk, tk, target, 16.0).sum()) if cameras else 0
            if n_ok > best:
                R[k], t[k], best = Rk, tk, n_ok
            if best >= 2:
                break
    dirs = rng.normal(size=(2, n_poses, 3))
    dirs /= np.linalg.norm(dirs, axis=2, keepdims=True)
    v = dirs[0] * rng.uniform(0.2, 1.0, (n_poses, 1))
    w = dirs[1] * rng.uniform(0.0, 1.5, (n_poses, 1))
    v[0] = w[0] = 0.0
    return BoardPoses(R, t, v, w)


def _camera_board(camera: RigCamera, R_bw, t_bw) -> tuple[np.ndarray, np.ndarray]:
    """Board -> camera: ``x_cam = R_cb X_board + t_cb``."""
    return camera.R @ R_bw, camera.R @ t_bw + camera.t


def true_corners(camera: RigCamera, pose, target, settings: RigRenderSettings | None = None,
                 key=(0, 0)) -> tuple[np.ndarray, np.ndarray]:
    """True images of ``target.object_points()`` in ``camera`` (``cv2.projectPoints``
    with K, dist, ``R_cam R_bw``, ``R_cam t_bw + t``) and whether each is
    visible: in front of the camera, the printed face towards it, inside
    the image by 2 px and not under the occluding bar of ``settings``."""
    import cv2
    R_bw, t_bw = pose[0], pose[1]
    R_cb, t_cb = _camera_board(camera, R_bw, t_bw)
    obj = target.object_points()
    xy = cv2.projectPoints(obj, cv2.Rodrigues(R_cb)[0], t_cb, camera.K, camera.dist)[0]
    xy = xy.reshape(-1, 2)
    depth = obj @ R_cb[2] + t_cb[2]
    w, h = camera.image_size
    vis = (depth > 0.05) & (R_cb[:, 2] @ t_cb > 0)
    vis &= (xy[:, 0] > 1) & (xy[:, 0] < w - 3) & (xy[:, 1] > 1) & (xy[:, 1] < h - 3)
    bar = _bar(camera, pose, target, settings, key) if settings else None
    if bar is not None:
        vis &= _bar_coverage(xy, bar) < 0.01
    return xy, vis


def _undistort(camera: RigCamera, uv: np.ndarray) -> np.ndarray:
    """Normalised coordinates of distorted pixels: the inverse of OpenCV's
    distortion to 1e-9 px (``cv2.undistortPoints`` with a convergence
    criterion)."""
    import cv2
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-9)
    out = cv2.undistortPoints(uv.reshape(-1, 1, 2).astype(np.float64), camera.K,
                              camera.dist, None, None, None, crit)
    return out.reshape(-1, 2)


def _bar(camera, pose, target, settings, key):
    """The occluding bar of view ``key`` = (camera index, frame) or None:
    (point, unit direction, half width) in px, through the board's image."""
    if not settings or settings.occlusion <= 0:
        return None
    rng = np.random.default_rng([settings.seed, 5, *key])
    if rng.uniform() >= settings.occlusion:
        return None
    import cv2
    R_cb, t_cb = _camera_board(camera, pose[0], pose[1])
    c = _board_centre(target)
    pts = np.array([c, c + [target.size, 0, 0]])
    if np.any(pts @ R_cb[2] + t_cb[2] <= 0.05):
        return None
    xy = cv2.projectPoints(pts, cv2.Rodrigues(R_cb)[0], t_cb, camera.K, camera.dist)[0]
    xy = xy.reshape(2, 2)
    sq = float(np.linalg.norm(xy[1] - xy[0]))
    ang = rng.uniform(0, np.pi)
    p = xy[0] + rng.uniform(-1.5, 1.5, 2) * sq
    return p, np.array([math.cos(ang), math.sin(ang)]), rng.uniform(0.3, 0.8) * sq


def _bar_coverage(xy, bar) -> np.ndarray:
    """Fraction of the pixel at ``xy`` covered by the bar (linear edge ramp);
    ``xy`` (..., 2) or a pair (x, y) of arrays that broadcast (a grid)."""
    p, d, hw = bar
    if isinstance(xy, tuple):
        rx, ry = xy[0] - p[0], xy[1] - p[1]
    else:
        rel = np.asarray(xy, float) - p
        rx, ry = rel[..., 0], rel[..., 1]
    dist = np.abs(rx * d[1] - ry * d[0])
    return np.clip(hw - dist + 0.5, 0.0, 1.0)
