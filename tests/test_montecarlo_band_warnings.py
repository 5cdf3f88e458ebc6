"""The Monte-Carlo summary warns when sigma_mc/sigma_prop leaves its 95 %
band more often than chance allows (photogram.montecarlo.report.band_warnings)."""

import numpy as np
import pandas as pd
import pytest
from scipy.stats import binom

from photogram.montecarlo.report import band_warnings, ratio_band


def _frame(ratios, group="station"):
    return pd.DataFrame({"quantity": [f"q{i}" for i in range(len(ratios))],
                         "group": group, "ratio": ratios})


def _sample_ratios(rng, n_quantities, runs, scale):
    """sigma_mc / sigma_prop of ``n_quantities`` normal quantities whose true
    sigma is ``scale`` times the propagated one (1: the propagation is right)."""
    x = rng.normal(0.0, scale, size=(runs, n_quantities))
    return x.std(0, ddof=1)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_right_sigmas_give_no_warning(seed):
    runs = 200
    r = _sample_ratios(np.random.default_rng(seed), 60, runs, 1.0)
    assert band_warnings(_frame(r), ratio_band(runs)) == []


@pytest.mark.parametrize("scale, side", [(1.3, "too small"), (0.75, "too large")])
def test_wrong_sigmas_are_named_with_their_side(scale, side):
    runs = 200
    r = _sample_ratios(np.random.default_rng(7), 60, runs, scale)
    lo, hi = ratio_band(runs)
    out = band_warnings(_frame(r), (lo, hi))
    assert len(out) == 1
    k = int(((r < lo) | (r > hi)).sum())
    assert f"{k} of 60 station quantities" in out[0]
    assert side in out[0]
    worst = int(np.argmax(np.maximum(np.log(lo / r), np.log(r / hi))))
    assert f"farthest: q{worst} " in out[0]


def test_the_threshold_is_the_binomial_tail():
    lo, hi = 0.9, 1.1
    n = 40
    # the smallest k whose tail probability under Binomial(n, 0.05) is < 0.01
    k_min = next(k for k in range(1, n + 1) if binom.sf(k - 1, n, 0.05) < 0.01)
    inside = np.ones(n)
    below = inside.copy()
    below[:k_min - 1] = 1.5
    assert band_warnings(_frame(below), (lo, hi)) == []
    at = inside.copy()
    at[:k_min] = 1.5
    assert len(band_warnings(_frame(at), (lo, hi))) == 1


def test_groups_are_judged_apart_and_nan_is_ignored():
    lo, hi = 0.9, 1.1
    good = _frame(np.r_[np.ones(30), np.nan], group="interior")
    bad = _frame(np.r_[np.full(10, 2.0), np.ones(20)], group="jumper")
    out = band_warnings(pd.concat([good, bad]), (lo, hi))
    assert len(out) == 1 and "jumper" in out[0] and "interior" not in out[0]
    assert band_warnings(bad, (float("nan"), float("nan"))) == []
