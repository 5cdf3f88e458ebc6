"""Rendered images of target fields with known truth (for tests and demos).

A planar target field (dots, ring-coded marks, anything drawn into a
texture) is imaged by a pinhole camera with radial distortion, then blurred
(defocus, Gaussian), lit unevenly, given noise and JPEG-compressed, all with
OpenCV:

* the sheet is drawn into a texture of ``texel`` object units per texel with
  anti-aliased, subpixel-positioned circles (``cv2.circle``, ``LINE_AA``,
  4 fractional bits);
* every image pixel is split into ``ss x ss`` sub-samples; each is traced
  back to the sheet (distortion removed by fixed-point iteration, ray-plane
  intersection) and the texture is sampled there bilinearly
  (``cv2.remap``); the sub-samples are averaged (area sampling);
* truth is the projection of each circle's centre (with distortion), the
  point the measurement must find after the eccentricity correction.

Camera: OpenCV's convention, ``x_c = R X + t``, ``u = fx x'' + cx`` with
``x'' = x' (1 + k1 r^2 + k2 r^4)``, pixel centres at integers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PlaneCamera", "draw_sheet", "render_plane", "look_at", "Scene", "grid_scene",
           "ring_code_shapes", "field_scene", "aruco_shapes"]


@dataclass
class PlaneCamera:
    """Pinhole camera with radial distortion looking at the plane Z = 0."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    size: tuple[int, int]
    k1: float = 0.0
    k2: float = 0.0

    def project(self, XY: np.ndarray) -> np.ndarray:
        """Image points (px, distorted) of sheet points (n, 2) on Z = 0."""
        X = np.column_stack([XY, np.zeros(len(XY))])
        xc = X @ self.R.T + self.t
        xn = xc[:, :2] / xc[:, 2:3]
        r2 = (xn ** 2).sum(axis=1, keepdims=True)
        xd = xn * (1 + self.k1 * r2 + self.k2 * r2 ** 2)
        return xd @ self.K[:2, :2].T + self.K[:2, 2]

    def homography(self) -> np.ndarray:
        """Sheet (X, Y, 1) -> undistorted image point (homogeneous)."""
        return self.K @ np.column_stack([self.R[:, 0], self.R[:, 1], self.t])

    def undistort(self, uv: np.ndarray) -> np.ndarray:
        """Undistorted pixel coordinates of distorted ones (fixed point)."""
        Ki = np.linalg.inv(self.K)
        xd = uv @ Ki[:2, :2].T + Ki[:2, 2]
        if self.k1 == 0 and self.k2 == 0:
            return uv
        # x, y as contiguous arrays, operation for operation as
        # r2 = x^2 + y^2, (x, y) = xd / (1 + k1 r2 + k2 r2^2): the same numbers
        dx, dy = np.ascontiguousarray(xd[..., 0]), np.ascontiguousarray(xd[..., 1])
        x, y = dx.copy(), dy.copy()
        r2, t = np.empty_like(x), np.empty_like(x)
        for _ in range(10):
            np.multiply(x, x, out=r2)
            r2 += np.multiply(y, y, out=t)
            if self.k2 != 0:                       # else k2 r2^2 = +0.0 adds nothing
                np.multiply(r2, r2, out=t)        # r2 ** 2
                t *= self.k2
            r2 *= self.k1
            r2 += 1
            if self.k2 != 0:
                r2 += t                            # 1 + k1 r2 + k2 r2^2
            np.divide(dx, r2, out=x)
            np.divide(dy, r2, out=y)
        return np.stack([x, y], axis=-1) @ self.K[:2, :2].T + self.K[:2, 2]


def look_at(eye, target, up=(0.0, 0.0, 1.0)):
    """Rotation R and translation t (OpenCV convention) of a camera at
    ``eye`` looking at ``target``; image y points down, "up" points up."""
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.vstack([x, y, z])
    return R, -R @ eye


