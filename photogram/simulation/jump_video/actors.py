"""The moving things: the jumper (suit, helmet, skis, markers) at any time
within the shutter, and the bystanders walking in the background.

Object coordinates are hill coordinates in dm (X down the hill, Y to the
left looking down the hill, Z up), as :mod:`photogram.simulation.jump`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.simulation.designs import slope_height
from photogram.simulation.jump import N_EXPOSURES, jump_truth

__all__ = ["Parts", "JumperMotion", "jumper_parts", "bystander_parts", "WALKS"]

SUIT, SUIT_DARK, HELMET, BOOT, SKI = 42.0, 30.0, 78.0, 55.0, 88.0
MARKER_GREY = 245.0
SKI_WIDTH, SKI_THICKNESS = 1.0, 0.3          # dm


@dataclass
class Parts:
    """3D primitives of one instant: capsules (A, B (m, 3), radii rA, rB
    (m,), grey (m,)), convex solids given by their corner points (list of
    (k, 3) arrays with their greys), and bright discs (centres (p, 3),
    radius dm, names)."""

    A: np.ndarray
    B: np.ndarray
    rA: np.ndarray
    rB: np.ndarray
    grey: np.ndarray
    solids: list
    solid_grey: list
    disc_centres: np.ndarray
    disc_radius: float
    disc_names: list


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class JumperMotion:
    """The jumper of :func:`photogram.simulation.jump.jump_truth` at any
    time near an exposure.

    At the exposure times the positions are exactly the truth's; between
    them (within a shutter) each point moves on its second-order Taylor
    expansion, velocity and acceleration from central differences over the
    exposures: over a 1/200 s shutter this differs from the smooth path by
    well under 0.01 dm.
    """

    def __init__(self, n_exposures: int = N_EXPOSURES):
        self.truth = jump_truth(n_exposures)
        self.times = self.truth["times"]
        q = np.concatenate([self.truth["P"], self.truth["ski_tail"], self.truth["ski_tip"]],
                           axis=1)                                       # (n, 8, 3)
        self._q = q
        self._v = np.gradient(q, self.times, axis=0)
        self._a = np.gradient(self._v, self.times, axis=0)

    def pose(self, exposure: int, dt: float = 0.0):
        """(P (4, 3), tail (2, 3), tip (2, 3)) at ``times[exposure] + dt``."""
        q = self._q[exposure] + self._v[exposure] * dt + 0.5 * self._a[exposure] * dt * dt
        return q[:4], q[4:6], q[6:8]


def _ski_corners(tail, tip, right, up, n_along: int = 6):
    """Corner points (4 n_along, 3) of a flat ski box on the axis tail-tip."""
    s = np.linspace(0.0, 1.0, n_along)[:, None]
    axis = tail + s * (tip - tail)
    offs = np.array([a * SKI_WIDTH / 2 * right + b * SKI_THICKNESS / 2 * up
                     for a in (-1, 1) for b in (-1, 1)])
    return (axis[:, None, :] + offs[None]).reshape(-1, 3)


def jumper_parts(P, tail, tip, marker_radius: float, hidden=(), body: bool = True) -> Parts:
    """The jumper's body, skis and markers for one pose.

    Joints from the four points (dm): the ankles 1.2 above the bindings
    (perpendicular to the skis), boots 2.6 long and ~1.3 thick around the
    bindings (the binding markers sit on them), hips 0.9 either side of P2, shoulders 5.2
    along P2->P1 and 1.7 either side, knees a little bent, arms along the
    body pointing back; the helmet a ball of radius 1.25 at P1. The skis are
    boxes 1.0 wide and 0.3 thick centred on their axes. ``hidden`` names
    markers not drawn; ``body=False`` leaves only the markers.
    """
    names = [n for n in ("P1", "P2", "P3", "P4") if n not in hidden]
    idx = [int(n[1]) - 1 for n in names]
    if not body:
        empty = np.zeros((0, 3))
        return Parts(empty, empty, np.zeros(0), np.zeros(0), np.zeros(0), [], [], P[idx],
                     marker_radius, names)
    P3, P4, P2, P1 = P[2], P[3], P[1], P[0]
    O = 0.5 * (P3 + P4)
    right = _unit(P3 - P4)
    ax = _unit((tip - tail).sum(axis=0))
    up = _unit(np.cross(right, ax))
    if up[2] < 0:
        up = -up
    trunk = _unit(P1 - P2)
    sh = P2 + 5.2 * trunk
    caps = []                                     # (A, B, rA, rB, grey)
    for s, bind in ((1.0, P3), (-1.0, P4)):
        hip = P2 + 0.9 * s * right
        ankle = bind + 1.2 * up
        knee = 0.5 * (hip + ankle) + 0.35 * up
        toe = bind + 1.5 * ax + 0.25 * up
        heel = bind - 1.1 * ax + 0.35 * up
        shoulder = sh + 1.7 * s * right
        hand = shoulder - 6.2 * trunk + 0.5 * s * right - 0.6 * up
        elbow = 0.5 * (shoulder + hand) + 0.2 * s * right
        grey = SUIT if s < 0 else SUIT_DARK       # the far (right) side a little darker
        caps += [(hip, knee, 0.8, 0.6, grey), (knee, ankle, 0.55, 0.45, grey),
                 (heel, toe, 0.7, 0.6, BOOT), (ankle, heel, 0.6, 0.65, BOOT),
                 (shoulder, elbow, 0.45, 0.4, grey), (elbow, hand, 0.4, 0.35, grey)]
    caps += [(P2, sh, 1.3, 1.45, SUIT), (sh, P1 - 0.6 * trunk, 0.5, 0.5, SUIT),
             (P1, P1, 1.25, 1.25, HELMET)]
    solids = [_ski_corners(tail[k], tip[k], _unit(np.cross(up, tip[k] - tail[k])), up)
              for k in range(2)]
    A, B, rA, rB, g = (np.array(v, float) for v in zip(*caps))
    return Parts(A, B, rA, rB, g, solids, [SKI, SKI], P[idx], marker_radius, names)


#: Walks of the bystanders: start (X, Y) in dm, heading (unit, in X-Y),
#: speed dm/s, gait phase. On the far side of the landing slope (Y < 0,
#: beyond the flight path from the cameras): seen by all three cameras, near
#: the images of the flight path in S2 and S3.
WALKS = (
    ((470.0, -150.0), (0.8, 0.6), 13.0, 0.0),
    ((505.0, -175.0), (-1.0, 0.15), 11.0, 1.3),
)
PERSON, JACKET, FACE, PATCH = 48.0, 62.0, 120.0, 238.0


def bystander_parts(k: int, t: float) -> Parts:
    """Walk ``k`` of :data:`WALKS` at time ``t`` (s from the first
    exposure): a dark person 1.75 m tall standing on the slope, legs and
    arms swinging at 0.9 strides per second, with a bright reflective patch
    (radius 0.45 dm) on the jacket's side facing the cameras (+Y)."""
    (x0, y0), (hx, hy), speed, phase = WALKS[k]
    h = np.array([hx, hy, 0.0]) / np.hypot(hx, hy)
    side = np.array([-h[1], h[0], 0.0])
    foot = np.array([x0, y0, 0.0]) + speed * t * h
    foot[2] = float(slope_height(foot[0]))
    z = np.array([0.0, 0.0, 1.0])
    swing = 0.35 * np.sin(2 * np.pi * 0.9 * t + phase)
    hip, shoulder, head = foot + 9.0 * z, foot + 14.5 * z, foot + 16.5 * z
    caps = []
    for s in (1.0, -1.0):
        f = foot + 0.8 * s * side + 8.5 * np.tan(s * swing) * h
        hand = shoulder + 1.9 * s * side - 6.0 * z - 6.0 * np.tan(s * swing) * h
        caps += [(hip + 0.8 * s * side, f, 0.75, 0.5, PERSON),
                 (shoulder + 1.9 * s * side, hand, 0.45, 0.4, JACKET)]
    caps += [(hip, shoulder, 1.5, 1.8, JACKET), (head, head, 1.0, 1.0, FACE)]
    A, B, rA, rB, g = (np.array(v, float) for v in zip(*caps))
    patch = shoulder - 1.5 * z + np.array([0.0, 1.9, 0.0])      # on the jacket, +Y side
    return Parts(A, B, rA, rB, g, [], [], patch[None], 0.45, [f"B{k + 1}"])
