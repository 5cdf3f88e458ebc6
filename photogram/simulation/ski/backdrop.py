"""The background of a rendered frame: snow on the slope plane and sky.

SIMULATED IMAGES (see :mod:`photogram.simulation.ski.render`). For every pixel of a
frame (exact lens model, :mod:`photogram.mocap.motion.lens`):

* the undistortion correction ``offset (r_u / r_d - 1)`` is computed exactly
  on a grid of 8 x 8 px cells (one cell beyond each border) and bilinearly
  interpolated (the field is smooth: within 1e-4 px for the simulator's
  cameras at 960 x 540, 2e-3 px for |k1| <= 0.05 and f >= 400 px);
* the undistorted ray is intersected with the slope plane by one
  homography (``cv2.perspectiveTransform``) giving plane coordinates
  relative to the camera's foot point;
* the snow is sampled from the camera's clipmap
  (:mod:`photogram.simulation.ski.texture`) at a level of detail
  ``lambda = log2(1.5 F / texel)`` from the ground footprint
  ``F = h |d| / (f (n.d)^2)`` (the long axis of a pixel's footprint, ``h``
  the camera height over the plane, ``d`` the ray): two levels blended, no
  texel shorter than about 1.5 px, so no aliasing flicker; lambda is exact
  at the grid nodes and interpolated;
* beyond the plane's horizon the sky: a smooth gradient of the elevation;
  the horizon is anti-aliased with the exact signed distance.

Work buffers are kept per image size (not thread-safe).
"""

from __future__ import annotations

import cv2
import numpy as np

from photogram.errors import InputError
from photogram.mocap.motion.lens import check_radial, scaled_parameters, undistort_radius
from photogram.simulation.ski.scene import SlopeScene
from photogram.simulation.ski.simulate import SkiSimulation

__all__ = ["FrameGeometry", "background", "ideal_offsets"]

FLIP = np.diag([1.0, -1.0, -1.0])
_CELL = 8
_LUT = 4096
_SKY_HORIZON = np.array([236.0, 228.0, 220.0])     # BGR, hazy near the horizon
_SKY_ZENITH = np.array([215.0, 160.0, 105.0])


class _Lens:
    """Radial undistortion of one frame: ``g(r_d) = r_u / r_d`` tabulated
    on 4096 radii by Newton's method (:func:`undistort_radius`), linear
    interpolation in between (relative error below 1e-9)."""

    def __init__(self, io, r_max):
        self.io = io
        self.r = np.linspace(0.0, r_max * 1.001 + 1e-12, _LUT)
        ru = undistort_radius(self.r, io[4], io[5], io[8])
        self.g = np.ones(_LUT)
        self.g[1:] = ru[1:] / self.r[1:]

    def rays(self, offsets):
        """Normalised coordinates (..., 2) of pixel offsets from the
        principal point (..., 2)."""
        d = offsets / self.io[0:2]
        return d * np.interp(np.hypot(d[..., 0], d[..., 1]), self.r, self.g)[..., None]


