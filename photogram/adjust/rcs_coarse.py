"""A two-level preconditioner for the iterative reduced-camera-system solve.

Schur-Jacobi (:func:`photogram.adjust.rcs_iterative.schur_jacobi`) inverts
every camera's diagonal block of ``S = N_cc - W A^-1 W^T`` exactly but sees
nothing across the camera graph: the smooth, long-range errors of a large
block (a slow bend of a ring of cameras) take many CG steps, more the
longer the graph. The second level corrects them on a coarse space of
camera clusters (aggregation, as in algebraic multigrid):

* the row groups (cameras) are clustered by covisibility (greedy breadth-
  first aggregation on the graph of groups that share points) into
  clusters of about ``cluster_size`` groups;
* the prolongation ``P`` (``n_r x n_c``, ``n_c = clusters x s``) maps the
  coarse unknown ``(cluster, slot j)`` to column ``j`` of every group of
  the cluster (a piecewise-constant interpolation per parameter slot);
* ``S P`` is formed exactly from the block structure, without any CG
  product: ``S P = N_cc P - W A^-1 (W^T P)``, where ``W^T P`` of a point
  is its E-rows' ``W_o^T`` summed per cluster (few clusters per point) and
  every (group, cluster) pair that shares a point gets an ``s x s`` block
  (:func:`photogram.adjust._numba_coarse.coupling_blocks`, or the numpy
  twin :func:`_coupling_numpy`); ``S_c = P^T S P`` (dense, ``n_c x n_c``)
  is factorized by Cholesky;
* the combination is the balancing (symmetrized multiplicative) form

      M^-1 r = Q r + (I - Q S) J (I - S Q) r,   Q = P S_c^-1 P^T,

  ``J`` the Schur-Jacobi inverse: symmetric by construction and positive
  definite whenever ``J`` and ``S_c`` are (``r^T M^-1 r = r^T Q r +
  w^T J w`` with ``w = (I - S Q) r``), so PCG stays valid. With ``S P``
  stored, an application costs one Schur-Jacobi application, two coarse
  triangular solves and two sparse products with ``S P``: no extra
  product with ``S``.

It needs every reduced column in at most one row group (BAL: one camera
with its own interior orientation); :func:`applicable` tells.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from photogram.adjust import kernels
from photogram.adjust.rcs_iterative import schur_jacobi

__all__ = ["PRECONDITIONERS", "applicable", "cluster_groups", "pattern_of",
           "preconditioner", "record", "resolve", "TwoLevel", "two_level"]

PRECONDITIONERS = ("auto", "schur_jacobi", "two_level", "adaptive")
# "adaptive": the two-level preconditioner only for a solve whose previous
# solve (same structure: the last LM step) took more than this many CG
# steps; Schur-Jacobi otherwise (the first LM steps need 2-5 steps, too
# few for the coarse pass to pay)
ADAPTIVE_STEPS = 4
# coarse modes whose eigenvalue of the unit-diagonal S_c is below this are
# left out of the coarse correction: the (damped) gauge freedom
FLOOR = 3e-2
# the columns of a row group that the coarse space aggregates ("all" or a
# tuple of slot numbers)
COARSE_SLOTS = "all"


def applicable(structure) -> bool:
    """Can the two-level preconditioner run on ``structure``? (at least
    two row groups and every reduced column in at most one group)."""
    gc = structure.group_cols
    if gc.ndim != 2 or gc.shape[0] < 2 or gc.shape[1] == 0 or structure.n_e_rows == 0:
        return False
    cols = gc[gc < structure.n_r]
    return len(np.unique(cols)) == len(cols)


def cluster_groups(C, size):
    """Greedy breadth-first aggregation of a weighted graph (``C``: sparse
    symmetric ``n x n``, weight = shared points): a cluster grows from a
    seed through its strongest unassigned neighbours first until it holds
    ``size`` nodes; the next seed is taken from the last cluster's
    unassigned frontier (compact, adjacent clusters); clusters under half
    the size are merged into the neighbouring cluster they share most
    with. Returns the cluster of every node (0 .. n_clusters-1)."""
    C = sp.csr_matrix(C)
    n = C.shape[0]
    size = max(int(size), 1)
    label = np.full(n, -1, dtype=np.int64)
    ip, ix, w = C.indptr, C.indices, C.data
    nbrs = [ix[ip[i]:ip[i + 1]][np.argsort(-w[ip[i]:ip[i + 1]], kind="stable")]
            for i in range(n)]
    seeds = deque()
    k = 0
    nxt = 0
    while True:
        seed = -1
        while seeds:
            c = seeds.popleft()
            if label[c] < 0:
                seed = c
                break
        if seed < 0:
            while nxt < n and label[nxt] >= 0:
                nxt += 1
            if nxt == n:
                break
            seed = nxt
        label[seed] = k
        members, queue, count = [seed], deque([seed]), 1
        while queue and count < size:
            v = queue.popleft()
            for u in nbrs[v]:
                if label[u] < 0:
                    label[u] = k
                    members.append(u)
                    queue.append(u)
                    count += 1
                    if count >= size:
                        break
        for v in members:
            seeds.extend(u for u in nbrs[v] if label[u] < 0)
        k += 1
    # merge small clusters into their best-connected neighbour cluster
    counts = np.bincount(label, minlength=k)
    Pm = sp.csr_matrix((np.ones(n), (np.arange(n), label)), shape=(n, k))
    between = (Pm.T @ C @ Pm).tolil()
    for c in np.flatnonzero(counts < max(size // 2, 1)):
        if counts[c] == 0:
            continue
        row = between.getrow(c).toarray().ravel()
        row[c] = 0.0
        row[counts == 0] = 0.0
        if k < 2 or not row.max() > 0:
            continue
        t = int(np.argmax(row))
        label[label == c] = t
        counts[t] += counts[c]
        counts[c] = 0
        between[t, :] = between[t, :] + between[c, :]
        between[:, t] = between[:, t] + between[:, c]
    return np.unique(label, return_inverse=True)[1].astype(np.int64)


class _Pattern:
    """What the coarse level needs of one structure and cluster size
    (fixed; cached): clusters, prolongation, the (group, cluster) blocks
    of ``W A^-1 W^T P`` and the sparse layout of ``S P``."""

    def __init__(self, gc, n_r, group, ptr, size, slots=None, compiled=False):
        n_g, s = gc.shape
        self.slots = np.arange(s) if slots is None else np.asarray(slots, dtype=np.int64)
        k = len(self.slots)
        self.s, self.k, self.n_r = s, k, n_r
        self.group, self.ptr = group, ptr
        seg = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
        M = sp.csr_matrix((np.ones(len(group)), (group, seg)), shape=(n_g, len(ptr) - 1))
        C = (M @ M.T).tocsr()
        C.setdiag(0.0)
        C.eliminate_zeros()
        self.cluster = cluster_groups(C, size)
        n_cl = self.n_clusters = int(self.cluster.max()) + 1
        self.n_c = n_cl * k
        gk = gc[:, self.slots]
        valid = gk < n_r
        coarse = self.cluster[:, None] * k + np.arange(k)[None, :]
        self.P = sp.csr_matrix((np.ones(int(valid.sum())), (gk[valid], coarse[valid])),
                               shape=(n_r, self.n_c))
        # (group, cluster) pairs that share a point: one s x k block each,
        # numbered in (group, cluster) order
        self._numpy = None
        if compiled:
            from photogram.adjust import _numba_coarse
            seen = np.zeros((n_g, n_cl), dtype=np.bool_)
            _numba_coarse.mark_blocks(group, ptr, self.cluster, seen)
            self.bg, self.bc = np.nonzero(seen)
        else:
            self.bg, self.bc = self.numpy_plan()[0]
        self.n_blocks = len(self.bg)
        self.lookup = np.full((n_g, n_cl), -1, dtype=np.int64)
        self.lookup[self.bg, self.bc] = np.arange(self.n_blocks)
        # the blocks' entries as a CSR matrix (n_r x n_c): rows gc[bg, a],
        # columns bc * k + b; the permutation from block order to CSR order
        a, b = np.meshgrid(np.arange(s), np.arange(k), indexing="ij")
        rows = gc[self.bg][:, :, None] + 0 * b[None]
        cols = self.bc[:, None, None] * k + b[None] + 0 * a[None]
        ok = (rows < n_r).ravel()
        src = np.arange(self.n_blocks * s * k)[ok]
        T = sp.csr_matrix((src.astype(float) + 1.0, (rows.ravel()[ok], cols.ravel()[ok])),
                          shape=(n_r, self.n_c))
        T.sort_indices()
        self.csr_src = T.data.astype(np.int64) - 1
        self.csr_indices, self.csr_indptr = T.indices, T.indptr

    def numpy_plan(self):
        """The numpy twin's index arrays (computed on first use): the
        blocks ``(bg, bc)``; the rows sorted by (point, cluster) and the
        starts of those runs; the (row, run) pairs sorted by block."""
        if self._numpy is None:
            group, ptr, n_cl = self.group, self.ptr, self.n_clusters
            seg = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
            key = seg * n_cl + self.cluster[group]
            perm = np.argsort(key, kind="stable")
            ks = key[perm]
            mstarts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]]) if len(ks) else \
                np.zeros(0, np.int64)
            mseg, mcl = ks[mstarts] // n_cl, ks[mstarts] % n_cl
            mptr = np.searchsorted(mseg, np.arange(len(ptr)))
            cnt = (mptr[1:] - mptr[:-1])[seg]                   # clusters of a row's point
            pr = np.repeat(np.arange(len(group)), cnt)
            first = np.repeat(np.cumsum(cnt) - cnt, cnt)
            pm = mptr[:-1][seg][pr] + np.arange(len(pr)) - first
            ukeys, bid = np.unique(group[pr] * n_cl + mcl[pm], return_inverse=True)
            order = np.argsort(bid, kind="stable")
            self._numpy = ((ukeys // n_cl, ukeys % n_cl), perm, mstarts, mseg,
                           pr[order], pm[order], bid[order])
        return self._numpy

    def to_csr(self, blocks):
        """The (group, cluster) blocks as a CSR ``n_r x n_c`` matrix."""
        data = blocks.reshape(-1)[self.csr_src]
        return sp.csr_matrix((data, self.csr_indices, self.csr_indptr),
                             shape=(self.n_r, self.n_c))


def pattern(owner, gc, n_r, group, ptr, size, slots=None, compiled=False):
    """The cached :class:`_Pattern` of ``owner`` (a structure or plan)."""
    cache = owner.__dict__.setdefault("_coarse_patterns", {})
    key = (size, None if slots is None else tuple(slots))
    if key not in cache:
        cache[key] = _Pattern(gc, n_r, group, ptr, size, slots, compiled)
    return cache[key]


def _coupling_numpy(pat, WT, Ainv_seg, chunk=1 << 18):
    """``(W A^-1 W^T P)`` per (group, cluster) block (n_blocks, s, k),
    numpy: ``W_o^T`` summed per (point, cluster), times the point's
    ``A^-1``, then one ``s x s`` product per (row, cluster of its point),
    summed per block in sorted chunks."""
    s, k = WT.shape[2], pat.k
    _, perm, mstarts, mseg, pair_row, pair_m, pair_bid = pat.numpy_plan()
    Y = np.add.reduceat(WT[perm][:, :, pat.slots], mstarts, axis=0) if len(perm) \
        else np.zeros((0, 3, k))
    Z = np.matmul(Ainv_seg[mseg], Y)                            # (n_m, 3, k)
    out = np.zeros((pat.n_blocks, s, k))
    n = len(pair_row)
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        bid = pair_bid[lo:hi]
        vals = np.einsum("nis,nit->nst", WT[pair_row[lo:hi]], Z[pair_m[lo:hi]])
        starts = np.flatnonzero(np.r_[True, bid[1:] != bid[:-1]])
        out[bid[starts]] += np.add.reduceat(vals, starts, axis=0)
    return out


def _coupling_numba(pat, WT, group, ptr, Ainv_seg):
    from photogram.adjust import _numba_coarse
    out = np.zeros((pat.n_blocks, WT.shape[2], pat.k))
    _numba_coarse.coupling_blocks(WT, group, ptr, Ainv_seg, pat.cluster, pat.lookup,
                                  pat.slots, out)
    return out


class TwoLevel:
    """``z = M^-1 r`` of the module docstring for one damped system.

    Parameters
    ----------
    Ncc : sparse (n_r, n_r)
        The damped camera block.
    jacobi : callable
        The Schur-Jacobi inverse ``J``.
    pat : _Pattern
    coupling : (n_blocks, s, k) array
        ``W A^-1 W^T P`` per (group, cluster) block.
    """

    def __init__(self, Ncc, jacobi, pat, coupling, floor=None):
        self.jacobi, self.pat = jacobi, pat
        NccP = (sp.csr_matrix(Ncc) @ pat.P).tocsr()
        self.SP = (NccP - pat.to_csr(coupling)).tocsr()
        self.SPT = self.SP.T.tocsr()
        Sc = (pat.P.T @ self.SP).toarray()
        Sc = 0.5 * (Sc + Sc.T)
        d = np.sqrt(np.where(np.diag(Sc) > 0, np.diag(Sc), 1.0))
        self.d = 1.0 / d
        w, V = la.eigh(Sc * self.d[:, None] * self.d[None, :])
        keep = w > (FLOOR if floor is None else floor)
        self.n_dropped = int(np.count_nonzero(~keep))
        self.V, self.winv = V[:, keep], 1.0 / w[keep]
        self.Pt = pat.P.T.tocsr()
        self.Sc = Sc

    def measure(self, r):
        """``J r``: the norm of :func:`~photogram.adjust.rcs_iterative.pcg`'s
        residual test (that of Schur-Jacobi: the same stopping rule with
        either preconditioner; this one's own norm weighs the coarse
        modes, among them the damped gauge freedom, so heavily that the
        relative test would stop after a step or two)."""
        return self.jacobi(r)

    def coarse(self, v):
        """``S_c^-1 v`` on the kept coarse modes (``D V (V^T D v) / w``)."""
        return self.d * (self.V @ (self.winv * (self.V.T @ (self.d * v))))

    def __call__(self, r):
        e = self.coarse(self.Pt @ r)
        u = self.jacobi(r - self.SP @ e)
        f = self.coarse(self.SPT @ u)
        return self.pat.P @ (e - f) + u


def _rows(op):
    """``(W_o^T, group, ptr, A^-1, owner)`` of the coupling rows in point
    (segment) order, whichever path built ``op``."""
    system = op.system
    st = system.structure
    pl = op.point
    if pl is not None:
        return op.WTp, pl.group, pl.ptr, op.Ainv_o, pl
    if not hasattr(op, "rcp"):
        op._index()
    WT = op.WTp
    if WT is None:
        cache = system.__dict__.setdefault("_rcs_cache", {})
        if "WTp" not in cache:
            cache["WTp"] = system.WT[st.pt_rows]
        WT = cache["WTp"]
    return WT, op.grp, st.pt_ptr, op.Ainv, st


def _setup(op, cluster_size, compiled, slots):
    st = op.system.structure
    WT, group, ptr, Ainv_seg, owner = _rows(op)
    group = np.ascontiguousarray(group, dtype=np.int64)
    ptr = np.ascontiguousarray(ptr, dtype=np.int64)
    if slots is None:
        slots = COARSE_SLOTS
    if isinstance(slots, str) or slots is None:
        slots = None
    else:
        slots = [j for j in slots if j < st.group_cols.shape[1]]
    if compiled is None:
        compiled = kernels.active(len(group)) and _have_numba()
    pat = pattern(owner, st.group_cols, st.n_r, group, ptr, int(cluster_size), slots, compiled)
    return pat, WT, group, ptr, Ainv_seg, compiled


def pattern_of(op, cluster_size=64, slots=None, compiled=None):
    """The cached :class:`_Pattern` that :func:`two_level` uses for
    ``op`` (for a caller that forms the coupling blocks itself, as the
    fused pass of :meth:`photogram.adjust.point_rows.PointSystem.schur_parts`)."""
    return _setup(op, cluster_size, compiled, slots)[0]


def two_level(op, jacobi, cluster_size=64, compiled=None, floor=None, slots=None,
              coupling=None):
    """The two-level preconditioner of a
    :class:`~photogram.adjust.rcs_iterative.SchurOperator` with smoother
    ``jacobi``; ``compiled``: use the numba kernel (None: when the
    kernels are active); ``floor``: the eigenvalue of the unit-diagonal
    ``S_c`` below which coarse modes are left out (None: ``FLOOR``);
    ``slots``: the columns of a group that the coarse space aggregates
    (None: ``COARSE_SLOTS``; "all": every column); ``coupling``: the
    blocks ``W A^-1 W^T P`` of :func:`pattern_of`'s pattern when already
    formed (the fused pass), else they are formed here."""
    pat, WT, group, ptr, Ainv_seg, compiled = _setup(op, cluster_size, compiled, slots)
    if coupling is None:
        coupling = (_coupling_numba(pat, WT, group, ptr, Ainv_seg) if compiled
                    else _coupling_numpy(pat, WT, Ainv_seg))
    return TwoLevel(op.Ncc, jacobi, pat, coupling, floor)


def _have_numba():
    try:
        from photogram.adjust import _numba_coarse  # noqa: F401
    except Exception:   # pragma: no cover - numba missing or broken
        return False
    return True


def _owner(op):
    return op.point if op.point is not None else op.system.structure


def resolve(op, kind):
    """The preconditioner that runs for ``kind`` on ``op``: ``kind``
    itself, or for ``"adaptive"`` ``"two_level"`` when the previous
    solve on the same structure (:func:`record`) took more than
    ``ADAPTIVE_STEPS`` CG steps, else ``"schur_jacobi"``."""
    if kind != "adaptive":
        return kind
    last = _owner(op).__dict__.get("_last_cg_steps", 0)
    return "two_level" if last > ADAPTIVE_STEPS else "schur_jacobi"


def record(op, steps):
    """Remember the CG steps of a solve on ``op``'s structure (for
    ``"adaptive"``)."""
    _owner(op).__dict__["_last_cg_steps"] = int(steps)


def preconditioner(op, kind="schur_jacobi", cluster_size=64, coupling=None, coarse=None):
    """``z = M^-1 r`` for PCG on ``op``: ``"schur_jacobi"`` or
    ``"two_level"``, or ``"adaptive"`` (:func:`resolve`; ``coupling``:
    the Schur-Jacobi blocks' summed
    ``-W A^-1 W^T`` part when known; ``coarse``: the two-level coupling
    blocks when known, see :func:`two_level`)."""
    jacobi = schur_jacobi(op, coupling)
    kind = resolve(op, kind)
    if kind == "schur_jacobi":
        return jacobi
    if kind != "two_level":
        raise ValueError(f"unknown CG preconditioner {kind!r} "
                         "(schur_jacobi, two_level or adaptive)")
    return two_level(op, jacobi, cluster_size, coupling=coarse)
