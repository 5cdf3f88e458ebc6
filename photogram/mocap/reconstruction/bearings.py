"""The athlete's path and the cameras' constant rotations from bearings.

With the rotation differences measured (``Q(t)``: the chained differences,
:func:`photogram.mocap.reconstruction.bootstrap.chain_rotations`), a pan-tilt camera's
rotation is ``R(t) = Q(t) R0`` with one unknown ``R0`` per camera and
segment. The athlete's image centre (the median of its detections) in every
camera and frame is a bearing; the path ``P(t)`` and the ``R0`` follow from
a small bundle adjustment: residuals ``n(Q(t) R0 (P(t) - X0)) - m``
between unit vectors in the camera frame (``n(X) = X/|X|``: a point behind
the camera is far off, unlike with image coordinates), unknowns the
increments ``R0 <- exp([w]x) R0`` (3 per camera) and ``P(t)`` (3 per
frame), Levenberg-Marquardt with the points eliminated per frame (3x3
blocks, Schur complement), Cauchy weights on the residuals (scale
``robust`` in radians), all vectorised over frames and cameras. The camera
centres are known, so there is no datum defect: the path's bearings seen
from six known places over a whole run fix the rotations.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.rotations import rodrigues_to_matrix, skew

__all__ = ["bearing_adjustment"]


def _residuals(X0, Q, R0, P, dirs, ok):
    R = Q @ R0[None]                                           # (F, C, 3, 3)
    d = P[:, None, :] - X0[None]                               # (F, C, 3)
    Xc = np.einsum("fcab,fcb->fca", R, d)
    norm = np.maximum(np.linalg.norm(Xc, axis=-1), 1e-12)
    n = Xc / norm[..., None]
    r = (n - dirs) * ok[..., None]
    return r, R, d, n, norm


def _cost(r, scale):
    e2 = np.sum(r * r, axis=-1)
    return float(np.sum(scale ** 2 * np.log1p(e2 / scale ** 2)))


def _roll(Q, R0, ok, weight):
    """Level-camera prior: ``weight * x_c . z`` (the camera's x axis, row 0
    of R(t), horizontal) per frame and camera, and its derivative with
    respect to the increment w of R0, ``-weight (Q^T e_x)^T [R0 z]x``."""
    Rz = R0[:, :, 2]                                            # R0 z, (C, 3)
    q0 = Q[:, :, 0, :]                                          # row 0 of Q, (F, C, 3)
    r = weight * np.einsum("fca,ca->fc", q0, Rz) * ok
    J = -weight * np.einsum("fca,cab->fcb", q0, skew(Rz)) * ok[..., None]
    return r, J


def bearing_adjustment(X0, Q, m, P, R0, robust=0.01, iterations=50, tol=1e-10,
                       level=0.1):
    """Adjust ``P`` (F, 3) and ``R0`` (C, 3, 3) of one segment (module doc)
    to the observed unit directions ``m`` (F, C, 3) of the athlete in the
    camera frames (NaN: not seen); returns (P, R0, cost).

    ``level`` weighs the prior that the cameras are level (no roll, as a
    pan-tilt head on a levelled tripod; the bootstrap's "global z axis
    up"). Without it the bearings of a short path (60 frames, 20 m) fit an
    upside-down mirror solution better than the truth."""
    ok = np.all(np.isfinite(m), axis=-1)
    ok &= (ok.sum(axis=1) >= 2)[:, None]            # a point needs two rays
    m = np.where(ok[..., None], m, 0.0)
    m = m / np.maximum(np.linalg.norm(m, axis=-1, keepdims=True), 1e-300)
    P, R0 = P.copy(), R0.copy()
    F, C = ok.shape
    def total(R0_, P_):
        r_, *_ = _residuals(X0, Q, R0_, P_, m, ok)
        rr, _ = _roll(Q, R0_, ok, level)
        return _cost(r_, robust) + float(np.sum(rr * rr))

    cost = total(R0, P)
    mu = 1e-3
    for _ in range(iterations):
        r, R, d, n, norm = _residuals(X0, Q, R0, P, m, ok)
        e2 = np.sum(r * r, axis=-1)
        w = ok / (1.0 + e2 / robust ** 2)                       # Cauchy IRLS weight
        g = (np.eye(3) - n[..., :, None] * n[..., None, :]) / norm[..., None, None]
        JP = g @ R                                              # (F, C, 2, 3)
        RX = np.einsum("cab,fcb->fca", R0, d)                   # R0 (P - X0)
        JW = g @ (Q @ -skew(RX.reshape(-1, 3)).reshape(F, C, 3, 3))
        WJP, WJW = w[..., None, None] * JP, w[..., None, None] * JW
        Hpp = np.einsum("fcka,fckb->fab", WJP, JP)              # (F, 3, 3)
        Hpw = np.einsum("fcka,fckb->fcab", WJP, JW)             # (F, C, 3, 3)
        rr, Jr = _roll(Q, R0, ok, level)
        Hww = np.einsum("fcka,fckb->cab", WJW, JW) + np.einsum("fca,fcb->cab", Jr, Jr)
        bp = -np.einsum("fcka,fck->fa", WJP, r)
        bw = -np.einsum("fcka,fck->ca", WJW, r) - np.einsum("fca,fc->ca", Jr, rr)
        for _trial in range(10):
            Dp = Hpp + mu * (np.einsum("fii->fi", Hpp)[..., None] * np.eye(3) + 1e-9 * np.eye(3))
            Ip = np.linalg.inv(Dp)
            S = np.zeros((C, 3, C, 3))
            cc = np.arange(C)
            S[cc, :, cc, :] = Hww + mu * np.einsum("cii->ci", Hww)[..., None] * np.eye(3)
            S -= np.einsum("fcab,fbd,fdeg->caeg", Hpw.transpose(0, 1, 3, 2), Ip,
                           Hpw.transpose(0, 2, 1, 3).reshape(F, 3, C, 3))
            y = bw - np.einsum("fcab,fbd,fd->ca", Hpw.transpose(0, 1, 3, 2), Ip, bp)
            dw = np.linalg.solve(S.reshape(3 * C, 3 * C) + 1e-12 * np.eye(3 * C),
                                 y.reshape(-1)).reshape(C, 3)
            dp = np.einsum("fab,fb->fa", Ip, bp - np.einsum("fcab,cb->fa", Hpw, dw))
            R0n = rodrigues_to_matrix(dw) @ R0
            Pn = P + dp
            cn = total(R0n, Pn)
            if cn <= cost:
                mu = max(mu / 3.0, 1e-9)
                break
            mu *= 10.0
        else:
            break
        P, R0, old, cost = Pn, R0n, cost, cn
        if old - cost <= tol * max(old, 1e-300):
            break
    return P, R0, cost
