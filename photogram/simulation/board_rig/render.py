"""Rendering the views of a rendered multi-camera set (module doc of
:mod:`photogram.simulation.board_rig`: images)."""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np

from photogram.simulation.board_rig.geometry import (MAX_LEVEL, STRIP, TEXELS_PER_SQUARE,
                                                     BoardPoses, RigCamera, RigRenderSettings,
                                                     _bar, _bar_coverage, _board_centre,
                                                     _camera_board, _rotvec, _undistort)


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
    pixels [y0, y1) x [x0, x1) (inside the image: 0 <= x0 < x1 <= w,
    0 <= y0 < y1 <= h): sample (a, b) of pixel (i, j) at
    ``(i + (a + 0.5) / s - 0.5, j + (b + 0.5) / s - 0.5)`` (OpenCV pixel
    centres at integers).

    The exact inverse (:func:`_undistort`) at the pixel centres (computed
    once per camera, :func:`_centre_rays`), bilinearly
    interpolated between them: the distortion's curvature over one pixel
    makes that < 1e-3 px (tested against the exact inverse).
    """
    return np.stack(_sample_xy(camera, s, x0, y0, x1, y1), axis=-1)


def _sample_xy(camera: RigCamera, s: int, x0: int, y0: int, x1: int, y1: int) -> tuple:
    """:func:`_sample_rays` as two contiguous arrays (rows, cols), x and y,
    interpolated component by component (the same numbers)."""
    grid = _centre_rays(_camera_key(camera, 0)).region(y0, y1 + 2, x0, x1 + 2)
    hh, ww = y1 - y0, x1 - x0
    offsets = (np.arange(s) + 0.5) / s - 0.5
    xy = []
    for k in (0, 1):
        g = grid[..., k]
        out = np.empty((hh, s, ww, s))
        for b, dy in enumerate(offsets):
            r0, fy = (1, dy) if dy >= 0 else (0, 1 + dy)
            rows = (1 - fy) * g[r0:r0 + hh] + fy * g[r0 + 1:r0 + 1 + hh]
            for a, dx in enumerate(offsets):
                c0, fx = (1, dx) if dx >= 0 else (0, 1 + dx)
                np.add((1 - fx) * rows[:, c0:c0 + ww], fx * rows[:, c0 + 1:c0 + 1 + ww],
                       out=out[:, b, :, a])
        xy.append(out.reshape(hh * s, ww * s))
    return tuple(xy)


def _key_camera(key) -> RigCamera:
    name, K, dist, size, _ = key
    return RigCamera(name, np.frombuffer(K).reshape(3, 3), np.frombuffer(dist), np.eye(3),
                     np.zeros(3), size)


class _CentreRays:
    """Normalised coordinates (h + 2, w + 2, 2) of the pixel centres -1 .. w
    by -1 .. h (row, column: pixel (i, j) at [j + 1, i + 1]) of one camera,
    exact (:func:`_undistort`), inverted by tiles of ``TILE`` x ``TILE`` on
    first use (:meth:`region`): the views of a set touch only part of the
    image, and ``cv2.undistortPoints`` inverts each point on its own, so the
    numbers are those of inverting the whole grid at once."""

    TILE = 32

    def __init__(self, camera: RigCamera):
        w, h = camera.image_size
        self.camera = camera
        self.grid = np.empty((h + 2, w + 2, 2))
        self.done = np.zeros((-(-(h + 2) // self.TILE), -(-(w + 2) // self.TILE)), bool)

    def region(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """``grid[r0:r1, c0:c1]``, its missing tiles inverted first."""
        T = self.TILE
        rows, cols = slice(r0 // T, -(-r1 // T)), slice(c0 // T, -(-c1 // T))
        todo = np.argwhere(~self.done[rows, cols]) + [rows.start, cols.start]
        if len(todo):
            h2, w2 = self.grid.shape[:2]
            blocks = [(slice(a * T, min(a * T + T, h2)), slice(b * T, min(b * T + T, w2)))
                      for a, b in todo]
            uv = np.concatenate([np.stack(np.meshgrid(np.arange(cs.start, cs.stop) - 1.0,
                                                      np.arange(rs.start, rs.stop) - 1.0),
                                          -1).reshape(-1, 2) for rs, cs in blocks])
            xn = _undistort(self.camera, uv)
            n0 = 0
            for rs, cs in blocks:
                n = (rs.stop - rs.start) * (cs.stop - cs.start)
                self.grid[rs, cs] = xn[n0:n0 + n].reshape(rs.stop - rs.start, -1, 2)
                n0 += n
            self.done[rows, cols] = True
        return self.grid[r0:r1, c0:c1]


@functools.lru_cache(maxsize=2)
def _centre_rays(key) -> _CentreRays:
    """The pixel-centre rays (:class:`_CentreRays`) of the camera of ``key``
    (:func:`_camera_key`): the same for every view, so inverted once (15 MB
    at 1280 x 720; :func:`render_rig` renders camera after camera)."""
    return _CentreRays(_key_camera(key))


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


def clear_caches() -> None:
    """Drop the per-camera caches of this module (textures, pixel rays,
    backgrounds: up to about 300 MB for 1920 x 1080 cameras), e.g. between
    rendered sets of different cameras in one long-lived process."""
    for cached in (_texture, _centre_rays, _coarse_rays, _background, _blurred_background):
        cached.cache_clear()


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
    (normalised, (..., 2), or the pair (x, y) of its components) and whether
    they hit the paper in front of the camera: the plane z_board = 0 is
    ``r3 . (lam d - t_cb) = 0`` with ``d = (x, y, 1)``."""
    x, y = (xn[..., 0], xn[..., 1]) if isinstance(xn, np.ndarray) else xn
    r1, r2, r3 = R_cb.T
    tmp = np.empty(np.shape(x))
    with np.errstate(divide="ignore", invalid="ignore"):
        # in place, operand for operand as lam = (r3 . t) / (x r3[0] + y r3[1] + r3[2]),
        # bx = lam (x r1[0] + y r1[1] + r1[2]) + (margin - r1 . t): the same numbers
        lam = _plane(x, y, r3, tmp)
        np.divide(r3 @ t_cb, lam, out=lam)
        bx = _plane(x, y, r1, tmp)
        bx *= lam
        bx += margin - r1 @ t_cb
        by = _plane(x, y, r2, tmp)
        by *= lam
        by += margin - r2 @ t_cb
    inside = bx >= 0
    inside &= bx <= W
    inside &= by >= 0
    inside &= by <= H
    inside &= lam > 0
    return bx, by, inside


