"""Closed-form starts of the relative orientation of a stereo pair.

Frames and the essential matrix as in :mod:`photogram.init.relative`
(``E_cv = -D R2 [b]x D`` with ``D = diag(1, -1, -1)``).

Closed-form start: the normalized 8-point algorithm (Hartley 1997) with
``n >= 8`` points and a non-degenerate design matrix, and the 5-point
algorithm (Nistér 2004, via OpenCV's ``findEssentialMat``) for 5-7 points
or a critical (e.g. planar) configuration, plus the decomposition of the
homography for planar scenes; each essential matrix gives four ``(R, t)``
of which chirality (points in front of both cameras) keeps one (Hartley &
Zisserman 2003, result 9.19). Also the zero-baseline model
(:func:`rotation_only_fit`).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError
from photogram.init.dlt import FLIP, _normalizing_transform
from photogram.init.intersection import intersect_points
from photogram.init.rays import bearings

__all__ = ["rotation_only_fit", "eight_point", "decompose_essential", "sampson_errors",
           "essential_candidates", "homography_candidates", "FLIP"]


def rotation_only_fit(xy1, xy2, c1, c2) -> tuple[np.ndarray, float]:
    """Best pure rotation between two images (zero baseline model).

    The rotation ``R`` minimising ``sum |d2 - R d1|^2`` for the unit rays
    ``d = (x̄, -ȳ, -c)/|.|`` (Kabsch / orthogonal Procrustes): for a pure
    rotation about the projection centre the images are related by the
    infinite homography ``K2 R K1^-1`` and this fit is exact.

    Parameters
    ----------
    xy1, xy2 : ndarray (n, 2)
        Ideal image coordinates reduced to the principal point.
    c1, c2 : float

    Returns
    -------
    R : ndarray (3, 3)
        Camera-1-to-camera-2 rotation.
    rms : float
        RMS residual per image coordinate in image units (angular residual
        times the mean principal distance).
    """
    d1, d2 = bearings(xy1, c1), bearings(xy2, c2)
    U, _, Vt = np.linalg.svd(d2.T @ d1)
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ S @ Vt
    ang = np.linalg.norm(np.cross(d1 @ R.T, d2), axis=1)
    rms = float(np.sqrt(np.mean(ang ** 2) / 2.0)) * 0.5 * (c1 + c2)
    return R, rms


def eight_point(u1, u2) -> tuple[np.ndarray, float]:
    """Normalized 8-point essential matrix (Hartley 1997).

    Solves ``ũ2^T E ũ1 = 0`` for the normalized computer-vision coordinates
    ``ũ = (x̄/c, ȳ/c, 1)`` after Hartley's conditioning, then projects ``E``
    onto the essential manifold (singular values 1, 1, 0).

    Parameters
    ----------
    u1, u2 : ndarray (n, 2), n >= 8

    Returns
    -------
    E : ndarray (3, 3)
    conditioning : float
        ``s_8 / s_9`` of the conditioned design matrix: large for a
        well-determined solution, about 1 when the configuration is critical
        (e.g. all points on a plane) or the data pure noise.
    """
    T1, T2 = _normalizing_transform(u1), _normalizing_transform(u2)
    h1 = np.c_[u1, np.ones(len(u1))] @ T1.T
    h2 = np.c_[u2, np.ones(len(u2))] @ T2.T
    A = (h2[:, :, None] * h1[:, None, :]).reshape(len(u1), 9)
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    En = Vt[-1].reshape(3, 3)
    E = T2.T @ En @ T1
    U, _, Vt = np.linalg.svd(E)
    E = U @ np.diag([1.0, 1.0, 0.0]) @ Vt
    cond = float(s[7] / max(s[8], 1e-300 * s[0])) if len(s) >= 9 else 1.0
    return E, cond


def decompose_essential(E) -> list[tuple[np.ndarray, np.ndarray]]:
    """The four ``(R_cv, t_cv)`` of an essential matrix ``E = [t]x R``
    (computer-vision frame, ``|t| = 1``; Hartley & Zisserman result 9.19)."""
    U, _, Vt = np.linalg.svd(E)
    if np.linalg.det(U) < 0:
        U = -U
    if np.linalg.det(Vt) < 0:
        Vt = -Vt
    W = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    t = U[:, 2]
    out = []
    for R in (U @ W @ Vt, U @ W.T @ Vt):
        for s in (1.0, -1.0):
            out.append((R, s * t))
    return out


def _cv_to_photogrammetric(R_cv, t_cv):
    """(R_cv, t_cv) of ``x2 = R_cv x1 + t_cv`` (computer-vision frames) to
    ``(R2, X0_2)`` in the model frame of the photogrammetric left camera."""
    R2 = FLIP @ R_cv @ FLIP
    X0 = -FLIP @ R_cv.T @ t_cv
    return R2, X0


def sampson_errors(E, u1, u2) -> np.ndarray:
    """Squared Sampson distances of point pairs to the epipolar geometry
    ``ũ2^T E ũ1 = 0`` (normalized units squared)."""
    h1 = np.c_[u1, np.ones(len(u1))]
    h2 = np.c_[u2, np.ones(len(u2))]
    Ex1 = h1 @ E.T
    Etx2 = h2 @ E
    num = np.einsum("ni,ni->n", h2, Ex1) ** 2
    den = Ex1[:, 0] ** 2 + Ex1[:, 1] ** 2 + Etx2[:, 0] ** 2 + Etx2[:, 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / den, np.inf)


def _five_point(u1, u2, threshold):
    import cv2
    Es, _ = cv2.findEssentialMat(np.ascontiguousarray(u1, dtype=np.float64),
                                 np.ascontiguousarray(u2, dtype=np.float64),
                                 np.eye(3), method=cv2.RANSAC, prob=0.9999,
                                 threshold=float(threshold))
    if Es is None or not np.size(Es):
        return []
    return list(np.asarray(Es, dtype=float).reshape(-1, 3, 3))


def essential_candidates(u1, u2, *, threshold: float = 1e-3, subsets: int = 10,
                         keep: int = 3, seed: int = 0) -> list[np.ndarray]:
    """Essential-matrix candidates for normalized coordinates (n >= 5).

    * the normalized 8-point solution (n >= 8, if not critical);
    * the best RANSAC hypothesis of OpenCV's 5-point ``findEssentialMat``
      on all points (``threshold`` in normalized units);
    * all 5-point solutions of ``subsets`` random 5-point subsets (all of
      them for n = 5), of which the ``keep`` with the smallest truncated
      Sampson error over all points are kept. Several candidates matter
      where the solution is not unique from the data's point of view, e.g.
      a planar scene (two solutions) or five points (up to ten).

    Parameters
    ----------
    u1, u2 : ndarray (n, 2)
        Normalized computer-vision coordinates ``(x̄/c, ȳ/c)``.
    threshold : float
        RANSAC inlier threshold and truncation of the Sampson score.
    subsets, keep, seed :
        Number of random minimal subsets, candidates kept from them, and
        the seed (the result is deterministic).

    Returns
    -------
    list of ndarray (3, 3)
    """
    cands = []
    n = len(u1)
    if n >= 8:
        E, cond = eight_point(u1, u2)
        if cond > 3.0:
            cands.append(E)
    try:
        cands.extend(_five_point(u1, u2, threshold)[:10 if n == 5 else 1])
        if n > 5:
            rng = np.random.default_rng(seed)
            pool = []
            for _ in range(subsets):                  # loop over minimal subsets
                idx = rng.choice(n, 5, replace=False)
                pool.extend(_five_point(u1[idx], u2[idx], threshold))
            if pool:
                score = np.array([np.minimum(sampson_errors(E, u1, u2), threshold ** 2).sum()
                                  for E in pool])
                chosen = []
                for k in np.argsort(score):
                    E = pool[k] / np.linalg.norm(pool[k])
                    if not any(min(np.abs(E - F).max(), np.abs(E + F).max()) < 1e-6
                               for F in chosen):
                        chosen.append(E)
                    if len(chosen) >= keep:
                        break
                cands.extend(chosen)
    except ImportError:                                # pragma: no cover - cv2 optional
        pass
    return cands


def homography_candidates(u1, u2) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(R_cv, t_cv)`` (``|t| = 1``) from the decomposition of the
    homography between the normalized images (Faugeras & Lustman 1988, via
    OpenCV): the solutions of a planar scene, which the essential matrix
    determines only up to a twofold ambiguity."""
    try:
        import cv2
    except ImportError:                                # pragma: no cover
        return []
    if len(u1) < 4:
        return []
    H, _ = cv2.findHomography(np.ascontiguousarray(u1, dtype=np.float64),
                              np.ascontiguousarray(u2, dtype=np.float64), 0)
    if H is None:
        return []
    _, Rs, ts, _ = cv2.decomposeHomographyMat(H, np.eye(3))
    out = []
    for R, t in zip(Rs, ts):
        t = np.asarray(t, dtype=float).ravel()
        nt = np.linalg.norm(t)
        if nt > 1e-12:
            out.append((np.asarray(R, dtype=float), t / nt))
    return out


