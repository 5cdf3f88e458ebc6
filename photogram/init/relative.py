"""Relative orientation of a stereo pair.

Frames (see :mod:`photogram.project.model`): ``Xc = R (X - X0)``, the
photogrammetric camera frame (x right, y up, looking along -z), image
coordinates with y down. The model frame of a relative orientation is the
camera frame of the left image: ``R1 = I``, ``X0_1 = 0``; the right station
has ``R2`` and ``X0_2 = b`` with the baseline scaled to ``|b_x| = 1``
("dependent" relative orientation).

Coplanarity condition. With the image rays in the model frame

    p1 = (x̄1, -ȳ1, -c1),   p2 = R2^T (x̄2, -ȳ2, -c2)

the rays and the baseline are coplanar, ``b · (p1 × p2) = 0``, i.e.

    p2_cam^T E p1 = 0,   E = R2 [b]x                                     (1)

(``p2_cam = R2 p2``). In the computer-vision camera frame (y down, z
forward: ``Xcv = D Xc``, ``D = diag(1, -1, -1)``) the normalized image
coordinates are simply ``(x̄/c, ȳ/c)``, the rotation ``R_cv = D R2 D`` and
the translation ``t_cv = -D R2 b``, so the essential matrix of the
computer-vision literature, ``E_cv = [t_cv]x R_cv``, is ``-D R2 [b]x D``.

Closed-form start: the normalized 8-point algorithm (Hartley 1997) with
``n >= 8`` points and a non-degenerate design matrix, and the 5-point
algorithm (Nistér 2004, via OpenCV's ``findEssentialMat``) for 5-7 points
or a critical (e.g. planar) configuration; each essential matrix gives four
``(R, t)`` of which chirality (points in front of both cameras) keeps one
(Hartley & Zisserman 2003, result 9.19).

Refinement: least squares of the *image residuals* of both images, i.e.
the bundle adjustment of the pair with the model points as unknowns
(equivalent to the Gauss-Helmert adjustment of the coplanarity condition
with the image coordinates as observations): 5 orientation unknowns
(rotation increment δ, ``R2 <- small_rotation(δ) R2``, and two baseline
unknowns, iterated on the unit sphere) and 3 per point. It is solved by
variable projection (Golub & Pereyra 2003): the points are kept at their
optimum for the current orientation (3x3 Gauss-Newton per point), the step
is the Levenberg-Marquardt-damped Schur-complement step of the orientation.
A joint step over points and orientation overshoots in the long curved
valley of narrow-field pairs (rotation about y against b_z); this does not.
The precision is that of the normal equations with ``|b_k| = 1`` held.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from photogram.errors import GeometryError
from photogram.init.intersection import intersect_points, max_intersection_angles

__all__ = ["RelativeOrientationResult", "relative_orientation", "essential_candidates",
           "homography_candidates", "eight_point", "decompose_essential", "sampson_errors",
           "rotation_only_fit"]

#: Camera-frame axis flip between the photogrammetric and the computer-vision frame.
FLIP = np.diag([1.0, -1.0, -1.0])


@dataclass
class RelativeOrientationResult:
    """A relatively oriented stereo pair (model frame = left camera frame).

    Attributes
    ----------
    R2 : ndarray (3, 3)
        World(model)-to-camera rotation of the right station.
    angles2 : ndarray (3,)
        Its omega-phi-kappa (radians).
    X0_2 : ndarray (3,)
        Right projection centre = baseline ``b``, scaled so that
        ``|b[fixed_component]| = 1`` (normally ``|b_x| = 1``).
    X : ndarray (n, 3)
        Model points.
    residuals1, residuals2 : ndarray (n, 2)
        Image residuals ``observed - computed`` in the left and right image.
    sigma0 : float
        A-posteriori sigma of an image coordinate,
        ``sqrt(v^T v / (4n - 3n - 5))`` (NaN for n = 5).
    covariance : ndarray (5, 5)
        Of ``(δx, δy, δz, b_j, b_k)`` (rotation increment, radians; the two
        free baseline components), scaled by ``sigma_image^2`` if given, else
        by ``sigma0^2``.
    sigma_X : ndarray (n, 3)
        Standard deviations of the model points (same scale).
    max_angle : ndarray (n,)
        Intersection angle of each point's two rays (radians).
    fixed_component : int
        Baseline component held at ±1 (0 = x).
    rotation_only_rms : float
        RMS image residual (image units) of the best pure-rotation fit, the
        parallax left for the baseline to explain.
    iterations : int
    converged : bool
    ambiguous : bool
        True when the solution may not be unique: only 5 points, or another
        candidate fitting as well (e.g. a planar scene).
    candidates : int
        Number of distinct refined candidates with all points in front.
    alternatives : list of (R2, X0_2, sigma0)
        The other distinct candidates that fit (almost) as well as the
        chosen one (see ``ambiguous``), best first.
    notes : list of str
    """

    R2: np.ndarray
    angles2: np.ndarray
    X0_2: np.ndarray
    X: np.ndarray
    residuals1: np.ndarray
    residuals2: np.ndarray
    sigma0: float
    covariance: np.ndarray
    sigma_X: np.ndarray
    max_angle: np.ndarray
    fixed_component: int
    rotation_only_rms: float
    iterations: int
    converged: bool
    ambiguous: bool
    candidates: int
    alternatives: list = field(default_factory=list)
    notes: list = field(default_factory=list)

    @property
    def baseline(self) -> np.ndarray:
        """Alias of ``X0_2``."""
        return self.X0_2


# ---------------------------------------------------------------------------
# closed-form pieces


def _rays(xy, c):
    """Unit rays in the photogrammetric camera frame, (x̄, -ȳ, -c)/|.|."""
    d = np.stack([xy[:, 0], -xy[:, 1], -np.broadcast_to(c, xy.shape[:1])], axis=1)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


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
    d1, d2 = _rays(xy1, c1), _rays(xy2, c2)
    U, _, Vt = np.linalg.svd(d2.T @ d1)
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ S @ Vt
    ang = np.linalg.norm(np.cross(d1 @ R.T, d2), axis=1)
    rms = float(np.sqrt(np.mean(ang ** 2) / 2.0)) * 0.5 * (c1 + c2)
    return R, rms


def _normalize2d(u):
    mu = u.mean(axis=0)
    dist = np.linalg.norm(u - mu, axis=1).mean()
    f = np.sqrt(2.0) / dist if dist > 0 else 1.0
    T = np.array([[f, 0, -f * mu[0]], [0, f, -f * mu[1]], [0, 0, 1.0]])
    return T


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
    T1, T2 = _normalize2d(u1), _normalize2d(u2)
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
# refinement of one candidate


def _skew(v):
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def _small_rotation(d):
    from photogram.geometry.rotations import small_rotation
    return np.asarray(small_rotation(np.asarray(d, dtype=float)), dtype=float)


@dataclass
class _Fit:
    R2: np.ndarray
    b: np.ndarray
    X: np.ndarray
    cost: float
    r1: np.ndarray
    r2: np.ndarray
    behind: int
    iterations: int
    converged: bool
    S: np.ndarray | None
    Npp_inv: np.ndarray | None
    Npc: np.ndarray | None
    k_fixed: int


def _proj(Xc, c):
    """Ideal projection (x̄, ȳ) of camera coordinates and its Jacobian
    d(x̄, ȳ)/dXc (n, 2, 3); lean version of
    :func:`photogram.init.intersection.project_ideal` for the inner loops."""
    iz = 1.0 / Xc[:, 2]
    u = Xc[:, 0] * iz
    v = Xc[:, 1] * iz
    xy = np.stack([-c * u, c * v], axis=1)
    J = np.zeros((len(Xc), 2, 3))
    J[:, 0, 0] = -c * iz
    J[:, 0, 2] = c * u * iz
    J[:, 1, 1] = c * iz
    J[:, 1, 2] = -c * v * iz
    return xy, J


def _residuals(xy1, xy2, c1, c2, R2, b, X):
    """Image residuals ``observed - computed`` of both images."""
    iz1 = 1.0 / X[:, 2]
    Xc2 = (X - b) @ R2.T
    iz2 = 1.0 / Xc2[:, 2]
    p1 = np.stack([-c1 * X[:, 0] * iz1, c1 * X[:, 1] * iz1], axis=1)
    p2 = np.stack([-c2 * Xc2[:, 0] * iz2, c2 * Xc2[:, 1] * iz2], axis=1)
    return xy1 - p1, xy2 - p2


def _tangent_basis(b):
    """Orthonormal basis (3, 2) of the plane perpendicular to the unit b."""
    a = np.zeros(3)
    a[int(np.argmin(np.abs(b)))] = 1.0
    t1 = np.cross(b, a)
    t1 /= np.linalg.norm(t1)
    return np.stack([t1, np.cross(b, t1)], axis=1)


def _blocks(xy1, xy2, c1, c2, R2, b, X, Tb, r1, r2):
    """Normal-equation blocks of the pair bundle for the residuals
    ``r = obs - f``: points (n, 3, 3), points x orientation (n, 3, 5),
    orientation (5, 5) and the right-hand sides. ``Tb`` (3, 2) maps the two
    baseline unknowns to ``db``."""
    _, J1X = _proj(X, c1)                                             # dXc1/dX = I
    Xc2 = (X - b) @ R2.T
    _, J2c = _proj(Xc2, c2)
    J2X = J2c @ R2                                                    # dXc2/dX = R2
    Jc = np.concatenate([-J2c @ _skew(Xc2),                           # dXc2/dδ = -[Xc2]x
                         -J2X @ Tb], axis=2)                          # dXc2/db = -R2
    Npp = np.einsum("nki,nkj->nij", J1X, J1X) + np.einsum("nki,nkj->nij", J2X, J2X)
    Npc = np.einsum("nki,nkj->nij", J2X, Jc)
    Ncc = np.einsum("nki,nkj->ij", Jc, Jc)
    gp = np.einsum("nki,nk->ni", J1X, r1) + np.einsum("nki,nk->ni", J2X, r2)
    gc = np.einsum("nki,nk->i", Jc, r2)
    return Npp, Npc, Ncc, gp, gc


def _refine(xy1, xy2, c1, c2, R2, b, X, fixed_component, max_iterations, tol):
    """Bundle of the pair by variable projection (see the module docstring).

    Iterates with the baseline on the unit sphere (two tangent unknowns),
    the points always at their optimum for the current orientation, at most
    ``max_iterations`` Levenberg-Marquardt steps of the five orientation
    unknowns; then rescales to ``|b_k| = 1`` and forms the normal equations
    with ``b_k`` fixed for the precision estimate (same minimum).
    """
    s0 = np.linalg.norm(b)
    b = b / s0
    X = X / s0

    def behind(R2, b, X):
        z1 = X[:, 2]
        z2 = (X - b) @ R2[2]
        return int(((z1 >= 0) | (z2 >= 0)).sum())

    def cost_of(R2, b, X):
        r1, r2 = _residuals(xy1, xy2, c1, c2, R2, b, X)
        return float((r1 ** 2).sum() + (r2 ** 2).sum()), r1, r2

    def points_opt(R2, b, X):
        """Optimal points for fixed cameras (Gauss-Newton on each 3x3 block)."""
        for _ in range(10):
            Xc2 = (X - b) @ R2.T
            p1, J1 = _proj(X, c1)
            p2, J2c = _proj(Xc2, c2)
            J2 = J2c @ R2
            r1, r2 = xy1 - p1, xy2 - p2
            N = np.einsum("nki,nkj->nij", J1, J1) + np.einsum("nki,nkj->nij", J2, J2)
            g = np.einsum("nki,nk->ni", J1, r1) + np.einsum("nki,nk->ni", J2, r2)
            try:
                dX = np.linalg.solve(N, g[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                break
            X = X + dX
            if not np.all(np.isfinite(X)) or \
                    np.abs(dX).max() <= 1e-11 * max(1.0, np.abs(X).max()):
                break
        return X

    X = points_opt(R2, b, X)
    cost, r1, r2 = cost_of(R2, b, X)
    lam = 0.0
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        # variable projection: the points are always at their optimum for the
        # current orientation, the step is the Schur-complement step of the
        # five orientation unknowns (Levenberg-Marquardt damped)
        Tb = _tangent_basis(b)
        Npp, Npc, Ncc, gp, gc = _blocks(xy1, xy2, c1, c2, R2, b, X, Tb, r1, r2)
        try:
            Ninv = np.linalg.inv(Npp)
        except np.linalg.LinAlgError:
            break
        T = np.einsum("nji,njk->nik", Npc, Ninv)
        S = Ncc - np.einsum("nik,nkj->ij", T, Npc)
        g = gc - np.einsum("nik,nk->i", T, gp)
        dS = np.diag(S).copy()
        accepted = False
        for _ in range(30):
            try:
                dc = np.linalg.solve(S + lam * np.diag(dS), g)
            except np.linalg.LinAlgError:
                lam = max(lam * 10.0, 1e-8)
                continue
            R2n = _small_rotation(dc[:3]) @ R2
            bn = b + Tb @ dc[3:]
            bn /= np.linalg.norm(bn)
            dp = np.einsum("nij,nj->ni", Ninv, gp - Npc @ dc)
            Xn = points_opt(R2n, bn, X + dp)
            costn, r1n, r2n = cost_of(R2n, bn, Xn)
            if np.isfinite(costn) and costn <= cost * (1 + 1e-12) + 1e-300:
                accepted = True
                lam = lam / 10.0 if lam > 1e-8 else 0.0
                break
            lam = max(lam * 10.0, 1e-8)
        if not accepted:
            converged = True          # no step decreases the cost: at the minimum
            break
        small = np.abs(dc).max() < tol
        decrease = cost - costn
        R2, b, X, cost, r1, r2 = R2n, bn, Xn, costn, r1n, r2n
        if small or decrease <= 1e-15 * cost:
            converged = True
            break
    k = _fixed(b, fixed_component)
    sk = abs(b[k])
    b, X = b / sk, X / sk
    free = [j for j in range(3) if j != k]
    Npp, Npc, _, _, _ = _blocks(xy1, xy2, c1, c2, R2, b, X, np.eye(3)[:, free], r1, r2)
    Ncc = _blocks(xy1, xy2, c1, c2, R2, b, X, np.eye(3)[:, free], r1, r2)[2]
    try:
        Npp_inv = np.linalg.inv(Npp)
        S = Ncc - np.einsum("nji,njk,nkl->il", Npc, Npp_inv, Npc)
    except np.linalg.LinAlgError:
        Npp_inv, S = None, None
    return _Fit(R2, b, X, cost, r1, r2, behind(R2, b, X), it, converged, S, Npp_inv, Npc,
                k)


# ---------------------------------------------------------------------------
# the public function


def relative_orientation(xy1_ideal, xy2_ideal, c1, c2, *, x0y0_1=None, x0y0_2=None,
                         sigma_image: float | None = None, fixed_component: int | None = 0,
                         parallax_factor: float = 3.0, max_iterations: int = 100,
                         tol: float = 1e-12, warn: bool = True) -> RelativeOrientationResult:
    """Relative orientation of a stereo pair from homologous image points.

    Closed-form start from the essential matrix (normalized 8-point or
    5-point algorithm, see :func:`essential_candidates`), disambiguated by
    chirality; then least squares of the image residuals of both images
    with the model points as unknowns (the coplanarity condition (1) in its
    Gauss-Helmert form), with the left camera at ``(I, 0)`` and the baseline
    component ``b_x`` held at ±1. Every candidate with all points in front
    of both cameras is refined; the smallest sum of squared residuals wins.

    Parameters
    ----------
    xy1_ideal, xy2_ideal : array_like (n, 2)
        Ideal (distortion-free) image coordinates of the same n >= 5 points
        in the left and right image, reduced to the principal point unless
        ``x0y0_1`` / ``x0y0_2`` are given.
    c1, c2 : float
        Principal distances (image units).
    x0y0_1, x0y0_2 : array_like (2,), optional
        Principal points to subtract.
    sigma_image : float, optional
        A-priori sigma of an image coordinate: scales the covariance and is
        the noise level of the zero-baseline test.
    fixed_component : int or None
        Baseline component held at ±1 (0: ``b_x``, the classical dependent
        relative orientation). ``None`` or a component that is less than a
        fifth of the baseline length (e.g. ``b_x`` of a vertical baseline)
        selects the largest component instead (noted in ``notes``).
    parallax_factor : float
        Zero-baseline test: the pair is rejected when the best pure
        rotation explains the images to within ``parallax_factor`` times
        the noise (``sigma_image``, or the relative orientation's own
        ``sigma0``).
    max_iterations, tol :
        Iteration control of the refinement.
    warn : bool
        Emit :class:`UserWarning` when the solution may be ambiguous.

    Returns
    -------
    RelativeOrientationResult

    Raises
    ------
    GeometryError
        Fewer than 5 points; non-finite input; zero baseline (pure rotation
        between the images, no parallax); no candidate with the points in
        front of both cameras.

    Warns
    -----
    UserWarning
        With exactly 5 points (up to 10 solutions of which chirality may not
        single out one) or when two distinct solutions fit equally well
        (e.g. a planar scene).
    """
    xy1 = np.asarray(xy1_ideal, dtype=float)
    xy2 = np.asarray(xy2_ideal, dtype=float)
    if xy1.ndim != 2 or xy1.shape[1:] != (2,) or xy1.shape != xy2.shape:
        raise GeometryError(
            f"relative orientation needs two (n, 2) arrays of homologous image points, "
            f"got {xy1.shape} and {xy2.shape}")
    n = len(xy1)
    if n < 5:
        raise GeometryError(
            f"relative orientation needs at least 5 homologous points, got {n}",
            hint="a relative orientation has 5 unknowns; measure 6 or more "
                 "points common to both images (8 or more for a unique linear start)")
    if x0y0_1 is not None:
        xy1 = xy1 - np.asarray(x0y0_1, dtype=float)
    if x0y0_2 is not None:
        xy2 = xy2 - np.asarray(x0y0_2, dtype=float)
    c1, c2 = float(c1), float(c2)
    if not (np.isfinite(xy1).all() and np.isfinite(xy2).all()):
        raise GeometryError("relative orientation: image coordinates contain NaN or inf")
    if not (c1 > 0 and c2 > 0):
        raise GeometryError(f"relative orientation: principal distances must be positive, "
                            f"got {c1:g} and {c2:g}")
    notes: list[str] = []
    c_mean = 0.5 * (c1 + c2)

    # zero baseline: a pure rotation explains everything
    _, rms_rot = rotation_only_fit(xy1, xy2, c1, c2)
    floor = 1e-9 * c_mean
    if sigma_image is not None:
        floor = max(floor, parallax_factor * float(sigma_image))
    if rms_rot <= floor:
        raise GeometryError(
            f"relative orientation: zero baseline; a pure rotation fits the "
            f"{n} points to {rms_rot:.3g} (image units), there is no parallax",
            hint="the two images were taken from (nearly) the same position; "
                 "use a pair with a wider baseline")

    u1, u2 = xy1 / c1, xy2 / c2
    thr = 3.0 * float(sigma_image) / c_mean if sigma_image is not None else 1e-3
    Es = essential_candidates(u1, u2, threshold=thr)
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

    # a few iterations for every start, then only the distinct ones to the end
    short = []
    for R2, b, X in _distinct(starts):             # loop over candidate solutions
        bad = ~np.isfinite(X).all(1)
        if bad.any():
            X[bad] = -np.array([0.0, 0.0, 1.0]) * 10.0 * np.linalg.norm(b)
        short.append(_refine(xy1, xy2, c1, c2, R2, b, X, fixed_component,
                             min(3, max_iterations), tol))
    short.sort(key=lambda f: (f.behind > 0, f.cost))
    s2_short = float(sigma_image) ** 2 if sigma_image is not None else \
        (short[0].cost / (n - 5) if n > 5 else 0.0)
    floor = 1e-20 * c_mean ** 2 * n
    kept: list = []
    for f in short:
        # only starts that may end as (distinct) equally good solutions go on:
        # not in the same basin as a kept one (10 sigma), and with a sum of
        # squares already within the tie margin of the best start
        if kept and (f.cost - short[0].cost > 9.0 * s2_short + floor or f.behind):
            continue
        if not any(_same(f, g, s2_short, floor, tol=0.05, k=10.0) for g in kept):
            kept.append(f)
    fits = []
    for j, st in enumerate([(f.R2, f.b, f.X) for f in kept]):
        # the most promising start gets the full budget, the others (which
        # only matter if they reach an equally good, distinct solution) 20
        budget = max_iterations if j == 0 else min(max_iterations, 20)
        f = _refine(xy1, xy2, c1, c2, *st, fixed_component, budget, tol)
        fits.append((f, f.k_fixed))
    dof = n - 5
    finite = [fk for fk in fits if np.isfinite(fk[0].cost)]
    if finite and sigma_image is None and dof > 0:
        # zero baseline, judged against the noise level the data show
        s_best = float(np.sqrt(min(f.cost for f, _ in finite) / dof))
        if rms_rot <= parallax_factor * s_best:
            raise GeometryError(
                f"relative orientation: zero baseline; a pure rotation fits the "
                f"{n} points to {rms_rot:.3g} (image units), not much worse than the "
                f"relative orientation ({s_best:.3g}): no usable parallax",
                hint="the two images were taken from (nearly) the same position; "
                     "use a pair with a wider baseline")
    good = [(f, k) for f, k in finite if f.behind == 0]
    if not good:
        worst = sorted(finite, key=lambda fk: (fk[0].behind, fk[0].cost))[:1]
        if not worst or worst[0][0].behind > max(1, n // 10):
            raise GeometryError(
                f"relative orientation: no solution puts the {n} points in front of both "
                f"cameras",
                hint="check the point correspondences, the principal distances and the "
                     "image y axis (down)")
        good = worst
        notes.append(f"{good[0][0].behind} point(s) behind a camera after refinement")
    good.sort(key=lambda fk: fk[0].cost)
    fit, k_fixed = good[0]
    # other solutions that fit as well
    # an alternative "fits as well" when it converged to a solution that is
    # distinct from the best one by more than 5 sigma (Mahalanobis distance
    # with the best one's normal matrix) and its sum of squares exceeds the
    # best one's by less than a 3-sigma margin
    s2 = float(sigma_image) ** 2 if sigma_image is not None else \
        (fit.cost / dof if dof > 0 else 0.0)
    floor = 1e-20 * c_mean ** 2 * n
    distinct_good = [good[0]]
    for f, k in good[1:]:
        if f.converged and not any(_same(f, g, s2, floor) for g, _ in distinct_good):
            distinct_good.append((f, k))
    tie = [f for f, _ in distinct_good[1:] if f.cost - fit.cost <= 9.0 * s2 + floor]
    sigma0 = float(np.sqrt(fit.cost / dof)) if dof > 0 else float("nan")
    if fit.k_fixed != fixed_component:
        notes.append(f"baseline component {'xyz'[fit.k_fixed]} held at ±1 "
                     f"(b_{'xyz'[fixed_component] if fixed_component is not None else 'x'}"
                     f" is small)")
    ambiguous = False
    if n == 5:
        ambiguous = True
        notes.append("5 points: the relative orientation may be ambiguous "
                     "(up to 10 solutions); measure more points")
    if tie:
        ambiguous = True
        notes.append(f"{len(tie) + 1} distinct solutions fit equally well "
                     "(critical configuration, e.g. all points on a plane)")
    if ambiguous and warn:
        warnings.warn("relative orientation may be ambiguous: " + "; ".join(
            m for m in notes if "ambig" in m or "distinct" in m), UserWarning, stacklevel=2)

    scale2 = float(sigma_image) ** 2 if sigma_image is not None else \
        (sigma0 ** 2 if np.isfinite(sigma0) else np.nan)
    if fit.S is not None:
        try:
            Sinv = np.linalg.inv(fit.S)
        except np.linalg.LinAlgError:
            Sinv = np.linalg.pinv(fit.S)
        cov = scale2 * Sinv
        B = np.einsum("nij,njk->nik", fit.Npp_inv, fit.Npc)          # Npp^-1 Npc
        Qpp = fit.Npp_inv + np.einsum("nik,kl,njl->nij", B, Sinv, B)
        sigma_X = np.sqrt(scale2 * np.einsum("nii->ni", Qpp))
    else:
        cov = np.full((5, 5), np.nan)
        sigma_X = np.full((n, 3), np.nan)
    from photogram.geometry.rotations import matrix_to_opk
    angles2 = np.asarray(matrix_to_opk(fit.R2), dtype=float)
    d1 = _rays(xy1, c1)
    d2 = _rays(xy2, c2) @ fit.R2                              # R2^T d2 (rows)
    ang = max_intersection_angles(np.repeat(np.arange(n), 2),
                                  np.stack([d1, d2], axis=1).reshape(-1, 3), n)
    return RelativeOrientationResult(
        R2=fit.R2, angles2=angles2, X0_2=fit.b, X=fit.X, residuals1=fit.r1,
        residuals2=fit.r2, sigma0=sigma0, covariance=cov, sigma_X=sigma_X,
        max_angle=ang, fixed_component=k_fixed, rotation_only_rms=rms_rot,
        iterations=fit.iterations, converged=fit.converged, ambiguous=ambiguous,
        candidates=len(distinct_good),
        alternatives=[(f.R2, f.b, float(np.sqrt(f.cost / dof)) if dof > 0 else float("nan"))
                      for f in tie], notes=notes)


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


def _fixed(b, fixed_component) -> int:
    """Baseline component to hold at ±1: ``fixed_component`` unless it is
    less than a fifth of the baseline length (or None): then the largest."""
    nb = np.linalg.norm(b)
    if fixed_component is not None and abs(b[fixed_component]) >= 0.2 * nb:
        return int(fixed_component)
    return int(np.argmax(np.abs(b)))


def _same(f, g, s2, floor, tol=1e-6, k=5.0) -> bool:
    """Whether fit ``f`` is the same solution as ``g`` (within ``k`` sigma
    of ``g``'s precision, or within ``tol`` where that is not available)."""
    bf = f.b / np.linalg.norm(f.b)
    bg = g.b / np.linalg.norm(g.b)
    if bf @ bg <= 0:
        return False
    from photogram.geometry import matrix_to_rodrigues
    delta = np.asarray(matrix_to_rodrigues(f.R2 @ g.R2.T), dtype=float)
    kf = g.k_fixed
    db = (f.b / abs(f.b[kf]) - g.b)[[j for j in range(3) if j != kf]]
    d = np.r_[delta, db]
    if g.S is not None and s2 > 0:
        return float(d @ g.S @ d) <= k * k * (s2 + floor)
    return np.abs(d).max() < tol


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
