"""The point-ordered, fused linearization of BAL-type problems (many
cameras; the iterative reduced-camera-system solve).

For a problem of one image-point block of the ``bal`` camera model (the
model names its compiled rows, ``row_kernel = "bal_rows"``), every point
eliminated, every parameter free and unit weights, with the reduced
camera system solved iteratively, the
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

Without the compiled kernels (numba missing or switched off, or fewer
E-rows than their threshold) the same system comes from the numpy twin
(:mod:`photogram.adjust._numpy_point`): the same formulas vectorised over
chunks of observations, ``N_cc`` and ``g_c`` as one BLAS Gram matrix per
camera, ``W_o`` also kept in camera order so that the CG products are
scipy's block-sparse (BSR) products in both directions.

The result is a :class:`PointSystem`, a
:class:`~photogram.adjust.normal.NormalSystem` whose ``W_o^T`` are kept in
point order (``WTp``); its ``WT`` (E-row order) is built only on request.
The values are those of the generic path up to rounding (the same
formulas; sums in another order).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from photogram.adjust import _numpy_point, kernels
from photogram.adjust.normal import NormalSystem, _NccSum
from photogram.adjust.point_plan import Plan as _Plan

__all__ = ["PointSystem", "plan", "linearize", "cost"]


def _compiled():
    """The point-ordered kernels (:mod:`photogram.adjust._numba_point`)."""
    from photogram.adjust import _numba_point
    return _numba_point


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
    assume (default: the problem's current one; only "iterative" fuses).
    The compiled kernels run it when they are active for the problem's
    size (:func:`compiled_for`), the numpy twin
    (:mod:`photogram.adjust._numpy_point`) otherwise."""
    if (method or problem.rcs.get("method")) != "iterative":
        return None
    st = problem.structure
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
    pts = np.take(np.asarray(state.points, dtype=float), pl.point, axis=0,
                  out=pl.scratch("points", (len(pl.point), 3)))
    return (pl.xy(), pts,
            np.ascontiguousarray(state.R, dtype=float),
            np.ascontiguousarray(state.X0, dtype=float), io)


def cost(problem, state):
    """``0.5 sum r^2`` by the fused kernel, or None (generic path)."""
    pl = plan(problem)
    if pl is None:
        return None
    xy, pts, R, X0, io = _model_arrays(pl, state)
    if not compiled_for(problem):
        _numpy_order(pl, problem.structure)
        return 0.5 * _numpy_point.cost(xy, pts, R, X0, io, pl)
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
    if compiled_for(problem):
        k, (WTp, A_o, g_o, g, back) = pl.buffers_for([(st.n_e_rows, 3, s), (n_e, 3, 3),
                                                      (n_e, 3), (n_r + 3 * n_e,), (n_e, 3)])
        g_grp = np.zeros((n_g, s))
        G = np.zeros((n_g, s, s))
        ssq = _compiled().bal_linearize(xy, pts, R, X0, io, pl.ptr, pl.station, pl.camera,
                                        pl.group, A_o, g_o, WTp, g_grp, G)
        iu = np.triu_indices(s, 1)
        G[:, iu[1], iu[0]] = G[:, iu[0], iu[1]]
        Wg = None
    else:
        _numpy_order(pl, st)
        k, (WTp, Wg, Qp, g) = pl.buffers_for([(st.n_e_rows, 3, s), (st.n_e_rows, s, 3),
                                              (9, st.n_e_rows), (n_r + 3 * n_e,)])
        back = None
        Gr = np.zeros((n_g, s + 1, s + 1))
        A_o, g_o = _numpy_point.linearize(xy, pts, R, X0, io, pl, WTp, Wg, Qp, Gr)
        G, g_grp, ssq = Gr[:, :s, :s], Gr[:, :s, s], float(Gr[:, s, s].sum())
    m = n_r + 1
    Ncc = _NccSum(m, True)
    Ncc.add(st._g_scatter, G.ravel())
    g_c = np.bincount(st.group_cols.ravel(), weights=g_grp.ravel(), minlength=m)
    g[:n_r] = g_c[:n_r]
    g[n_r:].reshape(n_e, 3)[pl.point] = g_o
    system = PointSystem(Ncc.matrix(), A_o, g_o, g, 0.5 * ssq, WTp, st, pl, Wg)
    system._back = back
    pl.own(k, system)
    return system


