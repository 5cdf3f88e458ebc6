"""Rendered test data for multi-camera calibration from a ChArUco board
(issue 20, item 1): a board waved through a capture volume seen by 4-6
cameras, with known truth.

What is simulated
-----------------
* **Cameras** (:func:`rig_cameras`): around a capture volume of 3 x 3 x 2 m
  (floor at Z = 0, world Z up, centre ``VOLUME_CENTRE`` = (0, 0, 1) m), at
  2-6 m from the centre, 1-3 m high, each looking at a point within 0.3 m of
  the centre (roll within 3 deg). OpenCV model: fx 900-1400 px for a 1280 px
  wide image (scaled with the width), fy = fx within 0.5 %, principal point
  within 3 % of the image centre, k1 -0.2..0.1, k2 -0.05..0.1, p1 p2 within
  1e-3, k3 within 0.02, drawn again until the radial distortion is
  invertible out to 1.5 times the image corner's radius. Extrinsics in
  OpenCV's convention: ``x_cam = R X + t``.
* **Board poses** (:func:`board_poses`): ``X_world = R_bw X_board + t_bw``.
  **Pose 0 lies flat on the floor**, printed face up: ``R_bw = Rz diag(1,
  -1, -1)`` with Rz a turn of 0 or 90 deg about Z (the board's z axis
  points into the printed face, OpenCV's convention, so it points down),
  centred on the point of a 0.25 m grid over the floor that the most
  cameras see well (:func:`_floor_pose`). The lead's "floor frame" (the
  board frame of pose 0, :func:`floor_frame`) is therefore the world frame
  turned 180 deg about X (and about Z) and shifted by ``t_bw[0]``. Every
  other pose k is shown to the cameras k and k + 1 (ordered by azimuth):
  centre uniform in the half of the volume nearer them (x, y in [-1.4, 1.4]
  m, z in [0.25, 1.75] m), printed face towards their midpoint, tilted by
  up to 30 deg about a random axis and rolled by up to 45 deg in its plane
  (with the cameras' elevations the board leans from the vertical by a
  median 30-40 deg, at most 60-80 deg, seeds 0 and 1), drawn again (``tries``) until two cameras see it whole with
  squares of 16 px or more. Each pose has a linear (0.2-1 m/s) and
  angular (0-1.5 rad/s) velocity for the motion blur; the pose is the one
  at mid-exposure.
* **Images** (:func:`render_view`): every output pixel is split into
  ``supersample`` x ``supersample`` samples at OpenCV pixel positions (pixel
  centres at integers, the convention of :func:`photogram.io.targets.detect`
  and ``cv2.projectPoints``); each sample's ray is the inverse of the
  distortion (``cv2.undistortPoints`` iterated to 1e-9 px at the pixel
  centres, interpolated within the pixel: < 1e-3 px), intersected with the
  board plane (only within the board's box, found on a 4 px grid); the board texture (``board.generateImage`` with 224 px per
  square and a white paper margin, area-downsampled by powers of 2 to about
  the sample spacing, a mip level per view) is sampled bilinearly
  (``cv2.remap``); the samples are averaged per pixel (area anti-aliasing)
  and composited over a static textured grey background by their coverage.
  The back of the board is plain grey. Motion blur: the mean of
  ``subframes`` renders at sub-poses spread over the ``shutter``, centred on
  the pose. Then a Gaussian lens blur, Gaussian noise, 8-bit rounding and
  JPEG (as :func:`photogram.measure.render.degrade`), and in some views an
  occluding dark bar (an arm) across the board, drawn before the blur.

Texture <-> board coordinates: texel centre ``(u, v)`` of mip level L is the
board point ``x = (u + 0.5) * texel * 2**L - margin`` (same for y), where
``object_points()`` are ``((c + 1) * size, (r + 1) * size)``: the board's
origin is the outer corner of its top-left square (tested).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

__all__ = ["RigCamera", "BoardPoses", "RigRenderSettings", "normal_settings",
           "harsh_settings", "rig_cameras", "board_poses", "render_view", "render_rig",
           "true_corners", "write_rig_set", "floor_frame", "cameras_toml", "VOLUME_CENTRE",
           "TARGET_SPEC", "detect_rig",
           "USABLE_DISTANCE"]

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
STRIP = 64                       # output rows rendered at a time


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


# ---------------------------------------------------------------- rendering

@functools.lru_cache(maxsize=2)
def _texture(target, margin: float) -> tuple[tuple, float, float]:
    """Mip levels of the board texture (float32, 0 ink .. 1 paper), the
    level-0 texel (m) and the margin used (m, a multiple of 32 texels)."""
    import cv2
    P = TEXELS_PER_SQUARE
    texel = target.size / P
    m = 32 * int(round(margin / texel / 32))
    img = target.board().generateImage((target.cols * P, target.rows * P), marginSize=0,
                                       borderBits=1)
    img = cv2.copyMakeBorder(img, m, m, m, m, cv2.BORDER_CONSTANT, value=255)
    levels = [img.astype(np.float32) / 255]
    for _ in range(MAX_LEVEL):
        levels.append(cv2.resize(levels[-1], None, fx=0.5, fy=0.5,
                                 interpolation=cv2.INTER_AREA))
    return tuple(levels), texel, m * texel


def _camera_key(camera: RigCamera, s: int) -> tuple:
    return (camera.name, camera.K.tobytes(), camera.dist.tobytes(), camera.image_size, s)


def _sample_rays(camera: RigCamera, s: int, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """Normalised coordinates (rows, cols, 2) of the samples of the output
    pixels [y0, y1) x [x0, x1): sample (a, b) of pixel (i, j) at
    ``(i + (a + 0.5) / s - 0.5, j + (b + 0.5) / s - 0.5)`` (OpenCV pixel
    centres at integers).

    The exact inverse (:func:`_undistort`) at the pixel centres, bilinearly
    interpolated between them: the distortion's curvature over one pixel
    makes that < 1e-3 px (tested against the exact inverse).
    """
    u = np.arange(x0 - 1, x1 + 1, dtype=float)
    v = np.arange(y0 - 1, y1 + 1, dtype=float)
    uu, vv = np.meshgrid(u, v)
    grid = _undistort(camera, np.column_stack([uu.ravel(), vv.ravel()]))
    grid = grid.reshape(len(v), len(u), 2)
    hh, ww = y1 - y0, x1 - x0
    out = np.empty((hh, s, ww, s, 2))
    offsets = (np.arange(s) + 0.5) / s - 0.5
    for b, dy in enumerate(offsets):
        r0, fy = (1, dy) if dy >= 0 else (0, 1 + dy)
        rows = (1 - fy) * grid[r0:r0 + hh] + fy * grid[r0 + 1:r0 + 1 + hh]
        for a, dx in enumerate(offsets):
            c0, fx = (1, dx) if dx >= 0 else (0, 1 + dx)
            out[:, b, :, a] = (1 - fx) * rows[:, c0:c0 + ww] + fx * rows[:, c0 + 1:c0 + 1 + ww]
    return out.reshape(hh * s, ww * s, 2)


@functools.lru_cache(maxsize=2)
def _coarse_rays(key) -> np.ndarray:
    """Rays of every 4th pixel's centre sample, for finding the board."""
    name, K, dist, (w, h), s = key
    cam = RigCamera(name, np.frombuffer(K).reshape(3, 3), np.frombuffer(dist), np.eye(3),
                    np.zeros(3), (w, h))
    uu, vv = np.meshgrid(np.arange(0, w, 4.0), np.arange(0, h, 4.0))
    return _undistort(cam, np.column_stack([uu.ravel(), vv.ravel()])).reshape(*uu.shape, 2)


