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
    S = A[:, cams, cams].copy()
    r = {j: b[:, blk(j)].copy() for j in range(J)}
    rc = b[:, cams].copy()
    kept = []
    for j, nb in steps:
        L = np.linalg.cholesky(get(j, j))
        Li = np.linalg.inv(L)
        G = np.concatenate([get(j, x) for x in nb] + [Pc[j], r[j][:, :, None]], axis=2)
        W = Li @ G                                                  # (m, bs, q)
        U = np.swapaxes(W, 1, 2) @ W
        k = len(nb) * bs
        for u, x in enumerate(nb):
            ux = slice(u * bs, (u + 1) * bs)
            for v, y in enumerate(nb):
                get(x, y)
                D[(x, y)] -= U[:, ux, v * bs:(v + 1) * bs]
            Pc[x] -= U[:, ux, k:-1]
            r[x] -= U[:, ux, -1]
        S -= U[:, k:-1, k:-1]
        rc -= U[:, k:-1, -1]
        kept.append((j, nb, Li, W))
    x = np.empty_like(b)
    for w in range(m):
        x[w, cams] = cho_solve(cho_factor(S[w], check_finite=False), rc[w],
                               check_finite=False)
    for j, nb, Li, W in reversed(kept):
        k = len(nb) * bs
        z = W[:, :, -1] - np.einsum("wpq,wq->wp", W[:, :, k:-1], x[:, cams])
        for u, y in enumerate(nb):
            z -= np.einsum("wpq,wq->wp", W[:, :, u * bs:(u + 1) * bs], x[:, blk(y)])
        x[:, blk(j)] = np.einsum("wqp,wq->wp", Li, z)
    return x
