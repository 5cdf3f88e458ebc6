"""The point-ordered, fused linearization of BAL-type problems (many
cameras; the iterative reduced-camera-system solve).

For a problem of one image-point block of the ``bal`` camera model (the
model names its compiled rows, ``row_kernel = "bal_rows"``), every point
eliminated, every parameter free and unit weights, with the compiled
kernels active and the reduced camera system solved iteratively, the
generic path (:meth:`Problem.evaluate`, then
:func:`photogram.adjust.normal.assemble`, then a copy of ``W_o^T`` into
point order for the Schur products) stores the residuals, three Jacobian
arrays and ``W_o^T`` twice per iteration, and most of its time goes into
writing fresh memory. Here one compiled pass
(:func:`photogram.adjust._numba_point.bal_linearize`) walks the
observations point by point and sums the normal equations directly:
``A_p`` and ``g_p`` in registers, ``W_o^T`` written once, in point order,
into a buffer reused between iterations, ``N_cc`` and ``g_c`` summed per
camera (a few hundred kB that stay in cache). The cost of a trial step is
a second kernel that stores nothing.

The result is a :class:`PointSystem`, a
:class:`~photogram.adjust.normal.NormalSystem` whose ``W_o^T`` are kept in
point order (``WTp``); its ``WT`` (E-row order) is built only on request.
The values are those of the generic path up to rounding (the same
formulas; sums in another order).
"""

from __future__ import annotations

import weakref

import numpy as np

from photogram.adjust import kernels
from photogram.adjust.normal import NormalSystem, _NccSum

__all__ = ["PointSystem", "plan", "linearize", "cost"]


def _compiled():
    """The point-ordered kernels (:mod:`photogram.adjust._numba_point`)."""
    from photogram.adjust import _numba_point
    return _numba_point


class _Plan:
    """Row indices of the fused path in point order (fixed per structure)."""

    def __init__(self, block, st):
        cls = st.e_classes[0]
        rows = cls.rows[st.pt_rows]                         # block row of each pt-ordered row
        self.block = block
        self.rows = rows
        self.station = np.ascontiguousarray(block.station[rows], dtype=np.int64)
        self.camera = np.ascontiguousarray(block.camera[rows], dtype=np.int64)
        self.group = np.ascontiguousarray(st.e_group[st.pt_rows], dtype=np.int64)
        self.ptr = np.ascontiguousarray(st.pt_ptr, dtype=np.int64)
        self.gcols = np.ascontiguousarray(st.group_cols, dtype=np.int64)
        pidx = st.e_point[st.pt_rows]
        # at most one row per (point, group): the Schur-Jacobi pass needs no merging
        self.unique = not np.any((pidx[1:] == pidx[:-1]) & (self.group[1:] == self.group[:-1]))
        self._xy = (None, None)
        self.buffers = []                                   # [(array, weakref to owner)]

    def xy(self):
        """The block's observations in point order (copied again when the
        block's array is replaced, e.g. by ``set_observations``)."""
        src, copy = self._xy
        if src is not self.block.xy:
            copy = np.ascontiguousarray(self.block.xy[self.rows])
            self._xy = (self.block.xy, copy)
        return copy

    def buffer(self, shape):
        """A float array of ``shape`` no live :class:`PointSystem` uses
        (reused between iterations: fresh memory costs the kernel's page
        faults)."""
        for k, (arr, owner) in enumerate(self.buffers):
            if owner() is None and arr.shape == shape:
                return k, arr
        self.buffers.append((np.empty(shape), lambda: None))
        return len(self.buffers) - 1, self.buffers[-1][0]

    def own(self, k, system):
        self.buffers[k] = (self.buffers[k][0], weakref.ref(system))


def _eligible(problem):
    """The fused path's structural conditions (fixed per problem)."""
    from photogram.adjust.residual_blocks import ImagePointBlock
    if len(problem.blocks) != 1:
        return None
    blk = problem.blocks[0]
    st, lay = problem.structure, problem.layout
    if (type(blk) is not ImagePointBlock or getattr(blk.model, "row_kernel", None) != "bal_rows"
            or len(st.e_classes) != 1 or st.c_classes or lay.derived is not None):
        return None
    cls = st.e_classes[0]
    n_p = len(problem.state.points)
    if (cls.e_slot != 0 or cls.gather != [(1, None), (2, None)] or st.s != 9
            or len(st.pt_rows) != st.n_e_rows or lay.n_eliminated != n_p
            or not all(problem._all_free[0])):
        return None
    if not np.array_equal(lay.point_cols[:, 0], lay.n_reduced + 3 * np.arange(n_p)):
        return None
    if not np.array_equal(st.e_rcols, st.group_cols[st.e_group]):
        return None
    return _Plan(blk, st)


