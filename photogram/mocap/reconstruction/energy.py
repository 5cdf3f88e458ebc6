"""The energy of eqs. (7)-(10) on a batch of windows, its gradient and its
Gauss-Newton (IRLS) linearisation.

For a window of T frames the unknowns are the DCT coefficients ``a`` (J, 3,
K) of every joint coordinate (:mod:`photogram.mocap.reconstruction.dct`), ``X(t) = B a``.
With the ideal image coordinates ``t_obs`` of a detection of joint j in
camera c at frame t, its confidence ``w`` and the camera's pixel scale ``s``
(:mod:`photogram.mocap.reconstruction.cameras`), the reprojection residual in pixels is

    r = s * (t_obs - pi_c(X_j(t))),     e2 = |r|^2,
    pi_c(X) = (-Xc_x / Xc_z, Xc_y / Xc_z),   Xc = R_c(t) (X - X0_c)

and the energy

    E = lambda_rep  sum_{t,c,j} w rho(e2)  +  lambda_limbs sum_{t,(a,b)} (|X_a - X_b| - L_ab)^2

with the Geman-McClure function ``rho(e2) = e2 / (e2 + sigma^2)`` (our
reading of the paper's robust confidence-weighted norm g, eqs. (7)-(9):
quadratic ``e2 / sigma^2`` for small errors, saturating at 1 for outliers;
sigma^2 = 100 px^2, so an error of 10 px costs half an outlier). A detection
behind the camera costs ``w`` (rho = 1, as an infinitely large error) and
has no gradient. The limb residuals ``|X_a - X_b| - L`` are measured in
**centimetres** (``limb_unit`` of the reconstruction settings; the caller
passes ``lambda_limbs / limb_unit^2`` for lengths in the project unit):
this is our assumption, because in metres a weight of 1 next to
lambda_rep = 80 has no measurable effect (10^4 times weaker; on Pose2Sim's
demo a weight of 1 and of 100 in metres give the same reconstruction),
while in centimetres the prior halves the bone-length variation there and
slightly improves the simulated skiing (MPJPE 9.3 -> 8.7 mm, knee flexion
1.1 -> 0.9 deg).

Linearisation (the Gauss-Newton model of the default solver): the
reprojection terms get the IRLS weight ``W = lambda_rep w rho'(e2)``
(``rho' = sigma^2 / (e2 + sigma^2)^2``); Geman-McClure is concave in e2, so
this model majorises the energy. With ``second_order`` Triggs' correction
of the robust function is added (as Ceres' loss-function corrector): the
3x3 normal block of a detection is ``W Jx^T (I - beta rhat rhat^T) Jx``
with ``beta = -2 e2 rho'' / rho' = 4 e2 / (e2 + sigma^2)`` capped at 0.9
(beyond ``e2 = sigma^2 / 3`` the exact Hessian is indefinite), ``Jx =
dr/dX``. Every reprojection residual depends on one joint, so the normal
matrix is block-diagonal over joints except for the limb terms (weight
``lambda_limbs``, Jacobian ``+-u^T``) that couple the two joints of a limb.
It is never formed: :meth:`Linearization.matvec` applies it in the frame
domain (``B^T diag(M_t) B``), which costs two products with the DCT basis.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["WindowBatch", "Linearization"]


@dataclass
class WindowBatch:
    """The data of nw windows of the same length T, gathered once.

    Observation arrays are laid out (nw, C, J, T) (frames last, so that the
    DCT products are plain matrix products): ideal coordinates ``tx``,
    ``ty`` (0 where invalid), confidences ``conf`` (0 where invalid); pixel
    scales ``sx``, ``sy`` (nw, C, 1, T); rotations ``R`` (nw, C, 3, 3, T) and
    ``RX0 = R X0`` (nw, C, 3, T); ``B`` (T, K); ``limbs`` (nl, 2);
    ``limb_mask`` (nw, nl) weight of each limb in each window (0: a joint
    unobserved or no length); ``n_coef`` (nw, J) coefficients each joint may
    use (0: not observed in the window). Coefficient arrays (nw, J, 3, k) may hold only the first
    k <= K coefficients. Frame-domain arrays are (nw, J, 3, T).
    """

    tx: np.ndarray
    ty: np.ndarray
    conf: np.ndarray
    sx: np.ndarray
    sy: np.ndarray
    R: np.ndarray
    RX0: np.ndarray
    B: np.ndarray
    limbs: np.ndarray
    limb_mask: np.ndarray
    n_coef: np.ndarray
    support: np.ndarray | None = None

    @property
    def observed(self) -> np.ndarray:
        return self.n_coef > 0

    def mask(self, k: int) -> np.ndarray:
        """(nw, J, 1, k): coefficients each joint may change."""
        return (np.arange(k) < self.n_coef[:, :, None])[:, :, None, :]

    @property
    def shape(self):
        nw, C, J, T = self.conf.shape
        return nw, T, C, J, self.B.shape[1]

    def subset(self, idx) -> "WindowBatch":
        return WindowBatch(self.tx[idx], self.ty[idx], self.conf[idx], self.sx[idx],
                           self.sy[idx], self.R[idx], self.RX0[idx], self.B, self.limbs,
                           self.limb_mask[idx], self.n_coef[idx],
                           None if self.support is None else self.support[idx])

    def subsample(self, step: int) -> "WindowBatch":
        """Every ``step``-th frame (for the cheap early continuation stages)."""
        if step <= 1:
            return self
        sl = (Ellipsis, slice(None, None, step))
        return WindowBatch(self.tx[sl], self.ty[sl], self.conf[sl], self.sx[sl], self.sy[sl],
                           self.R[sl], self.RX0[sl], self.B[::step], self.limbs,
                           self.limb_mask, self.n_coef,
                           None if self.support is None else self.support[..., ::step])

    def with_limb_mask(self, mask) -> "WindowBatch":
        return WindowBatch(self.tx, self.ty, self.conf, self.sx, self.sy, self.R, self.RX0,
                           self.B, self.limbs, mask, self.n_coef, self.support)

    # ------------------------------------------------------------------
    def positions(self, a: np.ndarray) -> np.ndarray:
        """Frame-domain positions (nw, J, 3, T) of coefficients (nw, J, 3, k)."""
        nw, J, _, k = a.shape
        return (a.reshape(-1, k) @ self.B[:, :k].T).reshape(nw, J, 3, -1)

    def to_coefficients(self, G: np.ndarray, k: int) -> np.ndarray:
        """``G B`` for frame-domain arrays (nw, n, 3, T) -> (nw, n, 3, k)."""
        nw, n, _, T = G.shape
        return (G.reshape(-1, T) @ self.B[:, :k]).reshape(nw, n, 3, k)

    def _project(self, X):
        """Camera coordinates and residuals of every observation."""
        R = self.R[:, :, :, :, None, :]                   # (nw,C,3,3,1,T)
        Xb = [X[:, None, :, b, :] for b in range(3)]      # (nw,1,J,T)
        Xc = [R[:, :, a, 0] * Xb[0] + R[:, :, a, 1] * Xb[1] + R[:, :, a, 2] * Xb[2]
              - self.RX0[:, :, a, None, :] for a in range(3)]
        z = Xc[2]
        front = z < -1e-9
        iz = np.where(front, 1.0 / np.where(front, z, -1.0), 0.0)
        u = -Xc[0] * iz
        v = Xc[1] * iz
        r0 = self.sx * (self.tx - u)
        r1 = self.sy * (self.ty - v)
        return front, iz, u, v, r0, r1

    def _limb_terms(self, X, lengths):
        a, b = self.limbs[:, 0], self.limbs[:, 1]
        d = X[:, a] - X[:, b]                             # (nw, nl, 3, T)
        length = np.sqrt(np.sum(d * d, axis=2))           # (nw, nl, T)
        u = d / np.maximum(length, 1e-12)[:, :, None, :]
        res = (length - np.asarray(lengths)[None, :, None]) * self.limb_mask[:, :, None]
        return res, u

    def _reprojection(self, X, sigma2, lambda_rep):
        front, iz, u, v, r0, r1 = self._project(X)
        e2 = r0 * r0 + r1 * r1
        rho = np.where(front, e2 / (e2 + sigma2), 1.0)
        E = lambda_rep * np.sum((self.conf * rho).reshape(len(rho), -1), axis=1)
        return E, front, iz, u, v, r0, r1, e2

    def energy(self, a, sigma2, lengths, lambda_rep, lambda_limbs) -> np.ndarray:
        """Energy of every window (nw,)."""
        X = self.positions(a)
        E = self._reprojection(X, sigma2, lambda_rep)[0]
        if lambda_limbs and len(self.limbs):
            res, _ = self._limb_terms(X, lengths)
            E = E + lambda_limbs * np.sum(res * res, axis=(1, 2))
        return E

    def _jacobian(self, front, iz, u, v):
        """Rows of dr/dX: J0, J1, each a list of three (nw, C, J, T) arrays."""
        R = self.R[:, :, :, :, None, :]
        f0 = self.sx * iz * front
        f1 = -self.sy * iz * front
        J0 = [f0 * (R[:, :, 0, b] + u * R[:, :, 2, b]) for b in range(3)]
        J1 = [f1 * (R[:, :, 1, b] - v * R[:, :, 2, b]) for b in range(3)]
        return J0, J1

    def _weights(self, front, e2, sigma2, lambda_rep):
        return lambda_rep * self.conf * front * sigma2 / (e2 + sigma2) ** 2

    def gradient(self, a, sigma2, lengths, lambda_rep, lambda_limbs):
        """Energy (nw,) and its gradient with respect to ``a``."""
        k = a.shape[-1]
        X = self.positions(a)
        E, front, iz, u, v, r0, r1, e2 = self._reprojection(X, sigma2, lambda_rep)
        W = self._weights(front, e2, sigma2, lambda_rep)
        J0, J1 = self._jacobian(front, iz, u, v)
        Wr0, Wr1 = 2.0 * W * r0, 2.0 * W * r1
        G = np.stack([np.sum(Wr0 * J0[b] + Wr1 * J1[b], axis=1) for b in range(3)], axis=2)
        if lambda_limbs and len(self.limbs):
            res, ul = self._limb_terms(X, lengths)
            E = E + lambda_limbs * np.sum(res * res, axis=(1, 2))
            gl = 2.0 * lambda_limbs * res[:, :, None, :] * ul
            for m, (p, q) in enumerate(self.limbs):
                G[:, p] += gl[:, m]
                G[:, q] -= gl[:, m]
        return E, self.to_coefficients(G, k)

    def linearize(self, a, sigma2, lengths, lambda_rep, lambda_limbs,
                  second_order: bool = True) -> "Linearization":
        """The Gauss-Newton model at ``a`` (module doc); ``second_order``
        False gives the plain IRLS model (a majoriser) for every residual."""
        k = a.shape[-1]
        X = self.positions(a)
        E, front, iz, u, v, r0, r1, e2 = self._reprojection(X, sigma2, lambda_rep)
        W = self._weights(front, e2, sigma2, lambda_rep)
        if second_order:
            beta = np.minimum(4.0 * e2 / (e2 + sigma2), 0.9)
        else:
            beta = np.zeros_like(e2)
        wc = W * beta / np.maximum(e2, 1e-300)
        J0, J1 = self._jacobian(front, iz, u, v)
        JtR = [J0[b] * r0 + J1[b] * r1 for b in range(3)]
        WJ0 = [W * j for j in J0]
        WJ1 = [W * j for j in J1]
        cJ = [wc * j for j in JtR]
        nw, C, J, T = W.shape
        M = np.empty((nw, J, 3, 3, T))
        for p in range(3):
            for q in range(p, 3):
                m = np.sum(WJ0[p] * J0[q] + WJ1[p] * J1[q] - cJ[p] * JtR[q], axis=1)
                M[:, :, p, q] = m
                if q != p:
                    M[:, :, q, p] = m
        g = np.stack([np.sum(W * JtR[b], axis=1) for b in range(3)], axis=2)   # (nw,J,3,T)
        rhs = -self.to_coefficients(g, k)
        lin = Linearization(E=E, M=M, B=self.B[:, :k], rhs=rhs, limbs=self.limbs,
                            limb_u=None, limb_w=0.0, mask=self.mask(k))
        if lambda_limbs and len(self.limbs):
            res, ul = self._limb_terms(X, lengths)
            lin.E = E + lambda_limbs * np.sum(res * res, axis=(1, 2))
            gl = self.to_coefficients(lambda_limbs * res[:, :, None, :] * ul, k)
            for m, (p, q) in enumerate(self.limbs):
                rhs[:, p] -= gl[:, m]
                rhs[:, q] += gl[:, m]
            lin.limb_u = ul                                          # (nw, nl, 3, T)
            lin.limb_w = lambda_limbs * self.limb_mask               # (nw, nl)
        return lin


@lru_cache(maxsize=32)
def _limb_rounds(limbs: bytes, J: int) -> list:
    """The limb terms of ``H V`` added to the joints in rounds: round r adds
    to every joint its r-th limb term (``+z`` as the first joint of the
    limb, ``-z`` as the second) in the limbs' order, so that each joint
    receives the same additions in the same order as a loop over the
    limbs (the same bits) with a few array operations (a joint has at most
    four limbs). ``limbs`` the bytes of the (nl, 2) index array; list of
    (joints, limbs, signs (n, 1, 1))."""
    pairs = np.frombuffer(limbs, dtype=np.intp).reshape(-1, 2)
    ops = [[] for _ in range(J)]
    for m, (a, b) in enumerate(pairs):
        ops[a].append((m, 1.0))
        ops[b].append((m, -1.0))
    out = []
    for r in range(max((len(o) for o in ops), default=0)):
        js = [j for j in range(J) if len(ops[j]) > r]
        out.append((np.array(js), np.array([ops[j][r][0] for j in js]),
                    np.array([ops[j][r][1] for j in js])[:, None, None]))
    return out


@dataclass
class Linearization:
    """Gauss-Newton model ``H delta = rhs`` of a batch (never formed).

    ``M`` (nw, J, 3, 3, T) per-frame normal blocks of the reprojection
    terms; ``limb_u`` (nw, nl, 3, T) limb directions with weights ``limb_w``
    (nw, nl); ``B`` (T, k); ``rhs`` (nw, J, 3, k); ``mask`` (nw, J, 1, k) the
    coefficients each joint may change (the solvers keep the others).
    """

    E: np.ndarray
    M: np.ndarray
    B: np.ndarray
    rhs: np.ndarray
    limbs: np.ndarray
    limb_u: np.ndarray | None
    limb_w: np.ndarray | float
    mask: np.ndarray

    def matvec(self, V: np.ndarray) -> np.ndarray:
        """H V for coefficient arrays V (nw, J, 3, k)."""
        nw, J, _, k = V.shape
        T = self.B.shape[0]
        Y = (V.reshape(-1, k) @ self.B.T).reshape(nw, J, 3, T)
        M = self.M
        Z = M[:, :, :, 0] * Y[:, :, None, 0] + M[:, :, :, 1] * Y[:, :, None, 1] \
            + M[:, :, :, 2] * Y[:, :, None, 2]
        if self.limb_u is not None:
            p, q = self.limbs[:, 0], self.limbs[:, 1]
            d = Y[:, p] - Y[:, q]                          # (nw, nl, 3, T)
            s = np.sum(self.limb_u * d, axis=2, keepdims=True) * self.limb_w[:, :, None, None]
            z = s * self.limb_u
            key = np.ascontiguousarray(self.limbs, dtype=np.intp).tobytes()
            for joints, limbs, sign in _limb_rounds(key, J):
                Z[:, joints] += z[:, limbs] * sign
        return (Z.reshape(-1, T) @ self.B).reshape(nw, J, 3, k)

    def block_diagonal(self) -> np.ndarray:
        """The 3x3 diagonal blocks of H per coefficient, (nw, J, 3, 3, k)."""
        T, k = self.B.shape
        B2 = self.B * self.B                               # (T, k)
        nw, J = self.M.shape[:2]
        D = (self.M.reshape(-1, T) @ B2).reshape(nw, J, 3, 3, k)
        if self.limb_u is not None:
            nl = len(self.limbs)
            uu = self.limb_u[:, :, :, None, :] * self.limb_u[:, :, None, :, :]
            uu = (uu.reshape(-1, T) @ B2).reshape(nw, nl, 3, 3, k) \
                * self.limb_w[:, :, None, None, None]
            for m, (p, q) in enumerate(self.limbs):
                D[:, p] += uu[:, m]
                D[:, q] += uu[:, m]
        return D

    def dense_blocks(self):
        """The joint blocks (nw, J, 3k, 3k) and the limb coupling blocks
        (nw, nl, 3k, 3k) (``H_pq = -coupling``), for the direct solver."""
        T, k = self.B.shape
        BB = (self.B[:, :, None] * self.B[:, None, :]).reshape(T, k * k)

        def kron(M):                                       # M (nw, n, 3, 3, T)
            nw, n = M.shape[:2]
            H = (M.reshape(-1, T) @ BB).reshape(nw, n, 3, 3, k, k)
            return H.transpose(0, 1, 2, 4, 3, 5).reshape(nw, n, 3 * k, 3 * k)

        diag = kron(self.M)
        if self.limb_u is None:
            return diag, None
        Ml = self.limb_w[:, :, None, None, None] * self.limb_u[:, :, :, None, :] \
            * self.limb_u[:, :, None, :, :]
        off = kron(Ml)
        for m, (p, q) in enumerate(self.limbs):
            diag[:, p] += off[:, m]
            diag[:, q] += off[:, m]
        return diag, off
