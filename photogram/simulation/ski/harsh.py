"""The HARSH setting of the ski simulator (issue 22): a longer run on uneven
terrain, lagging mis-levelled cameras, a poor detector, bystanders.

THE DATA OF THIS MODULE ARE SIMULATED. Seeded (:class:`HarshSettings`
``seed``) and reproducible; the numbers below are the defaults of
:class:`HarshSettings`. Scene (lengths in m, world Z up, X downhill, Y left;
slope coordinates ``p`` downhill and ``q`` across, as in
:mod:`photogram.simulation.ski.simulate`, whose default output this module
leaves unchanged):

* **run**: 450 frames at 50 fps (9 s), five giant-slalom turns (turn radius
  about 23 m at the apex), speed rising from about 15.5 to 19 m/s, 0.5 m/s
  lost in each turn; skier 1.80 m +- 3 %.
* **non-planar slope**: a 20 deg plane plus, along its normal,
  ``0.0008 (p - p_mid)^2`` (the slope 3-4 deg steeper at the top, flatter
  at the bottom), rolls ``0.6 sin(2 pi p / 45 m)``, a cross slope of
  ``0.05 q`` and a **kicker** at 62 % of the run: a ramp 0.5 m high and
  5 m long (lip slope 0.2) that throws the skier into a ballistic flight
  of about 0.8 s (gravity 9.81 cos 20 deg along the normal) until the
  trajectory meets the snow again; the body's up direction follows the
  terrain normal (smoothed over 3 frames).
* **cameras** (1920 x 1080 px, OpenCV k1 = -0.01): ``C1`` at the finish,
  25 m below the end of the run, looking up the course; ``C2``-``C6``
  along the sides at 12, 32, 52, 72, 92 % of the run, alternately left and
  right, 18-26 m outside the turns' amplitude; 1.6 m above the snow. Every
  camera *lags* the athlete (first-order lag 0.08-0.2 s; ``C6`` 0.28 s, so
  that the athlete drifts off centre and leaves its image at times), has a
  slow aiming error (0.6 m, smoothed over 12 frames) and a jitter (0.04 deg
  per axis and frame, smoothed over 1 frame); its base is **mis-levelled**
  by 1.5-5 deg about a random horizontal axis (the pan axis tilted: the
  roll changes with the pan); zoom aims at 35 % of the image height for
  the athlete, lagged by 0.4 s, principal distance 1500-12000 px (far away
  the athlete gets small). Camera ``C4`` loses the athlete for 95 frames
  (:mod:`photogram.simulation.ski.harsh_detector`).
* **detector**, **bystanders**, **tracking losses**: see
  :mod:`photogram.simulation.ski.harsh_detector`.
* **rotation differences** (estimate mode): the true differences with
  0.03 deg of noise per axis, 2 % failed pairs (empty, ``ok`` 0) in runs
  of 1-8, and 1 % wrong but accepted pairs (0.5-3 deg off); **lagged
  pairs** (frames t and t+10, t+25 whose true rotation is below half the
  horizontal field of view) from a separate random stream, with 0.03 deg
  per axis (growing as the overlap shrinks), a per-camera zoom scale error
  of +-0.3 % of the pan and tilt (correlated over the run), wrong pairs at
  the same rate and more failures near the overlap limit
  (:mod:`photogram.simulation.ski.harsh_lagged`).

Two cameras (:func:`two_cameras`, the projects' ``two-cameras/``): ``C3`` and ``C5``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import lfilter

from photogram.geometry.aiming import look_at
from photogram.geometry.rotations import rodrigues_to_matrix
from photogram.mocap.body.anthropometry import centre_of_mass
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.simulation.ski.simulate import IMAGE_SIZE, SkiSimulation, pose_run, slope_axes

__all__ = ["HarshSettings", "HarshSimulation", "simulate_harsh", "two_cameras",
           "simulated_rotation_differences", "TWO_CAMERAS"]

G = 9.81
TWO_CAMERAS = ("C3", "C5")


@dataclass(frozen=True)
class HarshSettings:
    """Every number of the harsh setting (module doc and
    :mod:`photogram.simulation.ski.harsh_detector`)."""

    seed: int = 22
    frames: int = 450
    fps: float = 50.0
    turns: int = 5
    slope_deg: float = 20.0
    # terrain
    curvature: float = 0.0008          # 1/m, along the normal
    roll_height: float = 0.6           # m
    roll_length: float = 45.0          # m
    cross_slope: float = 0.05
    kicker_at: float = 0.62            # fraction of the run
    kicker_height: float = 0.5         # m
    kicker_length: float = 5.0         # m
    # cameras
    lag_s: tuple = (0.08, 0.2)
    slow_camera: str = "C6"
    slow_lag_s: float = 0.28
    aim_error_m: float = 0.6
    jitter_deg: float = 0.04
    base_tilt_deg: tuple = (1.5, 5.0)
    zoom_fraction: float = 0.35
    zoom_lag_s: float = 0.4
    focal_range: tuple = (1500.0, 12000.0)
    # detector (harsh_detector)
    sigma_rel: float = 0.024           # of the athlete's image height, at 300 px
    sigma_size_exponent: float = 0.5   # relative noise ~ (300 px / height)^0.5
    extremity_factor: float = 1.7
    student_dof: float = 3.0
    correlated_share: float = 0.5      # of the noise variance, smoothed over frames
    correlated_frames: float = 4.0
    bias_rel: float = 0.012            # per camera and joint, of the image height
    outlier_fraction: float = 0.07
    outlier_rel: tuple = (0.25, 0.8)   # of the image height, at least 40 px
    swap_fraction: float = 0.05        # of the camera frames, in bursts
    swap_burst: tuple = (3, 12)
    joint_occlusion_start: float = 0.01
    joint_occlusion_frames: tuple = (5, 25)
    person_occlusion_start: float = 0.004
    person_occlusion_frames: tuple = (3, 15)
    missing_fraction: float = 0.02
    loss_camera: str = "C4"
    loss_frames: int = 95
    loss_start: int = 180
    ghost_camera: str = "C2"
    ghost_frames: int = 25
    ghost_start: int = 300
    near_camera: str = "C1"
    near_distance: float = 30.0        # m from the near camera
    # rotation differences
    dr_noise_deg: float = 0.03
    dr_failed: float = 0.02
    dr_wrong: float = 0.01
    # lagged rotation differences (harsh_lagged)
    dr_lags: tuple = (10, 25)
    dr_lag_max_fraction: float = 0.5   # of the horizontal field of view
    dr_lag_scale: float = 0.003        # zoom calibration error, per camera
    dr_lag_fail: float = 0.3           # more failures at the overlap limit


@dataclass
class HarshSimulation(SkiSimulation):
    """A :class:`SkiSimulation` (the athlete) plus the other people.

    ``people`` (P, F, C, J, 3): the detections of every person, index 0
    the athlete (= ``observations``), then the bystanders and the ghost;
    ``person_id`` (F, C, P) the id each person carries in the detections of
    that camera frame (shuffled per frame; -1: not detected); ``lost``
    (F, C) camera frames whose athlete the detector lost (long loss, ghost,
    occlusion); ``kinds`` (P,) names of the people."""

    people: np.ndarray = None
    person_id: np.ndarray = None
    lost: np.ndarray = None
    kinds: list = field(default_factory=list)
    people_3d: np.ndarray = None       # (P-1 bystanders, F, J, 3) truth (the ghost: NaN)
    settings: HarshSettings = None


def _turn_line(S, turns, radius=23.0):
    """Gate distance and amplitude of a ``turns``-turn sinusoid of arc length S."""
    Gd = S / turns
    for _ in range(6):
        A = (Gd / np.pi) ** 2 / radius
        p = np.linspace(0.0, turns * Gd, 8001)
        dq = A * np.pi / Gd * np.cos(np.pi * p / Gd)
        arc = np.sum(np.sqrt(1 + dq ** 2)) * (p[1] - p[0])
        Gd *= S / arc
    return Gd, (Gd / np.pi) ** 2 / radius


class Terrain:
    """Height above the 20 deg plane along its normal, and its gradient."""

    def __init__(self, st: HarshSettings, length: float):
        self.st, self.mid = st, 0.5 * length
        self.lip = st.kicker_at * length

    def height(self, p, q):
        st = self.st
        u = (p - (self.lip - st.kicker_length)) / st.kicker_length
        kick = np.where((u >= 0) & (u <= 1), st.kicker_height * np.clip(u, 0, 1) ** 2, 0.0)
        return (st.curvature * (p - self.mid) ** 2
                + st.roll_height * np.sin(2 * np.pi * p / st.roll_length)
                + st.cross_slope * q + kick)

    def gradient(self, p, q, eps=0.05):
        return ((self.height(p + eps, q) - self.height(p - eps, q)) / (2 * eps),
                (self.height(p, q + eps) - self.height(p, q - eps)) / (2 * eps))


def _run(rng, st: HarshSettings, alpha):
    """The athlete: joints (F, 24, 3), the path (p, q), the terrain, info."""
    F, fps = st.frames, st.fps
    T = F / fps
    t = np.arange(F) / fps
    v0, v1 = 15.5 + rng.uniform(-0.3, 0.3), 19.0 + rng.uniform(-0.5, 0.5)
    turn = np.sin(st.turns * np.pi * t / T) ** 2
    v = v0 + (v1 - v0) * t / T - 0.5 * turn
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / fps)])
    Gd, A = _turn_line(s[-1], st.turns, radius=23.0 * rng.uniform(0.95, 1.05))
    pp = np.linspace(0.0, st.turns * Gd, 8001)
    qq = A * np.sin(np.pi * pp / Gd)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(pp), np.diff(qq)))])
    p = np.interp(s, arc, pp)
    q = np.interp(s, arc, qq) + rng.uniform(-0.5, 0.5)
    terrain = Terrain(st, st.turns * Gd)
    h = terrain.height(p, q)
    z = h.copy()                                      # the flight over the kicker
    k = int(np.searchsorted(p, terrain.lip))
    if 2 <= k < F - 1:
        vz = (h[k - 1] - h[k - 2]) * fps
        tau = (np.arange(F) - (k - 1)) / fps
        ballistic = h[k - 1] + vz * tau - 0.5 * G * np.cos(alpha) * tau ** 2
        air = (tau > 0) & (ballistic > h)
        land = np.flatnonzero((tau > 0) & ~air)
        end = land[0] if len(land) else F
        z[k:end] = ballistic[k:end]
        airborne = (k, end)
    else:
        airborne = (0, 0)
    e_fall, e_lat, n0 = slope_axes(alpha)
    P = p[:, None] * e_fall + q[:, None] * e_lat + z[:, None] * n0
    gp, gq = terrain.gradient(p, q)
    n = n0[None] - gp[:, None] * e_fall - gq[:, None] * e_lat
    n = gaussian_filter1d(n / np.linalg.norm(n, axis=1, keepdims=True), 3.0, axis=0,
                          mode="nearest")
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    dp, dq = np.gradient(p, t), np.gradient(q, t)
    ddp, ddq = np.gradient(dp, t), np.gradient(dq, t)
    kappa = (dp * ddq - dq * ddp) / np.maximum((dp ** 2 + dq ** 2) ** 1.5, 1e-9)
    d = dp[:, None] * e_fall + dq[:, None] * e_lat + np.gradient(z, t)[:, None] * n0
    phi = np.arctan(v ** 2 * kappa / (G * np.cos(alpha)))
    phi = gaussian_filter1d(np.clip(phi, -1.15, 1.15), 3.0, mode="nearest")
    joints, body = pose_run(rng, P, d, n, phi, turn, t, T, turns=st.turns)
    info = {"gate_distance": Gd, "amplitude": A, "length": st.turns * Gd,
            "speed_min": float(v.min()), "speed_max": float(v.max()),
            "airborne_frames": [int(airborne[0]), int(airborne[1])],
            "flight_height_m": float(np.max(z - h)), "height": body.height}
    return joints, p, q, terrain, info


def _lag(x, tau, fps):
    """First-order lag (time constant ``tau`` s) of x (F, ...) along frames."""
    k = 1.0 - np.exp(-1.0 / (tau * fps))
    return lfilter([k], [1.0, -(1.0 - k)], x, axis=0, zi=(1.0 - k) * x[:1])[0]


def _lost_aim(aim, com, st: HarshSettings):
    """The aim of the camera that loses the athlete (harsh_detector doc):
    on at 30 % of the athlete's velocity for ``loss_frames``, then back in
    12 frames."""
    a, b = st.loss_start, min(st.loss_start + st.loss_frames, len(aim))
    out = aim.copy()
    v = (com[a] - com[max(a - 5, 0)]) / 5.0
    out[a:b] = aim[a] + 0.3 * v * np.arange(b - a)[:, None]
    back = np.arange(b, min(b + 12, len(aim)))
    s = ((back - b + 1) / 12.0)[:, None]
    s = s * s * (3 - 2 * s)
    out[back] = (1 - s) * out[b - 1] + s * aim[back]
    return out


def _cameras(rng, st: HarshSettings, com, terrain, length, amplitude, alpha):
    F = len(com)
    e_fall, e_lat, n0 = slope_axes(alpha)
    sides = np.array([1.0, -1.0, 1.0, -1.0, 1.0])
    pq = [(length + 25.0, 6.0)] + [
        (f * length, sides[i] * (amplitude + rng.uniform(18.0, 26.0)))
        for i, f in enumerate((0.12, 0.32, 0.52, 0.72, 0.92))]
    pq = np.array(pq)
    X0 = (pq[:, :1] * e_fall + pq[:, 1:] * e_lat
          + terrain.height(pq[:, 0], pq[:, 1])[:, None] * n0 + np.array([0.0, 0.0, 1.6]))
    C = len(X0)
    names = [f"C{c + 1}" for c in range(C)]
    R = np.empty((F, C, 3, 3))
    io, info = [], {"lag_s": [], "base_tilt_deg": []}
    for c in range(C):
        tau = st.slow_lag_s if names[c] == st.slow_camera else rng.uniform(*st.lag_s)
        err = np.stack([gaussian_filter1d(rng.normal(0, 1, F), 12, mode="nearest")
                        for _ in range(3)], -1) * np.sqrt(12) * st.aim_error_m
        aim = _lag(com, tau, st.fps) + err
        if names[c] == st.loss_camera:
            aim = _lost_aim(aim, com, st)
        tilt = np.radians(rng.uniform(*st.base_tilt_deg))
        az = rng.uniform(0, 2 * np.pi)
        axis = np.array([np.cos(az), np.sin(az), 0.0])
        up = rodrigues_to_matrix(tilt * axis) @ np.array([0.0, 0.0, 1.0])
        R0 = look_at(np.repeat(X0[c:c + 1], F, 0), aim, up=up)
        jit = gaussian_filter1d(rng.normal(0, np.radians(st.jitter_deg), (F, 3)), 1.0, axis=0)
        R[:, c] = rodrigues_to_matrix(jit) @ R0
        dist = np.linalg.norm(com - X0[c], axis=1)
        f = _lag(st.zoom_fraction * IMAGE_SIZE[1] * dist / 1.8, st.zoom_lag_s, st.fps)
        f = np.clip(f, *st.focal_range)
        prm = np.zeros((F, 9))
        prm[:, 0] = prm[:, 1] = f
        prm[:, 2], prm[:, 3] = IMAGE_SIZE[0] / 2, IMAGE_SIZE[1] / 2
        prm[:, 4] = -0.01
        io.append(prm)
        info["lag_s"].append(float(tau))
        info["base_tilt_deg"].append(float(np.degrees(tilt)))
    return MocapCameras(names, ["opencv"] * C, io, X0, R, np.tile(IMAGE_SIZE, (C, 1))), info


def simulate_harsh(settings: HarshSettings | None = None, seed: int | None = None
                   ) -> HarshSimulation:
    """Simulate the harsh setting (module doc), reproducibly from the seed
    (``seed`` overrides ``settings.seed``)."""
    from dataclasses import replace

    from photogram.simulation.ski.harsh_detector import bystanders, detect_people
    st = settings or HarshSettings()
    if seed is not None:
        st = replace(st, seed=seed)
    rng = np.random.default_rng(st.seed)
    alpha = np.deg2rad(st.slope_deg)
    joints, p, q, terrain, info = _run(rng, st, alpha)
    com = centre_of_mass({nm: joints[:, k] for k, nm in enumerate(SKI24.joints)})
    cams, cinfo = _cameras(rng, st, com, terrain, info["length"], info["amplitude"], alpha)
    others, kinds = bystanders(rng, st, joints, cams, terrain, alpha)
    xy = cams.project(joints)
    det = detect_people(rng, st, cams, xy, [cams.project(X) for X in others])
    _, _, n0 = slope_axes(alpha)
    info.update(cinfo)
    info.update({"seed": st.seed, "runs": 1, "frames_per_run": st.frames,
                 "slope_deg": st.slope_deg, "setting": "harsh"})
    return HarshSimulation(
        fps=st.fps, joints=joints, observations=det["people"][0], image_truth=xy,
        cameras=cams, breaks=[], slope_normal=n0, outlier=det["outlier"],
        swapped=det["swapped"], info=info, people=det["people"],
        person_id=det["person_id"], lost=det["lost"], kinds=["athlete"] + kinds + ["ghost"],
        people_3d=np.stack(others), settings=st)


def two_cameras(sim: SkiSimulation, names=TWO_CAMERAS) -> SkiSimulation:
    """The simulation (harsh or not) seen by two of its cameras only
    (``C3``, ``C5``)."""
    from dataclasses import replace
    idx = [sim.cameras.index(n) for n in names]
    cams = sim.cameras
    sub = MocapCameras([cams.names[c] for c in idx], [cams.models[c] for c in idx],
                       [cams.io[c] for c in idx], cams.X0[idx], cams.R[:, idx],
                       cams.image_size[idx])
    extra = {}
    if isinstance(sim, HarshSimulation):
        extra = {"people": sim.people[:, :, idx], "person_id": sim.person_id[:, idx],
                 "lost": sim.lost[:, idx]}
    return replace(sim, cameras=sub, observations=sim.observations[:, idx],
                   image_truth=sim.image_truth[:, idx], outlier=sim.outlier[:, idx],
                   swapped=sim.swapped[:, idx], **extra)


def simulated_rotation_differences(sim: SkiSimulation, st: HarshSettings, seed: int):
    """Per camera name a :class:`photogram.mocap.motion.homography.RotationDifferences`:
    the true differences with noise, failed and wrong pairs (module doc),
    and lagged pairs (``lagged``; :mod:`photogram.simulation.ski.harsh_lagged`,
    drawn from ``default_rng(seed + 7919)``; None when ``st.dr_lags`` is
    empty)."""
    from photogram.mocap.motion.homography import RotationDifferences
    from photogram.simulation.ski.harsh_lagged import simulated_lagged_differences
    rng = np.random.default_rng(seed)
    lag_rng = np.random.default_rng(seed + 7919)
    R = sim.cameras.R
    F = R.shape[0]
    out = {}
    for c, name in enumerate(sim.cameras.names):
        true = R[1:, c] @ np.swapaxes(R[:-1, c], -1, -2)
        noise = rng.normal(0, np.radians(st.dr_noise_deg), (F - 1, 3))
        wrong = rng.uniform(0, 1, F - 1) < st.dr_wrong
        big = rng.normal(0, 1, (F - 1, 3))
        big *= (np.radians(rng.uniform(0.5, 3.0, F - 1)) / np.linalg.norm(big, axis=1))[:, None]
        noise[wrong] = big[wrong]
        dR = rodrigues_to_matrix(noise) @ true
        failed = np.zeros(F - 1, bool)
        starts = np.flatnonzero(rng.uniform(0, 1, F - 1) < st.dr_failed / 4.5)
        for s0 in starts:
            failed[s0:s0 + rng.integers(1, 9)] = True
        matches = rng.integers(220, 420, F - 1)
        inliers = np.where(failed, rng.integers(4, 12, F - 1),
                           np.where(wrong, rng.integers(15, 40, F - 1),
                                    (matches * rng.uniform(0.6, 0.95, F - 1)).astype(int)))
        dR[failed] = np.nan
        lagged = (simulated_lagged_differences(R[:, c], sim.cameras.io[c],
                                               sim.cameras.image_size[c][0], st, lag_rng)
                  if st.dr_lags else None)
        out[name] = RotationDifferences(dR, inliers, matches, ~failed, 0.0, F, lagged)
    return out