@functools.lru_cache(maxsize=8)
def _background(name: str, image_size: tuple, seed: int) -> np.ndarray:
    """Static textured grey background of a camera (blotches and grain)."""
    import cv2
    w, h = image_size
    rng = np.random.default_rng([seed, 3, sum(map(ord, name))])
    coarse = cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), 25)
    coarse *= 25 / max(coarse.std(), 1e-9)
    fine = cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), 1.5)
    fine *= 6 / max(fine.std(), 1e-9)
    return (110 + coarse + fine).astype(np.float64)


@functools.lru_cache(maxsize=8)
def _blurred_background(name: str, image_size: tuple, seed: int, blur: float) -> np.ndarray:
    """The background after the lens blur."""
    import cv2
    bg = _background(name, image_size, seed)
    return cv2.GaussianBlur(bg, (0, 0), blur) if blur > 0 else bg


def _sub_poses(pose, settings: RigRenderSettings) -> list:
    """Poses spread over the shutter, centred on ``pose`` (rotation about
    the board's centre at angular velocity w, translation at velocity v)."""
    R, t, v, w = (np.asarray(p, float) for p in pose)
    n = settings.subframes
    if n <= 1 or settings.shutter <= 0:
        return [(R, t)]
    out = []
    for tau in (np.arange(n) + 0.5) / n - 0.5:
        dt = tau * settings.shutter
        out.append((_rotvec(w * dt) @ R, t + v * dt))
    return out


