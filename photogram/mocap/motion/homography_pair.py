"""The pieces of one frame pair of :mod:`photogram.mocap.motion.homography`
(Bachmann et al., eqs. (12)-(13)): the ideal pinhole matrices ``K_t`` of
the frames, undistorted keypoints, Hamming matching guided by a predicted
homography, and the rotation difference ``dR = D dR_cv D`` from a
homography (eq. (13)) or refitted to the inliers' unit rays (orthogonal
Procrustes). Each is a small function over arrays; the loop over the
frames, the settings and the lagged pairs are in ``homography``.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry import camera_model
from photogram.mocap.motion.lens import undistort_radius

__all__ = ["D", "pinhole_matrices", "rotation_from_homography", "rotation_from_rays",
           "undistort_points", "horizontal_fov", "guided_matches"]

#: photogrammetric from OpenCV camera axes: ``dR = D dR_cv D``
D = np.diag([1.0, -1.0, -1.0])


def pinhole_matrices(model: str, io, image_scale: float = 1.0) -> np.ndarray:
    """(F, 3, 3) ideal pinhole matrices of the frames at ``image_scale``:
    the model's pixels per unit of normalised coordinates and principal
    point at the centre of the image (``fx, fy, cx, cy`` for opencv), with
    the pixel-centre convention ``x_s = s (x + 0.5) - 0.5``."""
    m = camera_model(model)
    io = np.atleast_2d(np.asarray(io, dtype=float))
    n, eps = len(io), 1e-6
    zero = m.ray_to_image(np.zeros((n, 2)), io)
    fx = (m.ray_to_image(np.tile([eps, 0.0], (n, 1)), io)[:, 0] - zero[:, 0]) / eps
    fy = (m.ray_to_image(np.tile([0.0, eps], (n, 1)), io)[:, 1] - zero[:, 1]) / eps
    K = np.zeros((n, 3, 3))
    s = float(image_scale)
    K[:, 0, 0], K[:, 1, 1] = s * fx, s * fy
    K[:, 0, 2], K[:, 1, 2] = s * (zero[:, 0] + 0.5) - 0.5, s * (zero[:, 1] + 0.5) - 0.5
    K[:, 2, 2] = 1.0
    return K


def rotation_from_homography(H, K0, K1) -> np.ndarray:
    """Photogrammetric rotation difference (eq. (13)) of a homography H
    between ideal pixels of frames t (``K0``) and t+1 (``K1``): the rotation
    nearest to ``K1^{-1} H K0`` (scaled to determinant 1), ``D dR_cv D``."""
    A = np.linalg.solve(K1, H @ K0)
    det = np.linalg.det(A)
    A = A / np.cbrt(det)
    U, _, Vt = np.linalg.svd(A)
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return D @ R @ D


def rotation_from_rays(p0, p1, K0, K1, threshold: float, iterations: int = 2):
    """Rotation difference (photogrammetric ``dR``) fitted to corresponding
    ideal pixels p0 (frame t) and p1 (frame t+1), (n, 2) each.

    The unit rays ``u = normalise(K^-1 (p, 1))`` give ``dR_cv`` by the
    orthogonal Procrustes problem (Kabsch: maximise ``sum u1 . dR_cv u0``);
    the pairs whose reprojection ``K1 dR_cv u0`` misses p1 by more than
    ``threshold`` px are dropped and the fit repeated (``iterations``).

    Returns
    -------
    dR : (3, 3)
    inliers : (n,) bool
    """
    def rays(p, K):
        r = np.column_stack([p, np.ones(len(p))]) @ np.linalg.inv(K).T
        return r / np.linalg.norm(r, axis=1, keepdims=True)

    u0, u1 = rays(p0, K0), rays(p1, K1)
    keep = np.ones(len(p0), bool)
    R = np.eye(3)
    for _ in range(iterations + 1):
        if keep.sum() < 3:
            break
        U, _, Vt = np.linalg.svd(u1[keep].T @ u0[keep])
        R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
        x = (u0 @ R.T) @ K1.T
        with np.errstate(divide="ignore", invalid="ignore"):
            err = np.linalg.norm(x[:, :2] / x[:, 2:] - p1, axis=1)
        keep = err < threshold
    return D @ R @ D, keep


def undistort_points(model: str, xy, io_row) -> np.ndarray:
    """Normalised coordinates (n, 2) of full-resolution pixels (n, 2) of one
    frame: ``camera_model(model).image_to_ray``, or for the radial OpenCV
    model (p1 = p2 = 0) the same values by the faster radius inversion."""
    xy = np.atleast_2d(np.asarray(xy, dtype=float))
    io = np.asarray(io_row, dtype=float)
    if model == "opencv" and io[6] == 0 and io[7] == 0:
        d = (xy - io[2:4]) / io[0:2]
        rd = np.hypot(d[:, 0], d[:, 1])
        ru = undistort_radius(rd, io[4], io[5], io[8])
        return d * np.where(rd > 0, ru / np.where(rd > 0, rd, 1.0), 1.0)[:, None]
    return camera_model(model).image_to_ray(xy, np.broadcast_to(io, (len(xy), len(io))))


def horizontal_fov(K, width: int) -> float:
    """Horizontal field of view (rad) of an ideal pinhole K (3, 3) and an
    image ``width`` px wide (the same scale as K)."""
    return float(2.0 * np.arctan(0.5 * width / K[0, 0]))


def guided_matches(p0, d0, p1, d1, H, radius: float, max_hamming: int):
    """Mutual best matches (i0, i1) of binary descriptors among the features
    of frame t+1 within ``radius`` px of the positions predicted by the
    homography H (3, 3) for the features of frame t (vectorised: the
    features of t+1 are bucketed in cells of ``radius``)."""
    q = np.column_stack([p0, np.ones(len(p0))]) @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        q = q[:, :2] / q[:, 2:]
    good = np.all(np.isfinite(q), axis=1) & np.all(np.abs(q) < 1e6, axis=1)
    i0 = np.flatnonzero(good)
    q = q[good]
    cell1 = np.floor(p1 / radius).astype(np.int64)
    lo_c = np.minimum(cell1.min(0), np.floor(q.min(0, initial=0) / radius)) - 1
    span = int(max(cell1[:, 1].max(), np.floor(q[:, 1].max(initial=0) / radius)) - lo_c[1] + 2)
    key1 = (cell1[:, 0] - lo_c[0]) * span + (cell1[:, 1] - lo_c[1])
    order = np.argsort(key1, kind="stable")
    sk = key1[order]
    c0 = np.floor(q / radius).astype(np.int64) - lo_c
    off = np.array([dx * span + dy for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    keys = (c0[:, 0] * span + c0[:, 1])[:, None] + off[None, :]          # (n, 9)
    lo = np.searchsorted(sk, keys.ravel(), "left")
    cnt = np.searchsorted(sk, keys.ravel(), "right") - lo
    i = np.repeat(np.repeat(np.arange(len(q)), 9), cnt)
    j = order[np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(int(cnt.sum()))]
    dq = (q[i] - p1[j]).astype(np.float32)
    close = np.einsum("ij,ij->i", dq, dq) < np.float32(radius * radius)
    i, j = i[close], j[close]
    if not len(i):
        return i, j
    dist = np.bitwise_count(d0.view(np.uint64)[i0[i]] ^ d1.view(np.uint64)[j]).sum(axis=1)
    keep = dist <= max_hamming
    i, j, dist = i0[i[keep]], j[keep], dist[keep].astype(np.int64)
    big = np.iinfo(np.int64).max
    best_j = np.full(len(p0), big)                  # dist * 2^32 + j, smallest per i
    np.minimum.at(best_j, i, (dist << 32) + j)
    best_i = np.full(len(p1), big)
    np.minimum.at(best_i, j, (dist << 32) + i)
    a = np.flatnonzero(best_j < big)
    b = best_j[a] & 0xFFFFFFFF
    mutual = (best_i[b] & 0xFFFFFFFF) == a
    return a[mutual], b[mutual]
