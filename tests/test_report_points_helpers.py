"""Small helpers of photogram/report/pages_points.py."""

import math
import warnings

import numpy as np

from photogram.report.pages_points import _largest


def test_largest_ignores_nan_and_gives_nan_without_values():
    assert _largest([0.002, np.nan, 0.005]) == 0.005
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # no "All-NaN slice" warning
        assert math.isnan(_largest([np.nan, np.nan, np.nan]))
        assert math.isnan(_largest([]))