def _plane(x, y, r, tmp) -> np.ndarray:
    """``x * r[0] + y * r[1] + r[2]`` (a new array), ``tmp`` a scratch
    array of its shape."""
    out = np.multiply(x, r[0])
    out += np.multiply(y, r[1], out=tmp)
    out += r[2]
    return out


def _look(camera, R_cb, t_cb, target, s, texel0) -> tuple:
    """(mip level, front seen) of one sub-pose: the level gives about one
    texel per sample at the board's centre."""
    depth = (R_cb @ _board_centre(target) + t_cb)[2]
    per_sample = depth / camera.K[0, 0] / s / texel0
    L = int(np.clip(np.floor(np.log2(max(per_sample, 1.0))), 0, MAX_LEVEL))
    return L, bool(R_cb[:, 2] @ t_cb > 0)


def _box_mean(a: np.ndarray, s: int) -> np.ndarray:
    """Mean (float64) of the s x s blocks of ``a`` (rows and columns
    multiples of s): sums along the contiguous axis first."""
    hs, ws = a.shape
    rows = a.reshape(hs, ws // s, s).sum(-1, dtype=np.float64)
    return rows.reshape(hs // s, s, ws // s).sum(1) / (s * s)


def _true_box(mask: np.ndarray):
    """The smallest (rows, cols) slices holding every True of the 2-D
    ``mask``, None if it has none."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask[rows[0]:rows[-1] + 1].any(axis=0))
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def _board_layer(camera: RigCamera, subs, target, settings) -> tuple | None:
    """(box, value x coverage, coverage) of the board averaged over the
    sub-poses ``subs`` [(R_bw, t_bw), ...]; box (x0, y0, x1, y1) holds
    every output pixel the board touches (found on a 4 px grid, grown by
    8 px), None if the board is not in the image. Rendered in strips of
    ``STRIP`` rows, each over the columns of the grid's hits near its rows
    only (grown the same way; a tilted or rolled board fills a fraction of
    its box): the same images as over the whole box."""
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
    # per sub-pose invariants: mip level (about one texel per sample at the
    # board's centre), its texel (m) and whether the camera sees the front
    looks = [_look(camera, R_cb, t_cb, target, s, texel0) for R_cb, t_cb in poses]
    grey = [(settings.black, settings.white - settings.black) if front else (settings.back, 0.0)
            for _, front in looks]
    for r0 in range(y0, y1, STRIP):          # strips of rows: bounded memory
        r1 = min(r0 + STRIP, y1)
        # the strip's columns: those of the coarse hits whose grown box
        # (-8 .. +11 px, as the whole box's) reaches the strip's rows
        band = found[max((r0 - 8) // 4, 0):(r1 + 7) // 4 + 1]
        cols = np.flatnonzero(band.any(axis=0))
        if cols.size == 0:
            continue
        c0, c1 = max(cols[0] * 4 - 8, 0), min(cols[-1] * 4 + 12, w)
        hh, ww = r1 - r0, c1 - c0
        xy = _sample_xy(camera, s, c0, r0, c1, r1)
        vsum = np.zeros((hh * s, ww * s), np.float32)
        nsum = np.zeros((hh * s, ww * s), np.float32)
        for (R_cb, t_cb), (L, _), (g0, dg) in zip(poses, looks, grey):
            bx, by, inside = _hit(xy, R_cb, t_cb, margin, W, H)
            # the texture only over the samples' box that hits the paper
            # (remap is per sample; outside it the old full-strip sum added 0)
            box = _true_box(inside)
            if box is None:
                continue
            inside, bx, by = inside[box], bx[box], by[box]
            texel = texel0 * 2 ** L
            # in place (bx, by are this sub-pose's own): the numbers of
            # np.where(inside, bx / texel - 0.5, -1) in float32
            outside = ~inside
            maps = []
            for b in (bx, by):
                b /= texel
                b -= 0.5
                np.copyto(b, -1.0, where=outside)
                maps.append(b.astype(np.float32))
            tex = cv2.remap(levels[L], maps[0], maps[1], cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REPLICATE)
            weight = inside.astype(np.float32)
            tex *= np.float32(dg)
            tex += np.float32(g0)
            tex *= weight
            vsum[box] += tex
            nsum[box] += weight
        val[r0 - y0:r1 - y0, c0 - x0:c1 - x0] = _box_mean(vsum, s)
        cov[r0 - y0:r1 - y0, c0 - x0:c1 - x0] = _box_mean(nsum, s)
    return (x0, y0, x1, y1), val / len(poses), cov / len(poses)


def face_seen(camera: RigCamera, pose, target, settings: RigRenderSettings) -> bool:
    """Whether the view of ``pose`` = (R_bw, t_bw[, v, w]) by ``camera``
    shows any of the board's printed face: some sub-pose of the shutter
    (:func:`_sub_poses`) turns its face towards the camera and hits the
    image's 4 px grid (as :func:`_board_layer` finds the board). A view
    without it holds no marker (the back is plain grey), so nothing in it
    can be detected as the board."""
    if len(pose) == 2:
        pose = (pose[0], pose[1], np.zeros(3), np.zeros(3))
    _, _, margin = _texture(target, settings.margin)
    W = target.cols * target.size + 2 * margin
    H = target.rows * target.size + 2 * margin
    coarse = None
    for R_bw, t_bw in _sub_poses(pose, settings):
        R_cb, t_cb = _camera_board(camera, R_bw, t_bw)
        if R_cb[:, 2] @ t_cb > 0:                      # the face towards the camera
            if coarse is None:
                coarse = _coarse_rays(_camera_key(camera, settings.supersample))
            if _hit(coarse, R_cb, t_cb, margin, W, H)[2].any():
                return True
    return False


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
            # _bar_coverage of every pixel (x, y), broadcast: the same numbers
            cov = _bar_coverage((np.arange(w, dtype=float)[None, :],
                                 np.arange(h, dtype=float)[:, None]), bar)
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
        grain = rng.standard_normal(img.shape, dtype=np.float32)
        grain *= settings.noise
        img += grain
    out = np.clip(np.rint(img, out=img), 0, 255, out=img).astype(np.uint8)
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