def draw_sheet(extent, texel: float, circles, polarity: str = "dark",
               shapes=None) -> tuple[np.ndarray, tuple[float, float]]:
    """Texture of a target sheet.

    Parameters
    ----------
    extent : (xmin, ymin, xmax, ymax) in object units
    texel : object units per texel
    circles : (n, 3) array of X, Y, radius
    polarity : "dark" (dark dots on a light sheet) or "bright"
    shapes : optional callable ``shapes(img, to_texel, ink, texel)`` drawing more
        (code rings, markers) with the ink colour

    Returns
    -------
    texture (uint8), origin (X, Y) of texel (0, 0)'s centre; row index grows
    with -Y (the sheet seen from the front, Y up)
    """
    import cv2
    xmin, ymin, xmax, ymax = extent
    w = int(np.ceil((xmax - xmin) / texel)) + 1
    h = int(np.ceil((ymax - ymin) / texel)) + 1
    paper, ink = (225, 25) if polarity == "dark" else (20, 235)
    img = np.full((h, w), paper, np.uint8)
    sh = 16

    def to_texel(X, Y):
        return (X - xmin) / texel, (ymax - Y) / texel

    for X, Y, r in np.asarray(circles, float):
        u, v = to_texel(X, Y)
        cv2.circle(img, (int(round(u * sh)), int(round(v * sh))), int(round(r / texel * sh)),
                   ink, -1, cv2.LINE_AA, 4)
    if shapes is not None:
        shapes(img, to_texel, ink, texel)
    return img, (xmin, ymax)


def render_plane(texture: np.ndarray, origin, texel: float, cam: PlaneCamera, *,
                 ss: int = 4, blur: float = 0.0, noise: float = 0.0, jpeg: int = 0,
                 gradient: float = 0.0, seed: int = 0) -> np.ndarray:
    """Render the textured plane Z = 0 (module doc).

    Parameters
    ----------
    blur : Gaussian sigma (px) of the defocus blur
    noise : standard deviation of additive Gaussian noise (grey levels)
    jpeg : JPEG quality 1-100 (0: none)
    gradient : relative brightness change across the image (uneven light)

    Returns
    -------
    uint8 grey image (h, w)
    """
    import cv2
    w, h = cam.size
    out = np.zeros((h, w), np.float64)
    tex = texture.astype(np.float32)
    for r0, r1, maps in _plane_maps(cam, tuple(map(float, origin)), float(texel), ss):
        acc = np.zeros((r1 - r0, w))
        for mu, mv in maps:
            acc += cv2.remap(tex, mu, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        out[r0:r1] = acc / ss ** 2
    if gradient:
        gx = np.linspace(1 - gradient / 2, 1 + gradient / 2, w)
        out *= gx[None, :]
    return degrade(out, blur=blur, noise=noise, seed=seed, jpeg=jpeg)


_MAPS: dict = {}
MAPS_KEPT_BYTES = 64 * 2 ** 20


def _plane_maps(cam: PlaneCamera, origin: tuple, texel: float, ss: int):
    """Texture coordinates (float32 ``cv2.remap`` maps) of every sub-sample
    of :func:`render_plane`: (r0, r1, [(mu, mv) per sub-sample offset]) per
    strip of rows. They depend on the camera and the sheet's placement
    only: the last set is kept if it holds at most :data:`MAPS_KEPT_BYTES`
    (35-40 MB at 800 x 600 and ss 3 or 640 x 480 and ss 4; larger ones are
    traced strip by strip), so that renders of one view with other
    textures, noise or blur (seeds, polarities) do not trace the rays again."""
    key = (cam.K.tobytes(), cam.R.tobytes(), np.asarray(cam.t, float).tobytes(),
           tuple(cam.size), float(cam.k1), float(cam.k2), origin, texel, ss)
    if key in _MAPS:
        return _MAPS[key]
    strips = _trace(cam, origin, texel, ss)
    w, h = cam.size
    if w * h * ss * ss * 8 > MAPS_KEPT_BYTES:
        return strips
    _MAPS.clear()
    _MAPS[key] = list(strips)
    return _MAPS[key]


def clear_caches() -> None:
    """Drop the kept texture maps of :func:`render_plane` (up to
    :data:`MAPS_KEPT_BYTES`)."""
    _MAPS.clear()


def _trace(cam: PlaneCamera, origin: tuple, texel: float, ss: int):
    """:func:`_plane_maps` computed, strip by strip (a generator)."""
    w, h = cam.size
    off = (np.arange(ss) + 0.5) / ss - 0.5
    Hi = np.linalg.inv(cam.homography())
    rows = max(1, int(2_000_000 // (w * ss * ss)))
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        yy, xx = np.mgrid[r0:r1, 0:w].astype(float)
        maps = []
        for oy in off:
            for ox in off:
                uv = np.stack([xx + ox, yy + oy], axis=-1)
                und = cam.undistort(uv)
                p = und @ Hi[:, :2].T + Hi[:, 2]
                X, Y = p[..., 0] / p[..., 2], p[..., 1] / p[..., 2]
                maps.append((((X - origin[0]) / texel).astype(np.float32),
                             ((origin[1] - Y) / texel).astype(np.float32)))
        yield r0, r1, maps


def degrade(out, *, blur: float = 0.0, noise: float = 0.0, seed=0, jpeg=None):
    """What a camera does to an ideal grey image: Gaussian blur (sigma
    ``blur`` px), Gaussian noise (sigma ``noise`` grey values, seeded),
    rounding to 8 bits and JPEG compression at quality ``jpeg``.

    Parameters
    ----------
    out : ndarray (H, W) of float
        The ideal image (grey values 0-255).

    Returns
    -------
    ndarray (H, W) of uint8
    """
    import cv2

    out = np.asarray(out, dtype=np.float64)
    if blur > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur)
    if noise > 0:
        out = out + np.random.default_rng(seed).normal(0, noise, out.shape)
    img = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    if jpeg:
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg)])
        img = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return img


