"""The snow texture of the simulated slope, as clipmaps around each camera.

THE TEXTURE IS SIMULATED. Value noise on the slope plane: octave ``k`` has
uniform random values (an integer hash of the lattice node, the octave and
the seed) on a world lattice of ``texel * 2**k`` m, bilinearly
interpolated, times the octave's amplitude; plus ski tracks and spots
(:class:`photogram.simulation.ski.scene.SlopeScene`), rasterised per level with
anti-aliasing (band-limited: lines thinner than a node are drawn one node
wide with proportionally less contrast).

Per camera the texture is a *clipmap*: ``levels`` grids of ``grid x grid``
nodes with a spacing of ``texel * 2**l`` centred on the camera's foot point;
level ``l`` holds the octaves ``>= l``, refined from the coarser level by
exact bilinear interpolation, so that blending two levels is seamless.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Clipmap", "build_clipmap", "value_noise_nodes", "SNOW_GREY", "EXTRA_OCTAVES"]

SNOW_GREY = 214.0
EXTRA_OCTAVES = 2            # coarser octaves than the last level (large brightness waves)


@dataclass
class Clipmap:
    """The snow texture around one camera's foot point.

    ``atlas`` is ``(levels * grid, grid, 4)`` uint8: block ``l`` (rows
    ``l*grid`` to ``(l+1)*grid``) holds level ``l`` (channel 0) and level
    ``l + 1`` resampled on the nodes of level ``l`` (channel 1); channels 2
    and 3 are zero (four channels are resampled fastest). Node ``(row k,
    column i)`` of level ``l`` lies at the plane coordinates
    ``(p, q) = foot + (i - grid/2, k - grid/2) * spacing[l]``: the lattices
    are centred on the camera; the noise is sampled (bilinearly) from the
    world lattices, so all cameras see the same snow.
    """

    atlas: np.ndarray
    spacing: np.ndarray          # (levels,) m
    foot: np.ndarray             # (2,) plane coordinates of the foot point
    grid: int


def _hash(ix, iy, octave: int, seed: int) -> np.ndarray:
    """Uniform values in [-1, 1) of integer lattice nodes (float32)."""
    m = np.uint64(0xFFFFFFFF)
    with np.errstate(over="ignore"):
        h = (ix.astype(np.uint64) * np.uint64(0x8DA6B343)
             + iy.astype(np.uint64) * np.uint64(0xD8163841)
             + np.uint64((octave * 0xCB1AB31F + seed * 0x165667B1 + 0x9E3779B9) & 0xFFFFFFFF)) & m
        for mult, s1 in ((0x7FEB352D, 15), (0x846CA68B, 13)):
            h ^= h >> np.uint64(s1)
            h = (h * np.uint64(mult)) & m
        h ^= h >> np.uint64(16)
    return (h.astype(np.float64) * (2.0 / 2 ** 32) - 1.0).astype(np.float32)


def value_noise_nodes(i0: int, k0: int, n: int, octave: int, seed: int) -> np.ndarray:
    """Lattice values (n, n) of octave ``octave`` at nodes ``i0..i0+n-1``
    (columns, along p) and ``k0..k0+n-1`` (rows, along q)."""
    i = np.arange(i0, i0 + n, dtype=np.int64)
    k = np.arange(k0, k0 + n, dtype=np.int64)
    return _hash(i[None, :] + (1 << 31), k[:, None] + (1 << 31), octave, seed)


def _refine(coarse: np.ndarray, n: int) -> np.ndarray:
    """Bilinear values of a coarse level at the nodes of the next finer level
    (spacing halved, both centred on node n/2); exact (multiples of 0.5)."""
    x = ((np.arange(n) - n // 2) / 2.0 + n // 2).astype(np.float32)
    mx = np.ascontiguousarray(np.broadcast_to(x[None, :], (n, n)))
    my = np.ascontiguousarray(np.broadcast_to(x[:, None], (n, n)))
    return cv2.remap(coarse, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def _octave(scene, level: int, spacing: float, foot, n: int) -> np.ndarray:
    """Octave ``level`` of the value noise (bilinear on its world lattice of
    ``spacing``) at the camera-centred nodes ``foot + (j - n/2) spacing``."""
    u = foot / spacing - n // 2                  # world lattice coordinate of node 0
    first = np.floor(u).astype(np.int64)
    frac = (u - first).astype(np.float32)
    h = value_noise_nodes(int(first[0]), int(first[1]), n + 1, level, scene.seed)
    fx, fy = frac
    top = h[:-1, :-1] * (1 - fx) + h[:-1, 1:] * fx
    bottom = h[1:, :-1] * (1 - fx) + h[1:, 1:] * fx
    return top * (1 - fy) + bottom * fy


def build_clipmap(scene, X0: np.ndarray) -> Clipmap:
    n, L = scene.grid, scene.levels
    foot = scene.plane_coordinates(X0)
    top = L + EXTRA_OCTAVES
    spacing = scene.texel * 2.0 ** np.arange(top + 1)
    noise, full = None, {}
    for l in range(top, -1, -1):
        if scene.texture:
            lvl = _octave(scene, l, spacing[l], foot, n) * np.float32(scene.amplitude[l])
        else:
            lvl = np.zeros((n, n), np.float32)
        if noise is not None:
            lvl += _refine(noise, n)
        noise = lvl
        if l <= L:
            full[l] = lvl + _marks(scene, spacing[l], foot, n) if scene.texture else lvl
    atlas = np.zeros((L * n, n, 4), np.uint8)
    for l in range(L):
        atlas[l * n:(l + 1) * n, :, 0] = np.clip(np.rint(full[l] + SNOW_GREY), 0, 255)
        atlas[l * n:(l + 1) * n, :, 1] = np.clip(np.rint(_refine(full[l + 1], n) + SNOW_GREY),
                                                 0, 255)
    return Clipmap(atlas, spacing[:L], foot, n)


def _marks(scene, spacing: float, foot, n: int) -> np.ndarray:
    """Ski tracks and spots rasterised at one level (grey-level offsets),
    band-limited: lines thinner than a node are drawn one node wide with
    proportionally less contrast."""
    canvas = np.zeros((n, n), np.uint8)
    scale = 16.0 / spacing                                   # shift = 4
    origin = foot - (n // 2) * spacing                       # plane coordinates of node 0
    lo, hi = origin - 4 * spacing, origin + (n + 4) * spacing
    for pts, width, depth in scene.tracks:
        inside = np.all((pts >= lo) & (pts <= hi), axis=1)
        if not inside.any():
            continue
        k = width / spacing
        value = int(round(min(255.0, 255.0 * depth / 80.0 * min(1.0, k))))
        if value < 2:
            continue
        xy = np.rint((pts - origin) * scale).astype(np.int32)
        # split at runs outside the level to keep coordinates small
        idx = np.flatnonzero(inside)
        runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
        polys = [xy[max(r[0] - 1, 0):r[-1] + 2] for r in runs if len(r)]
        cv2.polylines(canvas, polys, False, value, max(1, int(round(k))), cv2.LINE_AA, 4)
    if scene.spots is not None and len(scene.spots):
        sp = scene.spots
        ok = np.all((sp[:, :2] >= lo) & (sp[:, :2] <= hi), axis=1)
        p, q, r, depth = sp[ok].T
        # the same float operations as one spot at a time (np.rint rounds
        # half to even like round()), then one cv2.circle per spot drawn
        k = r / spacing
        value = np.rint(np.minimum(255.0, 255.0 * depth / 80.0 * np.minimum(1.0, k * k)))
        cx = np.rint((p - origin[0]) * scale)
        cy = np.rint((q - origin[1]) * scale)
        rad = np.rint(np.maximum(k, 0.5) * 16)
        drawn = value >= 2
        for x, y, radius, v in zip(cx[drawn].astype(int).tolist(), cy[drawn].astype(int).tolist(),
                                   rad[drawn].astype(int).tolist(),
                                   value[drawn].astype(int).tolist()):
            cv2.circle(canvas, (x, y), radius, v, -1, cv2.LINE_AA, 4)
    return canvas.astype(np.float32) * np.float32(-80.0 / 255.0)


