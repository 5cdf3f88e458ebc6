"""The joint energy of poses and camera rotations (section 4.5) on a batch of
windows, and its dense Gauss-Newton model.

Unknowns per window: the pose coefficients ``a`` (J, 3, K_Pi) of
:mod:`photogram.mocap.reconstruction.energy` (``X(t) = B_Pi a``) and the camera angle
coefficients ``g`` (C, 3, K_Gamma) of :mod:`photogram.mocap.motion.camera_motion`
(``R_c(t) = R_ref,c E(B_Gamma g_c)``). The energy

    E = lambda_rep sum w rho(e^2) + lambda_limbs sum ((|X_a - X_b| - L)/u)^2
        + lambda_rot sum_{c,t} |r_c(t)|^2                       (eqs. (7)-(10), (14))

is the energy of part 1 with the camera rotations free, plus the rotation
prior (``lambda_rot = 0``: the ablation without E_rot). The Gauss-Newton
model is formed densely per window (pose and camera coefficients together,
about 1000 unknowns with the paper's N_Pi = N_Gamma = 11): every detection
contributes the 6x6 block of its joint (3) and camera (3) angles,
``W J^T J - wc (J^T r)(J^T r)^T`` with the IRLS weight W and Triggs'
correction ``wc`` (as in :mod:`photogram.mocap.reconstruction.energy`), expanded to the
coefficients by Kronecker products with the bases, all vectorised over
windows, cameras, joints and frames.

Derivatives (checked against finite differences in
tests/test_mocap_joint.py): ``dr/dX = g R`` with the rows
``g0 = s_x/z (1, 0, u)``, ``g1 = -s_y/z (0, 1, -v)`` of ``dr/dXc``, and
``dr/dgamma_a = g (G_a Xc)`` with the generators ``G_a`` of
:func:`photogram.mocap.motion.camera_motion.generators`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.mocap.motion.camera_motion import euler_matrices, generators, rotation_residuals
from photogram.mocap.reconstruction.energy import WindowBatch

__all__ = ["JointBatch"]


def _kron_blocks(M, B1, B2):
    """``sum_t M[..., p, q, t] B1[t, k] B2[t, l]`` laid out (..., p, k, q, l)."""
    T, K1 = B1.shape
    K2 = B2.shape[1]
    BB = (B1[:, :, None] * B2[:, None, :]).reshape(T, K1 * K2)
    lead = M.shape[:-3]
    P, Q = M.shape[-3], M.shape[-2]
    H = (M.reshape(-1, T) @ BB).reshape(lead + (P, Q, K1, K2))
    n = len(lead)
    order = tuple(range(n)) + (n, n + 2, n + 1, n + 3)
    return H.transpose(order)


@dataclass
class JointBatch:
    """Windows of equal length with free camera rotations.

    ``obs`` holds the detections, pose basis, limbs and masks (its ``R`` and
    ``RX0`` are not used); ``X0`` (C, 3); ``R_ref`` (nw, C, 3, 3);
    ``dR`` (nw, C, T-1, 3, 3) measured rotation differences and
    ``rot_w`` (nw, C, T-1) their weights (0: no measurement); ``BG``
    (T, K_Gamma) the camera basis. ``R_ref`` may also be given per frame,
    (nw, C, T, 3, 3): the chained differences of
    :mod:`photogram.mocap.motion.camera_motion`. ``camera_free`` (nw, C):
    False holds a camera's angle coefficients (a camera without athlete
    detections in the window: nothing but E_rot's differences would
    determine its orientation there); None: all free.
    """

    obs: WindowBatch
    X0: np.ndarray
    R_ref: np.ndarray
    dR: np.ndarray
    rot_w: np.ndarray
    BG: np.ndarray
    camera_free: np.ndarray | None = None

    @property
    def ref_frames(self) -> np.ndarray:
        """R_ref per frame, (nw, C, T, 3, 3) or broadcastable (nw, C, 1, 3, 3)."""
        return self.R_ref if self.R_ref.ndim == 5 else self.R_ref[:, :, None]

    @property
    def sizes(self):
        nw, C, J, T = self.obs.conf.shape
        return nw, C, J, T, self.obs.B.shape[1], self.BG.shape[1]

    def subset(self, idx) -> "JointBatch":
        return JointBatch(self.obs.subset(idx), self.X0, self.R_ref[idx], self.dR[idx],
                          self.rot_w[idx], self.BG,
                          None if self.camera_free is None else self.camera_free[idx])

    # ------------------------------------------------------------------
    def rotations(self, g, derivatives=False):
        """Angles (nw, C, T, 3), E, R (nw, C, T, 3, 3) [and dE (3, ...)]."""
        gam = np.einsum("wcak,tk->wcta", g, self.BG)
        if derivatives:
            E, dE = euler_matrices(gam, derivatives=True)
        else:
            E, dE = euler_matrices(gam), None
        R = self.ref_frames @ E
        return gam, E, R, dE

    def _camera_points(self, X, R):
        """Xc components (nw, C, J, T) of positions X (nw, J, 3, T)."""
        Rt = R.transpose(0, 1, 3, 4, 2)[:, :, :, :, None, :]       # (nw,C,3,3,1,T)
        d = [X[:, None, :, b, :] - self.X0[None, :, b, None, None] for b in range(3)]
        return [Rt[:, :, i, 0] * d[0] + Rt[:, :, i, 1] * d[1] + Rt[:, :, i, 2] * d[2]
                for i in range(3)]

    def _reprojection(self, Xc, sigma2, lambda_rep):
        o = self.obs
        z = Xc[2]
        front = z < -1e-9
        iz = np.where(front, 1.0 / np.where(front, z, -1.0), 0.0)
        u, v = -Xc[0] * iz, Xc[1] * iz
        r0, r1 = o.sx * (o.tx - u), o.sy * (o.ty - v)
        e2 = r0 * r0 + r1 * r1
        rho = np.where(front, e2 / (e2 + sigma2), 1.0)
        E = lambda_rep * np.sum((o.conf * rho).reshape(len(rho), -1), axis=1)
        return E, front, iz, u, v, r0, r1, e2

    def _rot(self, E, dE, jacobian):
        return rotation_residuals(self.R_ref, E, dE, self.dR, jacobian)

    def energy(self, a, g, sigma2, lengths, lambda_rep, lambda_limbs, lambda_rot):
        """Energy of every window (nw,)."""
        X = self.obs.positions(a)
        _, E, R, _ = self.rotations(g)
        out = self._reprojection(self._camera_points(X, R), sigma2, lambda_rep)[0]
        if lambda_limbs and len(self.obs.limbs):
            res, _ = self.obs._limb_terms(X, lengths)
            out = out + lambda_limbs * np.sum(res * res, axis=(1, 2))
        if lambda_rot:
            r = self._rot(E, None, False)
            out = out + lambda_rot * np.sum(self.rot_w[..., None] * r * r, axis=(1, 2, 3))
        return out

    # ------------------------------------------------------------------
    def residual_jacobians(self, a, g, sigma2, lambda_rep):
        """Per detection: residuals r0, r1 and their derivatives with respect
        to the joint position (Jx, 3 arrays per row) and to the camera's
        angles (Jg, 3 arrays per row), all (nw, C, J, T); for the tests and
        :meth:`linearize`."""
        X = self.obs.positions(a)
        _, E, R, dE = self.rotations(g, derivatives=True)
        Xc = self._camera_points(X, R)
        Er, front, iz, u, v, r0, r1, e2 = self._reprojection(Xc, sigma2, lambda_rep)
        Rt = R.transpose(0, 1, 3, 4, 2)[:, :, :, :, None, :]
        f0 = self.obs.sx * iz * front
        f1 = -self.obs.sy * iz * front
        Jx0 = [f0 * (Rt[:, :, 0, b] + u * Rt[:, :, 2, b]) for b in range(3)]
        Jx1 = [f1 * (Rt[:, :, 1, b] - v * Rt[:, :, 2, b]) for b in range(3)]
        G = generators(self.ref_frames[None], E[None], dE)            # (3,nw,C,T,3,3)
        Jg0, Jg1 = [], []
        for k in range(3):
            Gt = G[k].transpose(0, 1, 3, 4, 2)[:, :, :, :, None, :]   # (nw,C,3,3,1,T)
            GX = [Gt[:, :, i, 0] * Xc[0] + Gt[:, :, i, 1] * Xc[1] + Gt[:, :, i, 2] * Xc[2]
                  for i in range(3)]
            Jg0.append(f0 * (GX[0] + u * GX[2]))
            Jg1.append(f1 * (GX[1] - v * GX[2]))
        return dict(E=Er, X=X, E_rot=E, dE=dE, front=front, r0=r0, r1=r1, e2=e2,
                    Jx0=Jx0, Jx1=Jx1, Jg0=Jg0, Jg1=Jg1)

    def linearize(self, a, g, sigma2, lengths, lambda_rep, lambda_limbs, lambda_rot,
                  second_order=True, hessian=True):
        """Energy (nw,), dense normal matrix (nw, n, n) and right-hand side
        (nw, n) over ``[a.ravel(), g.ravel()]`` per window (the gradient of
        the energy is ``-2 rhs``); ``hessian`` False skips the matrix (None),
        for the L-BFGS comparison."""
        nw, C, J, T, KP, KG = self.sizes
        q = self.residual_jacobians(a, g, sigma2, lambda_rep)
        r0, r1, e2 = q["r0"], q["r1"], q["e2"]
        W = lambda_rep * self.obs.conf * q["front"] * sigma2 / (e2 + sigma2) ** 2
        beta = np.minimum(4.0 * e2 / (e2 + sigma2), 0.9) if second_order else 0.0
        wc = W * beta / np.maximum(e2, 1e-300)
        J0 = q["Jx0"] + q["Jg0"]                      # 6 columns: 3 joint, 3 camera
        J1 = q["Jx1"] + q["Jg1"]
        JtR = [J0[i] * r0 + J1[i] * r1 for i in range(6)]
        WJ0 = [W * x for x in J0]
        WJ1 = [W * x for x in J1]
        cJ = [wc * x for x in JtR]

        def block(i, k):
            return WJ0[i] * J0[k] + WJ1[i] * J1[k] - cJ[i] * JtR[k]

        Mpp = np.empty((nw, J, 3, 3, T))
        Mcc = np.empty((nw, C, 3, 3, T))
        Q = np.empty((nw, J, C, 3, 3, T))
        for i in range(3 if hessian else 0):
            for k in range(3):
                if k >= i:
                    Mpp[:, :, i, k] = Mpp[:, :, k, i] = np.sum(block(i, k), axis=1)
                    Mcc[:, :, i, k] = Mcc[:, :, k, i] = np.sum(block(3 + i, 3 + k), axis=2)
                Q[:, :, :, i, k] = block(i, 3 + k).transpose(0, 2, 1, 3)
        gp = np.stack([np.sum(W * JtR[i], axis=1) for i in range(3)], axis=2)   # (nw,J,3,T)
        gc = np.stack([np.sum(W * JtR[3 + i], axis=2) for i in range(3)], axis=2)  # (nw,C,3,T)
        BP, BG = self.obs.B, self.BG
        nP, nC = J * 3 * KP, C * 3 * KG
        Hpp = np.zeros((nw, J, 3 * KP, J, 3 * KP) if hessian else (nw, J, 1, J, 1))
        jj = np.arange(J)
        if hessian:
            Hpp[:, jj, :, jj, :] = _kron_blocks(Mpp, BP, BP).reshape(
                nw, J, 3 * KP, 3 * KP).transpose(1, 0, 2, 3)
        rp = -(gp.reshape(-1, T) @ BP).reshape(nw, J, 3, KP)
        Etot = q["E"].copy()
        limbs = self.obs.limbs
        if lambda_limbs and len(limbs):
            res, ul = self.obs._limb_terms(q["X"], lengths)
            Etot += lambda_limbs * np.sum(res * res, axis=(1, 2))
            gl = ((lambda_limbs * res[:, :, None, :] * ul).reshape(-1, T) @ BP).reshape(
                nw, len(limbs), 3, KP)
            lw = lambda_limbs * self.obs.limb_mask
            Ml = lw[:, :, None, None, None] * ul[:, :, :, None, :] * ul[:, :, None, :, :]
            Hl = _kron_blocks(Ml, BP, BP).reshape(nw, len(limbs), 3 * KP, 3 * KP) \
                if hessian else np.zeros((nw, len(limbs), 1, 1))
            for m, (p, s) in enumerate(limbs):
                rp[:, p] -= gl[:, m]
                rp[:, s] += gl[:, m]
                Hpp[:, p, :, p, :] += Hl[:, m]
                Hpp[:, s, :, s, :] += Hl[:, m]
                Hpp[:, p, :, s, :] -= Hl[:, m]
                Hpp[:, s, :, p, :] -= Hl[:, m]
        cc = np.arange(C)
        Hc_diag = _kron_blocks(Mcc, BG, BG).reshape(nw, C, 3 * KG, 3 * KG) if hessian else 0.0
        rc = -(gc.reshape(-1, T) @ BG).reshape(nw, C, 3, KG)
        if lambda_rot:
            r, D0, D1 = self._rot(q["E_rot"], q["dE"], True)          # (nw,C,T-1,3[,3])
            w = lambda_rot * self.rot_w[..., None, None]
            # Jacobian with respect to the coefficients: (nw, C, T-1, 3, 3, KG)
            Jr = D0[..., None] * BG[:-1, None, None, :] + D1[..., None] * BG[1:, None, None, :]
            Jr = Jr.reshape(nw, C, T - 1, 3, 3 * KG)
            if hessian:
                Hc_diag = Hc_diag + np.einsum("wctik,wctil->wckl", w * Jr, Jr)
            rc = rc - np.einsum("wctik,wcti->wck", w * Jr, r).reshape(nw, C, 3, KG)
            Etot += lambda_rot * np.sum(self.rot_w[..., None] * r * r, axis=(1, 2, 3))
        rhs = np.concatenate([rp.reshape(nw, nP), rc.reshape(nw, nC)], axis=1)
        if not hessian:
            return Etot, None, rhs
        Hcc = np.zeros((nw, C, 3 * KG, C, 3 * KG))
        Hcc[:, cc, :, cc, :] = Hc_diag.transpose(1, 0, 2, 3)
        Hpc = _kron_blocks(Q, BP, BG)                       # (nw,J,C,3,KP,3,KG)
        Hpc = Hpc.transpose(0, 1, 3, 4, 2, 5, 6).reshape(nw, nP, nC)
        H = np.empty((nw, nP + nC, nP + nC))
        H[:, :nP, :nP] = Hpp.reshape(nw, nP, nP)
        H[:, nP:, nP:] = Hcc.reshape(nw, nC, nC)
        H[:, :nP, nP:] = Hpc
        H[:, nP:, :nP] = Hpc.transpose(0, 2, 1)
        return Etot, H, rhs
