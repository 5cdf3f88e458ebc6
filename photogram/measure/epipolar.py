"""Uncoded targets of a 3D field without a layout: matched across views.

Once the coded targets orient the images (a projection matrix per image by
DLT from six or more codes, :mod:`photogram.measure.space`), an uncoded
target seen in image i lies on its epipolar line in image j,
``l = F_ij x`` with the fundamental matrix of the two projection matrices
(``F = [e']_x P' P^+``, Hartley & Zisserman eq. 9.1). Every pair of plain
detections within ``tol`` px of each other's epipolar lines is triangulated
(DLT triangulation) and the point is projected into all other images: a
*track* is the set of detections within ``tol`` px of the projections. A
track seen in at least ``min_views`` images, none of whose detections is
claimed by a better track (more views, then smaller reprojection RMS),
becomes a new target ``U0001``, ``U0002``, ... numbered in every image of
its track. A pair that is consistent in two views only is not enough (any
point on the epipolar line would do); the third view decides, which is
what makes the matching safe.
"""

from __future__ import annotations

import numpy as np

from photogram.measure.network import triangulate

__all__ = ["fundamental", "match_tracks"]


def fundamental(P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
    """F with ``x2^T F x1 = 0`` for the projection matrices P1, P2."""
    _, _, vt = np.linalg.svd(P1)
    C = vt[-1]                                   # centre of camera 1 (null vector)
    e2 = P2 @ C
    ex = np.array([[0, -e2[2], e2[1]], [e2[2], 0, -e2[0]], [-e2[1], e2[0], 0]])
    return ex @ P2 @ np.linalg.pinv(P1)


def _project(P, X):
    h = np.append(X, 1.0) @ P.T
    return h[:2] / h[2], h[2]


def match_tracks(points: list[np.ndarray], Ps: list[np.ndarray], *, tol: float = 1.5,
                 min_views: int = 3, prefix: str = "U"):
    """Tracks of uncoded targets over oriented images (module doc).

    Parameters
    ----------
    points : per image, (n_i, 2) plain detections (px)
    Ps : per image, its (3, 4) projection matrix (None: not oriented)
    tol : px, epipolar and reprojection tolerance
    min_views : views a track needs

    Returns
    -------
    labels : per image, (n_i,) object array of new ids ("" unmatched)
    xyz : dict id -> (3,) triangulated coordinates
    """
    from scipy.spatial import cKDTree
    m = len(points)
    trees = [cKDTree(p) if len(p) else None for p in points]
    cands = []
    for i in range(m):
        for j in range(i + 1, m):
            if Ps[i] is None or Ps[j] is None or not len(points[i]) or not len(points[j]):
                continue
            F = fundamental(Ps[i], Ps[j])
            h1 = np.column_stack([points[i], np.ones(len(points[i]))])
            h2 = np.column_stack([points[j], np.ones(len(points[j]))])
            lines = h1 @ F.T                                      # epipolar lines in j
            lines /= np.linalg.norm(lines[:, :2], axis=1, keepdims=True)
            dist = np.abs(lines @ h2.T)                           # (n_i, n_j)
            for a, b in zip(*np.nonzero(dist < tol)):
                cands.append((i, a, j, b))
    tracks = []
    for i, a, j, b in cands:
        X = triangulate([Ps[i], Ps[j]], np.array([points[i][a], points[j][b]]))
        members = {}
        err = []
        for k in range(m):
            if Ps[k] is None or trees[k] is None:
                continue
            q, depth = _project(Ps[k], X)
            if depth <= 0 or not np.isfinite(q).all():
                continue
            d, idx = trees[k].query(q)
            if d < tol:
                members[k] = int(idx)
                err.append(d)
        if members.get(i) != a or members.get(j) != b or len(members) < min_views:
            continue
        Pl = [Ps[k] for k in members]
        X = triangulate(Pl, np.array([points[k][v] for k, v in members.items()]))
        rms = float(np.sqrt(np.mean([np.sum((_project(Ps[k], X)[0] - points[k][v]) ** 2)
                                     for k, v in members.items()])))
        if rms < tol:
            tracks.append((len(members), rms, members, X))
    tracks.sort(key=lambda t: (-t[0], t[1]))
    labels = [np.full(len(p), "", dtype=object) for p in points]
    xyz = {}
    n = 0
    seen = set()
    for nv, rms, members, X in tracks:
        key = tuple(sorted(members.items()))
        if key in seen or any(labels[k][v] for k, v in members.items()):
            continue
        seen.add(key)
        n += 1
        pid = f"{prefix}{n:04d}"
        for k, v in members.items():
            labels[k][v] = pid
        xyz[pid] = X
    return labels, xyz
