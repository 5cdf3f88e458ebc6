"""Synthetic camera networks with known truth.

Small building blocks: a look-at rotation in the photogrammetric camera
frame (:func:`photogram.geometry.aiming.look_at`), a frame of target
points, ring-shaped station layouts, and exact image observations
(optionally with Gaussian noise) from a camera model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.geometry import camera_model, matrix_to_opk
from photogram.geometry.aiming import look_at   # used here and by the designs


@dataclass
class SyntheticNetwork:
    """Truth of a simulated network and its image observations."""

    model_name: str
    io: np.ndarray            # (K, p) interior orientation per camera
    image_size: tuple
    station_camera: np.ndarray  # (S,) camera index per station
    R: np.ndarray             # (S, 3, 3)
    X0: np.ndarray            # (S, 3)
    points: np.ndarray        # (P, 3)
    station: np.ndarray       # (N,) observation -> station
    point: np.ndarray         # (N,) observation -> point
    xy_true: np.ndarray       # (N, 2)
    xy: np.ndarray            # (N, 2) with noise

    @property
    def angles(self):
        return matrix_to_opk(self.R)


#: station-point pairs projected per pass: 50,000 pairs take about 15 MB per
#: temporary (a 150-station, 8000-point wall: 76 MB and 1.8 s CPU; 200,000
#: pairs took 279 MB and 2.5 s)
_PAIRS = 50_000


def _observe_stations(model, io, station_camera, R, X0, points, image_size, margin, stations):
    """(station, point, xy) of the points the given stations see (in front,
    inside the image less ``margin``), station-major as :func:`observe`."""
    P = len(points)
    st = np.repeat(stations, P)
    pt = np.tile(np.arange(P), len(stations))
    Xc_z = np.einsum("nj,nj->n", R[st][:, 2, :], points[pt] - X0[st])
    front = Xc_z < 0
    st, pt = st[front], pt[front]
    xy = model.project(points[pt], matrix_to_opk(R[st]), X0[st], io[station_camera[st]])
    w, h = image_size
    inside = ((xy[:, 0] >= margin) & (xy[:, 0] <= w - margin)
              & (xy[:, 1] >= margin) & (xy[:, 1] <= h - margin))
    return st[inside], pt[inside], xy[inside]


def observe(model_name, io, station_camera, R, X0, points, image_size,
            sigma=0.0, rng=None, margin=0.0) -> SyntheticNetwork:
    """Project every point into every station; keep those inside the image
    (with ``margin`` px) and in front of the camera; add N(0, sigma) noise.
    Stations are projected a few at a time (about ``_PAIRS`` station-point
    pairs), so the memory stays bounded; the result does not depend on it."""
    model = camera_model(model_name)
    io = np.atleast_2d(np.asarray(io, dtype=float))
    S, P = len(X0), len(points)
    step = max(1, _PAIRS // max(P, 1))
    parts = [_observe_stations(model, io, station_camera, R, X0, points, image_size, margin,
                               np.arange(s0, min(s0 + step, S)))
             for s0 in range(0, S, step)] or [(np.zeros(0, int), np.zeros(0, int),
                                               np.zeros((0, 2)))]
    st, pt, xy = (np.concatenate(a) for a in zip(*parts))
    rng = rng if rng is not None else np.random.default_rng(0)
    noisy = xy + (rng.normal(0.0, sigma, xy.shape) if sigma > 0 else 0.0)
    return SyntheticNetwork(model_name, io, tuple(image_size), np.asarray(station_camera),
                            R, X0, np.asarray(points, float), st, pt, xy, noisy)


def roll(R, angle):
    """Turn cameras about their viewing axis by ``angle`` (radians, (n,))."""
    a = np.broadcast_to(np.asarray(angle, dtype=float), (len(R),))
    c, s = np.cos(a), np.sin(a)
    Rz = np.zeros((len(a), 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, s, -s, c, 1.0
    return Rz @ R


def ring_stations(n, radius, height, target, jitter=0.0, rng=None, rolls=None):
    """``n`` stations on a horizontal circle around ``target``, looking at it;
    ``rolls`` (radians, cycled) turns them about their viewing axes, as a
    self-calibration network needs."""
    rng = rng if rng is not None else np.random.default_rng(0)
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    X0 = np.stack([target[0] + radius * np.cos(a), target[1] + radius * np.sin(a),
                   np.full(n, target[2] + height)], axis=1)
    X0 = X0 + rng.normal(0, jitter, X0.shape)
    R = look_at(X0, target)
    if rolls is not None:
        R = roll(R, np.resize(np.asarray(rolls, dtype=float), n))
    return X0, R


def to_project(net: SyntheticNetwork, *, control=(), check=(), sigma_image=0.3,
               camera_names=None, free_interior=(), point_sigma=None,
               perturb_points=0.0, perturb_stations=0.0, rng=None, name="synthetic"):
    """A :class:`~photogram.project.model.Project` of a synthetic network.

    Approximate values are the truth plus Gaussian perturbations
    (``perturb_points`` for unknown points, ``perturb_stations`` for
    positions; angles are perturbed by ``perturb_stations`` radians per unit
    of length, a rough but adequate start). Control/check points keep their
    true coordinates as reference values.
    """
    from photogram.project.model import (
        AdjustmentSettings, Camera, ImagePoints, Parameter, Points, Project, Stations)
    rng = rng if rng is not None else np.random.default_rng(0)
    model = camera_model(net.model_name)
    K = len(net.io)
    camera_names = camera_names or [f"K{k + 1}" for k in range(K)]
    cams = {}
    for k, cname in enumerate(camera_names):
        params = {p: Parameter(float(v), p in free_interior)
                  for p, v in zip(model.parameter_names, net.io[k])}
        cams[cname] = Camera(cname, net.model_name, params, image_size=tuple(net.image_size))
    S, P = len(net.X0), len(net.points)
    kind = np.array(["tie"] * P, dtype=object)
    kind[list(control)] = "control"
    kind[list(check)] = "check"
    xyz = net.points + rng.normal(0, perturb_points, net.points.shape) * (kind == "tie")[:, None]
    sig = np.full((P, 3), np.nan)
    if point_sigma is not None:
        sig[kind == "control"] = point_sigma
    from photogram.geometry import small_rotation
    R = small_rotation(rng.normal(0, perturb_stations, (S, 3))) @ net.R
    stations = Stations(names=[f"S{s + 1}" for s in range(S)],
                        camera=[camera_names[c] for c in net.station_camera],
                        position=net.X0 + rng.normal(0, perturb_stations, (S, 3)),
                        angles=matrix_to_opk(R),
                        position_sigma=np.full((S, 3), np.nan),
                        angle_sigma=np.full((S, 3), np.nan))
    points = Points(ids=[f"P{i + 1}" for i in range(P)], kind=kind, xyz=xyz, sigma=sig)
    obs = ImagePoints(station=net.station.copy(), point=net.point.copy(), xy=net.xy.copy(),
                      sigma=np.full(len(net.station), np.nan),
                      record=np.arange(len(net.station)) + 2)
    return Project(name=name, cameras=cams, stations=stations, points=points, image_points=obs,
                   adjustment=AdjustmentSettings(sigma_image=sigma_image))


def frame_network(n_stations=8, n_points=60, sigma=0.3, seed=0, model_name="brown",
                       io=(1420.0, 320.0, 240.0, -5e-8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)):
    """A convergent self-calibration network: a 0.5 x 0.5 x 0.3 m frame of
    target points seen from a ring of stations at 2 m, rolled by 0/90/180/270
    degrees (the geometry a lab calibration uses)."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-0.25, -0.25, 0.0], [0.25, 0.25, 0.3], (n_points, 3))
    X0, R = ring_stations(n_stations, 2.0, 1.0, np.array([0.0, 0.0, 0.15]), jitter=0.05,
                          rng=rng, rolls=[0, np.pi / 2, np.pi, -np.pi / 2])
    return observe(model_name, np.asarray(io, float), np.zeros(n_stations, int), R, X0, pts,
                   (640, 480), sigma=sigma, rng=rng)