def _hit(xn, R_cb, t_cb, margin, W, H):
    """Board coordinates (from the paper's corner) of the rays ``xn``
    (normalised, (..., 2)) and whether they hit the paper in front of the
    camera: the plane z_board = 0 is ``r3 . (lam d - t_cb) = 0``."""
    d = np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], -1)
    a = d @ R_cb[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = (R_cb[:, 2] @ t_cb) / a
        bx = lam * (d @ R_cb[:, 0]) - R_cb[:, 0] @ t_cb + margin
        by = lam * (d @ R_cb[:, 1]) - R_cb[:, 1] @ t_cb + margin
    inside = (lam > 0) & (bx >= 0) & (bx <= W) & (by >= 0) & (by <= H)
    return bx, by, inside


def _board_layer(camera: RigCamera, subs, target, settings) -> tuple | None:
    """(box, value x coverage, coverage) of the board averaged over the
    sub-poses ``subs`` [(R_bw, t_bw), ...]; box (x0, y0, x1, y1) holds
    every output pixel the board touches (found on a 4 px grid, grown by
    8 px), None if the board is not in the image."""
    import cv2
    s = settings.supersample
    levels, texel0, margin = _texture(target, settings.margin)
    W = target.cols * target.size + 2 * margin
    H = target.rows * target.size + 2 * margin
    coarse = _coarse_rays(_camera_key(camera, s))
    poses = [_camera_board(camera, R_bw, t_bw) for R_bw, t_bw in subs]
    found = np.zeros(coarse.shape[:2], bool)
    for R_cb, t_cb in poses:
        found |= _hit(coarse, R_cb, t_cb, margin, W, H)[2]
    if not found.any():
        return None
    w, h = camera.image_size
    jj, ii = np.nonzero(found)
    x0, x1 = max(ii.min() * 4 - 8, 0), min(ii.max() * 4 + 12, w)
    y0, y1 = max(jj.min() * 4 - 8, 0), min(jj.max() * 4 + 12, h)
    val = np.zeros((y1 - y0, x1 - x0))
    cov = np.zeros_like(val)
    for r0 in range(y0, y1, STRIP):          # strips of rows: bounded memory
        r1 = min(r0 + STRIP, y1)
        rays = _sample_rays(camera, s, x0, r0, x1, r1)
        for R_cb, t_cb in poses:
            bx, by, inside = _hit(rays, R_cb, t_cb, margin, W, H)
            # mip level: about one texel per sample at the board's centre
            depth = (R_cb @ _board_centre(target) + t_cb)[2]
            per_sample = depth / camera.K[0, 0] / s / texel0
            L = int(np.clip(np.floor(np.log2(max(per_sample, 1.0))), 0, MAX_LEVEL))
            texel = texel0 * 2 ** L
            mu = np.where(inside, bx / texel - 0.5, -1).astype(np.float32)
            mv = np.where(inside, by / texel - 0.5, -1).astype(np.float32)
            tex = cv2.remap(levels[L], mu, mv, cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REPLICATE)
            front = R_cb[:, 2] @ t_cb > 0
            grey = settings.black + (settings.white - settings.black) * tex if front else \
                np.full(tex.shape, settings.back)
            hh, ww = r1 - r0, x1 - x0
            val[r0 - y0:r1 - y0] += np.where(inside, grey, 0.0).reshape(hh, s, ww, s).mean((1, 3))
            cov[r0 - y0:r1 - y0] += inside.reshape(hh, s, ww, s).mean((1, 3))
    return (x0, y0, x1, y1), val / len(poses), cov / len(poses)


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
    """Fraction of the pixel at ``xy`` covered by the bar (linear edge ramp)."""
    p, d, hw = bar
    rel = np.asarray(xy, float) - p
    dist = np.abs(rel[..., 0] * d[1] - rel[..., 1] * d[0])
    return np.clip(hw - dist + 0.5, 0.0, 1.0)


def render_view(camera: RigCamera, pose, target, settings: RigRenderSettings,
                key=(0, 0)) -> np.ndarray:
    """The uint8 image of the board at ``pose`` = (R_bw, t_bw[, v, w]) seen
    by ``camera`` (module doc); ``key`` = (camera index, frame) seeds the
    noise and the occluder."""
    if len(pose) == 2:
        pose = (pose[0], pose[1], np.zeros(3), np.zeros(3))
    bg = _background(camera.name, tuple(camera.image_size), settings.seed)
    import cv2
    layer = _board_layer(camera, _sub_poses(pose, settings), target, settings)
    bar = _bar(camera, pose, target, settings, key)
    if bar is not None or layer is None:
        img = bg.copy()
        if layer is not None:
            (x0, y0, x1, y1), val, cov = layer
            img[y0:y1, x0:x1] = val + (1 - cov) * img[y0:y1, x0:x1]
        if bar is not None:
            h, w = img.shape
            jj, ii = np.mgrid[0:h, 0:w]
            cov = _bar_coverage(np.stack([ii, jj], -1), bar)
            img = cov * 40.0 + (1 - cov) * img
        return _degrade(img, settings, key)
    # blur is linear and the background static: blur(bg + diff) = blur(bg),
    # cached, + blur(diff) over the board's box grown by the kernel radius
    # (zero beyond the box, image borders reflected as in a full blur)
    img = _blurred_background(camera.name, tuple(camera.image_size), settings.seed,
                              settings.blur).copy()
    (x0, y0, x1, y1), val, cov = layer
    h, w = img.shape
    pad = int(math.ceil(4 * settings.blur)) + 2
    X0, Y0, X1, Y1 = max(x0 - pad, 0), max(y0 - pad, 0), min(x1 + pad, w), min(y1 + pad, h)
    diff = np.zeros((Y1 - Y0, X1 - X0))
    diff[y0 - Y0:y1 - Y0, x0 - X0:x1 - X0] = val - cov * bg[y0:y1, x0:x1]
    if settings.blur > 0:
        diff = cv2.GaussianBlur(diff, (0, 0), settings.blur)
    img[Y0:Y1, X0:X1] += diff
    return _degrade(img, replace(settings, blur=0.0), key)


def _degrade(img, settings: RigRenderSettings, key) -> np.ndarray:
    """Lens blur (Gaussian), sensor noise (Gaussian, seeded by the view),
    8-bit rounding and JPEG: :func:`photogram.measure.render.degrade` in
    float32."""
    import cv2
    img = img.astype(np.float32)
    if settings.blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), settings.blur)
    if settings.noise > 0:
        rng = np.random.default_rng([settings.seed, 4, *key])
        img += settings.noise * rng.standard_normal(img.shape, dtype=np.float32)
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if settings.jpeg_quality:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(settings.jpeg_quality)])
        out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return out


