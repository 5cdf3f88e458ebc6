"""Refinement of one relative-orientation candidate.

Least squares of the *image residuals* of both images, i.e. the bundle
adjustment of the pair with the model points as unknowns (equivalent to the
Gauss-Helmert adjustment of the coplanarity condition with the image
coordinates as observations; frames as in :mod:`photogram.init.relative`):
5 orientation unknowns (rotation increment δ, ``R2 <- small_rotation(δ) R2``,
and two baseline unknowns, iterated on the unit sphere) and 3 per point. It
is solved by variable projection (Golub & Pereyra 2003): the points are kept
at their optimum for the current orientation (3x3 Gauss-Newton per point),
the step is the Levenberg-Marquardt-damped Schur-complement step of the
orientation. A joint step over points and orientation overshoots in the long
curved valley of narrow-field pairs (rotation about y against b_z); this does
not. The precision is that of the normal equations with ``|b_k| = 1`` held.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.geometry.rotations import matrix_to_rodrigues, skew, small_rotation


def _small_rotation(d):
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
    Jc = np.concatenate([-J2c @ skew(Xc2),                           # dXc2/dδ = -[Xc2]x
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
    delta = np.asarray(matrix_to_rodrigues(f.R2 @ g.R2.T), dtype=float)
    kf = g.k_fixed
    db = (f.b / abs(f.b[kf]) - g.b)[[j for j in range(3) if j != kf]]
    d = np.r_[delta, db]
    if g.S is not None and s2 > 0:
        return float(d @ g.S @ d) <= k * k * (s2 + floor)
    return np.abs(d).max() < tol


def _precision(fit: _Fit, scale2: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Covariance (5, 5) of the orientation unknowns and standard deviations
    (n, 3) of the model points of a refined fit, scaled by ``scale2``."""
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
    return cov, sigma_X