def wall_geometry(n_stations=100, n_points=10_000, distance=10.0, rays=20, seed=0):
    """The truth of :func:`wall_network` before observing: ``(points, X0,
    R, io, image_size, rng)`` (rng positioned for the observation noise)."""
    rng = np.random.default_rng(seed)
    c, w, h = 1000.0, 4000, 3000
    window = distance * (w / 2 - 50) / c * 2          # wall width one image sees
    spacing = window / rays
    length = spacing * n_stations
    pts = np.stack([rng.uniform(0, length, n_points), rng.uniform(-0.5, 0.5, n_points),
                    rng.uniform(-distance * 1.2, distance * 1.2, n_points)], axis=1)
    X0 = np.stack([spacing * (np.arange(n_stations) + 0.5), np.full(n_stations, -distance),
                   rng.normal(0, 0.2, n_stations)], axis=1)
    R = look_at(X0, X0 + [0.0, distance, 0.0])
    io = np.array([c, w / 2, h / 2, 0, 0, 0, 0, 0, 0, 0])
    return pts, X0, R, io, (w, h), rng


def wall_network(n_stations=100, n_points=10_000, distance=10.0, rays=20, sigma=0.5, seed=0):
    """A large synthetic network for scaling tests: points on a wall with
    relief, stations along it at ``distance``, spaced so that each point is
    seen by about ``rays`` stations (c = 1000 px, 4000 x 3000 px images)."""
    pts, X0, R, io, size, rng = wall_geometry(n_stations, n_points, distance, rays, seed)
    return observe("brown", io, np.zeros(n_stations, int), R, X0, pts, size, sigma=sigma,
                   rng=rng, margin=5)