def render_rig(cameras, poses: BoardPoses, target, settings: RigRenderSettings) -> dict:
    """{camera name: [uint8 image per pose]}; view (i, k) is
    :func:`render_view` of camera i and pose k with ``key=(i, k)``."""
    return {cam.name: [render_view(cam, poses[k], target, settings, key=(i, k))
                       for k in range(len(poses))]
            for i, cam in enumerate(cameras)}


# ---------------------------------------------------------------- files

def _toml_array(a) -> str:
    a = np.asarray(a, float)
    if a.ndim == 1:
        return "[" + ", ".join(repr(float(x)) for x in a) + "]"
    return "[" + ", ".join(_toml_array(r) for r in a) + "]"


def cameras_toml(cameras) -> str:
    """The true cameras as TOML: one table per camera with ``size`` (w, h),
    ``matrix`` (K), ``distortions`` (k1 k2 p1 p2 k3), ``rotation`` (R, 3 x 3)
    and ``translation`` (t), OpenCV's convention ``x_cam = R X + t``."""
    out = ["# true cameras (photogram.simulation.board_rig); x_cam = R X_world + t, "
           "pixel centres at integers\n"]
    for c in cameras:
        out.append(f"[{c.name}]\nname = \"{c.name}\"\nsize = [{c.image_size[0]}, "
                   f"{c.image_size[1]}]\nmatrix = {_toml_array(c.K)}\n"
                   f"distortions = {_toml_array(c.dist)}\nrotation = {_toml_array(c.R)}\n"
                   f"translation = {_toml_array(c.t)}\n")
    return "\n".join(out)


