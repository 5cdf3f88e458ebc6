"""DCT basis, windows and blending weights."""

import numpy as np
import pytest
from scipy.fft import idct

from photogram.errors import InputError
from photogram.mocap.reconstruction.dct import blend_weights, dct_basis, plan_windows


def test_basis_is_the_orthonormal_inverse_dct():
    B = dct_basis(50, 25)
    assert np.allclose(B.T @ B, np.eye(25))
    a = np.random.default_rng(0).normal(size=25)
    full = np.zeros(50)
    full[:25] = a
    assert np.allclose(B @ a, idct(full, norm="ortho"))
    assert dct_basis(10, 25).shape == (10, 10)


def test_windows_cover_every_frame_and_respect_breaks():
    ws = plan_windows(279, 50, 10, 25, breaks=[120])
    covered = np.zeros(279, int)
    for w in ws:
        covered[w.start:w.stop] += 1
        assert not (w.start < 120 < w.stop)
    assert covered.min() >= 1
    assert ws[0].start == 0 and ws[-1].stop == 279
    short = plan_windows(30, 50, 10, 25)
    assert len(short) == 1 and short[0].length == 30 and short[0].n_coefficients == 25


@pytest.mark.parametrize("overlap", [10, 25])
def test_blend_weights_add_up_to_one_in_the_overlaps(overlap):
    w = blend_weights(50, overlap)
    assert np.allclose(w[-overlap:] + w[:overlap], 1.0)
    assert w.min() > 0


def test_bad_windows_are_input_errors():
    with pytest.raises(InputError):
        plan_windows(100, 50, 50)
    with pytest.raises(InputError):
        plan_windows(0)
