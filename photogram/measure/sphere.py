"""Balls as targets: the outline of a sphere and its eccentricity, and
rendered images of a field of balls with known truth.

The image of a sphere (centre C in the camera frame, radius R) is bounded
by the cone of rays tangent to it: a ray d touches the sphere when
``(d . C)^2 = |d|^2 (|C|^2 - R^2)``, i.e. ``d^T M d = 0`` with
``M = C C^T - (|C|^2 - R^2) I``. With ``d = K^-1 x`` the outline is the conic
``A = K^-T M K^-1``, an ellipse elongated away from the principal point,
whose centre (the pole of the line at infinity, ``A^-1 (0, 0, 1)^T``) is
*not* the image of C: the **eccentricity of a ball**, zero on the optical
axis and growing with the angle off it and the ball's apparent size
(Luhmann et al., *Close-Range Photogrammetry*, sec. 3.6.1.2). The measured
ellipse centre minus this eccentricity is the image of the ball's centre.

Camera: OpenCV's convention (``x_c = R X + t``, z forward; pixel centres at
integers), no lens distortion in the outline formula (locally it is an
affinity that keeps centres to first order).
"""

from __future__ import annotations

import numpy as np

__all__ = ["outline_conic", "outline_centre", "ball_eccentricity", "render_balls"]


def outline_conic(K: np.ndarray, C: np.ndarray, R: float) -> np.ndarray:
    """3 x 3 image conic of the outline of a sphere (camera frame centre C)."""
    C = np.asarray(C, float)
    M = np.outer(C, C) - (C @ C - R * R) * np.eye(3)
    Ki = np.linalg.inv(K)
    return Ki.T @ M @ Ki


def outline_centre(K: np.ndarray, C: np.ndarray, R: float) -> np.ndarray:
    """Centre of the outline ellipse (px)."""
    e = np.linalg.solve(outline_conic(K, C, R), [0.0, 0.0, 1.0])
    return e[:2] / e[2]


def ball_eccentricity(K: np.ndarray, C: np.ndarray, R: float) -> np.ndarray:
    """Outline centre minus the image of the sphere's centre (px)."""
    p = K @ np.asarray(C, float)
    return outline_centre(K, C, R) - p[:2] / p[2]


def render_balls(centres: np.ndarray, radius: float, K: np.ndarray, Rm: np.ndarray,
                 t: np.ndarray, size, *, ss: int = 3, ball: float = 230.0,
                 background: float = 30.0, blur: float = 0.0, noise: float = 0.0,
                 jpeg: int = 0, seed: int = 0) -> np.ndarray:
    """Bright balls (retro-reflective: uniformly lit discs) on a dark background.

    Every pixel is split into ``ss x ss`` sub-samples whose rays are tested
    against each ball (ray-sphere intersection, inside the ball's image
    bounding box only); covered sub-samples take the ball's grey level.
    Then blur, noise, JPEG as :func:`photogram.measure.render.render_plane`.
    """
    w, h = size
    buf = np.full((h * ss, w * ss), background, np.float32)
    Ki = np.linalg.inv(K)
    for X in np.atleast_2d(centres):
        C = Rm @ X + t
        if C[2] <= radius:
            continue
        A = outline_conic(K, C, radius)
        # bounding box: rays on the tangent cone (axis C, half angle asin(R / |C|))
        a = C / np.linalg.norm(C)
        alpha = np.arcsin(radius / np.linalg.norm(C))
        e1 = np.cross(a, [0.0, 1.0, 0.0] if abs(a[1]) < 0.9 else [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(a, e1)
        phi = np.linspace(0, 2 * np.pi, 64, endpoint=False)
        rays = (np.cos(alpha) * a[None] + np.sin(alpha) * (np.cos(phi)[:, None] * e1
                                                             + np.sin(phi)[:, None] * e2))
        q = rays @ K.T
        q = q[:, :2] / q[:, 2:3]
        x0, y0 = np.floor(q.min(axis=0) - 2).astype(int)
        x1, y1 = np.ceil(q.max(axis=0) + 2).astype(int)
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x1 <= x0 or y1 <= y0:
            continue
        ys, xs = np.mgrid[y0 * ss:y1 * ss, x0 * ss:x1 * ss]
        u = (xs + 0.5) / ss - 0.5
        v = (ys + 0.5) / ss - 0.5
        pts = np.stack([u, v, np.ones_like(u)], axis=-1)
        inside = np.einsum("...i,ij,...j->...", pts, A, pts) >= 0     # inside the cone
        # the cone's two nappes: keep rays in front of the camera
        d = pts @ Ki.T
        inside &= (d @ C) > 0
        region = buf[y0 * ss:y1 * ss, x0 * ss:x1 * ss]
        region[inside] = ball
    out = buf.reshape(h, ss, w, ss).mean(axis=(1, 3)).astype(np.float64)
    from photogram.measure.render import degrade
    return degrade(out, blur=blur, noise=noise, seed=seed, jpeg=jpeg)
