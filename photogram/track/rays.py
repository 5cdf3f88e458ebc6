"""Triangulation and epipolar distances of tracked markers, vectorised over
many points (frames x markers) at once.

The cameras are :class:`photogram.lines.views.ViewCamera` (measured px in,
distortion corrected through the camera model). A point seen in k >= 2
views is the least-squares point nearest to its k rays, the *midpoint*
method generalised to k rays (Hartley & Zisserman 2003, sec. 12.3 lists it;
``sum_i (I - d_i d_i^T) (X - X0_i) = 0``): closed form, one 3 x 3 solve per
point, accurate enough to gate and check correspondences (the adjustment
of ``photogram intersect`` does the final, weighted intersection). The
check of a correspondence is its reprojection residual in px.
"""

from __future__ import annotations

import numpy as np

from photogram.lines.views import ViewCamera

__all__ = ["triangulate", "reprojection_residuals", "epipolar_distances"]


def triangulate(cameras: list[ViewCamera], xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points nearest to their rays (module doc).

    Parameters
    ----------
    cameras : list of k ViewCamera
    xy : (k, n, 2)
        Measured image coordinates per camera; NaN where a camera does not
        see the point.

    Returns
    -------
    X : (n, 3)
        NaN where fewer than two views see the point (or the rays are parallel).
    n_views : (n,) int
    """
    xy = np.asarray(xy, dtype=float)
    k, n = xy.shape[:2]
    A = np.zeros((n, 3, 3))
    b = np.zeros((n, 3))
    seen = np.isfinite(xy).all(axis=2)                                # (k, n)
    for i, cam in enumerate(cameras):
        s = seen[i]
        if not s.any():
            continue
        d = cam.rays(cam.ideal(xy[i, s]))                               # (m, 3)
        Pm = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
        A[s] += Pm
        b[s] += Pm @ cam.X0
    nv = seen.sum(axis=0)
    X = np.full((n, 3), np.nan)
    ok = nv >= 2
    if ok.any():
        det = np.linalg.det(A[ok])
        good = np.abs(det) > 1e-12
        idx = np.nonzero(ok)[0][good]
        X[idx] = np.linalg.solve(A[idx], b[idx][:, :, None])[:, :, 0]
    return X, nv


def reprojection_residuals(cameras: list[ViewCamera], X: np.ndarray,
                           xy: np.ndarray) -> np.ndarray:
    """Distances (k, n) px between ``xy`` (k, n, 2) and the projections of
    ``X`` (n, 3); NaN where either is missing."""
    out = np.full(xy.shape[:2], np.nan)
    ok = np.isfinite(X).all(axis=1)
    for i, cam in enumerate(cameras):
        if ok.any():
            q = cam.project(X[ok])
            out[i, ok] = np.hypot(*(q - xy[i, ok]).T)
    return out


def epipolar_distances(cam_a: ViewCamera, cam_b: ViewCamera, xa: np.ndarray,
                       xb: np.ndarray) -> np.ndarray:
    """Symmetric epipolar distance (n,) in ideal px of measured points ``xa``
    in ``cam_a`` and ``xb`` in ``cam_b`` (both (n, 2)): the mean of the
    distances of each point from the epipolar line of the other, with the
    fundamental matrix of the two ideal projection matrices
    (:func:`photogram.measure.epipolar.fundamental`)."""
    from photogram.measure.epipolar import fundamental
    F = fundamental(cam_a.matrix, cam_b.matrix)
    ha = np.column_stack([cam_a.ideal(xa), np.ones(len(xa))])
    hb = np.column_stack([cam_b.ideal(xb), np.ones(len(xb))])
    lb = ha @ F.T                                  # lines in b
    la = hb @ F                                    # lines in a
    with np.errstate(invalid="ignore", divide="ignore"):
        db = np.abs((lb * hb).sum(1)) / np.hypot(lb[:, 0], lb[:, 1])
        da = np.abs((la * ha).sum(1)) / np.hypot(la[:, 0], la[:, 1])
    return 0.5 * (da + db)
