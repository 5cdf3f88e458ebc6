"""A dense path through a :class:`~photogram.adjust.solver.Problem`, for
small problems solved many times (Monte Carlo) and for their first-order
propagation.

The residual blocks, weights and parameter blocks are the engine's own
(``Problem.blocks``, ``Problem.weights``, ``Layout``); only the linear algebra
is dense: the whitened Jacobian of the free columns is scattered into one
``(m, n_free)`` matrix through indices computed once (:class:`DenseStructure`,
cached on the problem), the normal equations are Jacobi-scaled and solved by
Cholesky, bordered with the datum conditions ``G`` of a free network. A
network of a few hundred unknowns takes a fraction of a millisecond per
iteration this way, where the sparse Schur path (:mod:`photogram.adjust.schur`)
pays its Python overhead per block.

* :func:`dense_jacobian` -- whitened residuals and Jacobian (free columns,
  optionally also the unmasked columns of fixed parameters, e.g. the
  interior orientation of ``orient`` for a sensitivity);
* :func:`gauss_newton` -- undamped Gauss-Newton from ``problem.state``
  until the largest scaled step is below a tolerance (the networks solved
  again and again start at the solution of exact observations);
* :func:`dense_cofactors` -- cofactors of the free unknowns (inner
  constraints with a free network);
* :func:`solve_dense` -- the linear step (``Problem.solve_linear`` with
  ``problem.linear = "dense"``).

To re-solve a problem with new observations, replace the observation
values of its blocks (``block.set_observations``) and the state
(:meth:`Problem.reset`), see docs/adjustment.md.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la

from photogram.adjust.residual_blocks import ImagePointBlock
from photogram.adjust.state import State

_potrf, _potrs = la.get_lapack_funcs(("potrf", "potrs"), (np.zeros((1, 1)),))
from photogram.errors import GeometryError

__all__ = ["DenseStructure", "dense_structure", "dense_jacobian", "dense_normal",
           "solve_dense", "gauss_newton", "dense_cofactors", "PointwiseStructure",
           "pointwise_structure", "point_normals"]


class DenseStructure:
    """Row offsets and scatter indices of a problem's dense Jacobian."""

    def __init__(self, problem):
        lay = problem.layout
        self.free = np.flatnonzero(lay.free)
        self.n = len(self.free)
        col_of = np.full(lay.n_columns, -1)                # fixed: -1
        col_of[self.free] = np.arange(self.n)
        self.col_of = col_of
        self.row_start = []
        m = sum(len(b) * b.dim for b in problem.blocks)
        self.m = m
        trash = m * self.n             # one spare entry takes the fixed columns' values
        row = 0
        self.flat = []                  # per block, per slot: flat indices (N*d*s,) or None
        self.flat_all = []              # the same into (m, n_columns)
        # a column named twice in a row (a tie fy = fx of shared interior
        # parameters): its Jacobian entries add up instead of being written
        self.accumulate = False
        for b in problem.blocks:
            N, d = len(b), b.dim
            rows = row + np.arange(N * d).reshape(N, d)
            self.row_start.append(row)
            per, per_all = [], []
            for cols in b.slot_cols:
                cols = np.asarray(cols).reshape(N, -1)
                if cols.shape[1] > 1 and len(cols):
                    srt = np.sort(cols, axis=1)
                    self.accumulate |= bool(np.any(srt[:, 1:] == srt[:, :-1]))
                c = col_of[cols][:, None, :]
                if np.all(c < 0):
                    per.append(None)            # every column fixed: nothing to write
                else:
                    per.append(np.where(c >= 0, rows[:, :, None] * self.n + c, trash).ravel())
                per_all.append((rows[:, :, None] * lay.n_columns + cols[:, None, :]).ravel())
            self.flat.append(per)
            self.flat_all.append(per_all)
            row += N * d
        self.block_rows = [(s, s + len(b) * b.dim) for s, b in zip(self.row_start, problem.blocks)]
        # image point blocks whose io columns are all fixed: no io Jacobian
        self.io_hint = [_plain_image_block(b) and self.flat[k][2] is None
                        for k, b in enumerate(problem.blocks)]
        self.G = None if problem.G is None else np.asarray(problem.G)[self.free]


def _plain_image_block(block) -> bool:
    return type(block).evaluate is ImagePointBlock.evaluate and len(block.slot_cols) == 3


