"""Small synthetic videos for the tests of photogram.track (no renderer needed).

Every camera gets a textured static background with a few bright static
discs (the arena's ball targets), a grey "body" stroke that moves with the
jumper, the markers as Gaussian blobs of known centre, and Gaussian noise.
Coordinates in photogram's image frame (pixel centres at half integers).
"""

from __future__ import annotations

import numpy as np


def textured_background(shape=(480, 640), seed=0, n_balls=12):
    """Static texture (blurred noise, 60-140 grey) with bright discs; also
    returns the disc centres (n, 2)."""
    import cv2
    rng = np.random.default_rng(seed)
    h, w = shape
    tex = cv2.GaussianBlur(rng.uniform(0, 1, (h, w)).astype(np.float32), (0, 0), 3)
    tex = (tex - tex.min()) / (np.ptp(tex) + 1e-9)
    img = 60 + 80 * tex
    balls = np.column_stack([rng.uniform(20, w - 20, n_balls), rng.uniform(20, h - 20, n_balls)])
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    for x, y in balls:
        img = np.where((xx - x) ** 2 + (yy - y) ** 2 <= 2.5 ** 2, 230.0, img)
    return img.astype(np.float32), balls


def blob_image(shape, xy, amplitude=150.0, sigma=0.8):
    """Sum of Gaussian blobs at xy (n, 2), integrated over each pixel (3x3
    subsamples)."""
    h, w = shape
    out = np.zeros(shape, np.float32)
    sub = (np.arange(3) - 1) / 3.0
    for x, y in np.atleast_2d(xy):
        if not (np.isfinite(x) and np.isfinite(y)):
            continue
        x0, x1 = max(int(x) - 5, 0), min(int(x) + 6, w)
        y0, y1 = max(int(y) - 5, 0), min(int(y) + 6, h)
        if x0 >= x1 or y0 >= y1:
            continue
        yy, xx = np.mgrid[y0:y1, x0:x1] + 0.5
        acc = np.zeros(yy.shape)
        for sy in sub:
            for sx in sub:
                acc += np.exp(-((xx + sx - x) ** 2 + (yy + sy - y) ** 2) / (2 * sigma ** 2))
        out[y0:y1, x0:x1] += amplitude * acc / 9.0
    return out


def render_views(cameras, X, *, visible=None, offsets=None, noise=2.0, seed=1,
                 shape=(480, 640), amplitude=150.0, body=True):
    """Frames per station of markers at X (T, M, 3).

    ``visible`` (station -> (T, M) bool) hides markers; ``offsets``
    (station -> int): that camera started ``offset`` frames late, its
    frame ``f`` shows instant ``f + offset`` (frames outside 0..T-1 show the
    background only; photogram.track's convention).
    Returns frames (station -> (T, H, W) uint8) and the true image
    positions (station -> (T, M, 2), in that station's frame numbers, NaN
    where hidden or outside).
    """
    import cv2
    rng = np.random.default_rng(seed)
    T, M = X.shape[:2]
    frames, truth = {}, {}
    for k, (name, cam) in enumerate(cameras.items()):
        bg, _ = textured_background(shape, seed=seed + 10 * k)
        off = (offsets or {}).get(name, 0)
        vis = (visible or {}).get(name, np.ones((T, M), bool))
        stack = np.empty((T, *shape), np.uint8)
        tru = np.full((T, M, 2), np.nan)
        for f in range(T):
            t = f + off
            img = bg.copy()
            if 0 <= t < T:
                q = cam.project(X[t])
                if body:
                    pts = np.rint(q).astype(np.int32).reshape(-1, 1, 2)
                    cv2.polylines(img, [pts], False, 100.0, thickness=5)
                inside = (q[:, 0] > 3) & (q[:, 0] < shape[1] - 3) & (q[:, 1] > 3) \
                    & (q[:, 1] < shape[0] - 3)
                show = inside & vis[t]
                img += blob_image(shape, q[show], amplitude)
                tru[f, show] = q[show]
            img += rng.normal(0, noise, shape).astype(np.float32)
            stack[f] = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        frames[name] = stack
        truth[name] = tru
    return frames, truth


def jump_markers(n_frames=40, separate_bindings=False):
    """Marker positions (T, 4, 3) dm of the simulated jump (P1 helmet, P2
    hip, P3/P4 bindings). With ``separate_bindings`` the bindings are moved
    apart (P3 down 4 dm, P4 up 4 dm along Z) so that every marker is a
    blob of its own."""
    from photogram.simulation.jump import jump_truth
    P = jump_truth(n_frames)["P"].copy()
    if separate_bindings:
        P[:, 2, 2] -= 4.0
        P[:, 3, 2] += 4.0
        P[:, 3, 0] -= 4.0
    return P
