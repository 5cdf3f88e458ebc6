"""The poor 2D detector, the bystanders and the tracking losses of the
harsh ski setting (:mod:`photogram.simulation.ski.harsh`). SIMULATED.

Numbers are the defaults of :class:`photogram.simulation.ski.harsh.HarshSettings`.

* **noise**: Student-t with 3 degrees of freedom (heavy tails), scaled to a
  standard deviation per axis of ``0.024 h (300 px / h)^0.5 (0.5 + u)``
  for a person ``h`` px tall in the image (the relative error grows as the
  person gets small), times 1.7 for poles and skis, ``u ~ U(0, 1)`` a
  difficulty per detection; half of the variance temporally correlated
  (Gaussian-smoothed over 4 frames: consecutive frames err alike); plus a
  bias per camera and joint of 1.2 % of ``h`` per axis (the detector's
  joint definitions differ from the skeleton's); mean 2D error about 20 px, PCK (head-neck
  distance) about 0.76 for the athlete;
* **confidence** falling with the error ``e``:
  ``0.97 exp(-e / (0.1 h)) + N(0, 0.04)``, clipped to [0.05, 1];
* **outliers**: 7 % of the detections moved by 0.25-0.8 ``h`` (at least
  40 px) in a random direction, confidence U(0.2, 0.9);
* **limb swaps in bursts**: 5 % of the camera frames, bursts of 3-12
  frames, the legs (with skis), the arms (with poles) or all left/right
  pairs exchanged;
* **occlusions**: runs of 5-25 frames in which one limb (an arm with its
  pole or a leg with its ski) is missing (a run starts at 1 % of the camera
  frames), runs of 3-15 frames in which the whole person is missing (0.4 %);
  2 % of the detections missing at random; joints outside the image
  missing;
* **long tracking loss**: camera ``C4`` loses the athlete for 95 frames
  (180-274): its operator pans on at 30 % of the athlete's speed (the
  athlete leaves the image) and whip-pans back in 12 frames at the end; the
  detector finds no athlete in those frames (the bystanders it sees are
  still detected); the athlete comes back far from its last box;
* **jump**: for 25 frames (300-324) camera ``C2`` detects, instead of the
  athlete, a ghost: the athlete's detections moved by (380, 70) px (the
  box jumps to a gate judge), confidence 0.6-0.8;
* **bystanders** (standing on skis, detected like the athlete, persons of
  their own): a *coach* standing still 30 m up the course from the finish
  camera ``C1``, on its line of sight to the athlete when the athlete is
  about 100 m away (nearer ``C1`` than the athlete: bigger in the image); a
  *walker* side-stepping up the slope at 0.3 m/s at 40 % of the run, 8 m
  outside the turns on the side of ``C3`` (nearer ``C3`` than the athlete
  around 47 % of the run); two *spectators* standing at 75 % of the run,
  9-10.5 m outside the turns;
* **person ids** shuffled per camera frame (as OpenPose numbers people per
  image): nothing in the ids says who the athlete is; the truth does
  (``HarshSimulation.person_id``, ``truth/identity.csv``).
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.ndimage import gaussian_filter1d

from photogram.mocap.body.skeleton import SKI24
from photogram.simulation.ski.simulate import IMAGE_SIZE, slope_axes
from photogram.simulation.ski.skier import SkierBody, pose_skier

__all__ = ["bystanders", "detect_people", "image_height"]

_EXTREMITIES = SKI24.indices(["r_pole", "l_pole", "r_ski_tip", "r_ski_tail", "l_ski_tip",
                              "l_ski_tail"])
_ARM = ("shoulder", "elbow", "hand", "pole")
_LEG = ("knee", "ankle", "toes", "heel", "ski_tip", "ski_tail")
_LIMBS = [SKI24.indices([s + j for j in part]) for s in ("r_", "l_") for part in (_ARM, _LEG)]
GHOST_SHIFT = (380.0, 70.0)


def _permutation(parts):
    perm = np.arange(SKI24.n_joints)
    for j in parts:
        a, b = SKI24.index("r_" + j), SKI24.index("l_" + j)
        perm[a], perm[b] = b, a
    return perm


_SWAPS = [_permutation(("hip",) + _LEG), _permutation(_ARM), SKI24.swap_permutation()]


def _standing(P, d, n, height):
    """SKI24 joints (F, 24, 3) of a person standing on skis at P (F, 3)."""
    F = len(P)
    body = SkierBody(height=height)
    z = np.zeros(F)
    return pose_skier(P, d, n, z, body, hip_height=np.full(F, 0.95 * height / 1.8),
                      trunk_flexion=np.full(F, 0.12), fore_aft=z, arm_swing=z + 0.1)


def _on_terrain(p, q, terrain, alpha):
    e_fall, e_lat, n0 = slope_axes(alpha)
    p, q = np.broadcast_arrays(np.asarray(p, float), np.asarray(q, float))
    return (p[..., None] * e_fall + q[..., None] * e_lat
            + terrain.height(p, q)[..., None] * n0)


def bystanders(rng, st, joints, cameras, terrain, alpha):
    """The 3D bystanders (list of (F, 24, 3)) and their names (module doc)."""
    from photogram.mocap.body.anthropometry import centre_of_mass
    e_fall, e_lat, n0 = slope_axes(alpha)
    F = len(joints)
    com = centre_of_mass({nm: joints[:, k] for k, nm in enumerate(SKI24.joints)})
    p_a, q_a = com @ e_fall, com @ e_lat
    length, amp = float(p_a.max()), float(np.max(np.abs(q_a)))
    out, names = [], []
    # the coach: on the near camera's line of sight when the athlete is ~100 m away
    X0 = cameras.X0[cameras.index(st.near_camera)]
    dist = np.linalg.norm(com - X0, axis=1)
    f1 = int(np.argmin(np.abs(dist - 100.0)))
    u = com[f1] - X0
    u -= (u @ n0) * n0
    u /= np.linalg.norm(u)
    spot = X0 + st.near_distance * u
    pc, qc = spot @ e_fall + rng.uniform(-1, 1), spot @ e_lat + rng.uniform(0.3, 0.8)
    P = np.repeat(_on_terrain(pc, qc, terrain, alpha)[None], F, 0)
    out.append(_standing(P, np.repeat(-u[None], F, 0), n0, 1.75 + rng.uniform(-0.05, 0.05)))
    names.append(f"coach (near {st.near_camera})")
    # the walker, side-stepping uphill on the side of C3
    t = np.arange(F) / st.fps
    pw = 0.40 * length + 4.0 - 0.3 * t
    qw = np.full(F, -(amp + 8.0))
    out.append(_standing(_on_terrain(pw, qw, terrain, alpha), np.repeat(e_lat[None], F, 0), n0,
                         1.82))
    names.append("walker")
    for dq, h in ((9.0, 1.70), (10.5, 1.78)):
        P = np.repeat(_on_terrain(0.75 * length, amp + dq, terrain, alpha)[None], F, 0)
        out.append(_standing(P, np.repeat(-e_lat[None], F, 0), n0, h))
        names.append("spectator")
    return out, names


def image_height(xy: np.ndarray) -> np.ndarray:
    """Height (px) of a person's projected joints (..., J, 2) (NaN: none)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmax(xy[..., 1], axis=-1) - np.nanmin(xy[..., 1], axis=-1)