def dense_structure(problem) -> DenseStructure:
    """The problem's :class:`DenseStructure` (computed once, cached)."""
    st = getattr(problem, "_dense", None)
    if st is None or st.m != sum(len(b) * b.dim for b in problem.blocks):
        st = problem._dense = DenseStructure(problem)
    return st


def dense_jacobian(problem, state, *, all_columns=False, residuals_only=False, weights=None):
    """Whitened residuals ``r`` (m,) and Jacobian ``J`` (m, n_free) of the free
    columns at ``state`` (rows in block order, each block's observations
    times its dimension); with ``all_columns`` also ``Jall`` (m, n_columns),
    every column unmasked (fixed parameters included). ``weights``: the
    list of ``problem.weights(k)`` if already computed."""
    st = dense_structure(problem)
    r = np.zeros(st.m)
    J = None
    if not residuals_only:
        # the scatter pattern never changes: every call writes the same
        # entries, the others stay zero (the buffer is reused: J is valid
        # until the next call)
        if getattr(st, "_buffer", None) is None:
            st._buffer = np.zeros(st.m * st.n + 1)
        J = st._buffer
        if st.accumulate:
            J[:] = 0.0
    Jall = np.zeros(st.m * problem.layout.n_columns) if all_columns else None
    for k, b in enumerate(problem.blocks):
        if st.io_hint[k] and not all_columns:
            e, Js = b.evaluate(state, not residuals_only, fixed_io=True)
        else:
            e, Js = b.evaluate(state, not residuals_only)
        w = problem.weights(k) if weights is None else weights[k]
        a, z = st.block_rows[k]
        r[a:z] = (np.where(w > 0, e, 0.0) * w).ravel()
        if residuals_only:
            continue
        for j, Jj in enumerate(Js):
            flat = st.flat[k][j]
            if flat is None and not all_columns or Jj is None:
                continue
            vals = (Jj * w[:, :, None]).ravel()
            if flat is not None and st.accumulate:
                np.add.at(J, flat, vals)
            elif flat is not None:
                J[flat] = vals
            if all_columns and st.accumulate:
                np.add.at(Jall, st.flat_all[k][j], vals)
            elif all_columns:
                Jall[st.flat_all[k][j]] = vals
    if residuals_only:
        return r
    J = J[:st.m * st.n].reshape(st.m, st.n)
    if all_columns:
        return r, J, Jall.reshape(st.m, -1)
    return r, J


class PointwiseStructure:
    """A problem whose free columns are all eliminated points (the
    orientation held fixed: ``photogram intersect``): every point is its own
    3x3 least-squares problem. Per block the slot of its point and the
    order that sums the rows per point (computed once)."""

    def __init__(self, problem):
        lay = problem.layout
        self.ok = problem.G is None and not lay.free[:lay.n_reduced].any()
        self.slots = []
        keys = []
        for b in problem.blocks:
            slot = None
            for j, cols in enumerate(b.slot_cols):
                cols = np.asarray(cols)
                if cols.ndim == 2 and cols.shape[1] == 3 and np.all(cols >= lay.n_reduced):
                    slot = j
            if slot is None:
                if any(lay.free[np.asarray(c)].any() for c in b.slot_cols):
                    self.ok = False
                self.slots.append(None)
                continue
            cols = np.asarray(b.slot_cols[slot])
            self.slots.append(slot)
            keys.append(_point_of(lay, cols[:, 0]))
        self.point = np.concatenate(keys) if keys else np.zeros(0, dtype=int)
        self.order = np.argsort(self.point, kind="stable")
        p = self.point[self.order]
        self.starts = np.flatnonzero(np.r_[True, p[1:] != p[:-1]]) if len(p) else \
            np.zeros(0, dtype=int)
        self.points = p[self.starts] if len(p) else np.zeros(0, dtype=int)
        sizes = np.diff(np.r_[self.starts, len(p)])
        # observations per point when every point has the same number
        self.views = int(sizes[0]) if len(sizes) and np.all(sizes == sizes[0]) else 0
        free = lay.free[lay.point_cols[self.points]]                  # (n, 3)
        self.free = free
        self.fixed = np.nonzero(~free)
        self.any_fixed = bool((~free).any())
        self.cols = lay.point_cols[self.points]


def _point_of(layout, first_col):
    """Point index of the first column of an eliminated point."""
    inv = np.full(layout.n_columns, -1)
    inv[layout.point_cols[:, 0]] = np.arange(len(layout.point_cols))
    return inv[first_col]


