"""The scenery of the simulated giant-slalom slope, for rendering camera images.

THE SCENE IS SIMULATED (no real images are involved). Built deterministically
from a seed and a :class:`~photogram.simulation.ski.simulate.SkiSimulation`:

* **slope**: the simulator's plane ``Z = -tan(alpha) X`` (infinite), with the
  plane axes ``e_fall`` (downhill) and ``e_lat`` and the normal ``n``; plane
  coordinates ``(p, q) = (e_fall . X, e_lat . X)``;
* **snow texture** on the plane: value noise (hashed lattice values,
  bilinear) summed over octaves with texels of ``texel * 2**k`` (3 cm to
  120 m by default), darker ski tracks of earlier racers near the racing
  line (pairs of grooves 0.17 m apart, about 7 cm wide) and of free skiers
  across the slope, and dark spots (dye, dirt); stored per camera as a
  clipmap (:mod:`photogram.simulation.ski.texture`), sampled per pixel at the level
  of detail of the ground footprint (:mod:`photogram.simulation.ski.backdrop`);
* **objects** (vertical polygons, drawn with the full camera model):
  giant-slalom gates at the apexes of the racing line (inner and outer gate,
  red and blue alternating per turn, each two poles with a panel), fences
  (posts and two bars, with advertising banners) along both sides of the
  piste at ``|q| = 44 m``, a forest of fir trees beyond ``|q| = 50 m`` and
  a few groups of trees beside the course, kept out of every camera's
  lines of sight to the athlete; trees and poles are billboards turned to
  each camera (exact for a camera that only rotates);
* the sky (a smooth gradient, drawn by the renderer) lies beyond the
  horizon of the slope plane.

Assumed: the slope is one plane without relief, the lighting is uniform
(no shadows), and nothing moves but the skier. ``texture=False`` gives a
blank scene (uniform snow, sky only) for testing featureless views.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.simulation.ski.simulate import SkiSimulation
from photogram.simulation.ski.texture import EXTRA_OCTAVES, Clipmap, build_clipmap

__all__ = ["SlopeScene", "CameraObjects", "build_scene"]


@dataclass
class CameraObjects:
    """The polygons of the scene as seen by one camera, far to near.

    ``vertices`` (V, 3) world; polygon ``i`` is ``vertices[start[i]:start[i+1]]``
    with colour ``colour[i]`` (BGR); ``centre`` (P, 3) and ``radius`` (P,)
    bound each polygon (for culling).
    """

    vertices: np.ndarray
    start: np.ndarray
    colour: np.ndarray
    centre: np.ndarray
    radius: np.ndarray

    def __post_init__(self):
        self.colour_list = [tuple(float(v) for v in c) for c in self.colour]

    @property
    def n_polygons(self) -> int:
        return len(self.colour)


@dataclass
class SlopeScene:
    """Slope, texture and objects of one simulated session (see the module doc)."""

    seed: int
    texture: bool
    alpha: float
    e_fall: np.ndarray
    e_lat: np.ndarray
    normal: np.ndarray
    texel: float = 0.03
    levels: int = 10
    grid: int = 512
    amplitude: np.ndarray = None          # per octave (levels + extra), grey levels
    tracks: list = field(default_factory=list)      # [(points (n,2) plane m, width m, depth)]
    spots: np.ndarray = None              # (S, 4): p, q, radius m, depth
    groups: list = field(default_factory=list)      # [(anchor (3,), [part, ...])]
    skier_colours: dict = field(default_factory=dict)
    _clipmaps: dict = field(default_factory=dict, repr=False)
    _objects: dict = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------
    def plane_coordinates(self, X) -> np.ndarray:
        """(..., 2) plane coordinates (p, q) of world points (..., 3)."""
        X = np.asarray(X, dtype=float)
        return np.stack([X @ self.e_fall, X @ self.e_lat], -1)

    def plane_point(self, p, q) -> np.ndarray:
        """World points (..., 3) of plane coordinates."""
        p, q = np.broadcast_arrays(np.asarray(p, float), np.asarray(q, float))
        return p[..., None] * self.e_fall + q[..., None] * self.e_lat

    def clipmap(self, X0) -> Clipmap:
        """The clipmap of a camera at ``X0`` (computed once, then cached)."""
        key = tuple(np.round(np.asarray(X0, float), 6))
        if key not in self._clipmaps:
            self._clipmaps[key] = build_clipmap(self, np.asarray(X0, float))
        return self._clipmaps[key]

    def camera_objects(self, X0) -> CameraObjects:
        """The polygons seen from ``X0``, far to near (cached)."""
        key = tuple(np.round(np.asarray(X0, float), 6))
        if key not in self._objects:
            self._objects[key] = _camera_objects(self, np.asarray(X0, float))
        return self._objects[key]


# --------------------------------------------------------------------------
# objects
# --------------------------------------------------------------------------
_RED, _BLUE = (40, 30, 200), (190, 80, 20)
_FENCE = [(20, 120, 240), (30, 30, 210), (200, 120, 0)]
_TREE_DARK = np.array([30, 70, 25], float)


def _tree_outline(h: float, w: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """Fir silhouette (three tiers) and trunk, local (u, v) in m."""
    tiers = [(1.0, 0.62, 0.45), (0.72, 0.36, 0.75), (0.45, 0.10, 1.0)]
    right = [(0.0, h)]
    for top, bottom, half in tiers:
        jag = rng.uniform(0.9, 1.1)
        right.append((0.5 * w * half * jag, bottom * h))
        right.append((0.5 * w * half * 0.55, bottom * h + 0.03 * h))
    right = right[:-1]
    right = np.array(right)
    left = right[1:][::-1] * [-1, 1]
    crown = np.vstack([right, left])
    tw = max(0.08 * w, 0.15)
    trunk = np.array([[-tw / 2, 0.0], [tw / 2, 0.0], [tw / 2, 0.12 * h], [-tw / 2, 0.12 * h]])
    return crown, trunk


def _course(sim: SkiSimulation, e_fall, e_lat):
    """Racing line q(p) = a sin(w p) + b cos(w p) + c fitted to the centre of
    mass of the first run (periodic continuation beyond it)."""
    n = sim.info.get("frames_per_run", len(sim.joints))
    com = sim.com[:n]
    p, q = com @ e_fall, com @ e_lat
    gd = float(sim.info.get("gate_distance", [np.ptp(p) / 3])[0])
    w = np.pi / gd
    A = np.stack([np.sin(w * p), np.cos(w * p), np.ones_like(p)], -1)
    coef = np.linalg.lstsq(A, q, rcond=None)[0]
    amp = float(np.hypot(coef[0], coef[1]))
    phase = float(np.arctan2(coef[1], coef[0]))
    line = lambda pp: coef[0] * np.sin(w * pp) + coef[1] * np.cos(w * pp) + coef[2]  # noqa: E731
    return line, w, phase, amp, (float(p.min()), float(p.max()))


def build_scene(sim: SkiSimulation, seed: int = 0, texture: bool = True) -> SlopeScene:
    """The scene of a simulated session (module doc), deterministic in ``seed``.

    Parameters
    ----------
    sim : SkiSimulation
        Gives the slope angle (``sim.info["slope_deg"]``), the course (the
        truth joints of the first run) and the cameras (billboards).
    seed : int
        Seed of the texture, the tracks and the object placement.
    texture : bool
        False: a blank scene (uniform snow, sky; no tracks and no objects).

    Returns
    -------
    SlopeScene
    """
    alpha = np.deg2rad(float(sim.info.get("slope_deg", 20.0)))
    e_fall = np.array([np.cos(alpha), 0.0, -np.sin(alpha)])
    e_lat = np.array([0.0, 1.0, 0.0])
    normal = np.cross(e_fall, e_lat)
    rng = np.random.default_rng([seed, 0x5C3E])
    levels = 10
    amplitude = np.array([7, 7, 8, 8, 8, 8, 7, 6, 5, 4, 6, 6], float)[:levels + EXTRA_OCTAVES + 1]
    amplitude = np.pad(amplitude, (0, levels + EXTRA_OCTAVES + 1 - len(amplitude)), "edge")
    scene = SlopeScene(seed=seed, texture=texture, alpha=alpha, e_fall=e_fall, e_lat=e_lat,
                       normal=normal, levels=levels, amplitude=amplitude)
    scene.skier_colours = {"suit": (30, 30, 200), "legs": (40, 20, 20), "helmet": (230, 230, 230),
                           "skin": (120, 150, 200), "ski": (20, 200, 230), "pole": (60, 60, 60)}
    if not texture:
        return scene
    line, w, phase, amp, (p0, p1) = _course(sim, e_fall, e_lat)
    # -- ski tracks: earlier racers near the line, free skiers across ---------
    pp = np.arange(p0 - 150.0, p1 + 150.0, 0.4)
    for _ in range(24):
        off = rng.normal(0.0, 0.8)
        wob = np.convolve(rng.normal(0, 1, len(pp)), np.ones(60) / 60, "same") * 1.5
        q = line(pp) * rng.uniform(0.9, 1.1) + off + wob
        for side in (-0.085, 0.085):
            scene.tracks.append((np.stack([pp, q + side], -1), 0.07, rng.uniform(15, 30)))
    for _ in range(40):
        start = np.array([rng.uniform(p0 - 120, p1 + 120), rng.uniform(-45, 45)])
        ang = rng.uniform(-1.2, 1.2)
        s = np.arange(0.0, rng.uniform(20, 120), 0.4)
        curve = np.cumsum(np.full(len(s), 0.4)[:, None]
                          * np.stack([np.cos(ang + 0.4 * np.sin(s / rng.uniform(6, 15))),
                                      np.sin(ang + 0.4 * np.sin(s / rng.uniform(6, 15)))], -1), 0)
        pts = start + curve
        for side in (-0.09, 0.09):
            scene.tracks.append((pts + [0, side], 0.08, rng.uniform(12, 25)))
    ns = 4000
    scene.spots = np.stack([rng.uniform(p0 - 200, p1 + 200, ns), rng.uniform(-60, 60, ns),
                            rng.uniform(0.03, 0.4, ns), rng.uniform(8, 30, ns)], -1)
    # -- gates at the apexes of the racing line ------------------------------
    k0 = int(np.floor(((p0 - 60.0) * w + phase) / np.pi - 0.5))
    k1 = int(np.ceil(((p1 + 60.0) * w + phase) / np.pi - 0.5))
    up = np.array([0.0, 0.0, 1.0])
    for k in range(k0, k1 + 1):
        pa = ((k + 0.5) * np.pi - phase) / w
        qa = line(pa)
        sgn = np.sign(qa - line(pa + np.pi / (2 * w)))     # outward at the apex
        colour = _RED if k % 2 else _BLUE
        for q_inner, outward in ((qa - sgn * 0.9, -sgn), (qa + sgn * 5.5, sgn)):
            a = scene.plane_point(pa, q_inner)
            b = scene.plane_point(pa, q_inner + outward * 0.75)
            pole = np.array([[-0.016, 0], [0.016, 0], [0.016, 1.85], [-0.016, 1.85]])
            panel = np.array([a + 0.95 * up, b + 0.95 * up, b + 1.75 * up, a + 1.75 * up])
            stripe = np.array([a + 1.45 * up, b + 1.45 * up, b + 1.6 * up, a + 1.6 * up])
            scene.groups.append(((a + b) / 2 + up, [
                _board(a, pole, colour), _board(b, pole, colour), _flat(panel, colour),
                _flat(stripe, (235, 235, 235))]))
    # -- fences with banners --------------------------------------------------
    for side in (-44.0, 44.0):
        posts = np.arange(p0 - 100.0, p1 + 100.0, 3.0)
        colour = _FENCE[int(rng.integers(len(_FENCE)))]
        post = np.array([[-0.04, 0], [0.04, 0], [0.04, 1.2], [-0.04, 1.2]])
        for pa in posts:
            base = scene.plane_point(pa, side)
            scene.groups.append((base + 0.6 * up, [_board(base, post, (60, 60, 60))]))
        for pa, pb in zip(posts[:-1], posts[1:]):
            a, b = scene.plane_point(pa, side), scene.plane_point(pb, side)
            bars = [_flat(np.array([a + z0 * up, b + z0 * up, b + z1 * up, a + z1 * up]), colour)
                    for z0, z1 in ((0.35, 0.45), (1.0, 1.12))]
            scene.groups.append(((a + b) / 2 + up * 0.5, bars))
        for pa in np.arange(p0 - 90.0, p1 + 90.0, rng.uniform(12, 18)):
            a, b = scene.plane_point(pa, side), scene.plane_point(pa + 3.0, side)
            ground = tuple(int(v) for v in rng.integers(0, 256, 3))
            base_quad = np.array([a + 0.45 * up, b + 0.45 * up, b + 1.0 * up, a + 1.0 * up])
            parts = [_flat(base_quad, ground)]
            ink = tuple(int(255 - v) for v in ground)
            x = 0.15
            while x < 2.7:
                wdt = rng.uniform(0.1, 0.35)
                z0, z1 = rng.uniform(0.52, 0.65), rng.uniform(0.8, 0.93)
                u0, u1 = a + (b - a) * x / 3.0, a + (b - a) * min(x + wdt, 2.85) / 3.0
                quad = np.array([u0 + z0 * up, u1 + z0 * up, u1 + z1 * up, u0 + z1 * up])
                parts.append(_flat(quad, ink))
                x += wdt + rng.uniform(0.06, 0.2)
            # banners hang on the inner side of the fence
            shift = -np.sign(side) * 0.05 * e_lat
            scene.groups.append(((a + b) / 2 + up * 0.7 + shift,
                                 [(kind, data + shift if kind == "flat" else data, c)
                                  for kind, data, c in parts]))
    # -- forest beyond the piste and groups of trees beside the course ------
    area = [(p0 - 300.0, p1 + 300.0, 50.0, 80.0), (p0 - 300.0, p1 + 300.0, -80.0, -50.0)]
    pts = []
    for a0, a1, b0, b1 in area:
        n = int((a1 - a0) * (b1 - b0) / 45.0)
        pts.append(np.stack([rng.uniform(a0, a1, n), rng.uniform(b0, b1, n)], -1))
    for _ in range(8):
        c = np.array([rng.uniform(p0 - 40, p1 + 40), rng.choice([-1, 1]) * rng.uniform(20, 40)])
        pts.append(c + rng.normal(0, 3.0, (int(rng.integers(3, 9)), 2)))
    pts = np.vstack(pts)
    sights = _sight_lines(sim, e_fall, e_lat)
    for p, q in pts:
        h = rng.uniform(7.0, 22.0)
        crown, trunk = _tree_outline(h, h * rng.uniform(0.3, 0.42), rng)
        if _blocks(np.array([p, q]), 0.5 * np.ptp(crown[:, 0]) + 1.5, sights):
            continue
        base = scene.plane_point(p, q) - 0.3 * up
        shade = np.clip(_TREE_DARK * rng.uniform(0.6, 1.4), 0, 255)
        scene.groups.append((base + 0.5 * h * up, [_board(base, trunk, (40, 60, 90)),
                                                    _board(base, crown, tuple(shade))]))
    return scene


def _sight_lines(sim: SkiSimulation, e_fall, e_lat):
    """Segments (S, 2, 2) in plane coordinates from every camera to the
    athlete (every 5th frame)."""
    cams = np.stack([sim.cameras.X0 @ e_fall, sim.cameras.X0 @ e_lat], -1)
    com = sim.com[::5]
    ath = np.stack([com @ e_fall, com @ e_lat], -1)
    a = np.repeat(cams, len(ath), axis=0)
    b = np.tile(ath, (len(cams), 1))
    return np.stack([a, b], 1)


def _blocks(point, radius, segments) -> bool:
    """Whether a disc in plane coordinates comes within ``radius`` of a
    segment (or of a camera)."""
    a, b = segments[:, 0], segments[:, 1]
    ab = b - a
    w = np.clip(np.sum((point - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-12),
                0.0, 1.0)
    return bool(np.any(np.linalg.norm(a + w[:, None] * ab - point, axis=1) < radius))


def _flat(vertices, colour):
    return ("flat", np.asarray(vertices, float), tuple(float(c) for c in colour))


def _board(base, outline, colour):
    return ("board", (np.asarray(base, float), np.asarray(outline, float)),
            tuple(float(c) for c in colour))


def _camera_objects(scene: SlopeScene, X0: np.ndarray) -> CameraObjects:
    """All polygons of the scene from ``X0``: groups sorted far to near, the
    parts of a group in their order; billboards turned to face the camera."""
    up = np.array([0.0, 0.0, 1.0])
    dist = [np.linalg.norm(anchor - X0) for anchor, _ in scene.groups]
    polys, colours = [], []
    for g in np.argsort(-np.asarray(dist), kind="stable"):
        for kind, data, colour in scene.groups[g][1]:
            if kind == "board":
                base, outline = data
                side = np.cross(base - X0, up)
                norm = np.linalg.norm(side)
                side = side / norm if norm > 0 else np.array([1.0, 0.0, 0.0])
                data = base + outline[:, :1] * side + outline[:, 1:] * up
            polys.append(data)
            colours.append(colour)
    if not polys:
        return CameraObjects(np.zeros((0, 3)), np.zeros(1, int), np.zeros((0, 3)),
                             np.zeros((0, 3)), np.zeros(0))
    start = np.concatenate([[0], np.cumsum([len(p) for p in polys])])
    centre = np.array([p.mean(0) for p in polys])
    radius = np.array([np.linalg.norm(p - c, axis=1).max() for p, c in zip(polys, centre)])
    return CameraObjects(np.vstack(polys), start, np.asarray(colours, float), centre, radius)