@dataclass
class Scene:
    """A rendered image with its truth."""

    image: np.ndarray
    truth: np.ndarray          # (n, 2) images of the circle centres (px, pixel centres at integers)
    ellipse_centre: np.ndarray  # (n, 2) centres of the imaged ellipses (no distortion applied)
    diameter_px: np.ndarray    # (n,) approximate imaged diameters (major axis)
    XY: np.ndarray             # (n, 2) sheet coordinates
    camera: PlaneCamera
    radius: float


def grid_scene(*, cols: int = 9, rows: int = 7, spacing: float = 0.1, radius: float = 0.02,
               polarity: str = "dark", size=(800, 600), f: float = 900.0, k1: float = -0.08,
               eye=(0.1, -0.6, 1.0), target=(0.4, 0.3, 0.0), blur: float = 0.7,
               noise: float = 2.0, jpeg: int = 90, gradient: float = 0.3, ss: int = 3,
               seed: int = 1, texel: float = 0.0005, shapes=None) -> Scene:
    """A regular grid of circular targets on a plane, rendered (module doc).

    The camera looks from ``eye`` at ``target`` (object units; the grid lies
    in Z = 0 from (0, 0) to ((cols-1), (rows-1)) * spacing)."""
    from photogram.measure.eccentricity import ellipse_centres
    gx, gy = np.meshgrid(np.arange(cols) * spacing, np.arange(rows) * spacing)
    XY = np.column_stack([gx.ravel(), gy.ravel()])
    m = 2 * spacing
    extent = (-m, -m, (cols - 1) * spacing + m, (rows - 1) * spacing + m)
    tex, org = draw_sheet(extent, texel, np.column_stack([XY, np.full(len(XY), radius)]),
                          polarity, shapes)
    R, t = look_at(eye, target, up=(0, 1, 0))
    K = np.array([[f, 0, size[0] / 2 - 0.5], [0, f, size[1] / 2 - 0.5], [0, 0, 1]])
    cam = PlaneCamera(K, R, t, tuple(size), k1=k1)
    img = render_plane(tex, org, texel, cam, ss=ss, blur=blur, noise=noise, jpeg=jpeg,
                       gradient=gradient, seed=seed)
    truth = cam.project(XY)
    ec = ellipse_centres(cam.homography(), XY, radius)
    d = np.linalg.norm(cam.project(XY + [radius, 0]) - cam.project(XY - [radius, 0]), axis=1)
    d2 = np.linalg.norm(cam.project(XY + [0, radius]) - cam.project(XY - [0, radius]), axis=1)
    return Scene(img, truth, ec, np.maximum(d, d2), XY, cam, radius)


