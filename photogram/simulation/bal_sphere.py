"""SIMULATED Bundle-Adjustment-in-the-Large problems: cameras on a sphere
looking in at points inside it, every point seen by 3-10 neighbouring
cameras (benchmarks/bal_scaling.py, tests of the reduced camera system).

The problem is returned in BAL's own conventions
(:class:`photogram.io.bal.BALProblem`: camera looks along -z, y up,
Rodrigues rotation, ``P = R X + t``, ``p = -P / P_z``,
``x = f (1 + k1 |p|^2 + k2 |p|^4) p``) with the observations made from the
true values plus Gaussian noise, and the cameras and points perturbed as
the start.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.geometry import matrix_to_rodrigues
from photogram.io.bal import BALProblem

__all__ = ["SphereBAL", "sphere_bal", "project_bal"]


@dataclass
class SphereBAL:
    """A SIMULATED BAL problem (start values) and its truth."""

    problem: BALProblem          # perturbed start, noisy observations
    true_cameras: np.ndarray     # (n_c, 9)
    true_points: np.ndarray      # (n_p, 3)


def _look_at_origin(C):
    """Rotations (n, 3, 3) of cameras at C whose -z axis points at the
    origin (BAL looks along -z)."""
    z = C / np.linalg.norm(C, axis=1, keepdims=True)          # camera +z: away from origin
    up = np.where(np.abs(z[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    x = np.cross(up, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)                          # rows: camera axes


def project_bal(cameras, points, camera, point):
    """Image coordinates (N, 2) of ``points[point]`` in ``cameras[camera]``
    (BAL's projection)."""
    from photogram.geometry import rodrigues_to_matrix
    R = rodrigues_to_matrix(cameras[:, :3])
    P = np.einsum("nij,nj->ni", R[camera], points[point]) + cameras[camera, 3:6]
    p = -P[:, :2] / P[:, 2:3]
    n2 = np.sum(p * p, axis=1)
    f, k1, k2 = cameras[camera, 6], cameras[camera, 7], cameras[camera, 8]
    return (f * (1.0 + k1 * n2 + k2 * n2 * n2))[:, None] * p


def sphere_bal(n_cameras: int, obs_per_camera: int = 3000, views=(3, 10), radius: float = 4.0,
               noise: float = 0.5, perturb_points: float = 0.01, perturb_rotation: float = 0.002,
               perturb_centre: float = 0.01, seed: int = 0) -> SphereBAL:
    """A SIMULATED BAL problem of ``n_cameras`` cameras on a sphere.

    Parameters
    ----------
    n_cameras : int
        Cameras on a Fibonacci sphere of ``radius``, all looking at the
        origin (f 800 px, k1 and k2 small, different per camera).
    obs_per_camera : int
        About this many observations per camera: the number of points is
        ``n_cameras * obs_per_camera / mean(views)``.
    views : (int, int)
        Each point (uniform in the unit ball) is seen by k cameras, k
        uniform in ``views`` (inclusive): the k cameras nearest to a random
        point on the camera sphere near the point's direction (a local
        camera graph, as in real reconstructions).
    noise : float
        Gaussian noise of the observations (px).
    perturb_points, perturb_rotation, perturb_centre : float
        Standard deviations of the start values' errors (units, rad, units).
    seed : int
    """
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(seed)
    lo, hi = views
    i = np.arange(n_cameras) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / n_cameras)
    theta = np.pi * (1.0 + 5.0 ** 0.5) * i
    C = radius * np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi),
                           np.cos(phi)], axis=1)
    R = _look_at_origin(C)
    cams = np.zeros((n_cameras, 9))
    cams[:, :3] = matrix_to_rodrigues(R)
    cams[:, 3:6] = -np.einsum("nij,nj->ni", R, C)
    cams[:, 6] = 800.0 * (1.0 + 0.05 * rng.standard_normal(n_cameras))
    cams[:, 7] = 0.02 * rng.standard_normal(n_cameras)
    cams[:, 8] = 0.005 * rng.standard_normal(n_cameras)
    n_points = max(1, int(round(n_cameras * obs_per_camera / (0.5 * (lo + hi)))))
    u = rng.standard_normal((n_points, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pts = u * rng.uniform(0.0, 1.0, (n_points, 1)) ** (1.0 / 3.0)
    k = rng.integers(lo, hi + 1, n_points)
    kmax = min(hi, n_cameras)
    k = np.minimum(k, kmax)
    look = u + 0.3 * rng.standard_normal((n_points, 3))
    look *= radius / np.linalg.norm(look, axis=1, keepdims=True)
    _, near = cKDTree(C).query(look, k=kmax)
    near = near.reshape(n_points, kmax)
    take = np.arange(kmax)[None, :] < k[:, None]
    point = np.broadcast_to(np.arange(n_points)[:, None], near.shape)[take]
    camera = near[take]
    order = np.lexsort((point, camera))
    camera, point = camera[order].astype(np.int64), point[order].astype(np.int64)
    xy = project_bal(cams, pts, camera, point) + noise * rng.standard_normal((len(camera), 2))
    start = cams.copy()
    from photogram.geometry import rodrigues_to_matrix
    dR = rodrigues_to_matrix(perturb_rotation * rng.standard_normal((n_cameras, 3)))
    R0 = np.einsum("nij,njk->nik", dR, R)
    C0 = C + perturb_centre * rng.standard_normal(C.shape)
    start[:, :3] = matrix_to_rodrigues(R0)
    start[:, 3:6] = -np.einsum("nij,nj->ni", R0, C0)
    p0 = pts + perturb_points * rng.standard_normal(pts.shape)
    bal = BALProblem(start, p0, camera, point, xy, name=f"sphere-{n_cameras}-{seed}")
    return SphereBAL(bal, cams, pts)
