"""photogram.jump.figure.chosen_exposures: which exposures a stick figure draws."""

import numpy as np

from photogram.jump.figure import chosen_exposures


def test_every_third_complete_exposure_or_every_third_complete_one():
    P = np.zeros((7, 4, 3))
    skis = np.zeros((7, 2, 2, 3))
    assert chosen_exposures(P, skis, 3) == [0, 3, 6]
    P[[0, 3, 6], 1] = np.nan                   # gaps at exactly those exposures
    assert chosen_exposures(P, skis, 3) == [1, 5]   # complete 1, 2, 4, 5 -> every 3rd
    skis[:] = np.nan
    assert chosen_exposures(P, skis, 3) == []
