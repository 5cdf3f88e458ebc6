"""Rendered images of a 3D target field (a test frame) with known truth.

Each target is a small square plate in its own plane (centre, normal):
a circular dot (retro-reflective: white on a black plate; or black on white)
or an ArUco marker with a white margin. A pinhole camera with radial
distortion (:class:`photogram.measure.render.PlaneCamera`'s K, R, t, k1, k2;
OpenCV's convention) images the plates: every pixel is split into
``ss x ss`` sub-samples, each traced back through the distortion and the
plate's homography ``K [R e1 | R e2 | R X + t]`` onto the plate and given the
plate texture's value there (plates drawn far to near); sub-samples are
averaged (area sampling), then blur, noise and JPEG as in
:func:`photogram.measure.render.render_plane`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.measure.render import PlaneCamera, degrade

__all__ = ["Plate", "project3", "render_plates", "corner_frame"]


@dataclass
class Plate:
    """A target plate: ``kind`` "dot" (radius) or "aruco" (marker id)."""

    id: str
    X: np.ndarray
    normal: np.ndarray
    kind: str = "dot"
    radius: float = 0.01
    side: float = 0.05
    marker: int = 0
    polarity: str = "bright"


def project3(cam: PlaneCamera, X: np.ndarray) -> np.ndarray:
    """Image points (px, distorted; pixel centres at integers) of 3D points."""
    xc = np.atleast_2d(X) @ cam.R.T + cam.t
    xn = xc[:, :2] / xc[:, 2:3]
    r2 = (xn ** 2).sum(axis=1, keepdims=True)
    xd = xn * (1 + cam.k1 * r2 + cam.k2 * r2 ** 2)
    return xd @ cam.K[:2, :2].T + cam.K[:2, 2]


def _basis(n):
    n = np.asarray(n, float) / np.linalg.norm(n)
    up = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(up, n)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def _texture(p: Plate, T: int = 200):
    import cv2
    if p.kind == "aruco":
        dic = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
        inner = int(T * 0.75)
        m = cv2.aruco.generateImageMarker(dic, int(p.marker), inner)
        tex = np.full((T, T), 235, np.uint8)
        o = (T - inner) // 2
        tex[o:o + inner, o:o + inner] = np.where(m > 127, 235, 20)
        return tex.astype(np.float32)
    paper, ink = (20, 235) if p.polarity == "bright" else (235, 20)
    tex = np.full((T, T), paper, np.uint8)
    c = (T - 1) / 2
    cv2.circle(tex, (int(round(c * 16)), int(round(c * 16))),
               int(round(p.radius / p.side * T * 16)), ink, -1, cv2.LINE_AA, 4)
    return tex.astype(np.float32)


def render_plates(plates: list[Plate], cam: PlaneCamera, *, background: float = 40.0,
                  ss: int = 3, blur: float = 0.0, noise: float = 0.0, jpeg: int = 0,
                  seed: int = 0) -> np.ndarray:
    """Render the plates (module doc); uint8 grey image."""
    import cv2
    w, h = cam.size
    buf = np.full((h * ss, w * ss), background, np.float32)
    depth = [float((cam.R @ p.X + cam.t)[2]) for p in plates]
    T = 200
    for k in np.argsort(depth)[::-1]:
        p = plates[k]
        if depth[k] <= 0:
            continue
        e1, e2 = _basis(p.normal)
        half = p.side / 2
        corners = np.array([p.X + a * half * e1 + b * half * e2
                            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        uv = project3(cam, corners)
        x0, y0 = np.floor(uv.min(axis=0) - 2).astype(int)
        x1, y1 = np.ceil(uv.max(axis=0) + 2).astype(int)
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w - 1), min(y1, h - 1)
        if x1 <= x0 or y1 <= y0:
            continue
        ys, xs = np.mgrid[y0 * ss:(y1 + 1) * ss, x0 * ss:(x1 + 1) * ss]
        pix = np.stack([(xs + 0.5) / ss - 0.5, (ys + 0.5) / ss - 0.5], axis=-1)
        und = cam.undistort(pix)
        H = cam.K @ np.column_stack([cam.R @ e1, cam.R @ e2, cam.R @ p.X + cam.t])
        q = und @ np.linalg.inv(H)[:, :2].T + np.linalg.inv(H)[:, 2]
        a, b = q[..., 0] / q[..., 2], q[..., 1] / q[..., 2]
        inside = (np.abs(a) <= half) & (np.abs(b) <= half)
        mu = ((a + half) / p.side * T - 0.5).astype(np.float32)
        mv = ((half - b) / p.side * T - 0.5).astype(np.float32)
        val = cv2.remap(_texture(p, T), mu, mv, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE)
        region = buf[y0 * ss:(y1 + 1) * ss, x0 * ss:(x1 + 1) * ss]
        region[inside] = val[inside]
    out = buf.reshape(h, ss, w, ss).mean(axis=(1, 3)).astype(np.float64)
    return degrade(out, blur=blur, noise=noise, seed=seed, jpeg=jpeg)


def corner_frame(n: int = 5, spacing: float = 0.2, radius: float = 0.012,
                 side: float = 0.05, marker_side: float = 0.12):
    """A 3D test frame: the corner of a room (floor Z = 0, walls X = 0 and
    Y = 0), an n x n grid of retro-reflective dots on each, three ArUco
    markers per plane (ids 0-8). Returns (plates, ids of the markers'
    points)."""
    plates = []
    markers = []
    mk = {(1, 3), (3, 1), (3, 3)}
    mid = 0
    axes = {"floor": (np.array([0, 0, 1.0]), 0, 1), "wallx": (np.array([1.0, 0, 0]), 1, 2),
            "wally": (np.array([0, 1.0, 0]), 0, 2)}
    for name, (normal, i, j) in axes.items():
        for r in range(n):
            for c in range(n):
                X = np.zeros(3)
                X[i] = (c + 0.5) * spacing
                X[j] = (r + 0.5) * spacing
                pid = f"{name[0].upper()}{name[-1] if name != 'floor' else ''}{r}{c}"
                if (r, c) in mk:
                    plates.append(Plate(f"A{mid}", X, normal, "aruco", side=marker_side,
                                        marker=mid))
                    markers.append(f"A{mid}")
                    mid += 1
                else:
                    plates.append(Plate(pid, X, normal, "dot", radius=radius, side=side))
    return plates, markers