def pointwise_structure(problem):
    st = getattr(problem, "_pointwise", None)
    if st is None:
        st = problem._pointwise = PointwiseStructure(problem)
    return st


def point_normals(problem, state, weights=None):
    """Per observed point the 3x3 normal matrix ``A`` and gradient ``b`` of a
    pointwise problem (fixed coordinates: unit rows and columns), with the
    point indices: ``(points, A, b)``."""
    ps = pointwise_structure(problem)
    system = _PointSystem(problem, state, weights)
    A, g = system.normals(state.points)
    return ps.points, A, g


class _PointSystem:
    """The blocks of a pointwise problem as functions of the points alone
    (:meth:`ImagePointBlock.points_only`: the orientation is fixed), their
    weights, and the sums of their 3x3 normal equations per point."""

    def __init__(self, problem, state, weights=None):
        self.ps = ps = pointwise_structure(problem)
        self.parts = []
        for k, b in enumerate(problem.blocks):
            j = ps.slots[k]
            if j is None:
                continue
            w = problem.weights(k) if weights is None else weights[k]
            if _plain_image_block(b):
                f = b.points_only(state)
            else:
                f = _points_function(b, state, j)
            self.parts.append((f, w, None if w.all() else w > 0))

    def normals(self, points):
        ps = self.ps
        rs, Js = [], []
        for f, w, used in self.parts:
            e, J = f(points)
            rs.append((e if used is None else np.where(used, e, 0.0)) * w)
            Js.append(J * w[:, :, None])
        if ps.views and len(Js) == 1:    # each point in as many rows: one product each
            n = len(ps.points)
            Jg = Js[0][ps.order].reshape(n, -1, 3)
            Jt = np.swapaxes(Jg, 1, 2)
            A = Jt @ Jg
            g = (Jt @ rs[0][ps.order].reshape(n, -1, 1))[..., 0]
        else:
            As, bs = [], []
            for r, J in zip(rs, Js):
                Jt = np.swapaxes(J, 1, 2)
                As.append(Jt @ J)
                bs.append((Jt @ r[..., None])[..., 0])
            As = As[0] if len(As) == 1 else np.concatenate(As)
            bs = bs[0] if len(bs) == 1 else np.concatenate(bs)
            A = np.add.reduceat(As[ps.order], ps.starts, axis=0)
            g = np.add.reduceat(bs[ps.order], ps.starts, axis=0)
        if ps.any_fixed:
            A = A * ps.free[:, :, None] * ps.free[:, None, :]
            g = g * ps.free
            i, q = ps.fixed
            A[i, q, q] = 1.0
        return A, g


def _points_function(block, state, slot):
    """A block's residuals and point Jacobian as a function of the points."""
    def f(points):
        e, Js = block.evaluate(State(points, state.R, state.X0, state.io), True)
        return e, Js[slot]
    return f


def _gauss_newton_points(problem, tolerance, max_iterations, scale):
    ps = pointwise_structure(problem)
    weights = [problem.weights(k) for k in range(len(problem.blocks))]
    s = scale[dense_structure(problem).col_of[ps.cols]] if scale is not None else None
    # (scale: per free column, as gauss_newton's)
    state = problem.state
    system = _PointSystem(problem, state, weights)
    points = state.points
    for it in range(1, max_iterations + 1):
        A, g = system.normals(points)
        try:
            step = -np.linalg.solve(A, g[..., None])[..., 0]
        except np.linalg.LinAlgError:
            raise GeometryError("singular normal equations of a point (rays nearly parallel?)",
                                hint="check the geometry of the intersection") from None
        if not np.all(np.isfinite(step)):
            raise GeometryError("the adjustment diverged (non-finite step)")
        points = points.copy()              # only points move: the orientation arrays
        points[ps.points] += step           # are shared with the new state (not copied)
        problem.state = State(points, state.R, state.X0, state.io)
        if s is None:
            size = 1.0 + float(np.nanmax(np.abs(points[ps.points]), initial=0.0))
            done = np.max(np.abs(step), initial=0.0) <= tolerance * size
        else:
            done = np.max(np.abs(step) / s, initial=0.0) < tolerance
        if done:
            return it
    raise GeometryError(f"the adjustment did not converge in {max_iterations} iterations")