def write_rig_set(folder, cameras, poses: BoardPoses, target, settings: RigRenderSettings,
                  *, video: bool = False, fps: float = 30.0, images: dict | None = None) -> Path:
    """Render (unless ``images`` are given) and write a set into ``folder``.

    Files: ``camNN/000000.png ...`` (one folder per camera, file k = pose k)
    or, with ``video``, ``camNN.avi`` (MJPG via ``cv2.VideoWriter``, which
    re-encodes the frames); ``truth/cameras.toml`` (:func:`cameras_toml`),
    ``truth/board_poses.csv`` (frame, R_bw row by row r00..r22, t_bw, v,
    w; frame 0 on the floor), ``truth/corners.csv`` (camera, frame, id, x,
    y, visible: :func:`true_corners`) and ``truth/settings.json`` (the
    settings, the target, the texture margin used).

    Raises
    ------
    FileExistsError
        ``folder`` exists and is not empty (never overwrites).
    """
    import cv2
    import pandas as pd
    folder = Path(folder)
    if folder.exists() and any(folder.iterdir()):
        raise FileExistsError(f"{folder} exists and is not empty: give a new folder")
    images = images if images is not None else render_rig(cameras, poses, target, settings)
    (folder / "truth").mkdir(parents=True, exist_ok=True)
    for cam in cameras:
        frames = images[cam.name]
        if video:
            vw = cv2.VideoWriter(str(folder / f"{cam.name}.avi"),
                                 cv2.VideoWriter_fourcc(*"MJPG"), fps, cam.image_size, True)
            for f in frames:
                vw.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
            vw.release()
        else:
            (folder / cam.name).mkdir()
            for k, f in enumerate(frames):
                cv2.imwrite(str(folder / cam.name / f"{k:06d}.png"), f)
    (folder / "truth" / "cameras.toml").write_text(cameras_toml(cameras))
    table = {"frame": np.arange(len(poses))}
    for i in range(3):
        for j in range(3):
            table[f"r{i}{j}"] = poses.R[:, i, j]
    for name, arr in (("t", poses.t), ("v", poses.v), ("w", poses.w)):
        for i, ax in enumerate("xyz"):
            table[f"{name}{ax}"] = arr[:, i]
    pd.DataFrame(table).to_csv(folder / "truth" / "board_poses.csv", index=False,
                               float_format="%.9g")
    rows = []
    for i, cam in enumerate(cameras):
        for k in range(len(poses)):
            xy, vis = true_corners(cam, poses[k], target, settings, key=(i, k))
            rows.append(pd.DataFrame({"camera": cam.name, "frame": k,
                                      "id": np.arange(len(xy)), "x": xy[:, 0],
                                      "y": xy[:, 1], "visible": vis}))
    pd.concat(rows).to_csv(folder / "truth" / "corners.csv", index=False, float_format="%.4f")
    meta = {"settings": asdict(settings), "margin_used": _texture(target, settings.margin)[2],
            "target": f"{target.kind}:{target.cols}x{target.rows}:{target.size}:"
                      f"{target.marker}:{target.dictionary}",
            "floor_pose": 0}
    (folder / "truth" / "settings.json").write_text(json.dumps(meta, indent=1) + "\n")
    return folder


def detect_rig(cameras, images: dict, target) -> dict:
    """The board detected in every rendered view (``photogram.io.targets.detect``):
    ``{camera: {pose index: (ids, xy)}}``, the input of
    :func:`photogram.rig.calibrate_rig`."""
    from photogram.io.targets import detect
    out = {}
    for c in cameras:
        out[c.name] = {}
        for k, img in enumerate(images[c.name]):
            hit = detect(img, target)
            if hit is not None:
                out[c.name][k] = hit
    return out