def plan(problem, method=None):
    """The fused path's plan of ``problem``, or None when it does not
    apply (then the generic path runs). ``method``: the RCS solve to
    assume (default: the problem's current one; only "iterative" fuses)."""
    if (method or problem.rcs.get("method")) != "iterative":
        return None
    st = problem.structure
    if not kernels.active(st.n_e_rows):
        return None
    cached = getattr(st, "_point_plan", False)
    if cached is False:
        cached = _eligible(problem)
        st._point_plan = cached
    if cached is None or not _unit_weights(problem):
        return None
    return cached


def _unit_weights(problem):
    """Every observation active with weight 1 (no whitening needed)."""
    b = problem.blocks[0]
    return (problem.variance[b.group] == 1.0 and bool(np.all(b.sigma == 1.0))
            and bool(np.all(problem.active[0])) and bool(np.all(problem.coordinate_active[0]))
            and bool(np.all(problem.robust_weight[0] == 1.0)))


def _model_arrays(pl, state):
    io = np.ascontiguousarray(np.stack([state.io[k] for k in pl.block.cameras]), dtype=float)
    return (pl.xy(), np.ascontiguousarray(state.points, dtype=float),
            np.ascontiguousarray(state.R, dtype=float),
            np.ascontiguousarray(state.X0, dtype=float), io)


def cost(problem, state):
    """``0.5 sum r^2`` by the fused kernel, or None (generic path)."""
    pl = plan(problem)
    if pl is None:
        return None
    xy, pts, R, X0, io = _model_arrays(pl, state)
    return 0.5 * _compiled().bal_cost(xy, pts, R, X0, io, pl.ptr, pl.station, pl.camera)


def linearize(problem, state):
    """The normal equations at ``state`` as a :class:`PointSystem`, or
    None (generic path)."""
    pl = plan(problem)
    if pl is None:
        return None
    st = problem.structure
    n_r, n_e, s, n_g = st.n_r, st.layout.n_eliminated, st.s, st.n_groups
    xy, pts, R, X0, io = _model_arrays(pl, state)
    A = np.empty((n_e, 3, 3))
    g_e = np.empty((n_e, 3))
    k, WTp = pl.buffer((st.n_e_rows, 3, s))
    g_grp = np.zeros((n_g, s))
    G = np.zeros((n_g, s, s))
    ssq = _compiled().bal_linearize(xy, pts, R, X0, io, pl.ptr, pl.station, pl.camera,
                                    pl.group, A, g_e, WTp, g_grp, G)
    iu = np.triu_indices(s, 1)
    G[:, iu[1], iu[0]] = G[:, iu[0], iu[1]]
    m = n_r + 1
    Ncc = _NccSum(m, True)
    Ncc.add(st._g_scatter, G.ravel())
    g_c = np.bincount(st.group_cols.ravel(), weights=g_grp.ravel(), minlength=m)
    g = np.concatenate([g_c[:n_r], g_e.ravel()])
    system = PointSystem(Ncc.matrix(), A, g, 0.5 * ssq, WTp, st, pl)
    pl.own(k, system)
    return system


class PointSystem(NormalSystem):
    """Normal equations whose per-E-row ``W_o^T`` are stored in point order
    (``WTp[k]`` is E-row ``structure.pt_rows[k]``)."""

    def __init__(self, Ncc, A, g, cost, WTp, structure, point_plan):
        self.Ncc, self.A, self.g, self.cost = Ncc, A, g, cost
        self.WTp = WTp
        self.structure = structure
        self.plan = point_plan
        self._W = None
        self._WT = None

    @property
    def WT(self):
        """``W_o^T`` in E-row order (a copy, built on request)."""
        if self._WT is None:
            out = np.empty_like(self.WTp)
            out[self.structure.pt_rows] = self.WTp
            self._WT = out
        return self._WT

    def wt_times_c(self, x_c):
        """``W^T x_c`` as (n_e, 3) for x_c (n_r,)."""
        pl = self.plan
        out = np.empty((self.structure.layout.n_eliminated, 3))
        _compiled().back(self.WTp, pl.group, pl.gcols, pl.ptr, np.append(x_c, 0.0), out)
        return out

    def schur_parts(self, Ncc, Ainv):
        """The Schur-Jacobi blocks before the ``N_cc`` part is added and
        ``W A^-1 g_e`` (n_r,), in one pass: ``(-sum W A^-1 W^T per group,
        rhs)``; None when a point has two rows in one group (the generic
        pass merges them)."""
        st, pl = self.structure, self.plan
        if not pl.unique:
            return None
        n_g, s = st.group_cols.shape
        blocks = np.zeros((n_g, s, s))
        rhs_g = np.zeros((n_g, s))
        g_e = self.g[st.n_r:].reshape(-1, 3)
        _compiled().jacobi_rhs(self.WTp, pl.group, pl.ptr, Ainv, g_e, blocks, rhs_g)
        iu = np.triu_indices(s, 1)
        blocks[:, iu[1], iu[0]] = blocks[:, iu[0], iu[1]]
        rhs = np.bincount(st.group_cols.ravel(), weights=rhs_g.ravel(), minlength=st.n_r + 1)
        return blocks, rhs[:st.n_r]