def ring_code_shapes(codes, radius: float, ring=(2.5, 4.3)):
    """A ``shapes`` callback for :func:`draw_sheet` drawing ring codes.

    ``codes`` is a list of (X, Y, bits, rotation_deg): inked sectors of a
    ring from ``ring[0]`` to ``ring[1]`` dot radii, clockwise on the sheet
    seen from the front, the first sector starting at ``rotation_deg``."""
    import cv2

    def draw(img, to_texel, ink, texel):
        paper = int(img[0, 0])
        sh = 16
        for X, Y, bits, rot in codes:
            u, v = to_texel(X, Y)
            cu, cv = int(round(u * sh)), int(round(v * sh))
            ro, ri = (int(round(ring[k] * radius / texel * sh)) for k in (1, 0))
            step = 360.0 / len(bits)
            for k, b in enumerate(bits):
                if b == "1":
                    cv2.ellipse(img, (cu, cv), (ro, ro), 0, rot + k * step, rot + (k + 1) * step,
                                ink, -1, cv2.LINE_AA, 4)
            cv2.circle(img, (cu, cv), ri, paper, -1, cv2.LINE_AA, 4)
            cv2.circle(img, (cu, cv), int(round(radius / texel * sh)), ink, -1, cv2.LINE_AA, 4)
    return draw


def field_scene(fld, *, eye=(0.5, -1.2, 1.9), target=(0.5, 0.5, 0.0), f: float = 700.0,
                size=(800, 600), k1: float = -0.05, blur: float = 0.7, noise: float = 2.0,
                jpeg: int = 90, gradient: float = 0.3, ss: int = 3, seed: int = 1,
                texel: float | None = None, code_rotation: float = 0.0, swap=None):
    """A rendered planar target field described by a :class:`TargetField`
    (grid dots and ring codes, diameter ``fld.diameter``).

    ``swap`` = (id_a, id_b) draws two codes at each other's place (a sheet
    that disagrees with its description). Returns (image, truth dict id ->
    (x, y) in the OpenCV frame, camera)."""
    ids, XY = fld.layout()
    r = fld.diameter / 2
    texel = texel or r / 12
    codes = []
    bits = {c.id: c.bits for c in fld.codes}
    for c in fld.codes:
        cid = c.id
        if swap and cid in swap:
            cid = swap[1] if cid == swap[0] else swap[0]
        X, Y = fld.code_xyz[c.id][:2]
        codes.append((X, Y, bits[cid], code_rotation))
    grid = np.column_stack([fld.grid_xy, np.full(len(fld.grid_xy), r)])
    m = 0.3
    extent = (XY[:, 0].min() - m, XY[:, 1].min() - m, XY[:, 0].max() + m, XY[:, 1].max() + m)
    tex, org = draw_sheet(extent, texel, grid, fld.polarity, ring_code_shapes(codes, r))
    R, t = look_at(eye, target, up=(0, 1, 0))
    K = np.array([[f, 0, size[0] / 2 - 0.5], [0, f, size[1] / 2 - 0.5], [0, 0, 1]])
    cam = PlaneCamera(K, R, t, tuple(size), k1=k1)
    img = render_plane(tex, org, texel, cam, ss=ss, blur=blur, noise=noise, jpeg=jpeg,
                       gradient=gradient, seed=seed)
    truth = dict(zip(ids, cam.project(XY)))
    return img, truth, cam


def aruco_shapes(markers, side: float, dictionary: str = "DICT_4X4_50"):
    """A ``shapes`` callback drawing ArUco markers (id, X, Y) of side ``side``
    (object units) centred at (X, Y), upright on the sheet seen from the front.
    The centres actually drawn (snapped to the texel grid) are stored in the
    callback's ``centres`` dict (id -> (X, Y)) for the truth."""
    import cv2
    dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))

    def draw(img, to_texel, ink, texel):
        paper = int(img[0, 0])
        S = int(round(side / texel))
        for mid, X, Y in markers:
            m = cv2.aruco.generateImageMarker(dic, int(mid), S)
            m = np.where(m > 127, paper, ink).astype(np.uint8)
            u, v = to_texel(X, Y)
            u0, v0 = int(round(u - (S - 1) / 2)), int(round(v - (S - 1) / 2))
            img[v0:v0 + S, u0:u0 + S] = m
            uc, vc = u0 + (S - 1) / 2, v0 + (S - 1) / 2
            draw.centres[mid] = (X + (uc - u) * texel, Y - (vc - v) * texel)

    draw.centres = {}
    return draw
