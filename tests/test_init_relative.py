"""Relative orientation of a stereo pair: closed-form start, chirality,
least-squares refinement, precision, ambiguity and degenerate pairs."""

import warnings

import numpy as np
import pytest

from photogram.errors import GeometryError
from photogram.geometry import matrix_to_rodrigues
from photogram.init.intersection import project_ideal
from photogram.init.relative import (decompose_essential, eight_point, relative_orientation,
                                     rotation_only_fit)
from photogram.simulation.network import look_at as simulated_look_at

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

C = 1420.0
TARGET = np.array([0.25, 0.25, 0.15])


def look_at(X0, target=TARGET, up=(0.0, 0.0, 1.0)):
    """World-to-camera rotation of one camera at X0 looking at target."""
    return simulated_look_at(X0, target, up)[0]


STATIONS = np.array([[-1.5, -2.5, 1.5], [0.3, -3.2, 2.0], [2.2, -1.8, 1.2]])


def pair(i, j, P, c1=C, c2=C, X0=STATIONS):
    """Images of P in stations i and j, and the truth in i's model frame with
    the baseline scaled to |b_x| = 1."""
    R1, R2 = look_at(X0[i]), look_at(X0[j])
    xy1 = project_ideal(P, R1, X0[i], c1)
    xy2 = project_ideal(P, R2, X0[j], c2)
    R2m = R2 @ R1.T
    b = R1 @ (X0[j] - X0[i])
    s = 1.0 / abs(b[0]) if b[0] != 0 else 1.0
    Pm = (P - X0[i]) @ R1.T * s
    return xy1, xy2, R2m, b * s, Pm


def frame_points(seed, n):
    return np.random.default_rng(seed).uniform([0, 0, 0], [0.5, 0.5, 0.3], (n, 3))


