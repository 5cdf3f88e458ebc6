"""Checks of a linearized BAL problem (its normal equations against the
generic path's, its gradient against finite differences), shared by the fused path's tests (numba, tests/test_bal_point_rows.py) and
its pure-numpy twin's (tests/test_bal_point_rows_numpy.py)."""

from __future__ import annotations

import numpy as np
import pytest


def check_gradient(problem, system, rng):
    """``system.g`` (``J^T r`` with ``r`` = observed - computed) equals the
    central-difference gradient of ``problem.cost`` at random station,
    rotation, interior and point columns: ``d(0.5 |r|^2)/dx = g``."""
    lay, state = problem.layout, problem.state
    n_stations = len(lay.station_cols)
    cols = np.concatenate([lay.station_cols[rng.integers(0, n_stations, 3)].ravel(),
                           np.concatenate([lay.camera_cols[k] for k in (0, 5)]),
                           lay.point_cols[rng.integers(0, lay.n_eliminated, 4)].ravel()])
    for c in cols:
        h = 1e-6 * max(1.0, abs(state.io[0][0])) if c < lay.n_camera_columns else 1e-6
        e = np.zeros(lay.n_columns)
        e[c] = h
        fd = (problem.cost(state.updated(lay, e)) - problem.cost(state.updated(lay, -e))) / (2 * h)
        assert system.g[c] == pytest.approx(fd, rel=1e-5, abs=1e-6 * np.abs(system.g).max())
    return cols


def assert_same_normal_equations(fused, ref, problem, state):
    """The fused path's :class:`~photogram.adjust.point_rows.PointSystem`
    ``fused`` equals the generic path's ``ref`` (``N_cc``, ``A``, ``g``,
    ``W^T``, the cost) to rounding, and ``problem.cost`` is its cost."""
    from photogram.adjust import point_rows
    assert isinstance(fused, point_rows.PointSystem)
    assert not isinstance(ref, point_rows.PointSystem)
    scale = np.abs(ref.Ncc.toarray()).max()
    np.testing.assert_allclose(fused.Ncc.toarray(), ref.Ncc.toarray(), rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(fused.A, ref.A, rtol=1e-12, atol=1e-12 * np.abs(ref.A).max())
    np.testing.assert_allclose(fused.g, ref.g, rtol=0, atol=1e-11 * np.abs(ref.g).max())
    np.testing.assert_allclose(fused.WT, ref.WT, rtol=0, atol=1e-12 * np.abs(ref.WT).max())
    assert fused.cost == pytest.approx(ref.cost, rel=1e-12)
    assert problem.cost(state) == pytest.approx(ref.cost, rel=1e-12)