def _runs(rng, shape, p_start, lengths):
    """(F, C) bool: runs of ``lengths`` frames starting with probability p_start."""
    F, C = shape
    out = np.zeros(shape, bool)
    for f, c in zip(*np.nonzero(rng.uniform(0, 1, shape) < p_start)):
        out[f:f + rng.integers(lengths[0], lengths[1] + 1), c] = True
    return out


def _degrade(rng, st, xy):
    """Noisy detections (F, C, J, 3) of one person from its projections
    (F, C, J, 2), the outlier mask (F, C, J) and the swapped frames (F, C)."""
    F, C, J, _ = xy.shape
    h = np.clip(np.nan_to_num(image_height(xy), nan=20.0), 20.0, None)        # (F, C)
    rel = st.sigma_rel * (300.0 / h) ** st.sigma_size_exponent
    factor = np.ones(J)
    factor[_EXTREMITIES] = st.extremity_factor
    u = rng.uniform(0, 1, (F, C, J))
    sigma = (rel * h)[..., None] * factor * (0.5 + u)
    nu = st.student_dof
    white = rng.standard_t(nu, (F, C, J, 2)) * np.sqrt((nu - 2) / nu)
    slow = gaussian_filter1d(rng.normal(0, 1, (F, C, J, 2)), st.correlated_frames, axis=0)
    slow /= np.sqrt(np.mean(slow ** 2))
    bias = rng.normal(0, st.bias_rel, (1, C, J, 2)) * h[..., None, None]
    w = st.correlated_share
    noise = (np.sqrt(1 - w) * white + np.sqrt(w) * slow) * sigma[..., None] + bias
    obs = np.empty((F, C, J, 3))
    obs[..., :2] = xy + noise
    err = np.linalg.norm(noise, axis=-1)
    obs[..., 2] = np.clip(0.97 * np.exp(-err / (0.1 * h[..., None]))
                          + rng.normal(0, 0.04, (F, C, J)), 0.05, 1.0)
    outlier = rng.uniform(0, 1, (F, C, J)) < st.outlier_fraction
    ang = rng.uniform(0, 2 * np.pi, (F, C, J))
    dist = np.maximum(rng.uniform(*st.outlier_rel, (F, C, J)) * h[..., None], 40.0)
    shift = np.stack([np.cos(ang), np.sin(ang)], -1) * dist[..., None]
    obs[..., :2] += np.where(outlier[..., None], shift, 0.0)
    obs[..., 2] = np.where(outlier, rng.uniform(0.2, 0.9, (F, C, J)), obs[..., 2])
    burst = 0.5 * (st.swap_burst[0] + st.swap_burst[1])
    swapped = np.zeros((F, C), bool)
    kind = np.zeros((F, C), int)
    for f, c in zip(*np.nonzero(rng.uniform(0, 1, (F, C)) < st.swap_fraction / burst)):
        n = rng.integers(st.swap_burst[0], st.swap_burst[1] + 1)
        swapped[f:f + n, c] = True
        kind[f:f + n, c] = rng.integers(0, 3)
    for k, perm in enumerate(_SWAPS):
        sel = swapped & (kind == k)
        obs[sel] = obs[sel][:, perm]
    gone = rng.uniform(0, 1, (F, C, J)) < st.missing_fraction
    limb_runs = [_runs(rng, (F, C), st.joint_occlusion_start / 4, st.joint_occlusion_frames)
                 for _ in _LIMBS]
    for idx, run in zip(_LIMBS, limb_runs):
        gone[..., idx] |= run[..., None]
    gone |= _runs(rng, (F, C), st.person_occlusion_start, st.person_occlusion_frames)[..., None]
    outside = ~((obs[..., 0] >= 0) & (obs[..., 0] < IMAGE_SIZE[0]) & (obs[..., 1] >= 0)
                & (obs[..., 1] < IMAGE_SIZE[1]))
    gone |= outside | ~np.all(np.isfinite(xy), -1)
    obs[gone] = (np.nan, np.nan, 0.0)
    return obs, outlier & ~gone, swapped