def compiled_for(problem):
    """Run the fused path with the compiled kernels (else the numpy twin)?"""
    return kernels.active(problem.structure.n_e_rows)


def _numpy_order(pl, st):
    """The numpy twin's group order of the plan (computed once)."""
    if getattr(pl, "numpy_order", None) is None:
        pl.numpy_order = _numpy_point.Order(pl, st.n_groups)
    return pl.numpy_order


class PointSystem(NormalSystem):
    """Normal equations whose per-E-row ``W_o^T`` are stored point by
    point in the plan's order (``WTp[k]`` is E-row ``plan.erows[k]``),
    with the point blocks and gradients in the plan's point order too
    (``A_o[i]``, ``g_o[i]`` of point ``plan.point[i]``); ``A`` and ``WT``
    in the engine's order are built on request.

    ``Wg``: None for the compiled kernels; for the numpy twin the same
    ``W_o`` (9 x 3 each) in the twin's group order, and every product is
    a block-sparse product of scipy (:func:`_numpy_point.bsr_pair`)."""

    def __init__(self, Ncc, A_o, g_o, g, cost, WTp, structure, point_plan, Wg=None):
        self.Ncc, self.A_o, self.g_o, self.g, self.cost = Ncc, A_o, g_o, g, cost
        self.WTp = WTp
        self.Wg = Wg
        self.structure = structure
        self.plan = point_plan
        self._W = self._WT = self._A = None
        self._last_back = None
        self._back = None          # the compiled back_o's output (a buffer of the plan)
        self._bsr = None

    def bsr(self):
        """``(W^T, W)`` as block-sparse matrices (numpy twin only)."""
        if self._bsr is None:
            self._bsr = _numpy_point.bsr_pair(self.WTp, self.Wg, self.plan)
        return self._bsr

    def _to_groups(self, x_c):
        """Reduced-column vector ``x_c`` in the numpy twin's group-block
        order (s per group; padding columns 0)."""
        return np.append(x_c, 0.0)[self.plan.gcols].ravel()

    def _from_groups(self, v):
        """Group-block vector to reduced columns (summed where groups
        share a column)."""
        n_r = self.structure.n_r
        return np.bincount(self.plan.gcols.ravel(), weights=v, minlength=n_r + 1)[:n_r]

    @property
    def A(self):
        """The point blocks (n_e, 3, 3) in point-number order (a copy)."""
        if self._A is None:
            self._A = np.empty_like(self.A_o)
            self._A[self.plan.point] = self.A_o
        return self._A

    @property
    def WT(self):
        """``W_o^T`` in E-row order (a copy, built on request)."""
        if self._WT is None:
            out = np.empty_like(self.WTp)
            out[self.plan.erows] = self.WTp
            self._WT = out
        return self._WT

    def back_o(self, x_c):
        """``W^T x_c`` (n_e, 3) in the plan's point order; the last product
        is kept (the trust region's model decrease asks again for the
        step's back-substitution product; compiled: in a buffer of the
        system that the next product overwrites)."""
        last = self._last_back
        if last is not None and np.array_equal(last[0], x_c):
            return last[1]
        pl = self.plan
        if self.Wg is not None:
            out = (self.bsr()[0] @ self._to_groups(x_c)).reshape(-1, 3)
        else:
            out = self._back if self._back is not None else np.empty((len(pl.point), 3))
            _compiled().back(self.WTp, pl.group, pl.gcols, pl.ptr, np.append(x_c, 0.0), out)
        self._last_back = (np.array(x_c, dtype=float), out)
        return out

    def wt_times_c(self, x_c):
        """``W^T x_c`` as (n_e, 3) for x_c (n_r,)."""
        out = np.empty((len(self.plan.point), 3))
        out[self.plan.point] = self.back_o(x_c)
        return out

    def quadratic(self, dx):
        """``dx^T N dx`` (= |J dx|^2) of the undamped normal equations."""
        n_r, pl = self.structure.n_r, self.plan
        dc = dx[:n_r]
        de = np.take(dx[n_r:].reshape(-1, 3), pl.point, axis=0,
                     out=pl.scratch("quadratic_e", (len(pl.point), 3)))
        q = float(dc @ (self.Ncc @ dc)) + float(np.einsum("ni,nij,nj->", de, self.A_o, de))
        wde = np.multiply(self.back_o(dc), de, out=pl.scratch("quadratic_w", de.shape))
        return q + 2.0 * float(np.sum(wde))

    def w_times_e(self, x_e):
        """``W x_e`` (n_r,) for x_e (n_e, 3)."""
        pl, n_r = self.plan, self.structure.n_r
        if self.Wg is not None:
            return self._from_groups(self.bsr()[1] @ np.ravel(x_e[pl.point]))
        v = np.einsum("nis,ni->ns", self.WTp, x_e[pl.row_points()])
        cols = pl.gcols[pl.group]
        return np.bincount(cols.ravel(), weights=v.ravel(), minlength=n_r + 1)[:n_r]

    def schur_matvec(self, Ainv_o, x_c):
        """``W A^-1 W^T x_c`` (n_r,) with ``Ainv_o`` in the plan's order."""
        pl = self.plan
        if self.Wg is not None:
            WT, W = self.bsr()
            y = (WT @ self._to_groups(x_c)).reshape(-1, 3)
            return self._from_groups(W @ _numpy_point.apply_blocks(Ainv_o, y).ravel())
        out = np.zeros(self.structure.n_r + 1)
        _compiled().matvec(self.WTp, pl.group, pl.gcols, pl.ptr, Ainv_o, np.append(x_c, 0.0), out)
        return out[:-1]

    def schur_parts(self, Ncc, Ainv, ordered=False, coarse=None):
        """The Schur-Jacobi blocks before the ``N_cc`` part is added and
        ``W A^-1 g_e`` (n_r,), in one pass: ``(-sum W A^-1 W^T per group,
        rhs)`` (``Ainv`` in point-number order, or in the plan's with
        ``ordered``); None when a point has two rows in one group (the
        generic pass merges them). ``coarse``: a two-level pattern
        (:func:`photogram.adjust.rcs_coarse.pattern_of`); then the
        coarse coupling blocks ``W A^-1 W^T P`` come third, from the same
        pass over ``W_o^T`` on the compiled path
        (``_numba_coarse.jacobi_rhs_coupling``; numpy: the two separate
        passes)."""
        st, pl = self.structure, self.plan
        if not pl.unique:
            return None
        Ainv_o = Ainv if ordered else Ainv[pl.point]
        n_g, s = st.group_cols.shape
        if self.Wg is not None:
            blocks = -_numpy_point.jacobi_blocks(self.Wg, Ainv_o, pl, n_g)
            z = _numpy_point.apply_blocks(Ainv_o, self.g_o)
            parts = blocks, self._from_groups(self.bsr()[1] @ z.ravel())
            if coarse is None:
                return parts
            from photogram.adjust.rcs_coarse import _coupling_numpy
            return parts + (_coupling_numpy(coarse, self.WTp, Ainv_o),)
        blocks = np.zeros((n_g, s, s))
        rhs_g = np.zeros((n_g, s))
        if coarse is None:
            _compiled().jacobi_rhs(self.WTp, pl.group, pl.ptr, Ainv_o, self.g_o, blocks, rhs_g)
        else:
            from photogram.adjust import _numba_coarse
            coupling = np.zeros((coarse.n_blocks, s, coarse.k))
            _numba_coarse.jacobi_rhs_coupling(self.WTp, pl.group, pl.ptr, Ainv_o, self.g_o,
                                              blocks, rhs_g, coarse.cluster, coarse.lookup,
                                              coarse.slots, coupling)
        iu = np.triu_indices(s, 1)
        blocks[:, iu[1], iu[0]] = blocks[:, iu[0], iu[1]]
        rhs = np.bincount(st.group_cols.ravel(), weights=rhs_g.ravel(), minlength=st.n_r + 1)
        if coarse is None:
            return blocks, rhs[:st.n_r]
        return blocks, rhs[:st.n_r], coupling

    def damped_inverse(self, layout, damping, point_labels=None):
        """``(N_cc, A^-1)`` of the damped normal equations (as
        ``schur.damped`` and ``schur.invert_point_blocks``; one compiled
        pass for the point blocks, ``A^-1`` in the plan's point order; on
        the compiled path ``A^-1`` is the plan's work array, valid until the
        next call)."""
        n_r = layout.n_reduced
        fixed = ~layout.free
        d = self.Ncc.diagonal()
        Ncc = (self.Ncc + sp.diags(d * damping + fixed[:n_r])).tocsr()
        pl, n_e = self.plan, len(self.A_o)
        fix_e = pl.scratch("fix", (n_e, 3))
        fix_e[...] = fixed[n_r:].reshape(-1, 3)[pl.point]
        if self.Wg is not None:
            from photogram.adjust.schur import invert_point_blocks
            Ad = self.A_o.copy()
            i3 = np.arange(3)
            Ad[:, i3, i3] = Ad[:, i3, i3] * (1.0 + damping) + fix_e
            labels = None if point_labels is None else np.asarray(point_labels)[self.plan.point]
            return Ncc, invert_point_blocks(Ad, labels)
        Ainv = pl.scratch("Ainv", self.A_o.shape)
        if _compiled().damped_inverse(self.A_o, float(damping), fix_e, Ainv):
            from photogram.adjust.schur import damped, invert_point_blocks
            invert_point_blocks(damped(self, layout, damping)[1], point_labels)   # raises
        return Ncc, Ainv

    def solve_iterative(self, layout, damping, tolerance, max_iterations, point_labels=None,
                        criterion="residual", precond=("schur_jacobi", 64)):
        """The damped step by preconditioned CG on the reduced camera
        system (:func:`photogram.adjust.schur.solve`'s iterative method),
        every point-side quantity in the plan's order (``precond``: kind
        and cluster size, :func:`photogram.adjust.rcs_coarse.preconditioner`)."""
        from photogram.adjust import rcs_coarse, rcs_iterative
        from photogram.errors import GeometryError
        n_r = layout.n_reduced
        pl = self.plan
        Ncc, Ainv_o = self.damped_inverse(layout, damping, point_labels)
        op = rcs_iterative.SchurOperator(self, Ncc, Ainv_o, ordered=True)
        coarse = None
        if rcs_coarse.resolve(op, precond[0]) == "two_level" and pl.unique:
            coarse = rcs_coarse.pattern_of(op, precond[1])
        parts = self.schur_parts(Ncc, Ainv_o, ordered=True, coarse=coarse)
        if parts is None:
            rhs_c = -self.g[:n_r] + op.w_times_e(
                np.einsum("nij,nj->ni", op.Ainv, self.g[n_r:].reshape(-1, 3)))
            apply = rcs_coarse.preconditioner(op, *precond)
        else:
            rhs_c = -self.g[:n_r] + parts[1]
            apply = rcs_coarse.preconditioner(op, *precond, coupling=parts[0],
                                              coarse=parts[2] if coarse is not None else None)
        rhs_c[~layout.free[:n_r]] = 0.0
        dx_c, steps = rcs_iterative.pcg(op, rhs_c, apply, tolerance, max_iterations, criterion)
        rcs_coarse.record(op, steps)
        rhs_o = np.negative(self.g_o, out=pl.scratch("rhs", self.g_o.shape))
        rhs_o -= self.back_o(dx_c)
        dx = np.empty(layout.n_columns)
        dx[:n_r] = dx_c
        dx[n_r:].reshape(-1, 3)[pl.point] = np.einsum("nij,nj->ni", Ainv_o, rhs_o,
                                                      out=pl.scratch("dx_e", rhs_o.shape))
        dx[~layout.free] = 0.0
        if not np.all(np.isfinite(dx)):
            raise GeometryError("the adjustment produced a non-finite step (divergence)",
                                hint="check the approximate values and the datum")
        return dx