# ---------------------------------------------------------------------------
# starts: chirality and distinct candidates


def _starts(xy1, xy2, c1, c2, threshold) -> list:
    """Starts ``(R2, b, X)`` for the refinement: the four poses of every
    essential-matrix candidate (and the two of every homography solution)
    reduced by chirality to the one with the most points in front of both
    cameras; those with (almost) all points in front, else the best one.

    Raises GeometryError when there is no candidate at all.
    """
    n = len(xy1)
    u1, u2 = xy1 / c1, xy2 / c2
    Es = essential_candidates(u1, u2, threshold=threshold)
    poses = [decompose_essential(E) for E in Es]
    poses += [[(R, t), (R, -t)] for R, t in homography_candidates(u1, u2)]
    starts = []
    fallback = None
    need = max(n - max(1, n // 10), 5)
    for group in poses:                            # loop over candidate solutions
        best = None
        for R_cv, t_cv in group:
            R2, b = _cv_to_photogrammetric(R_cv, t_cv)
            X = _triangulate(xy1, xy2, c1, c2, R2, b)
            z1 = X[:, 2]
            z2 = (X - b) @ R2[2]
            front = int(((z1 < 0) & (z2 < 0)).sum())
            if best is None or front > best[0]:
                best = (front, R2, b, X)
        if best is None:
            continue
        if best[0] >= need:
            starts.append(best[1:])
        elif fallback is None or best[0] > fallback[0]:
            fallback = best
    if not starts and fallback is not None:
        starts.append(fallback[1:])                # judged after refinement
    if not starts:
        raise GeometryError(
            f"relative orientation: no essential matrix found for the {n} points",
            hint="check the point correspondences and the principal distances")
    return starts


def _triangulate(xy1, xy2, c1, c2, R2, b):
    n = len(xy1)
    idx = np.repeat(np.arange(n), 2)
    xy = np.stack([xy1, xy2], axis=1).reshape(-1, 2)
    R = np.stack([np.broadcast_to(np.eye(3), (n, 3, 3)),
                  np.broadcast_to(R2, (n, 3, 3))], axis=1).reshape(-1, 3, 3)
    X0 = np.stack([np.zeros((n, 3)), np.broadcast_to(b, (n, 3))], axis=1).reshape(-1, 3)
    c = np.tile([c1, c2], n)
    res = intersect_points(idx, xy, R, X0, c, min_angle_deg=0.0, strict=False,
                           max_iterations=3)
    return res.X


def _distinct(starts, tol: float = 0.02):
    """Starts that differ by more than ``tol`` (radians) in rotation or
    baseline direction (nearby starts lie in the same basin; the first one,
    from the better closed form, is kept)."""
    out = []
    for R2, b, X in starts:
        bu = b / np.linalg.norm(b)
        same = False
        for R, bb, _ in out:
            ang = np.arccos(np.clip((np.trace(R2 @ R.T) - 1) / 2, -1, 1))
            bang = np.arccos(np.clip(bu @ (bb / np.linalg.norm(bb)), -1, 1))
            if ang < tol and bang < tol:
                same = True
                break
        if not same:
            out.append((R2, b.copy(), X.copy()))
    return out