def quiet(*a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return relative_orientation(*a, **k)


@pytest.mark.parametrize("i,j", [(0, 1), (1, 2), (2, 0)])
@pytest.mark.parametrize("n", [30, 8, 6])
def test_noise_free_truth(i, j, n):
    P = frame_points(11 + n, n)
    xy1, xy2, R2, b, Pm = pair(i, j, P)
    res = relative_orientation(xy1, xy2, C, C)
    assert res.fixed_component == 0
    assert abs(res.X0_2[0]) == 1.0
    assert np.abs(res.R2 - R2).max() < 1e-8
    assert np.abs(res.X0_2 - b).max() < 1e-8 * np.abs(b).max()
    assert np.abs(res.X - Pm).max() < 1e-8 * np.abs(Pm).max()
    assert res.converged and not res.ambiguous
    assert res.sigma0 < 1e-8
    assert np.abs(res.residuals1).max() < 1e-8 and np.abs(res.residuals2).max() < 1e-8
    assert np.all(np.degrees(res.max_angle) > 20)
    assert res.angles2.shape == (3,)


def test_different_principal_distances_and_principal_points():
    P = frame_points(2, 20)
    xy1, xy2, R2, b, Pm = pair(0, 2, P, c1=1420.0, c2=2100.0)
    pp1, pp2 = np.array([320.0, 240.0]), np.array([300.5, 250.0])
    res = relative_orientation(xy1 + pp1, xy2 + pp2, 1420.0, 2100.0, x0y0_1=pp1, x0y0_2=pp2)
    assert np.abs(res.R2 - R2).max() < 1e-8
    assert np.abs(res.X - Pm).max() < 1e-8 * np.abs(Pm).max()


def test_planar_scene():
    """All points on a plane: the 8-point algorithm is critical, the 5-point
    solution is not."""
    rng = np.random.default_rng(5)
    P = np.c_[rng.uniform(0, 0.5, (25, 2)), np.zeros(25)]
    X0 = np.array([[-1.0, -2.5, 1.5], [1.0, -2.0, 2.0]])
    xy1, xy2, R2, b, Pm = pair(0, 1, P, X0=X0)
    _, cond = eight_point(xy1 / C, xy2 / C)
    assert cond < 3                              # critical for the linear algorithm
    res = quiet(xy1, xy2, C, C)
    cands = [(res.R2, res.X0_2)] + [(R, bb) for R, bb, _ in res.alternatives]
    assert min(max(np.abs(R - R2).max(), np.abs(bb - b).max()) for R, bb in cands) < 1e-7


def test_vertical_baseline_holds_the_largest_component():
    P = frame_points(4, 20)
    X0 = np.array([[0.0, -3.0, 0.2], [0.0, -3.0, 2.0]])
    xy1, xy2, _, _, _ = pair(0, 1, P, X0=X0)
    res = relative_orientation(xy1, xy2, C, C)
    b = look_at(X0[0]) @ (X0[1] - X0[0])
    k = int(np.argmax(np.abs(b)))
    assert res.fixed_component == k == 1
    assert np.abs(res.X0_2 - b / abs(b[k])).max() < 1e-8
    assert any("held at" in note for note in res.notes)


def test_five_points_warns_and_contains_truth():
    P = frame_points(21, 5)
    xy1, xy2, R2, b, Pm = pair(0, 1, P)
    with pytest.warns(UserWarning, match="ambiguous"):
        res = relative_orientation(xy1, xy2, C, C)
    assert res.ambiguous
    assert np.isnan(res.sigma0)                  # no redundancy
    cands = [(res.R2, res.X0_2)] + [(R, bb) for R, bb, _ in res.alternatives]
    assert min(max(np.abs(R - R2).max(), np.abs(bb - b).max()) for R, bb in cands) < 1e-7
    # no warning when asked not to
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        relative_orientation(xy1, xy2, C, C, warn=False)


def test_noise_within_claimed_accuracy():
    """0.3 px noise: orientation and point errors agree with the claimed
    covariance (aggregated over 25 pairs)."""
    zo, zp = [], []
    for seed in range(25):
        rng = np.random.default_rng(100 + seed)
        P = frame_points(seed, 30)
        xy1, xy2, R2, b, Pm = pair(seed % 3, (seed + 1) % 3, P)
        xy1 = xy1 + rng.normal(0, 0.3, xy1.shape)
        xy2 = xy2 + rng.normal(0, 0.3, xy2.shape)
        res = relative_orientation(xy1, xy2, C, C, sigma_image=0.3)
        assert res.fixed_component == 0 and res.converged
        delta = matrix_to_rodrigues(res.R2 @ R2.T)       # R2_est = small_rotation(δ) R2
        err = np.r_[delta, (res.X0_2 - b)[1:]]
        zo.append(err / np.sqrt(np.diag(res.covariance)))
        zp.append(((res.X - Pm) / res.sigma_X).ravel())
        assert 0.15 < res.sigma0 < 0.45            # chi-square with 25 dof
    zo, zp = np.concatenate(zo), np.concatenate(zp)
    assert np.all(np.abs(zo) < 4)
    assert 0.7 < np.sqrt(np.mean(zo ** 2)) < 1.3
    assert np.mean(np.abs(zp) < 4) > 0.995
    assert 0.7 < np.sqrt(np.mean(zp ** 2)) < 1.3


def test_decompose_essential_contains_truth():
    rng = np.random.default_rng(1)
    from photogram.geometry import rodrigues_to_matrix
    R = rodrigues_to_matrix(rng.normal(size=3) * 0.3)
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    sols = decompose_essential(-3.0 * tx @ R)
    assert any(np.allclose(Rc, R, atol=1e-12) and np.allclose(tc, t, atol=1e-12)
               for Rc, tc in sols)


# ------------------------------------------------------------- degenerate --

def test_too_few_points():
    P = frame_points(3, 4)
    xy1, xy2, *_ = pair(0, 1, P)
    with pytest.raises(GeometryError, match="at least 5 homologous points, got 4"):
        relative_orientation(xy1, xy2, C, C)


def test_zero_baseline_noise_free():
    P = frame_points(6, 30)
    X0 = np.array([0.0, -3.0, 1.0])
    xy1 = project_ideal(P, look_at(X0), X0, C)
    xy2 = project_ideal(P, look_at(X0, TARGET + [0.1, -0.05, 0.05]), X0, C)
    R, rms = rotation_only_fit(xy1, xy2, C, C)
    assert rms < 1e-9
    with pytest.raises(GeometryError, match="zero baseline") as e:
        relative_orientation(xy1, xy2, C, C)
    assert "wider baseline" in str(e.value)


@pytest.mark.parametrize("sigma", [None, 0.3])
def test_zero_baseline_with_noise(sigma):
    rng = np.random.default_rng(7)
    P = frame_points(7, 40)
    X0 = np.array([0.0, -3.0, 1.0])
    xy1 = project_ideal(P, look_at(X0), X0, C) + rng.normal(0, 0.3, (40, 2))
    xy2 = project_ideal(P, look_at(X0, TARGET + [0.1, -0.05, 0.05]), X0, C) \
        + rng.normal(0, 0.3, (40, 2))
    with pytest.raises(GeometryError, match="zero baseline"):
        quiet(xy1, xy2, C, C, sigma_image=sigma)


def test_small_real_baseline_is_accepted():
    """A 15 cm baseline at 3 m still gives several pixels of parallax."""
    rng = np.random.default_rng(8)
    P = frame_points(8, 40)
    X0 = np.array([[0.0, -3.0, 1.0], [0.15, -3.0, 1.0]])
    xy1, xy2, R2, b, Pm = pair(0, 1, P, X0=X0)
    xy1 = xy1 + rng.normal(0, 0.3, xy1.shape)
    xy2 = xy2 + rng.normal(0, 0.3, xy2.shape)
    res = relative_orientation(xy1, xy2, C, C, sigma_image=0.3)
    assert res.rotation_only_rms > 3 * 0.3
    assert not res.ambiguous and res.converged
    # a weak pair, but its own precision estimate is honest
    delta = matrix_to_rodrigues(res.R2 @ R2.T)
    err = np.r_[delta, (res.X0_2 - b)[1:]]
    assert np.all(np.abs(err) < 4 * np.sqrt(np.diag(res.covariance)))


def test_malformed_input():
    with pytest.raises(GeometryError, match=r"\(n, 2\)"):
        relative_orientation(np.zeros((6, 2)), np.zeros((7, 2)), C, C)
    with pytest.raises(GeometryError, match="NaN"):
        relative_orientation(np.full((6, 2), np.nan), np.zeros((6, 2)), C, C)
    with pytest.raises(GeometryError, match="positive"):
        relative_orientation(np.ones((6, 2)), np.zeros((6, 2)), 0.0, C)