def dense_normal(J, r=None):
    """Jacobi-scaled normal matrix ``Ns``, scaled gradient and the scale ``d``
    (``N = Ns / (d d^T)``)."""
    N = J.T @ J
    d = np.sqrt(np.diag(N))
    d = 1.0 / np.where(d > 0, d, 1.0)
    Ns = N * d[:, None] * d[None, :]
    g = None if r is None else d * (J.T @ r)
    return Ns, g, d


def _step(Ns, gs, d, G, damping=0.0):
    if damping:
        Ns = Ns + damping * np.diag(np.diag(Ns))
    if G is None:
        # LAPACK's Cholesky directly (what scipy.linalg.cho_factor/cho_solve
        # call, without their checks and copies: the same numbers)
        c, info = _potrf(Ns, lower=False, overwrite_a=False, clean=False)
        if info != 0:
            raise GeometryError("singular normal equations (datum defect?)",
                                hint="check the datum of the adjustment")
        x, info = _potrs(c, gs, lower=False, overwrite_b=False)
        return -d * x
    Gs = G * d[:, None]
    k = Gs.shape[1]
    M = np.block([[Ns, Gs], [Gs.T, np.zeros((k, k))]])
    sol = np.linalg.solve(M, np.concatenate([-gs, np.zeros(k)]))
    return d * sol[:len(d)]


def solve_dense(problem, state, damping=0.0):
    """The (damped) Gauss-Newton step of all columns (zero for fixed ones)."""
    st = dense_structure(problem)
    r, J = dense_jacobian(problem, state)
    Ns, gs, d = dense_normal(J, r)
    dx = np.zeros(problem.layout.n_columns)
    dx[st.free] = _step(Ns, gs, d, st.G, damping)
    return dx


def parameter_scale(problem, state):
    from photogram.adjust.lm_loops import _parameter_scale
    return _parameter_scale(problem, state)[dense_structure(problem).free]


def gauss_newton(problem, *, tolerance=1e-10, max_iterations=30, scale=None):
    """Undamped Gauss-Newton on ``problem.state`` (in place) until the largest
    step relative to the parameter scale (:func:`lm_loops._parameter_scale`,
    taken at the start) is below ``tolerance``; returns the iterations.
    A problem whose free unknowns are all eliminated points (fixed
    orientation) is solved point by point (3x3 normal equations each,
    :func:`point_normals`; the step relative to the largest coordinate).

    Raises
    ------
    GeometryError
        Non-finite step or no convergence within ``max_iterations``.
    """
    if pointwise_structure(problem).ok:
        return _gauss_newton_points(problem, tolerance, max_iterations, scale)
    st = dense_structure(problem)
    state = problem.state
    s = parameter_scale(problem, state) if scale is None else scale
    lay = problem.layout
    weights = [problem.weights(k) for k in range(len(problem.blocks))]
    for it in range(1, max_iterations + 1):
        r, J = dense_jacobian(problem, state, weights=weights)
        Ns, gs, d = dense_normal(J, r)
        dxf = _step(Ns, gs, d, st.G)
        if not np.all(np.isfinite(dxf)):
            raise GeometryError("the adjustment diverged (non-finite step)")
        dx = np.zeros(lay.n_columns)
        dx[st.free] = dxf
        state = state.updated(lay, dx)
        problem.state = state
        if np.max(np.abs(dxf) / s, initial=0.0) < tolerance:
            return it
    raise GeometryError(f"the adjustment did not converge in {max_iterations} iterations")


def dense_cofactors(problem, state=None):
    """``(r, J, Q, Jall)`` at ``state`` (default the problem's): whitened
    residuals and Jacobian (free columns), the cofactors ``Q`` (n_free,
    n_free) of the free unknowns (a-priori sigma0 = 1; inner-constraint
    cofactors with datum conditions) and the unmasked Jacobian of every
    column (m, n_columns)."""
    st = dense_structure(problem)
    state = problem.state if state is None else state
    r, J, Jall = dense_jacobian(problem, state, all_columns=True)
    J = J.copy()
    Ns, _, d = dense_normal(J)
    if st.G is None:
        Q = np.linalg.inv(Ns)
    else:
        Gs = st.G * d[:, None]
        k = Gs.shape[1]
        M = np.block([[Ns, Gs], [Gs.T, np.zeros((k, k))]])
        Q = np.linalg.inv(M)[:st.n, :st.n]
    return r, J, Q * d[:, None] * d[None, :], Jall
