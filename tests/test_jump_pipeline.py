"""The intersect step on the simulated jump (known truth)."""

import numpy as np
import pytest

from photogram.jump.pipeline import intersect_jump
from photogram.simulation.jump import jump_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def exact():
    project, truth = jump_project(noise=False)
    return intersect_jump(project), truth


@pytest.fixture(scope="module")
def noisy():
    project, truth = jump_project(noise=True)
    return intersect_jump(project), truth


def test_noise_free_points_lines_and_stick_model_are_exact(exact):
    r, t = exact
    scale = np.abs(t["P"]).max()
    assert np.abs(r.P - t["P"]).max() < 1e-8 * scale
    d = np.stack([t["d1"], t["d2"]], axis=1)
    got = np.stack([r.model.d1, r.model.d2], axis=1)
    assert np.abs(got - d).max() < 1e-8
    m = r.model
    np.testing.assert_allclose(m["alpha"], t["legs"], atol=1e-8)
    np.testing.assert_allclose(m["beta"], t["trunk"], atol=1e-8)
    np.testing.assert_allclose(m["delta_phi"], t["v_angle"], atol=1e-8)
    np.testing.assert_allclose(m["gamma"], np.pi - (t["trunk"] - t["legs"]), atol=1e-8)
    np.testing.assert_allclose(m["Z0"], t["O"][:, 2], atol=1e-8 * scale)
    axis = t["d1"] + t["d2"]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    np.testing.assert_allclose(m["phi"], np.arcsin(-axis[:, 2]), atol=1e-8)
    np.testing.assert_allclose(m["heading"], np.arctan2(axis[:, 1], axis[:, 0]), atol=1e-8)
    v_true = np.linalg.norm(np.gradient(t["O"], t["times"], axis=0), axis=1)
    inner = slice(1, -1)             # central differences agree exactly inside
    np.testing.assert_allclose(m["v"][inner], v_true[inner], rtol=1e-8)


def test_point_errors_agree_with_propagated_sigmas(noisy):
    r, t = noisy
    e = (r.P - t["P"]).reshape(len(r.P), 12)
    chi2 = sum(float(e[k] @ np.linalg.solve(r.cov_P[k], e[k])) for k in range(len(e)))
    dof = e.size
    # 99 % band of chi-square with 288 degrees of freedom
    assert dof - 2.58 * np.sqrt(2 * dof) < chi2 < dof + 2.58 * np.sqrt(2 * dof)


def test_stick_parameter_errors_agree_with_their_sigmas(noisy):
    r, t = noisy
    m = r.model
    z = []
    for name, true in (("alpha", t["legs"]), ("beta", t["trunk"]), ("delta_phi", t["v_angle"]),
                       ("gamma", np.pi - (t["trunk"] - t["legs"]))):
        z.append((m[name] - true) / m.sigma[name])
    z = np.concatenate(z)
    assert 0.5 < np.mean(z ** 2) < 1.6
    assert np.all(np.abs(z) < 4.5)


def test_a_swapped_ski_is_detected_and_fixed():
    project, truth = jump_project(noise=True)
    il = project.image_lines
    s2 = project.stations.names.index("S2")
    rows = (il.station == s2) & np.isin(il.line, ["L1@005", "L2@005"])
    il.line[rows] = np.where(il.line[rows] == "L1@005", "L2@005", "L1@005")
    r = intersect_jump(project)
    assert r.ski_checks["005"].status == "swapped"
    assert r.ski_checks["005"].swapped == ["S2"]
    assert any("S2" in w for w in r.summary["warnings"])
    project.intersect.swap_skis = True
    fixed = intersect_jump(project)
    d_true = truth["d1"][4]
    assert np.degrees(np.arccos(abs(fixed.model.d1[4] @ d_true))) < 1.0


def test_a_ski_seen_in_one_image_is_a_clear_gap():
    """Since issue 19 (a ski flagged by photogram track in all views but
    one): the exposure goes on without that ski, a warning names it and the
    values that need it are empty (was a GeometryError stopping the run)."""
    project, _ = jump_project(noise=True)
    il = project.image_lines
    keep = ~((il.line == "L1@007") & (il.station != 0))
    for name in ("station", "line", "xy", "sigma", "record"):
        setattr(il, name, getattr(il, name)[keep])
    r = intersect_jump(project)
    assert any("L1@007 is measured in 1 image(s)" in w for w in r.summary["warnings"])
    assert ("007", "L1") not in r.lines and ("007", "L2") in r.lines
    e = list(r.exposures).index("007")
    assert np.isnan(r.model.d1[e]).all() and np.isfinite(r.model.d2[e]).all()


def test_the_lines_sigma_column_weights_the_ski_lines():
    """The ``sigma`` of each point along a ski (photogram track writes
    them): twice the sigma in every image is twice the sigma of the 3D ski
    direction (the line fits and the intersection are linear in the
    weights); points without a sigma take [adjustment] sigma_image."""
    project, _ = jump_project(noise=True)
    il = project.image_lines
    sig = project.adjustment.sigma_image
    sig = float(sig if np.isscalar(sig) else next(iter(sig.values())))
    il.sigma = np.full(len(il), np.nan)
    base = intersect_jump(project)
    il.sigma = np.full(len(il), 2 * sig)
    doubled = intersect_jump(project)
    for key, line in base.lines.items():
        c0, c1 = line.line.covariance_plucker[:3, :3], doubled.lines[key].line.covariance_plucker[:3, :3]
        np.testing.assert_allclose(c1, 4 * c0, rtol=1e-6, atol=1e-15)
        np.testing.assert_allclose(doubled.lines[key].line.direction, line.line.direction,
                                   atol=1e-9)
