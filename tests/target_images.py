"""Synthetic images of planar calibration targets with known cameras, for
the tests of photogram.io.targets (no real calibration images are in our
data). Each output pixel is traced back through the distortion
(cv2.undistortPointsIter) to the target plane and the target's texture is
sampled there, so the images follow the OpenCV camera model exactly (up to
the texture's antialiasing).
"""

from __future__ import annotations

import cv2
import numpy as np

PX_PER_UNIT = 1000.0          # texture resolution: texels per length unit (1 mm at m)


def texture(target, ppu: float = PX_PER_UNIT):
    """(image, origin): the target drawn at ``ppu`` texels per unit, and the
    target coordinates of texel (0, 0)."""
    s = target.size
    if target.kind == "chessboard":
        nx, ny = target.cols + 1, target.rows + 1
        margin = s
        w, h = int(round((nx * s + 2 * margin) * ppu)), int(round((ny * s + 2 * margin) * ppu))
        img = np.full((h, w), 255, np.uint8)
        for i in range(ny):
            for j in range(nx):
                if (i + j) % 2 == 0:
                    x0 = int(round((margin + j * s) * ppu))
                    y0 = int(round((margin + i * s) * ppu))
                    img[y0:int(round((margin + (i + 1) * s) * ppu)),
                        x0:int(round((margin + (j + 1) * s) * ppu))] = 0
        origin = (-(margin + s), -(margin + s))        # first inner corner at (0, 0)
    elif target.kind in ("circles", "acircles"):
        obj = target.object_points()
        margin = 2 * s
        w = int(round((obj[:, 0].max() + 2 * margin) * ppu))
        h = int(round((obj[:, 1].max() + 2 * margin) * ppu))
        img = np.full((h, w), 255, np.uint8)
        for x, y, _ in obj:
            # drawing coordinates are texel centres: shift by the half texel of render()
            c = (int(round(((x + margin) * ppu - 0.5) * 16)),
                 int(round(((y + margin) * ppu - 0.5) * 16)))
            cv2.circle(img, c, int(round(0.3 * s * ppu * 16)), 0, -1, cv2.LINE_AA, shift=4)
        origin = (-margin, -margin)
    else:
        board = target.board()
        margin = target.size
        w = int(round((target.cols * s + 2 * margin) * ppu))
        h = int(round((target.rows * s + 2 * margin) * ppu))
        img = board.generateImage((w, h), marginSize=int(round(margin * ppu)), borderBits=1)
        origin = (-margin, -margin)
    return cv2.GaussianBlur(img, (0, 0), 1.0), origin


_RAYS: dict = {}


def pixel_rays(K, dist, size) -> np.ndarray:
    """Normalised undistorted coordinates of every pixel centre (cached)."""
    key = (np.asarray(K, float).tobytes(), np.asarray(dist, float).tobytes(), tuple(size))
    if key not in _RAYS:
        w, h = size
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        pts = np.stack([u.ravel(), v.ravel()], axis=-1).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-10)
        if hasattr(cv2, "undistortPointsIter"):                 # OpenCV 4
            n = cv2.undistortPointsIter(pts, K, dist, None, None, crit)
        else:                                                    # OpenCV 5
            n = cv2.undistortPoints(pts, K, dist, criteria=crit)
        _RAYS[key] = n.reshape(-1, 2)
    return _RAYS[key]


def render(target, K, dist, rvec, tvec, size, tex=None, noise: float = 0.0, rng=None):
    """A grey image (uint8) of ``target`` seen by the OpenCV camera."""
    tex, origin = tex if tex is not None else texture(target)
    w, h = size
    n = pixel_rays(K, dist, size)
    R, _ = cv2.Rodrigues(np.asarray(rvec, float))
    t = np.asarray(tvec, float).ravel()
    C = -R.T @ t
    d = np.column_stack([n, np.ones(len(n))]) @ R          # rows: R^T [x', y', 1]
    s = -C[2] / d[:, 2]
    X = C + s[:, None] * d
    # texel i covers [i, i + 1) of the drawing; remap samples texel centres at integers
    mx = ((X[:, 0] - origin[0]) * PX_PER_UNIT - 0.5).reshape(h, w).astype(np.float32)
    my = ((X[:, 1] - origin[1]) * PX_PER_UNIT - 0.5).reshape(h, w).astype(np.float32)
    behind = (s <= 0).reshape(h, w)
    mx[behind] = -1
    img = cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=200)
    if noise:
        rng = rng or np.random.default_rng(0)
        img = np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)
    return img


def look_at_pose(centre, target_point, up=(0.0, -1.0, 0.0)):
    """OpenCV (rvec, tvec) of a camera at ``centre`` looking at ``target_point``
    (image y roughly along ``up`` of the board)."""
    c = np.asarray(centre, float)
    z = np.asarray(target_point, float) - c
    z /= np.linalg.norm(z)
    x = np.cross(np.asarray(up, float), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.vstack([x, y, z])
    rvec, _ = cv2.Rodrigues(R)
    return rvec.ravel(), -R @ c


def views(target, n: int = 8, distance: float = 0.5, seed: int = 3):
    """``n`` varied poses around the target's centre (tilts up to ~35 deg)."""
    rng = np.random.default_rng(seed)
    obj = target.object_points()
    centre = obj.mean(axis=0)
    out = []
    for k in range(n):
        az = 2 * np.pi * k / n + rng.uniform(-0.2, 0.2)
        tilt = np.radians(rng.uniform(15, 35))
        c = centre + distance * np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az),
                                          -np.cos(tilt)])
        roll = rng.uniform(-0.3, 0.3)
        up = (np.sin(roll), -np.cos(roll), 0.0)
        out.append(look_at_pose(c, centre + rng.uniform(-0.02, 0.02, 3) * [1, 1, 0], up))
    return out
