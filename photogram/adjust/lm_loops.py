"""The iterations of :func:`photogram.adjust.solver.solve`: Gauss-Newton
with Marquardt's damping after failures, step halving or none
(:func:`gauss_newton`), and Ceres' Levenberg-Marquardt trust region
(:func:`trust_region`). Both work on a
:class:`~photogram.adjust.solver.Problem` through its ``linearize``,
``solve_linear`` and ``cost`` and fill a
:class:`~photogram.adjust.solver.Summary`.
"""

from __future__ import annotations

import time

import numpy as np

from photogram.errors import GeometryError

__all__ = ["gauss_newton", "trust_region"]


def gauss_newton(problem, opt, s, state, cost):
    """Gauss-Newton with Marquardt's damping after failures ("lm"), step
    halving ("armijo") or nothing ("none"). The normal equations are
    assembled once per iterate; only the solve is repeated per lambda."""
    lam = opt.initial_lambda if opt.damping == "lm" else 0.0
    s.status = "max_iterations"
    system = None
    for it in range(1, opt.max_iterations + 1):
        accepted = False
        if system is None:
            system = problem.linearize(state)
        while True:
            dx, _ = problem.solve_linear(system, lam)
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
            s.unsuccessful_steps += 1
            if not np.isfinite(new_cost):
                s.status, s.message = "failed", "the iteration diverged (non-finite cost)"
            else:
                s.status, s.message = "converged", "no step decreases the cost any further"
            break
        s.successful_steps += 1
        decrease = cost - new_cost
        state, cost = trial, new_cost
        system = None
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
    return state, cost


def trust_region(problem, opt, s, state, cost):
    """Ceres' Levenberg-Marquardt trust region (levenberg_marquardt_strategy.cc,
    trust_region_minimizer.cc): solve ``(N + diag(N) / radius) dx = -g``;
    ``rho = (cost - new cost) / (model decrease)``; a step with
    ``rho > min_relative_decrease`` is taken and the radius grows by
    ``1 / max(1/3, 1 - (2 rho - 1)^3)``; otherwise the radius shrinks by a
    factor that doubles with every consecutive failure. A singular damped
    system counts as an invalid step (radius shrinks). Stops when
    ``|cost change| <= ftol cost`` (Ceres' function tolerance; a decrease is
    kept), ``|dx| <= ptol (|x| + ptol)``, ``max |g| <= gtol``, or the
    radius falls below ``min_radius``.
    """
    ftol = opt.function_tolerance
    if ftol is None:
        ftol = 1e-6 if opt.tolerance == type(opt).tolerance else opt.tolerance
    radius, factor = opt.initial_radius, 2.0
    invalid = 0
    s.status = "max_iterations"
    s.message = f"no convergence in {opt.max_iterations} iterations"
    t_sol = t_cost = 0.0
    t = time.perf_counter()
    system = problem.linearize(state)
    t_lin = time.perf_counter() - t
    for it in range(1, opt.max_iterations + 1):
        s.iterations = it
        if _max_abs(system.g, problem.layout.free) <= opt.gradient_tolerance:
            s.status, s.message = "converged", "gradient tolerance reached"
            s.iterations = it - 1
            break
        lam = 1.0 / radius
        error = None
        t = time.perf_counter()
        try:
            dx, _ = problem.solve_linear(system, lam)
            valid = True
        except GeometryError as exc:
            valid, error = False, exc
        t_sol += time.perf_counter() - t
        if valid:
            model = -(float(system.g @ dx) + 0.5 * system.quadratic(dx))
            t = time.perf_counter()
            trial = state.updated(problem.layout, dx)
            new_cost = problem.cost(trial)
            t_cost += time.perf_counter() - t
            valid = np.isfinite(new_cost) and model > 0
        if not valid:
            invalid += 1
            s.unsuccessful_steps += 1
            radius /= factor
            factor *= 2.0
            if invalid >= opt.max_invalid_steps or radius < opt.min_radius:
                if error is not None:
                    raise error
                s.status, s.message = "converged", "no valid step (trust region collapsed)"
                break
            continue
        invalid = 0
        change = cost - new_cost
        if np.linalg.norm(dx) <= opt.parameter_tolerance * (
                _state_norm(state) + opt.parameter_tolerance):
            s.status, s.message = "converged", "parameter tolerance reached"
            if change > 0:
                state, cost = trial, new_cost
                s.cost_trace.append(cost)
                s.successful_steps += 1
            break
        if abs(change) <= ftol * cost:
            s.status, s.message = "converged", (
                f"function tolerance reached: |cost change| / cost = {abs(change) / cost:.3g}")
            if change > 0:
                state, cost = trial, new_cost
                s.cost_trace.append(cost)
                s.successful_steps += 1
            break
        rho = change / model
        if rho > opt.min_relative_decrease:
            s.successful_steps += 1
            state, cost = trial, new_cost
            s.cost_trace.append(cost)
            radius = min(opt.max_radius, radius / max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3))
            factor = 2.0
            if opt.callback is not None:
                opt.callback(it, cost, lam)
            t = time.perf_counter()
            system = None          # the old system's buffers are free for the new one
            system = problem.linearize(state)
            t_lin += time.perf_counter() - t
        else:
            s.unsuccessful_steps += 1
            radius /= factor
            factor *= 2.0
            if radius < opt.min_radius:
                s.status, s.message = "converged", "trust region radius below its minimum"
                break
    s.timings.update({"linearize": t_lin, "linear_solve": t_sol, "cost": t_cost})
    return state, cost


def _max_abs(v, mask):
    """``max |v[mask]|`` (0 when empty) without copying ``v`` (at 10^6
    points a copy is fresh pages that the kernel must zero)."""
    hi = np.max(v, where=mask, initial=-np.inf)
    lo = np.min(v, where=mask, initial=np.inf)
    return max(float(hi), -float(lo), 0.0)


def _state_norm(state):
    """|x| of the parameter vector (points, centres, interior; rotations
    count as unit-norm 3-vectors), for Ceres' parameter tolerance."""
    total = float(np.sum(state.points ** 2) + np.sum(state.X0 ** 2)
                  + sum(float(np.sum(v ** 2)) for v in state.io)) + 3.0 * len(state.R)
    return float(np.sqrt(total))


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
