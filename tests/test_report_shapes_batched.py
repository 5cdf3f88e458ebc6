"""The report's batched geometry (issue 23, item 1: report speed) gives the
same numbers as the per-item code it replaced."""

import numpy as np
import pytest

from photogram.report.shapes import (_monotone_chain, convex_hull, ellipse, ellipses,
                                     largest_ray_angles)


@pytest.mark.parametrize("kind", ["normal", "uniform", "grid", "line", "few"])
def test_convex_hull_with_prefilter_equals_the_plain_chain(kind):
    rng = np.random.default_rng(7)
    for _ in range(20):
        n = int(rng.integers(3, 3000)) if kind != "few" else int(rng.integers(1, 40))
        xy = {"normal": lambda: rng.normal(size=(n, 2)),
              "uniform": lambda: rng.uniform(0, 4000, (n, 2)),
              "grid": lambda: np.round(rng.uniform(0, 15, (n, 2))),
              "line": lambda: np.c_[np.linspace(0, 1, n), 3 * np.linspace(0, 1, n)],
              "few": lambda: rng.normal(size=(n, 2))}[kind]()
        ref = np.unique(xy, axis=0)
        ref = ref if len(ref) < 3 else _monotone_chain(ref)
        assert np.array_equal(convex_hull(xy), ref)


def test_hull_of_a_square_with_interior_points():
    rng = np.random.default_rng(1)
    xy = np.vstack([rng.uniform(0.1, 0.9, (500, 2)), [[0, 0], [1, 0], [1, 1], [0, 1]]])
    assert np.array_equal(convex_hull(xy), [[0, 0], [1, 0], [1, 1], [0, 1]])


def test_batched_ellipses_equal_one_by_one():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(200, 2, 2))
    C = A @ np.swapaxes(A, 1, 2)
    C[0], C[1] = np.diag([4.0, 1.0]), np.zeros((2, 2))
    np.testing.assert_allclose(ellipses(C), [ellipse(c) for c in C], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ellipses(C[:1])[0], [2.0, 1.0, 0.0], atol=1e-12)


def test_largest_ray_angles_against_a_loop_and_a_known_angle():
    rng = np.random.default_rng(3)
    n_points = 300
    point = rng.integers(0, n_points, 2000)
    rays = rng.normal(size=(2000, 3))
    got = largest_ray_angles(rays, point, n_points)
    for p in range(n_points):
        u = rays[point == p]
        if len(u) < 2:
            assert np.isnan(got[p])
            continue
        u = u / np.linalg.norm(u, axis=1, keepdims=True)
        ref = np.degrees(np.arccos(np.clip(u @ u.T, -1, 1).min()))
        assert got[p] == pytest.approx(ref, abs=1e-9)
    # two rays at right angles and one between them: 90 deg
    right = largest_ray_angles(np.array([[1.0, 0, 0], [0, 2.0, 0], [1, 1, 0]]),
                               np.array([0, 0, 0]), 1)
    assert right[0] == pytest.approx(90.0)
    assert np.isnan(largest_ray_angles(np.array([[np.nan, 0, 0], [1.0, 0, 0]]),
                                       np.array([0, 0]), 1)[0])
