"""Simulated giant-slalom runs filmed by pan-tilt-zoom cameras, with truth.

THE DATA OF THIS MODULE ARE SIMULATED. The scene (all lengths in m, world
Z up, X horizontal downhill, Y to the left):

* **slope** inclined by ``slope_deg`` (20 deg): surface ``Z = -tan(alpha) X``,
  normal ``n = (sin alpha, 0, cos alpha)``;
* **run**: three turns on a sinusoidal line across the fall line, lateral
  amplitude from a turn radius of about 23 m at the apex, the gate distance
  chosen so that the run fills ``frames_per_run`` frames at 50 fps; speed
  rising from about 15.5 to 19 m/s and dropping by 0.5 m/s in each turn;
  lean angle from the centripetal acceleration, ``tan(phi) = v^2 kappa /
  (g cos alpha)``, smoothed; pelvis lower at the turn apex; the skier of
  :mod:`photogram.simulation.ski.skier` (24 joints, skis and poles) with a random
  height of 1.80 m +- 3 %;
* **cameras**: six pan-tilt-zoom cameras on a circle of 40 m radius around
  the middle of the course (neighbours 34-46 m apart), 1.6 m above the
  snow, 1920 x 1080 px, OpenCV model with k1 = -0.01; each follows the
  athlete's centre of mass with a smooth aiming error of about 0.3 m and
  zooms so that the athlete spans about 40 % of the image height
  (principal distance 900-15000 px). Rotations and principal distances per
  frame are known (part 1 of the issue);
* **detections** (a learned 2D detector's output): Gaussian noise with a
  standard deviation of 0.8 % of the athlete's image height for body joints
  and 1.5 % for poles and skis, scaled per detection by ``0.5 + u`` with a
  difficulty ``u ~ U(0, 1)`` that also lowers the confidence
  (``0.95 - 0.45 u``, +- 0.03); 5 % of the detections are outliers moved by
  50-150 px with a confidence in [0.2, 0.9]; 1 % of the camera frames have
  left and right swapped (bursts of 1-3 frames); 1 % of detections are
  missing; joints outside the image are missing.

Several runs (``n_runs``) of the same course with the same cameras make one
session, each run an independent segment (``breaks``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d

from photogram.geometry.aiming import look_at
from photogram.mocap.body.anthropometry import centre_of_mass
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.simulation.ski.skier import SkierBody, pose_skier

__all__ = ["SkiSimulation", "simulate_session", "IMAGE_SIZE", "slope_axes", "pose_run"]

IMAGE_SIZE = (1920, 1080)
G = 9.81
_EXTREMITIES = SKI24.indices(["r_pole", "l_pole", "r_ski_tip", "r_ski_tail", "l_ski_tip",
                              "l_ski_tail"])


@dataclass
class SkiSimulation:
    """A simulated session: truth, cameras, detections."""

    fps: float
    joints: np.ndarray            # (F, 24, 3) truth
    observations: np.ndarray      # (F, C, 24, 3) x, y, confidence (NaN: missing)
    image_truth: np.ndarray       # (F, C, 24, 2) noise-free projections
    cameras: MocapCameras
    breaks: list                  # first frame of every run after the first
    slope_normal: np.ndarray
    outlier: np.ndarray           # (F, C, 24) bool
    swapped: np.ndarray           # (F, C) bool
    info: dict = field(default_factory=dict)

    @property
    def com(self) -> np.ndarray:
        return centre_of_mass({n: self.joints[:, k] for k, n in enumerate(SKI24.joints)})


def slope_axes(alpha):
    """Fall line, lateral and normal unit vectors of a plane slope of
    inclination ``alpha`` (rad; module doc)."""
    e_fall = np.array([np.cos(alpha), 0.0, -np.sin(alpha)])
    e_lat = np.array([0.0, 1.0, 0.0])
    return e_fall, e_lat, np.cross(e_fall, e_lat)


def _course_line(S, radius=23.0):
    """Gate distance and amplitude of a three-turn sinusoid of arc length S."""
    Gd = S / 3.0
    for _ in range(6):
        A = (Gd / np.pi) ** 2 / radius
        p = np.linspace(0.0, 3 * Gd, 6001)
        dq = A * np.pi / Gd * np.cos(np.pi * p / Gd)
        arc = np.sum(np.sqrt(1 + dq ** 2)) * (p[1] - p[0])
        Gd *= S / arc
    return Gd, (Gd / np.pi) ** 2 / radius


def pose_run(rng, P, d, n, phi, turn, t, T, turns: int = 3):
    """The skier along a run (joints (F, 24, 3) and its body): a random
    height of 1.80 m +- 3 %, the pelvis lower and the trunk more flexed in
    the turns (``turn`` in [0, 1]), fore/aft and arm swing with ``turns``
    periods over the run's duration ``T``, small smooth wobbles (module
    doc); shared by the old and the harsh settings."""
    F = len(t)

    def wobble(sd, sig):
        return gaussian_filter1d(rng.normal(0, sd, F), sig, mode="nearest") * np.sqrt(sig)

    body = SkierBody(height=1.80 * (1 + rng.normal(0, 0.03)))
    k = body.height / 1.8
    joints = pose_skier(
        P, d, n, phi, body,
        hip_height=k * (0.86 - 0.12 * turn + wobble(0.01, 8)),
        trunk_flexion=0.55 + 0.12 * turn + wobble(0.02, 10),
        fore_aft=0.05 * np.sin(2 * turns * np.pi * t / T + 0.7) + wobble(0.01, 10),
        arm_swing=0.25 * np.sin(2 * turns * np.pi * t / T) + wobble(0.03, 6),
        counter_rotation=-0.35 * phi)
    return joints, body


def _run(rng, n_frames, fps, alpha, Gd_nominal):
    """Truth of one run: joints (F, 24, 3)."""
    T = n_frames / fps
    t = np.arange(n_frames) / fps
    v0, v1 = 15.5 + rng.uniform(-0.3, 0.3), 19.0 + rng.uniform(-0.5, 0.5)
    turn = np.sin(3 * np.pi * t / T) ** 2
    v = v0 + (v1 - v0) * t / T - 0.5 * turn
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / fps)])
    Gd, A = _course_line(s[-1], radius=23.0 * rng.uniform(0.95, 1.05))
    pp = np.linspace(0.0, 3 * Gd, 6001)
    qq = A * np.sin(np.pi * pp / Gd)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(pp), np.diff(qq)))])
    p = np.interp(s, arc, pp) + 1.5 * (Gd_nominal - Gd)     # centred on the course
    q = np.interp(s, arc, qq) + rng.uniform(-0.5, 0.5)
    e_fall, e_lat, n = slope_axes(alpha)
    P = p[:, None] * e_fall + q[:, None] * e_lat
    dp, dq = np.gradient(p, t), np.gradient(q, t)
    ddp, ddq = np.gradient(dp, t), np.gradient(dq, t)
    kappa = (dp * ddq - dq * ddp) / np.maximum((dp ** 2 + dq ** 2) ** 1.5, 1e-9)
    d = dp[:, None] * e_fall + dq[:, None] * e_lat
    phi = np.arctan(v ** 2 * kappa / (G * np.cos(alpha)))
    phi = gaussian_filter1d(np.clip(phi, -1.15, 1.15), 3.0, mode="nearest")
    joints, _ = pose_run(rng, P, d, n, phi, turn, t, T, turns=3)
    return joints, {"speed_profile": v, "lean_true": phi, "gate_distance": Gd, "amplitude": A}


def _cameras(rng, com, alpha, centre, n_cameras, radius, fps):
    F = len(com)
    e_fall, e_lat, n = slope_axes(alpha)
    ang = np.deg2rad(30.0 + 360.0 / n_cameras * np.arange(n_cameras)
                     + rng.uniform(-5, 5, n_cameras))
    pq = centre[None, :] + radius * np.stack([np.cos(ang), np.sin(ang)], -1)
    X0 = pq[:, :1] * e_fall + pq[:, 1:] * e_lat + np.array([0.0, 0.0, 1.6])
    R = np.empty((F, n_cameras, 3, 3))
    io = []
    for c in range(n_cameras):
        err = np.stack([gaussian_filter1d(rng.normal(0, 1, F), 12, mode="nearest")
                        for _ in range(3)], -1) * np.sqrt(12) * 0.3
        aim = com + err
        R[:, c] = look_at(np.repeat(X0[c:c + 1], F, 0), aim)
        dist = np.linalg.norm(com - X0[c], axis=1)
        zoom = gaussian_filter1d(0.4 * IMAGE_SIZE[1] * dist / 2.0, 5, mode="nearest")
        f = np.clip(zoom * (1 + gaussian_filter1d(rng.normal(0, 0.03, F), 10) * 3), 900, 15000)
        p = np.zeros((F, 9))
        p[:, 0] = p[:, 1] = f
        p[:, 2], p[:, 3] = IMAGE_SIZE[0] / 2, IMAGE_SIZE[1] / 2
        p[:, 4] = -0.01
        io.append(p)
    names = [f"C{c + 1}" for c in range(n_cameras)]
    return MocapCameras(names, ["opencv"] * n_cameras, io, X0, R,
                        np.tile(IMAGE_SIZE, (n_cameras, 1)))


def _detections(rng, xy):
    """Noisy detections (F, C, J, 3) from noise-free projections (F, C, J, 2)."""
    F, C, J, _ = xy.shape
    with np.errstate(invalid="ignore"):
        height = np.nanmax(xy[..., 1], axis=2) - np.nanmin(xy[..., 1], axis=2)   # (F, C)
    rel = np.full(J, 0.008)
    rel[_EXTREMITIES] = 0.015
    u = rng.uniform(0, 1, (F, C, J))
    sigma = rel[None, None, :] * height[..., None] * (0.5 + u)
    obs = np.empty((F, C, J, 3))
    obs[..., :2] = xy + rng.normal(0, 1, (F, C, J, 2)) * sigma[..., None]
    obs[..., 2] = np.clip(0.95 - 0.45 * u + rng.normal(0, 0.03, (F, C, J)), 0.05, 1.0)
    outlier = rng.uniform(0, 1, (F, C, J)) < 0.05
    ang = rng.uniform(0, 2 * np.pi, (F, C, J))
    dist = rng.uniform(50, 150, (F, C, J))
    shift = np.stack([np.cos(ang), np.sin(ang)], -1) * dist[..., None]
    obs[..., :2] += np.where(outlier[..., None], shift, 0.0)
    obs[..., 2] = np.where(outlier, rng.uniform(0.2, 0.9, (F, C, J)), obs[..., 2])
    swapped = np.zeros((F, C), bool)
    starts = rng.uniform(0, 1, (F, C)) < 0.01 / 2.0
    for f, c in zip(*np.nonzero(starts)):
        swapped[f:f + rng.integers(1, 4), c] = True
    perm = SKI24.swap_permutation()
    obs = np.where(swapped[:, :, None, None], obs[:, :, perm], obs)
    missing = rng.uniform(0, 1, (F, C, J)) < 0.01
    outside = ~((obs[..., 0] >= 0) & (obs[..., 0] < IMAGE_SIZE[0]) & (obs[..., 1] >= 0)
                & (obs[..., 1] < IMAGE_SIZE[1]))
    gone = missing | outside | ~np.all(np.isfinite(xy), -1)
    obs[gone] = np.nan
    return obs, outlier & ~gone, swapped


def simulate_session(seed: int = 8, n_runs: int = 1, frames_per_run: int = 279,
                     fps: float = 50.0, n_cameras: int = 6, radius: float = 40.0,
                     slope_deg: float = 20.0) -> SkiSimulation:
    """Simulate ``n_runs`` runs of the course (module doc), reproducibly.

    The default session (one run of 279 frames) is the example project
    ``projects/ski-ptz``; six runs (1674 frames) are the benchmark's.
    """
    rng = np.random.default_rng(seed)
    alpha = np.deg2rad(slope_deg)
    T = frames_per_run / fps
    t = np.arange(frames_per_run) / fps
    v_mean = np.mean(15.5 + 3.5 * t / T - 0.5 * np.sin(3 * np.pi * t / T) ** 2)
    Gd_nominal, _ = _course_line(v_mean * T)
    runs, infos = [], []
    for _ in range(n_runs):
        joints, info = _run(rng, frames_per_run, fps, alpha, Gd_nominal)
        runs.append(joints)
        infos.append(info)
    joints = np.concatenate(runs)
    com = centre_of_mass({nm: joints[:, k] for k, nm in enumerate(SKI24.joints)})
    cams = _cameras(rng, com, alpha, np.array([1.5 * Gd_nominal, 0.0]), n_cameras, radius, fps)
    xy = cams.project(joints)
    breaks = [frames_per_run * r for r in range(1, n_runs)]
    obs, outlier, swapped = _detections(rng, xy)
    _, _, n = slope_axes(alpha)
    return SkiSimulation(fps=fps, joints=joints, observations=obs, image_truth=xy,
                         cameras=cams, breaks=breaks, slope_normal=n, outlier=outlier,
                         swapped=swapped,
                         info={"seed": seed, "runs": n_runs, "frames_per_run": frames_per_run,
                               "slope_deg": slope_deg, "radius": radius,
                               "gate_distance": [i["gate_distance"] for i in infos],
                               "amplitude": [i["amplitude"] for i in infos],
                               "speed_min": float(min(i["speed_profile"].min() for i in infos)),
                               "speed_max": float(max(i["speed_profile"].max() for i in infos))})