def detect_people(rng, st, cameras, xy_athlete, xy_others):
    """The detections of the athlete and the others (module doc): dict with
    ``people`` (P, F, C, J, 3), ``person_id`` (F, C, P), ``outlier``
    (F, C, J) and ``swapped`` (F, C) of the athlete, ``lost`` (F, C)."""
    F, C = xy_athlete.shape[:2]
    athlete, outlier, swapped = _degrade(rng, st, xy_athlete)
    others = []
    for xy in xy_others:
        o, _, _ = _degrade(rng, st, xy)
        few = np.sum(o[..., 2] > 0, axis=-1) < 8          # a person needs 8 joints
        o[few] = (np.nan, np.nan, 0.0)
        others.append(o)
    names = list(cameras.names)
    ghost = np.full_like(athlete, np.nan)
    ghost[..., 2] = 0.0
    lost = np.zeros((F, C), bool)
    c = names.index(st.loss_camera)
    lost[st.loss_start:st.loss_start + st.loss_frames, c] = True
    c = names.index(st.ghost_camera)
    g = slice(st.ghost_start, st.ghost_start + st.ghost_frames)
    ghost[g, c] = athlete[g, c]
    ghost[g, c, :, :2] += GHOST_SHIFT
    ghost[g, c, :, 2] = np.where(athlete[g, c, :, 2] > 0,
                                 rng.uniform(0.6, 0.8, ghost[g, c, :, 2].shape), 0.0)
    lost[g, c] = True
    athlete[lost] = (np.nan, np.nan, 0.0)
    outlier &= ~lost[..., None]
    people = np.stack([athlete] + others + [ghost])
    present = np.any(np.nan_to_num(people[..., 2]) > 0, axis=-1)      # (P, F, C)
    lost |= ~present[0]
    keys = np.where(np.moveaxis(present, 0, -1), rng.uniform(0, 1, (F, C, len(people))),
                    np.inf)
    rank = np.argsort(np.argsort(keys, axis=-1), axis=-1)
    person_id = np.where(np.isfinite(keys), rank, -1)
    return {"people": people, "person_id": person_id, "outlier": outlier,
            "swapped": swapped & present[0], "lost": lost}
