"""The damped Gauss-Newton system of the joint pose and rotation energy
(:mod:`photogram.mocap.reconstruction.joint_solver`) solved block by block.

The normal matrix of a window is sparse in blocks: its pose part couples a
joint's ``3 K_Pi`` coefficients with those of the joints it shares a limb
with only, its camera part is block-diagonal (one ``3 K_Gamma`` block per
camera), and the pose-camera part is dense. The joints are eliminated one
at a time (block Cholesky: ``L_jj = chol(A_jj)``, ``W = L_jj^-1 [A_jN, A_jc,
b_j]`` and the Schur update ``A_xy -= W_x^T W_y`` of the joint's neighbours
``N`` and the cameras), in a minimum-degree order of the limb graph (a tree
with two loops for SKI24: little fill), then the cameras by a dense
Cholesky of their Schur complement, and the joints back-substituted in
reverse order. About a quarter of the floating-point work of the dense
factorisation of the whole matrix; all windows of a trial at once (a loop
over joints, never over windows or observations). The solution equals the
dense one to rounding.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.linalg import cho_factor, cho_solve

__all__ = ["elimination_order", "solve_blocks"]


@lru_cache(maxsize=32)
def elimination_order(J: int, limbs: tuple) -> tuple:
    """Minimum-degree elimination order of the joints of the limb graph
    ``limbs`` ((a, b) pairs): per step (joint, its neighbours left (sorted),
    including the fill of earlier steps)."""
    adj = [set() for _ in range(J)]
    for a, b in limbs:
        if a != b:
            adj[a].add(b)
            adj[b].add(a)
    left = set(range(J))
    steps = []
    while left:
        j = min(left, key=lambda i: (len(adj[i]), i))
        nb = tuple(sorted(adj[j]))
        steps.append((j, nb))
        for x in nb:
            adj[x].discard(j)
            adj[x].update(y for y in nb if y != x)
        left.remove(j)
    return tuple(steps)


def solve_blocks(A, b, nP, J, steps):
    """Solve ``A x = b`` for a stack of windows: ``A`` (m, n, n) symmetric
    positive definite with the ``nP`` pose unknowns first (``J`` joints of
    ``nP / J`` each, coupled as ``steps`` of :func:`elimination_order` says)
    and the camera unknowns last; ``b`` (m, n). Raises
    ``numpy.linalg.LinAlgError`` where a pivot is not positive definite."""
    m, n = b.shape
    bs = nP // J
    cams = slice(nP, n)

    def blk(i):
        return slice(i * bs, (i + 1) * bs)

    D = {}

    def get(i, k):
        key = (i, k)
        if key not in D:
            D[key] = A[:, blk(i), blk(k)].copy()
        return D[key]

    Pc = {j: A[:, blk(j), cams].copy() for j in range(J)}
    r = {j: b[:, blk(j)].copy() for j in range(J)}
    Wc = np.empty((m, nP, n - nP))               # rows L^-1 [A_jc] of every joint
    z = np.empty((m, nP))                        # and L^-1 b_j
    kept = []
    for e, (j, nb) in enumerate(steps):
        L = np.linalg.cholesky(get(j, j))
        Li = np.linalg.inv(L)
        k = len(nb) * bs
        W = Li @ np.concatenate([get(j, x) for x in nb] + [Pc[j], r[j][:, :, None]], axis=2)
        rows = slice(e * bs, (e + 1) * bs)
        Wc[:, rows], z[:, rows] = W[:, :, k:-1], W[:, :, -1]
        if k:
            U = np.swapaxes(W[:, :, :k], 1, 2) @ W           # (m, k, q)
            for u, x in enumerate(nb):
                ux = slice(u * bs, (u + 1) * bs)
                for v, y in enumerate(nb):
                    get(x, y)
                    D[(x, y)] -= U[:, ux, v * bs:(v + 1) * bs]
                Pc[x] -= U[:, ux, k:-1]
                r[x] -= U[:, ux, -1]
        kept.append((j, nb, Li, W[:, :, :k]))
    # the cameras' Schur complement: one product over all joints
    WcT = np.swapaxes(Wc, 1, 2)
    S = A[:, cams, cams] - WcT @ Wc
    rc = b[:, cams] - np.einsum("wcp,wp->wc", WcT, z)
    x = np.empty_like(b)
    for w in range(m):
        x[w, cams] = cho_solve(cho_factor(S[w], check_finite=False), rc[w],
                               check_finite=False)
    for e in range(len(kept) - 1, -1, -1):
        j, nb, Li, WN = kept[e]
        rows = slice(e * bs, (e + 1) * bs)
        y = z[:, rows] - np.einsum("wpq,wq->wp", Wc[:, rows], x[:, cams])
        for u, i in enumerate(nb):
            y -= np.einsum("wpq,wq->wp", WN[:, :, u * bs:(u + 1) * bs], x[:, blk(i)])
        x[:, blk(j)] = np.einsum("wqp,wq->wp", Li, y)
    return x
