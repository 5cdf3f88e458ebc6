"""The Gauss-Newton / Levenberg-Marquardt loop over a :class:`Problem`
(parameter blocks + residual blocks + weights), with solver options in one
place and a full summary at the end (as Ceres does).

Two damping strategies: ``"lm"`` (the default; the undamped Gauss-Newton
step first, Marquardt's lambda x 10 only after a failed step) and
``"trust_region"`` (Ceres' Levenberg-Marquardt: always damped with
``lambda = 1 / radius``, the radius updated from the ratio of the actual to
the predicted decrease, ``radius /= max(1/3, 1 - (2 rho - 1)^3)`` after a
success and halved with a doubling factor after a failure; Ceres' default
function, gradient and parameter tolerances). The trust region copes with a
gauge freedom (no datum: the damping keeps the system regular), which is
how Ceres solves BAL problems.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field

import numpy as np

from photogram.adjust import kernels, point_rows
from photogram.adjust.diagnostics import worst_observations
from photogram.adjust.lm_loops import gauss_newton, trust_region
from photogram.adjust.normal import assemble
from photogram.adjust.structure import Structure
from photogram.adjust.schur import RCS_METHODS, solve as schur_solve
from photogram.errors import GeometryError

DAMPINGS = ("none", "lm", "armijo", "trust_region")
# reduced columns from which "auto" solves the RCS iteratively: {numba: n;
# "fused": point_rows' fused BAL linearization, numba or its numpy twin}
ITERATIVE_MIN_COLUMNS = {True: 1500, False: 4000, "fused": 500}
# row groups (cameras) from which "auto" preconditions CG adaptively with
# two levels ("adaptive": two-level after a solve of more than
# rcs_coarse.ADAPTIVE_STEPS CG steps). Measured on seed 0 of the simulated
# sphere problems (docs/benchmarks.md, "Follow-up 4", "Fused coarse
# pass"): 3-8 % less CPU per iteration than Schur-Jacobi at 3333 cameras
# (10^7 observations, three pairs), 2-18 % more at 1000 cameras (two
# pairs); plain two-level paid at neither. 3000 lies between the two.
TWO_LEVEL_MIN_GROUPS = 3000


@dataclass
class SolverOptions:
    """Everything that steers the iteration.

    ``tolerance`` is relative: stop when the cost decreases by less than
    ``tolerance * cost`` and the largest step is below ``tolerance`` times
    the parameter scale.

    With ``damping="trust_region"`` (Ceres' Levenberg-Marquardt) the
    tolerances are Ceres': ``tolerance`` is the function tolerance
    (``|cost change| <= tolerance * cost``; Ceres' default 1e-6 is used when
    ``tolerance`` is left at this class's default), ``parameter_tolerance``
    bounds the step (``|dx| <= ptol (|x| + ptol)``) and
    ``gradient_tolerance`` the largest gradient entry.

    ``linear_solver`` chooses how the reduced camera system (RCS) is
    solved: ``"dense"`` (formed and factorized by a dense Cholesky),
    ``"iterative"`` (conjugate gradients on the implicit Schur complement
    with the Schur-Jacobi preconditioner, never forming the RCS: Ceres'
    ITERATIVE_SCHUR; :mod:`photogram.adjust.rcs_iterative`) or ``"auto"``
    (default): iterative when the problem has no datum conditions (inner
    constraints) and at least ``iterative_min_columns`` reduced columns
    (None: 500 when the fused BAL linearization of
    :mod:`photogram.adjust.point_rows` applies, with numba or its numpy
    twin; otherwise 1500 when the numba kernels run, 4000 on the generic
    pure-numpy path; the crossovers measured on SIMULATED BAL problems),
    dense otherwise. CG stops when the preconditioned residual has
    fallen by ``cg_tolerance`` (``cg_criterion="residual"``) or, with
    ``"model"``, by Ceres' test for Levenberg-Marquardt steps (the last
    step's share of the quadratic model's decrease, times the step count,
    below ``cg_tolerance``; :func:`photogram.adjust.rcs_iterative.pcg`), or
    after ``cg_max_iterations`` steps. ``cg_preconditioner``:
    ``"schur_jacobi"``, ``"two_level"`` (Schur-Jacobi plus a coarse
    correction on clusters of about ``coarse_cluster_size`` cameras,
    :mod:`photogram.adjust.rcs_coarse`), ``"adaptive"`` (two-level only
    after a solve of more than ``rcs_coarse.ADAPTIVE_STEPS`` CG steps,
    :func:`photogram.adjust.rcs_coarse.resolve`) or ``"auto"`` (adaptive from
    ``TWO_LEVEL_MIN_GROUPS`` row groups on with the numba kernels, where
    it was measured to pay, when it applies). ``Summary.cg_preconditioner`` says which one ran.
    """

    max_iterations: int = 50
    tolerance: float = 1e-8
    damping: str = "lm"
    initial_lambda: float = 0.0       # try the Gauss-Newton step first
    restart_lambda: float = 1e-4      # lambda after a failed undamped step
    max_lambda: float = 1e12
    callback: object = None   # called as callback(iteration, cost, lambda)
    # trust_region (Ceres' defaults)
    initial_radius: float = 1e4
    max_radius: float = 1e16
    min_radius: float = 1e-32
    min_relative_decrease: float = 1e-3
    function_tolerance: float | None = None   # None: 1e-6 (Ceres) for trust_region
    parameter_tolerance: float = 1e-8
    gradient_tolerance: float = 1e-10
    max_invalid_steps: int = 10
    # the reduced camera system
    linear_solver: str = "auto"       # auto | dense | iterative
    iterative_min_columns: int | None = None   # None: 1500 with numba kernels, 4000 without
    cg_tolerance: float = 0.1         # Ceres' eta (ITERATIVE_SCHUR)
    cg_max_iterations: int = 500
    cg_criterion: str = "residual"    # residual | model (Ceres' LM test, rcs_iterative.pcg)
    cg_preconditioner: str = "auto"   # auto | schur_jacobi | two_level | adaptive (rcs_coarse)
    coarse_cluster_size: int = 64     # row groups (cameras) per coarse cluster (two_level)


@dataclass
class Summary:
    status: str = "not run"             # converged | max_iterations | failed
    message: str = ""
    iterations: int = 0
    initial_cost: float = float("nan")
    final_cost: float = float("nan")
    cost_trace: list = field(default_factory=list)
    n_observations: int = 0
    n_unknowns: int = 0
    n_conditions: int = 0
    redundancy: int = 0
    sigma0: float = float("nan")
    timings: dict = field(default_factory=dict)
    successful_steps: int = 0
    unsuccessful_steps: int = 0
    linear_solver: str = ""             # dense | iterative (the RCS solve used)
    cg_preconditioner: str = ""         # schur_jacobi | two_level | adaptive (iterative RCS only)

    def to_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items()}


class Problem:
    """A bundle adjustment problem: state, layout, residual blocks, datum
    conditions and the current weighting (variance factors per group,
    active observations, robust weights).
    """

    def __init__(self, state, layout, blocks, G=None, point_labels=None):
        self.state = state
        self.layout = layout
        self.blocks = list(blocks)
        self.G = G
        self.point_labels = point_labels
        self.structure = Structure(layout, [b.slot_cols for b in self.blocks])
        self.variance = {b.group: 1.0 for b in self.blocks}
        self.active = [np.ones(len(b), dtype=bool) for b in self.blocks]
        # per coordinate (N, dim): data snooping takes out one coordinate of
        # a record (the Z of a control point), not the whole record
        self.coordinate_active = [np.ones((len(b), b.dim), dtype=bool) for b in self.blocks]
        self.robust_weight = [np.ones((len(b), b.dim)) for b in self.blocks]
        self._free_masks = [[layout.free[c][:, None, :] for c in b.slot_cols] for b in self.blocks]
        self._all_free = [[bool(np.all(m)) for m in ms] for ms in self._free_masks]
        self._all_fixed = [[not np.any(m) for m in ms] for ms in self._free_masks]
        # how solve_linear solves the reduced camera system (set by solve()
        # for its run from SolverOptions; dense otherwise)
        self.rcs = {"method": "dense", "cg_tolerance": 0.1, "cg_max_iterations": 500,
                    "cg_criterion": "residual", "cg_preconditioner": "schur_jacobi",
                    "coarse_cluster_size": 64}

    def weights(self, k):
        """sqrt of the weight of every residual of block k (0 = not used)."""
        b = self.blocks[k]
        with np.errstate(divide="ignore"):
            w = 1.0 / (b.sigma * np.sqrt(self.variance[b.group]))
        w = np.where(np.isfinite(w), w, 0.0)
        return (w * self.active[k][:, None] * self.coordinate_active[k]
                * np.sqrt(self.robust_weight[k]))

    def evaluate(self, state, jacobians=True):
        """Whitened residuals (and Jacobians) of all blocks at ``state``."""
        rs, Js = [], []
        for k, b in enumerate(self.blocks):
            e, J = b.evaluate(state, jacobians)
            w = self.weights(k)
            unit = bool(np.all(w == 1.0))
            rs.append(e if unit else np.where(w > 0, e, 0.0) * w)
            if jacobians:
                out = []
                for Jj, m, all_free, all_fixed in zip(J, self._free_masks[k], self._all_free[k],
                                                      self._all_fixed[k]):
                    if all_fixed:
                        out.append(np.zeros(Jj.shape))
                        continue
                    if not unit:
                        Jj = Jj * w[:, :, None]
                    if not all_free:
                        Jj = Jj * m
                    out.append(Jj)
                Js.append(out)
        return rs, Js

    def cost(self, state) -> float:
        fused = point_rows.cost(self, state)
        if fused is not None:
            return fused
        rs, _ = self.evaluate(state, jacobians=False)
        return 0.5 * sum(float(np.sum(r * r)) for r in rs)

    def n_observations(self) -> int:
        return int(sum(np.count_nonzero(self.weights(k)) for k in range(len(self.blocks))))

    def n_conditions(self) -> int:
        return 0 if self.G is None else self.G.shape[1]

    def redundancy(self) -> int:
        return self.n_observations() - self.layout.n_free + self.n_conditions()

    def linearize(self, state):
        """The normal equations at ``state`` (residuals, Jacobians, sums)."""
        fused = point_rows.linearize(self, state)
        if fused is not None:
            return fused
        rs, Js = self.evaluate(state)
        return assemble(self.structure, rs, Js, sparse=self.rcs["method"] == "iterative")

    def solve_linear(self, system, damping=0.0):
        """The (damped) step of assembled normal equations: ``(dx, fact)``
        (``fact`` is None when the reduced camera system is solved
        iteratively, ``self.rcs``)."""
        return schur_solve(system, self.layout, damping, self.G, self.point_labels,
                           **self.rcs)

    def reset(self, state):
        """Start again from ``state`` (a copy is taken); the structure, the
        weights and the cached indices stay (re-solving with new
        observations: ``block.set_observations``, then :func:`solve` or
        :func:`photogram.adjust.dense.gauss_newton`)."""
        self.state = state.copy()

    def observations(self):
        """The observed values of every block (a list; None where a block
        observes nothing replaceable)."""
        return [b.observations() for b in self.blocks]

    def set_observations(self, values):
        """Replace the observed values of the blocks (a list as
        :meth:`observations` gives; None leaves a block as it is)."""
        for b, v in zip(self.blocks, values):
            if v is not None:
                b.set_observations(v)

    def step(self, state, damping=0.0):
        system = self.linearize(state)
        dx, fact = self.solve_linear(system, damping)
        return system, dx, fact


_CONTROLLER = []


def single_thread_blas():
    """Context: one BLAS thread, the policy of ``photogram/__init__.py``,
    also when numpy was imported before photogram (so that the environment
    variable came too late), e.g. under pytest. A thread count the user set
    (``OPENBLAS_NUM_THREADS``) is respected; without threadpoolctl this is
    a no-op."""
    if "OPENBLAS_NUM_THREADS" in os.environ:
        return contextlib.nullcontext()
    try:
        if not _CONTROLLER:
            from threadpoolctl import ThreadpoolController
            _CONTROLLER.append(ThreadpoolController())
        return _CONTROLLER[0].limit(limits=1, user_api="blas")
    except Exception:   # pragma: no cover - threadpoolctl missing or failing
        return contextlib.nullcontext()


def solve(problem: Problem, options: SolverOptions | None = None) -> Summary:
    """Minimize the weighted sum of squares of ``problem`` in place.

    See :func:`_solve`; runs with one BLAS thread (:func:`single_thread_blas`).
    """
    opt = options or SolverOptions()
    saved = dict(problem.rcs)
    method = rcs_method(problem, opt)
    precond = cg_preconditioner(problem, opt, method)
    problem.rcs.update(method=method, cg_tolerance=opt.cg_tolerance,
                       cg_max_iterations=opt.cg_max_iterations, cg_criterion=opt.cg_criterion,
                       cg_preconditioner=precond or "schur_jacobi",
                       coarse_cluster_size=opt.coarse_cluster_size)
    try:
        with single_thread_blas():
            s = _solve(problem, opt)
    finally:
        method = problem.rcs["method"]
        problem.rcs = saved
    s.linear_solver = method
    s.cg_preconditioner = precond
    return s


def cg_preconditioner(problem: Problem, options: SolverOptions, method: str) -> str:
    """The CG preconditioner of the iterative RCS solve that
    ``options.cg_preconditioner`` asks for ("" with the dense solve;
    ``"auto"``: adaptive from ``TWO_LEVEL_MIN_GROUPS`` row groups on, with
    the compiled kernels active, when
    :func:`photogram.adjust.rcs_coarse.applicable`)."""
    from photogram.adjust import rcs_coarse
    choice = options.cg_preconditioner
    if choice not in rcs_coarse.PRECONDITIONERS:
        raise ValueError(f"unknown cg_preconditioner {choice!r} "
                         f"({', '.join(rcs_coarse.PRECONDITIONERS)})")
    if method != "iterative":
        return ""
    ok = rcs_coarse.applicable(problem.structure)
    if choice in ("two_level", "adaptive") and not ok:
        raise ValueError(f"cg_preconditioner={choice!r} needs at least two row groups and "
                         "every reduced column in at most one group; use 'schur_jacobi'")
    if choice == "auto":
        st = problem.structure
        big = st.group_cols.shape[0] >= TWO_LEVEL_MIN_GROUPS and kernels.active(st.n_e_rows)
        return "adaptive" if big and ok else "schur_jacobi"
    return choice


def rcs_method(problem: Problem, options: SolverOptions) -> str:
    """``"dense"`` or ``"iterative"``: the solve of the reduced camera
    system that ``options.linear_solver`` asks for (``"auto"``: iterative
    from ``options.iterative_min_columns`` reduced columns on, when there
    are no datum conditions and there are points to eliminate)."""
    choice = options.linear_solver
    if choice not in ("auto",) + RCS_METHODS:
        raise ValueError(f"unknown linear_solver {choice!r} (auto, dense or iterative)")
    if choice == "iterative" and problem.G is not None:
        raise ValueError("linear_solver='iterative' takes no datum conditions "
                         "(inner constraints); use 'dense'")
    if choice != "auto":
        return choice
    least = options.iterative_min_columns
    if least is None:
        fused = (problem.layout.n_reduced >= ITERATIVE_MIN_COLUMNS["fused"] and problem.G is None
                 and point_rows.plan(problem, "iterative") is not None)
        least = ITERATIVE_MIN_COLUMNS["fused" if fused else
                                      kernels.active(problem.structure.n_e_rows)]
    big = problem.layout.n_reduced >= least
    return "iterative" if big and problem.G is None and problem.structure.n_e_rows else "dense"


def _solve(problem: Problem, options: SolverOptions | None = None) -> Summary:
    """Minimize the weighted sum of squares of ``problem`` in place.

    Gauss-Newton steps; with ``damping="lm"`` the undamped step is tried
    first and Marquardt's diagonal damping enters only when a step fails
    (lambda from ``restart_lambda``, x 10 per failure, / 10 per success, back
    to 0 once small): near the solution the iteration is pure Gauss-Newton,
    which converges quadratically even in the narrow valleys of correlated
    interior parameters where a small fixed lambda crawls. With
    ``"armijo"`` a failed step is halved. With ``"trust_region"`` every
    step is damped as in Ceres (:func:`photogram.adjust.lm_loops.trust_region`).
    """
    opt = options or SolverOptions()
    if opt.damping not in DAMPINGS:
        raise ValueError(f"unknown damping {opt.damping!r}")
    t0 = time.perf_counter()
    s = Summary(n_unknowns=problem.layout.n_free, n_conditions=problem.n_conditions())
    s.n_observations = problem.n_observations()
    # problem.redundancy() without a second pass over the weights (at 10^7
    # observations about 1 GB of fresh temporaries)
    s.redundancy = s.n_observations - problem.layout.n_free + s.n_conditions
    state = problem.state
    cost = problem.cost(state)
    if not np.isfinite(cost):
        raise GeometryError(_non_finite_message(problem, state),
                            hint="check the approximate values (a point at or behind a camera?)")
    s.initial_cost = cost
    s.cost_trace.append(cost)
    if opt.damping == "trust_region":
        state, cost = trust_region(problem, opt, s, state, cost)
    else:
        state, cost = gauss_newton(problem, opt, s, state, cost)
    problem.state = state
    s.final_cost = cost
    s.sigma0 = float(np.sqrt(2 * cost / s.redundancy)) if s.redundancy > 0 else float("nan")
    s.timings["solve"] = time.perf_counter() - t0
    if s.status in ("failed", "max_iterations"):
        s.message += worst_observations(problem, state)
    if s.status == "failed":
        raise GeometryError(s.message, hint="check the approximate values, the datum and gross errors")
    return s


def _non_finite_message(problem, state):
    """Name the observations whose residuals are not finite."""
    bad = []
    for blk in problem.blocks:
        e, _ = blk.evaluate(state, False)
        rows = np.flatnonzero(~np.all(np.isfinite(e), axis=1))
        labels = getattr(blk, "labels", None)
        bad += [f"{blk.name} {labels[i] if labels is not None else i}" for i in rows[:3]]
    return ("non-finite residuals at the approximate values: " + ", ".join(bad[:5])
            + (" ..." if len(bad) > 5 else ""))