class _Work:
    """Fixed per-pixel arrays and work buffers of one image size and
    principal point (the renderer is therefore not thread-safe).

    Everything per pixel lives on an *extended* raster of ``(ny C, nx C)``
    pixels, one cell of ``C = _CELL`` px beyond each border: extended pixel
    ``(x_e, y_e)`` is image pixel ``(x_e - C, y_e - C)``, and the coarse
    grid node ``(i, j)`` sits at extended pixel ``(C j + C/2 - 1/2, ...)``,
    where ``cv2.resize`` puts it, so that bilinear up-sampling of the coarse
    grid covers the whole image.
    """

    def __init__(self, size, io):
        W, H = size
        C = _CELL
        self.W, self.H = W, H
        self.nx, self.ny = -(-W // C) + 2, -(-H // C) + 2
        self.Wx, self.Hx = self.nx * C, self.ny * C
        x = np.arange(self.Wx, dtype=np.float64) - C - io[2]
        y = np.arange(self.Hx, dtype=np.float64) - C - io[3]
        self.offsets = np.empty((self.Hx, self.Wx, 2), np.float32)
        self.offsets[..., 0] = x[None, :]
        self.offsets[..., 1] = y[:, None]
        gx = C * np.arange(self.nx) + C / 2.0 - 0.5 - C - io[2]
        gy = C * np.arange(self.ny) + C / 2.0 - 0.5 - C - io[3]
        self.nodes = np.stack(np.broadcast_arrays(gx[None, :], gy[:, None]), -1)
        shape = (self.Hx, self.Wx)
        f32, u8 = np.float32, np.uint8
        self.buf = {name: np.empty(shape + ((k,) if k > 1 else ()), dtype)
                    for name, k, dtype in (("corr", 2, f32), ("q", 2, f32), ("P", 2, f32),
                                           ("lam", 1, f32), ("lev", 1, u8), ("lev2", 2, u8),
                                           ("frac", 1, f32), ("wfrac", 1, f32),
                                           ("e2", 2, np.int32), ("row", 1, f32), ("m", 2, f32),
                                           ("S", 4, u8), ("a", 1, u8), ("b", 1, u8),
                                           ("grey", 1, u8), ("snow", 3, u8), ("sky", 3, u8))}


_WORK: dict = {}


def _work(size, io) -> _Work:
    key = (size[0], size[1], float(io[2]), float(io[3]))
    w = _WORK.get(key)
    if w is None:
        if len(_WORK) > 2:
            _WORK.clear()
        w = _WORK[key] = _Work(size, io)
    return w


def _corrections(w: _Work, io):
    """The lens of the frame and the exact undistortion correction
    ``offset (g - 1)`` (px) at the coarse nodes (ny, nx, 2); bilinear
    interpolation of this smooth field is within 2e-3 px of the exact
    value for |k1| <= 0.05 at f >= 400 px (1e-4 px for the simulator's
    cameras at 960 x 540)."""
    d = w.nodes / io[0:2]
    lens = _Lens(io, float(np.hypot(d[..., 0], d[..., 1]).max()))
    t = lens.rays(w.nodes)
    corr = (t * io[0:2] - w.nodes).astype(np.float32)
    return t, corr


def ideal_offsets(io_row, size) -> np.ndarray:
    """Undistorted pixel offsets ``(fx t_x, fy t_y)`` (H, W, 2) float32 of
    every pixel of an image of ``size``, as the renderer computes them
    (``t``: normalised coordinates; :func:`pixel_rays` gives the exact
    float64 values)."""
    io = np.asarray(io_row, float)
    check_radial("opencv", io)
    w = _work(size, io)
    _, corr = _corrections(w, io)
    up = cv2.resize(corr, (w.Wx, w.Hx), interpolation=cv2.INTER_LINEAR)
    C = _CELL
    return (w.offsets + up)[C:C + w.H, C:C + w.W].copy()


class FrameGeometry:
    """Geometry of one frame at the render size."""

    def __init__(self, scene: SlopeScene, sim: SkiSimulation, camera: int, frame: int, size):
        cams = sim.cameras
        F = cams.n_frames or 1
        if not 0 <= camera < cams.n_cameras:
            raise InputError(f"no camera {camera}", hint=f"cameras 0..{cams.n_cameras - 1}")
        if not 0 <= frame < max(F, len(sim.joints)):
            raise InputError(f"no frame {frame}", hint=f"frames 0..{len(sim.joints) - 1}")
        io_full = cams.io[camera][min(frame, len(cams.io[camera]) - 1)]
        check_radial(cams.models[camera], io_full)
        self.size = (int(size[0]), int(size[1]))
        self.io = scaled_parameters(io_full, cams.image_size[camera], self.size)
        self.R = cams.R[min(frame, cams.R.shape[0] - 1), camera]
        self.R_cv = FLIP @ self.R
        self.X0 = cams.X0[camera]
        self.f = float(np.sqrt(self.io[0] * self.io[1]))
        self.h = float(scene.normal @ self.X0)         # height over the slope plane
        if self.h <= 0:
            raise InputError(f"camera {cams.names[camera]} is below the slope")


def _grid(fr: FrameGeometry, scene: SlopeScene, clip, t):
    """Level of detail, ground flag and sky colour at the coarse nodes
    (normalised coordinates t (ny, nx, 2))."""
    shape = t.shape[:2]
    t = t.reshape(-1, 2)
    # world directions d = R_cv^T (t, 1); their components along n, e_fall,
    # e_lat and Z are linear in (t, 1)
    A = fr.R_cv @ np.column_stack([scene.normal, scene.e_fall, scene.e_lat, [0.0, 0.0, 1.0]])
    comp = t @ A[:2] + A[2]
    nd, ef, el_, dz = comp.T
    ground = nd < -1e-9
    s = -fr.h / np.where(ground, nd, -1.0)
    norm2 = 1.0 + np.einsum("ij,ij->i", t, t)
    with np.errstate(divide="ignore"):
        # footprint F = h |d| / (f (n.d)^2); lambda = log2(1.5 F / texel)
        lam = 0.5 * np.log2(norm2) - 2.0 * np.log2(np.maximum(np.abs(nd), 1e-15)) \
            + np.log2(1.5 * fr.h / (fr.f * scene.texel))
        reach = np.log2(np.maximum(np.maximum(np.abs(s * ef), np.abs(s * el_)), 1e-9)) \
            + (1.0 - np.log2((clip.grid / 2 - 10) * scene.texel))
    top = np.float32(scene.levels - 1e-3)              # floor(lambda) <= levels - 1
    lam = np.where(ground, np.clip(np.maximum(lam, reach), 0.0, top), top).astype(np.float32)
    el = np.clip(dz / np.sqrt(norm2), 0.0, 1.0)
    mix = np.sqrt(np.clip(el / 0.5, 0.0, 1.0))[:, None]
    sky = np.rint(_SKY_HORIZON * (1 - mix) + _SKY_ZENITH * mix).astype(np.uint8)
    return lam.reshape(shape), ground.reshape(shape), sky.reshape(shape + (3,))


def background(fr: FrameGeometry, scene: SlopeScene, clip) -> np.ndarray:
    W, H = fr.size
    io = fr.io
    w = _work(fr.size, io)
    B, C = w.buf, _CELL
    t_g, corr = _corrections(w, io)
    lam_g, ground_g, sky_g = _grid(fr, scene, clip, t_g)
    sky = cv2.resize(sky_g, (w.Wx, w.Hx), dst=B["sky"], interpolation=cv2.INTER_LINEAR)
    out = sky[C:C + H, C:C + W].copy()
    if not ground_g.any():
        return out
    gh, gw = ground_g.shape
    # cells whose 3 x 3 neighbourhood mixes ground and sky hold the horizon
    pad = np.pad(ground_g, 1, mode="edge")
    win = np.stack([pad[a:a + gh, b:b + gw] for a in range(3) for b in range(3)])
    mixed = win.any(0) & ~win.all(0)
    rows = np.flatnonzero((ground_g | mixed).any(axis=1))
    y0, y1 = C * rows[0], C * (rows[-1] + 1)                      # extended rows
    rs = slice(y0, y1)
    corr_up = cv2.resize(corr, (w.Wx, w.Hx), dst=B["corr"], interpolation=cv2.INTER_LINEAR)
    q = cv2.add(w.offsets[rs], corr_up[rs], dst=B["q"][rs])         # undistorted px offsets
    # plane coordinates (in finest texels) relative to the foot point:
    # (dp, dq) = -h (e.d) / (n.d), d = R_cv^T (q_x / fx, q_y / fy, 1)
    M = np.vstack([fr.h * scene.e_fall / scene.texel, fr.h * scene.e_lat / scene.texel,
                   -scene.normal]) @ fr.R_cv.T
    P = cv2.perspectiveTransform(q, M @ np.diag([1.0 / io[0], 1.0 / io[1], 1.0]),
                                 dst=B["P"][rs])
    lam = cv2.resize(lam_g, (w.Wx, w.Hx), dst=B["lam"], interpolation=cv2.INTER_LINEAR)[rs]
    n, half = clip.grid, clip.grid // 2
    lev, frac = B["lev"][rs], B["frac"][rs]
    np.copyto(lev, lam, casting="unsafe")               # floor: 0 <= lam < levels
    np.subtract(lam, lev, out=frac)
    # node coordinates P 2^-lev (exact: the float exponent minus lev), centred
    lev2 = cv2.merge([lev, lev], dst=B["lev2"][rs])
    e2 = np.left_shift(lev2, 23, out=B["e2"][rs], dtype=np.int32)
    m = B["m"][rs]
    np.subtract(P.view(np.int32), e2, out=m.view(np.int32))
    np.clip(m, -half, n - 1 - half, out=m)
    m[..., 0] += np.float32(half)
    row = np.multiply(lev, np.float32(n), out=B["row"][rs])
    row += np.float32(half)
    m[..., 1] += row
    S = cv2.remap(clip.atlas, m, None, cv2.INTER_LINEAR, dst=B["S"][rs])
    a = cv2.extractChannel(S, 0, dst=B["a"][rs])
    b = cv2.extractChannel(S, 1, dst=B["b"][rs])
    wf = np.subtract(np.float32(1.0), frac, out=B["wfrac"][rs])
    grey = cv2.blendLinear(b, a, frac, wf, dst=B["grey"][rs])
    snow = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR, dst=B["snow"][rs])
    # paste: pure ground cells copied, horizon cells blended (anti-aliased)
    n_cv = fr.R_cv @ scene.normal
    gxy = np.array([n_cv[0] / io[0], n_cv[1] / io[1]])
    norm = np.float32(np.hypot(*gxy))

    def real(a0, a1, n):               # extended -> image pixel range, clipped
        return max(a0 - C, 0), min(a1 - C, n)

    for r in rows:
        ya, yb = real(C * r, C * r + C, H)
        if ya >= yb:
            continue
        sa, sb = ya + C - y0, yb + C - y0                            # rows in snow/q
        ground_row, mixed_row = ground_g[r], mixed[r]
        if not mixed_row.any():
            if ground_row.any():
                out[ya:yb] = snow[sa:sb, C:C + W]
            continue
        mc = np.flatnonzero(mixed_row)
        xa, xb = real(C * mc[0], C * (mc[-1] + 1), W)
        if xa > 0 and ground_row[mc[0] - 1]:
            out[ya:yb, :xa] = snow[sa:sb, C:C + xa]
        if xb < W and ground_row[mc[-1] + 1]:
            out[ya:yb, xb:] = snow[sa:sb, C + xb:C + W]
        if xa >= xb:
            continue
        qq = q[sa:sb, C + xa:C + xb]
        dist = (qq[..., 0] * np.float32(gxy[0]) + qq[..., 1] * np.float32(gxy[1])
                + np.float32(n_cv[2])) / norm
        alpha = np.clip(0.5 - dist, 0.0, 1.0).astype(np.float32)
        out[ya:yb, xa:xb] = cv2.blendLinear(snow[sa:sb, C + xa:C + xb], out[ya:yb, xa:xb],
                                            alpha, 1.0 - alpha)
    return out

