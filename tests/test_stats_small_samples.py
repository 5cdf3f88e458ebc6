"""median_of_few is np.median bit for bit (photogram/stats/small_samples.py)."""

import numpy as np

from photogram.stats.small_samples import median_of_few


def test_median_of_few_is_numpys_median_bit_for_bit():
    rng = np.random.default_rng(0)
    for n in range(1, 12):
        for _ in range(200):
            v = (rng.standard_normal(n) * 10.0 ** rng.integers(-3, 4)).tolist()
            got, want = median_of_few(v), np.median(v)
            assert isinstance(got, np.float64) and got.tobytes() == want.tobytes()


def test_median_of_few_leaves_empty_and_nan_to_numpy():
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert np.isnan(median_of_few([]))
    assert np.isnan(median_of_few([1.0, float("nan"), 2.0]))
