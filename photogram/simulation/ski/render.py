"""Camera images of the simulated giant-slalom runs (rendered, not real).

THE IMAGES ARE SIMULATED: every frame of a pan-tilt-zoom camera of
:func:`photogram.simulation.ski.simulate.simulate_session` is rendered from the scene
of :mod:`photogram.simulation.ski.scene` (textured slope, gates, fences, trees, sky)
with the camera's true rotation and interior orientation of that frame, and
the skier is drawn in from the truth joints, so that real feature tracking
(:mod:`photogram.mocap.motion.homography`) runs on them.

How a frame is made (``size`` = (W, H), scale ``s = W / W_full``; pixel
centres scale as ``x_small = s (x_full + 0.5) - 0.5``, OpenCV's resize
convention, so ``fx_s = s fx``, ``cx_s = s (cx + 0.5) - 0.5``):

1. **exact lens model** (:mod:`photogram.mocap.motion.lens`): distorted
   normalised coordinates ``d = (p - c) / f`` are undistorted radially,
   ``r_u (1 + k1 r_u^2 + k2 r_u^4 + k3 r_u^6) = r_d`` by Newton's method
   (:func:`undistort_radius`); tangential distortion (p1, p2) is not
   supported (InputError);
2. **slope and sky** (:mod:`photogram.simulation.ski.backdrop`): the undistorted
   ray of every pixel meets the slope plane (one homography); the snow is
   sampled from the camera's clipmap (:mod:`photogram.simulation.ski.texture`) with
   a per-pixel level of detail from the ground footprint (no texel shorter
   than about 1.5 px: no aliasing flicker); beyond the plane's horizon
   (anti-aliased) a smooth, nearly featureless sky gradient;
3. **objects** (gates, fences and banners, trees; :mod:`photogram.simulation.ski.scene`):
   polygons projected with the full camera model (edges subdivided where
   the distortion would bend them by more than 0.02 px), clipped at the
   near plane, filled with anti-aliasing at 1/16 px, far to near;
4. **skier**: the truth joints projected with ``sim.cameras.project``:
   thick limbs, torso, helmet, skis and poles, always on top (a gate or a
   fence in front of the athlete does not hide it); no shadows.

Cost: about 25 ms per 960 x 540 frame on one core (background 18 ms,
objects 6 ms), plus 0.3-0.7 s per camera once (its clipmap).

The background of consecutive frames is therefore related exactly by the
rotation homography ``K_{t+1} R_cv(t+1) R_cv(t)^T K_t^{-1}`` (up to
resampling), as for a real camera turning about its projection centre.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.motion.lens import distort, pixel_rays, scaled_parameters, undistort_radius
from photogram.project.atomic import give_file_mode
from photogram.simulation.ski.backdrop import FrameGeometry, background, ideal_offsets
from photogram.simulation.ski.scene import SlopeScene, build_scene
from photogram.simulation.ski.simulate import SkiSimulation

__all__ = ["build_scene", "undistort_radius", "scaled_parameters", "pixel_rays", "ideal_offsets",
           "render_frame", "render_camera", "write_video", "RENDER_SIZE"]

RENDER_SIZE = (960, 540)


# --------------------------------------------------------------------------
# objects and skier
# --------------------------------------------------------------------------
def _clip_polygon(P, near):
    """Sutherland-Hodgman clipping of a polygon (k, 3) (OpenCV camera
    coordinates) to z >= near; None if nothing is left."""
    pts = P.tolist()
    out = []
    for i in range(len(pts)):
        a, b = pts[i], pts[(i + 1) % len(pts)]
        ina, inb = a[2] >= near, b[2] >= near
        if ina:
            out.append(a)
        if ina != inb:
            w = (near - a[2]) / (b[2] - a[2])
            out.append([a[k] + w * (b[k] - a[k]) for k in range(3)])
    return np.array(out) if len(out) >= 3 else None


def _clip_box(T, lo, hi):
    """Clip a polygon (k, 2) in normalised coordinates to a box."""
    poly = T.tolist()
    for axis in (0, 1):
        for bound, sign in ((float(lo[axis]), 1.0), (float(hi[axis]), -1.0)):
            out = []
            for i in range(len(poly)):
                a, b = poly[i], poly[(i + 1) % len(poly)]
                ina, inb = sign * (a[axis] - bound) >= 0, sign * (b[axis] - bound) >= 0
                if ina:
                    out.append(a)
                if ina != inb:
                    w = (bound - a[axis]) / (b[axis] - a[axis])
                    out.append([a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])])
            poly = out
            if len(poly) < 3:
                return None
    return np.array(poly)


def _subdivide(T, step):
    """Insert points on the edges of a closed polygon (k, 2) every ``step``."""
    nxt = np.concatenate([T[1:], T[:1]])
    n = np.maximum(1, np.ceil(np.linalg.norm(nxt - T, axis=1) / step).astype(int))
    if n.max() == 1:
        return T
    w = np.concatenate([np.arange(m) / m for m in n])
    i = np.repeat(np.arange(len(T)), n)
    return T[i] + w[:, None] * (nxt[i] - T[i])


def _draw_objects(img, fr: FrameGeometry, scene: SlopeScene):
    obj = scene.camera_objects(fr.X0)
    if obj.n_polygons == 0:
        return
    W, H = fr.size
    io = fr.io
    corners = np.array([[0, 0], [W - 1, 0], [0, H - 1], [W - 1, H - 1], [W / 2, 0],
                        [W / 2, H - 1], [0, H / 2], [W - 1, H / 2]], float)
    tc = pixel_rays(io, corners)
    span = tc.max(0) - tc.min(0)
    lo, hi = tc.min(0) - 0.02 * span, tc.max(0) + 0.02 * span       # the image
    big_lo, big_hi = tc.min(0) - 2.0 * span, tc.max(0) + 2.0 * span  # drawn without clipping
    r_big = float(np.max(np.hypot(*np.abs(np.stack([big_lo, big_hi])).max(0))))
    r2 = r_big * r_big
    if 1.0 + r2 * (3 * io[4] + r2 * (5 * io[5] + 7 * r2 * io[8])) <= 0.5:
        big_lo, big_hi, r_big = lo, hi, float(np.max(np.hypot(tc[:, 0], tc[:, 1])))
    near = 0.05
    C = (obj.centre - fr.X0) @ fr.R_cv.T
    r = obj.radius
    z = C[:, 2]
    vis = ((z + r > near) & (C[:, 0] - hi[0] * z <= r * np.hypot(1, hi[0]))
           & (lo[0] * z - C[:, 0] <= r * np.hypot(1, lo[0]))
           & (C[:, 1] - hi[1] * z <= r * np.hypot(1, hi[1]))
           & (lo[1] * z - C[:, 1] <= r * np.hypot(1, lo[1])))
    ids = np.flatnonzero(vis)
    if not len(ids):
        return
    lens = np.diff(obj.start)
    sel = np.repeat(vis, lens)
    V = (obj.vertices[sel] - fr.X0) @ fr.R_cv.T
    starts = np.concatenate([[0], np.cumsum(lens[ids])])
    zz = V[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        T = V[:, :2] / zz[:, None]
    good = (zz > near) & np.all((T >= big_lo) & (T <= big_hi), axis=1)
    good_poly = np.logical_and.reduceat(good, starts[:-1])
    XY = distort(np.where(good[:, None], T, 0.0), io)
    first = starts[:-1]
    nxt = np.arange(1, len(T) + 1)
    nxt[starts[1:] - 1] = first
    # a straight edge of length l (px) between distorted vertices departs from
    # the true curve by up to l^2/8 |d''| (d'' at the polygon's largest
    # radius r); keep that below 0.02 px
    rr = np.maximum.reduceat(np.where(good, np.hypot(T[:, 0], T[:, 1]), r_big), first)
    curv = (6 * abs(io[4]) * rr + 20 * abs(io[5]) * rr ** 3 + 42 * abs(io[8]) * rr ** 5) / io[0]
    edge = np.maximum.reduceat(np.linalg.norm(XY[nxt] - XY, axis=1), first)
    long_poly = edge * edge * curv > 0.16
    l_max = np.sqrt(0.16 / np.maximum(curv, 1e-30))
    pts = np.rint(XY * 16.0).astype(np.int32)
    colours = obj.colour_list
    for j, i in enumerate(ids):
        a, b = starts[j], starts[j + 1]
        if good_poly[j] and not long_poly[j]:
            cv2.fillPoly(img, [pts[a:b]], colours[i], cv2.LINE_AA, 4)
            continue
        if good_poly[j]:
            Tp = T[a:b]
        else:
            P = _clip_polygon(V[a:b], near)
            if P is None:
                continue
            Tp = _clip_box(P[:, :2] / P[:, 2:], lo, hi)
            if Tp is None:
                continue
        if curv[j] > 0:
            Tp = _subdivide(Tp, l_max[j] / io[0])
        xy = np.rint(distort(Tp, io) * 16.0).astype(np.int32)
        cv2.fillPoly(img, [xy], colours[i], cv2.LINE_AA, 4)


_LIMBS = [("r_hip", "r_knee", 0.15, "legs"), ("r_knee", "r_ankle", 0.12, "legs"),
          ("l_hip", "l_knee", 0.15, "legs"), ("l_knee", "l_ankle", 0.12, "legs"),
          ("r_shoulder", "r_elbow", 0.10, "suit"), ("r_elbow", "r_hand", 0.085, "suit"),
          ("l_shoulder", "l_elbow", 0.10, "suit"), ("l_elbow", "l_hand", 0.085, "suit"),
          ("neck", "head", 0.11, "suit")]
_SKIS = [("r_ski_tip", "r_toes"), ("r_toes", "r_heel"), ("r_heel", "r_ski_tail"),
         ("l_ski_tip", "l_toes"), ("l_toes", "l_heel"), ("l_heel", "l_ski_tail")]


def _skier_projection(scene: SlopeScene, sim: SkiSimulation):
    """(F, C, J, 2) image points (full resolution) of the truth joints by
    ``sim.cameras.project`` and their depths (F, C, J), cached in the scene."""
    cache = scene._objects.get("skier")
    if cache is None or cache[0] is not sim:
        xy = sim.cameras.project(sim.joints)
        depth = -sim.cameras.camera_points(sim.joints)[..., 2]
        cache = scene._objects["skier"] = (sim, xy, depth)
    return cache[1], cache[2]


def _draw_skier(img, fr: FrameGeometry, scene: SlopeScene, sim: SkiSimulation, camera, frame):
    xy_all, depth_all = _skier_projection(scene, sim)
    xy_full, depth = xy_all[frame, camera], depth_all[frame, camera]
    if not np.all(np.isfinite(xy_full)) or np.any(depth <= 0.1):
        return
    s = np.array(fr.size, float) / sim.cameras.image_size[camera]
    xy = s * (xy_full + 0.5) - 0.5
    fpx = fr.f
    col = scene.skier_colours
    J = {name: k for k, name in enumerate(SKI24.joints)}
    P = np.rint(xy * 16).astype(np.int32)

    def thick(width, a, b):
        return max(1, int(round(width * fpx / (0.5 * (depth[a] + depth[b])))))

    def line(a, b, width, colour):
        cv2.line(img, tuple(P[a]), tuple(P[b]), colour, thick(width, a, b), cv2.LINE_AA, 4)

    for a, b in _SKIS:
        line(J[a], J[b], 0.05, col["ski"])
    for side in ("r_", "l_"):
        line(J[side + "hand"], J[side + "pole"], 0.02, col["pole"])
    for a, b, w, c in _LIMBS[:4]:
        line(J[a], J[b], w, col[c])
    torso = np.array([P[J["r_shoulder"]], P[J["l_shoulder"]], P[J["l_hip"]], P[J["r_hip"]]])
    cv2.fillPoly(img, [torso], col["suit"], cv2.LINE_AA, 4)
    line(J["r_hip"], J["l_hip"], 0.12, col["legs"])
    line(J["r_shoulder"], J["l_shoulder"], 0.1, col["suit"])
    for a, b, w, c in _LIMBS[4:]:
        line(J[a], J[b], w, col[c])
    head = J["head"]
    centre = 0.6 * xy[head] + 0.4 * xy[J["neck"]]
    radius = max(1, int(round(0.12 * fpx / depth[head] * 16)))
    cv2.circle(img, tuple(np.rint(centre * 16).astype(np.int32)), radius, col["helmet"],
               -1, cv2.LINE_AA, 4)


# --------------------------------------------------------------------------
# public
# --------------------------------------------------------------------------
def render_frame(scene: SlopeScene, sim: SkiSimulation, camera: int, frame: int,
                 size=RENDER_SIZE, skier: bool = True) -> np.ndarray:
    """The image of camera ``camera`` (index) at frame ``frame``.

    Parameters
    ----------
    scene : SlopeScene
        From :func:`build_scene` (``build_scene(sim)``).
    sim : SkiSimulation
        Cameras (rotation and interior orientation per frame) and joints.
    camera, frame : int
        Indices.
    size : (int, int)
        Width and height in px (the full resolution is
        ``sim.cameras.image_size``; 960 x 540 is half of 1920 x 1080).
    skier : bool
        Draw the athlete (False: the background alone).

    Returns
    -------
    ndarray (H, W, 3) uint8, BGR.
    """
    fr = FrameGeometry(scene, sim, camera, frame, size)
    img = background(fr, scene, scene.clipmap(fr.X0))
    _draw_objects(img, fr, scene)
    if skier and frame < len(sim.joints):
        _draw_skier(img, fr, scene, sim, camera, frame)
    return img


def render_camera(scene: SlopeScene, sim: SkiSimulation, camera: int, frames=None,
                  size=RENDER_SIZE, skier: bool = True):
    """Iterator over the images of one camera (all frames, or ``frames``)."""
    frames = range(len(sim.joints)) if frames is None else frames
    for f in frames:
        yield render_frame(scene, sim, camera, int(f), size, skier)


_FOURCC = {".avi": "MJPG", ".mp4": "mp4v", ".mkv": "MJPG", ".mov": "mp4v"}


def write_video(path, images, fps: float) -> int:
    """Write BGR (or grey) uint8 images to a video file, atomically.

    The codec follows the extension (.avi and .mkv: MJPG, .mp4 and .mov:
    mp4v). The video is written to a temporary file in the same folder and
    renamed over ``path`` when complete.

    Returns
    -------
    int
        The number of frames written.

    Raises
    ------
    InputError
        Unknown extension, missing folder, no images, images of different
        sizes, or a codec OpenCV cannot open.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in _FOURCC:
        raise InputError(f"cannot write videos of type {ext or '(none)'!r}", file=path,
                         hint="use one of " + ", ".join(sorted(_FOURCC)))
    if not path.parent.is_dir():
        raise InputError("the folder does not exist", file=path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=ext, dir=path.parent)
    os.close(fd)
    give_file_mode(tmp, path)           # mkstemp's 0600 -> the umask's mode
    writer, n, shape = None, 0, None
    try:
        for img in images:
            img = np.asarray(img)
            if img.ndim == 2:
                img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
            if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
                raise InputError("images must be uint8 BGR or grey", file=path)
            if writer is None:
                shape = img.shape
                writer = cv2.VideoWriter(tmp, cv2.VideoWriter_fourcc(*_FOURCC[ext]), float(fps),
                                         (shape[1], shape[0]))
                if not writer.isOpened():
                    raise InputError(f"OpenCV cannot write {_FOURCC[ext]} videos", file=path,
                                     hint="try an .avi file (MJPG)")
            elif img.shape != shape:
                raise InputError(f"image {n} is {img.shape[1]} x {img.shape[0]}, the first "
                                 f"{shape[1]} x {shape[0]}", file=path)
            writer.write(img)
            n += 1
        if writer is not None:
            writer.release()
            writer = None
        if n == 0:
            raise InputError("no images to write", file=path)
        os.replace(tmp, path)
    except BaseException:
        if writer is not None:
            writer.release()
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise
    return n
