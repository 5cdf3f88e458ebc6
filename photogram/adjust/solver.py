"""The Gauss-Newton / Levenberg-Marquardt loop over a :class:`Problem`
(parameter blocks + residual blocks + weights), with solver options in one
place and a full summary at the end (as Ceres does).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from photogram.adjust.normal import Structure, assemble
from photogram.adjust.schur import solve as schur_solve
from photogram.errors import GeometryError

DAMPINGS = ("none", "lm", "armijo")


@dataclass
class SolverOptions:
    """Everything that steers the iteration.

    ``tolerance`` is relative: stop when the cost decreases by less than
    ``tolerance * cost`` and the largest step is below ``tolerance`` times
    the parameter scale.
    """

    max_iterations: int = 50
    tolerance: float = 1e-8
    damping: str = "lm"
    initial_lambda: float = 0.0       # try the Gauss-Newton step first
    restart_lambda: float = 1e-4      # lambda after a failed undamped step
    max_lambda: float = 1e12
    callback: object = None   # called as callback(iteration, cost, lambda)


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
        self.robust_weight = [np.ones((len(b), b.dim)) for b in self.blocks]
        self._free_masks = [[layout.free[c][:, None, :] for c in b.slot_cols] for b in self.blocks]

    def weights(self, k):
        """sqrt of the weight of every residual of block k (0 = not used)."""
        b = self.blocks[k]
        with np.errstate(divide="ignore"):
            w = 1.0 / (b.sigma * np.sqrt(self.variance[b.group]))
        w = np.where(np.isfinite(w), w, 0.0)
        return w * self.active[k][:, None] * np.sqrt(self.robust_weight[k])

    def evaluate(self, state, jacobians=True):
        """Whitened residuals (and Jacobians) of all blocks at ``state``."""
        rs, Js = [], []
        for k, b in enumerate(self.blocks):
            e, J = b.evaluate(state, jacobians)
            w = self.weights(k)
            rs.append(np.where(w > 0, e, 0.0) * w)
            if jacobians:
                Js.append([Jj * w[:, :, None] * m for Jj, m in zip(J, self._free_masks[k])])
        return rs, Js

    def cost(self, state) -> float:
        rs, _ = self.evaluate(state, jacobians=False)
        return 0.5 * sum(float(np.sum(r * r)) for r in rs)

    def n_observations(self) -> int:
        return int(sum(np.count_nonzero(self.weights(k)) for k in range(len(self.blocks))))

    def n_conditions(self) -> int:
        return 0 if self.G is None else self.G.shape[1]

    def redundancy(self) -> int:
        return self.n_observations() - self.layout.n_free + self.n_conditions()

    def step(self, state, damping=0.0):
        rs, Js = self.evaluate(state)
        system = assemble(self.structure, rs, Js)
        dx, fact = schur_solve(system, self.layout, damping, self.G, self.point_labels)
        return system, dx, fact


def solve(problem: Problem, options: SolverOptions | None = None) -> Summary:
    """Minimize the weighted sum of squares of ``problem`` in place.

    Gauss-Newton steps; with ``damping="lm"`` the undamped step is tried
    first and Marquardt's diagonal damping enters only when a step fails
    (lambda from ``restart_lambda``, x 10 per failure, / 10 per success, back
    to 0 once small): near the solution the iteration is pure Gauss-Newton,
    which converges quadratically even in the narrow valleys of correlated
    interior parameters where a small fixed lambda crawls. With
    ``"armijo"`` a failed step is halved.
    """
    opt = options or SolverOptions()
    if opt.damping not in DAMPINGS:
        raise ValueError(f"unknown damping {opt.damping!r}")
    t0 = time.perf_counter()
    s = Summary(n_unknowns=problem.layout.n_free, n_conditions=problem.n_conditions())
    s.n_observations = problem.n_observations()
    s.redundancy = problem.redundancy()
    state = problem.state
    cost = problem.cost(state)
    if not np.isfinite(cost):
        raise GeometryError(_non_finite_message(problem, state),
                            hint="check the approximate values (a point at or behind a camera?)")
    s.initial_cost = cost
    s.cost_trace.append(cost)
    lam = opt.initial_lambda if opt.damping == "lm" else 0.0
    s.status = "max_iterations"
    for it in range(1, opt.max_iterations + 1):
        accepted = False
        while True:
            _, dx, _ = problem.step(state, lam)
            trial = state.updated(problem.layout, dx)
            new_cost = problem.cost(trial)
            if np.isfinite(new_cost) and new_cost <= cost * (1 + 1e-12):
                accepted = True
                break
            if opt.damping == "lm" and lam < opt.max_lambda:
                lam = lam * 10.0 if lam > 0 else opt.restart_lambda
                continue
            if opt.damping in ("armijo", "none"):
                halved = False
                for _ in range(20):
                    dx = dx * 0.5
                    trial = state.updated(problem.layout, dx)
                    new_cost = problem.cost(trial)
                    if np.isfinite(new_cost) and new_cost <= cost:
                        accepted, halved = True, True
                        break
                if halved:
                    break
            break
        s.iterations = it
        if not accepted:
            if not np.isfinite(new_cost):
                s.status, s.message = "failed", "the iteration diverged (non-finite cost)"
            else:
                s.status, s.message = "converged", "no step decreases the cost any further"
            break
        decrease = cost - new_cost
        state, cost = trial, new_cost
        s.cost_trace.append(cost)
        if opt.callback is not None:
            opt.callback(it, cost, lam)
        if opt.damping == "lm":
            lam = 0.0 if lam <= opt.restart_lambda * 1e-2 else lam / 10.0
        scale = _parameter_scale(problem, state)
        small_step = np.max(np.abs(dx) / scale, initial=0.0) < opt.tolerance ** 0.5
        if decrease <= opt.tolerance * max(cost, 1e-300) or small_step:
            s.status, s.message = "converged", "relative change of the cost below tolerance"
            break
    else:
        s.message = f"no convergence in {opt.max_iterations} iterations"
    problem.state = state
    s.final_cost = cost
    s.sigma0 = float(np.sqrt(2 * cost / s.redundancy)) if s.redundancy > 0 else float("nan")
    s.timings["solve"] = time.perf_counter() - t0
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


def _parameter_scale(problem, state):
    """A per-column scale for the step test: 1 for angles, the size of the
    network for coordinates, the parameter itself (or 1) for interior ones."""
    lay = problem.layout
    scale = np.ones(lay.n_columns)
    size = float(np.nanmax(np.abs(state.points), initial=1.0)) or 1.0
    scale[lay.point_cols] = size
    scale[lay.station_cols[:, :3]] = size
    for k, cols in enumerate(lay.camera_cols):
        scale[cols] = np.maximum(np.abs(state.io[k]), 1e-3)
    return scale
