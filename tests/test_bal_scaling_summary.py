"""The per-iteration summary of benchmarks/bal_scaling.py (issue 23, item
5): the spans between the solver's iteration callbacks, the steady-state
CPU per iteration and the one-off setup, and the fitted exponent. Pure
arithmetic on given numbers; no timing."""

import math

import numpy as np
import pytest

from benchmark_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bal_scaling")


def test_spans_between_callbacks_with_a_rejected_step(bench):
    # accepted iterations 1, 2 and 4 (iteration 3 rejected): cumulative user, system
    spans = bench.iteration_spans([(1, 2.0, 1.5), (2, 3.0, 1.625), (4, 5.5, 1.75)])
    assert spans == [(1, 1, 2.0, 1.5), (2, 2, 1.0, 0.125), (3, 4, 2.5, 0.125)]


def test_steady_mean_and_setup(bench):
    # iteration 1 costs 3.5 (setup 2.5 + steady 1), then 1.0, 1.5, 0.5 per iteration
    steady, setup = bench.steady_and_setup([1, 2, 3, 4], [3.5, 4.5, 6.0, 6.5])
    assert steady == pytest.approx(1.0)
    assert setup == pytest.approx(2.5)
    assert setup + 4 * steady == pytest.approx(6.5)          # the whole of the 4 iterations
    # a rejected step between the callbacks counts as an iteration of the steady mean
    steady, setup = bench.steady_and_setup([1, 3], [3.5, 5.5])
    assert (steady, setup) == (pytest.approx(1.0), pytest.approx(2.5))
    # the first callback after a rejected step: setup is beyond two steady iterations
    assert bench.steady_and_setup([2, 4], [5.0, 7.0]) == (pytest.approx(1.0), pytest.approx(3.0))


def test_steady_needs_two_callbacks(bench):
    assert all(math.isnan(v) for v in bench.steady_and_setup([1], [3.0]))
    assert all(math.isnan(v) for v in bench.steady_and_setup([], []))


def test_fit_exponent_recovers_a_power_law(bench):
    obs = np.array([3e5, 1e6, 3e6, 1e7])
    assert bench.fit_exponent(obs, 2e-7 * obs ** 1.1) == pytest.approx(1.1)
    assert bench.fit_exponent(obs, 5e-8 * obs) == pytest.approx(1.0)
    assert math.isnan(bench.fit_exponent([1e6], [1.0]))
