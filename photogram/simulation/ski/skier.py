"""A kinematic model of a giant-slalom skier (SKI24 joints) for the simulator.

Given, per frame, the point between the boots on the snow ``P``, the
direction of travel ``d`` (in the slope plane), the slope normal ``n`` and
the lean angle ``phi`` (positive: leaning to the left of ``d``), the body
is built from fixed segment lengths, so that every limb of the skeleton has
a constant length:

1. skis parallel to ``d`` on the snow, ``stance`` apart across the slope,
   edged by the lean angle; boot points (toes, heel) and ankles above the
   ski along the edged ski normal; tips and tails on the ski line;
2. the pelvis on the leaned body axis ``u = cos(phi) n + sin(phi) l``
   (``l = n x d``, left), lowered where a leg would be overstretched; the
   inside leg (nearer the turn centre) is automatically the more flexed;
3. knees by two-link inverse kinematics, bending forward;
4. trunk flexed forward by ``trunk_flexion``, head more upright, arms forward
   and out (elbows by inverse kinematics), poles trailing backwards.

Lengths scale with the athlete's height (1.80 m nominal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.mocap.body.skeleton import SKI24

__all__ = ["SkierBody", "pose_skier"]


@dataclass
class SkierBody:
    """Segment lengths (m) of a 1.80 m athlete, scaled by ``height / 1.8``."""

    height: float = 1.80
    thigh: float = 0.44
    shank: float = 0.44
    pelvis: float = 0.19          # hip joint distance
    trunk: float = 0.56           # mid-hips to neck (upper neck)
    shoulder_drop: float = 0.07   # neck to shoulder line along the trunk
    shoulder_width: float = 0.38
    head: float = 0.20            # neck to head top
    upper_arm: float = 0.30
    forearm: float = 0.27
    pole: float = 1.12            # wrist to basket
    ski_front: float = 1.02       # boot centre to ski tip
    ski_back: float = 0.90        # boot centre to ski tail
    boot_front: float = 0.15      # boot centre to toes
    boot_back: float = 0.16       # boot centre to heel
    boot_height: float = 0.07     # ski line to toes/heel
    ankle_height: float = 0.16    # ski line to ankle
    stance: float = 0.26          # distance of the boot centres across the slope

    def scaled(self) -> "SkierBody":
        k = self.height / 1.80
        vals = {f: getattr(self, f) * (k if f not in ("height", "ski_front", "ski_back",
                                                      "pole") else 1.0)
                for f in self.__dataclass_fields__}
        vals["height"] = self.height
        return SkierBody(**vals)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rot(v, axis, angle):
    """Rotate vectors v (F,3) about unit axes (F,3) by angles (F,) (Rodrigues)."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return v * c + np.cross(axis, v) * s + axis * np.sum(axis * v, -1, keepdims=True) * (1 - c)


def _two_link(root, end, l1, l2, bend):
    """Middle joint of a two-link chain root-end bending towards ``bend``."""
    e = end - root
    D = np.linalg.norm(e, axis=-1)
    e = e / D[:, None]
    cosg = np.clip((l1 ** 2 + D ** 2 - l2 ** 2) / (2 * l1 * D), -1, 1)
    q = bend - np.sum(bend * e, -1, keepdims=True) * e
    q = _unit(q)
    return root + l1 * (cosg[:, None] * e + np.sqrt(1 - cosg ** 2)[:, None] * q)


def pose_skier(P, d, n, phi, body: SkierBody, *, hip_height, trunk_flexion, fore_aft,
               arm_swing, counter_rotation=None) -> np.ndarray:
    """SKI24 joints (F, 24, 3) of the skier (module doc).

    ``hip_height`` (F,): pelvis above the snow along the body axis (m, before
    the leg-length limit); ``trunk_flexion`` (F,) rad; ``fore_aft`` (F,) m
    of the pelvis along ``d``; ``arm_swing`` (F,) rad of the arms and poles.
    """
    b = body.scaled()
    F = len(P)
    n = np.broadcast_to(n, (F, 3))
    d = _unit(d - np.sum(d * n, -1, keepdims=True) * n)
    lat = np.cross(n, d)                                   # left
    u = np.cos(phi)[:, None] * n + np.sin(phi)[:, None] * lat
    lat_b = np.cos(phi)[:, None] * lat - np.sin(phi)[:, None] * n
    nski = u                                               # skis edged like the body
    J = {}
    for side, sgn in (("l_", 1.0), ("r_", -1.0)):
        c = P + sgn * 0.5 * b.stance * lat
        J[side + "ski_tip"] = c + b.ski_front * d
        J[side + "ski_tail"] = c - b.ski_back * d
        J[side + "toes"] = c + b.boot_front * d + b.boot_height * nski
        J[side + "heel"] = c - b.boot_back * d + b.boot_height * nski
        J[side + "ankle"] = c + b.ankle_height * nski
    reach = 0.985 * (b.thigh + b.shank)
    hc = P + hip_height[:, None] * u + fore_aft[:, None] * d
    for _ in range(3):                                     # keep the legs bent
        worst = np.zeros(F)
        for side, sgn in (("l_", 1.0), ("r_", -1.0)):
            hip = hc + sgn * 0.5 * b.pelvis * lat_b
            worst = np.maximum(worst, np.linalg.norm(J[side + "ankle"] - hip, axis=-1) - reach)
        hc = hc - np.maximum(worst, 0)[:, None] * u
    for side, sgn in (("l_", 1.0), ("r_", -1.0)):
        J[side + "hip"] = hc + sgn * 0.5 * b.pelvis * lat_b
        J[side + "knee"] = _two_link(J[side + "hip"], J[side + "ankle"], b.thigh, b.shank,
                                     d + 0.15 * u)
    rot = np.zeros(F) if counter_rotation is None else counter_rotation
    t_dir = _rot(u, lat_b, -trunk_flexion)                 # forward flexion about lat_b
    fwd_b = np.cross(lat_b, t_dir)
    lat_s = _rot(lat_b, t_dir, rot)
    fwd_s = np.cross(lat_s, t_dir)
    J["neck"] = hc + b.trunk * t_dir
    head_dir = _rot(u, lat_b, -(trunk_flexion - 0.45))
    J["head"] = J["neck"] + b.head * head_dir
    s_c = J["neck"] - b.shoulder_drop * t_dir
    for side, sgn in (("l_", 1.0), ("r_", -1.0)):
        sh = s_c + sgn * 0.5 * b.shoulder_width * lat_s
        J[side + "shoulder"] = sh
        reach_v = (0.30 * fwd_s + sgn * 0.16 * lat_s - 0.22 * t_dir)
        reach_v = _rot(reach_v, lat_s, arm_swing)
        hand = sh + 0.74 * (b.upper_arm + b.forearm) * _unit(reach_v)
        J[side + "hand"] = hand
        J[side + "elbow"] = _two_link(sh, hand, b.upper_arm, b.forearm,
                                      -fwd_s + sgn * 0.8 * lat_s - 0.3 * t_dir)
        pole_dir = _unit(-0.85 * fwd_b - 0.45 * t_dir + sgn * 0.12 * lat_b)
        pole_dir = _rot(pole_dir, lat_b, 0.6 * arm_swing)
        J[side + "pole"] = hand + b.pole * pole_dir
    return np.stack([J[name] for name in SKI24.joints], axis=1)
