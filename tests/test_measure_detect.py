"""Target detection and subpixel centres on rendered images with known truth.

Truth: the projection of each circle's centre (with lens distortion); the
measured ellipse centres are corrected by the eccentricity of the projected
circle (computed from the true homography and the circle radius) before the
comparison. Two centre methods are compared (ellipse fit to subpixel edge
points, grey-value weighted centroid); the ellipse fit is the method kept.
Figures recorded in docs/measure.md.
"""

import numpy as np
import pytest

from photogram.measure.detect import detect_targets
from photogram.measure.eccentricity import (eccentricity, eccentricity_jacobian,
                                            ellipse_centres)
from photogram.measure.ellipse import (conic_axes, conic_centre, conic_from_matrix,
                                       conic_matrix, fit_ellipse, fit_ellipses)
from photogram.measure.render import grid_scene

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

GOOD = dict(size=(640, 480), f=720.0)
HARSH = dict(size=(640, 480), f=720.0, radius=0.014, blur=1.3, noise=5.0, jpeg=50,
             gradient=0.5, seed=7)


def _errors(scene, det, xy):
    d = np.linalg.norm(det.xy[:, None] - scene.truth[None], axis=2)
    j = d.argmin(axis=1)
    ok = d.min(axis=1) < 2.0
    ecc = eccentricity(scene.camera.homography(), scene.XY, scene.radius)
    raw = xy[ok] - scene.truth[j[ok]]
    return raw - ecc[j[ok]], raw, j[ok], ok


def _rms(e):
    return float(np.sqrt((e ** 2).sum(axis=1).mean()))


@pytest.fixture(scope="module")
def scenes():
    return {"good": grid_scene(**GOOD), "harsh": grid_scene(**HARSH),
            "bright": grid_scene(polarity="bright", **GOOD),
            "bright-harsh": grid_scene(polarity="bright", **HARSH)}


def test_ellipse_fit_recovers_an_exact_ellipse():
    rng = np.random.default_rng(0)
    t = rng.uniform(0, 2 * np.pi, 40)
    a, b, ang, c = 12.0, 7.0, 0.4, np.array([101.3, 57.8])
    p = np.column_stack([a * np.cos(t), b * np.sin(t)])
    R = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    xy = p @ R.T + c
    conic = fit_ellipse(xy)
    assert np.allclose(conic_centre(conic), c, atol=1e-8)
    A, B, th = conic_axes(conic)
    assert np.allclose([A, B], [a, b], atol=1e-8)
    assert np.isclose(np.mod(th - ang, np.pi), 0, atol=1e-8)
    # the vectorised fit gives the same conic (up to sign), also with unused points
    x = np.vstack([xy[:, 0], np.r_[xy[:30, 0], np.zeros(10)]])
    y = np.vstack([xy[:, 1], np.r_[xy[:30, 1], np.zeros(10)]])
    w = np.vstack([np.ones(40, bool), np.r_[np.ones(30, bool), np.zeros(10, bool)]])
    cs, ok = fit_ellipses(x, y, w)
    assert ok.all()
    for k in range(2):
        assert np.allclose(conic_centre(cs[k]), c, atol=1e-8)


def test_ellipse_centre_is_the_centre_of_the_imaged_conic():
    rng = np.random.default_rng(1)
    H = np.array([[800.0, 40, 300], [-30, 760, 250], [0.3, -0.2, 1.1]])
    XY = rng.uniform(-0.5, 0.5, (5, 2))
    r = 0.05
    got = ellipse_centres(H, XY, r)
    Hi = np.linalg.inv(H)
    for k, (X, Y) in enumerate(XY):
        C = np.array([[1, 0, -X], [0, 1, -Y], [-X, -Y, X * X + Y * Y - r * r]])
        Ci = Hi.T @ C @ Hi
        assert np.allclose(conic_centre(conic_from_matrix(Ci)), got[k], atol=1e-9)
    assert np.allclose(conic_matrix(conic_from_matrix(Ci)), Ci)


def test_eccentricity_jacobian_against_finite_differences():
    rng = np.random.default_rng(2)
    H = np.array([[800.0, 40, 300], [-30, 760, 250], [0.3, -0.2, 1.1]])
    XY = rng.uniform(-0.5, 0.5, (4, 2))
    J = eccentricity_jacobian(H, XY, 0.04)
    num = np.zeros_like(J)
    for k in range(9):
        h = 1e-6 * max(1.0, abs(H.flat[k]))
        Hp, Hm = H.copy(), H.copy()
        Hp.flat[k] += h
        Hm.flat[k] -= h
        num[:, :, k] = (eccentricity(Hp, XY, 0.04) - eccentricity(Hm, XY, 0.04)) / (2 * h)
    assert np.allclose(J, num, rtol=1e-5, atol=1e-9)
    assert np.abs(J[:, :, 6:]).max() > 1e-3       # depends on the vanishing line


@pytest.mark.parametrize("name", ["good", "bright", "harsh", "bright-harsh"])
def test_rendered_centres_and_two_methods(scenes, name):
    sc = scenes[name]
    polarity = "bright" if name.startswith("bright") else "dark"
    det = detect_targets(sc.image, polarity, min_diameter=4, max_diameter=60, centroid=True)
    e_fit, raw, j, ok = _errors(sc, det, det.xy)
    e_cen, _, _, _ = _errors(sc, det, det.xy_centroid)
    # every target found once, nothing else accepted
    assert ok.all() and len(set(j)) == len(sc.XY)
    big = sc.diameter_px[j] >= 10
    assert big.sum() >= 0.9 * len(j)
    rms_fit, rms_cen = _rms(e_fit[big]), _rms(e_cen[big])
    print(f"{name}: diameters {sc.diameter_px.min():.1f}-{sc.diameter_px.max():.1f} px, "
          f"ellipse fit {rms_fit:.4f} px, weighted centroid {rms_cen:.4f} px, "
          f"without eccentricity correction {_rms(raw[big]):.4f} px")
    assert rms_fit < rms_cen                      # the method kept is the better one
    if "harsh" in name:
        assert rms_fit <= 0.045                  # measured 0.032-0.034 (docs/measure.md)
    else:
        assert rms_fit <= 0.025                  # measured 0.014-0.017; issue goal 0.05
    # the eccentricity is a real effect here: up to a tenth of a pixel
    ecc = eccentricity(sc.camera.homography(), sc.XY, sc.radius)
    assert np.abs(ecc).max() > 0.05
    assert _rms(raw[big]) > 1.5 * rms_fit
    # the sigma of a centre is of the size of the error (not 10x off)
    assert 0.1 < np.median(det.sigma) / (rms_fit / np.sqrt(2)) < 3


HARSHER = dict(size=(640, 480), f=720.0, radius=0.012, blur=1.8, noise=8.0, jpeg=30,
               gradient=0.6)


def test_blurred_step_edges_against_mid_level_edges(scenes):
    """The alternative edge points (a blurred step fitted across each ray's
    profile, ``edge="erf"``) against the default mid-level crossing, on
    rendered truth: as good at good contrast, better on the noisiest level
    (blur 1.8 px, noise 8, JPEG 30; four seeds, dark and bright)."""
    det = detect_targets(scenes["good"].image, "dark", min_diameter=4, max_diameter=60,
                         edge="erf")
    e, _, j, ok = _errors(scenes["good"], det, det.xy)
    assert ok.all() and len(set(j)) == len(scenes["good"].XY)
    assert _rms(e) <= 0.025                      # measured 0.015 (mid level 0.014)
    for polarity in ("dark", "bright"):
        err = {"mid": [], "erf": []}
        for seed in (11, 12, 13, 14):
            sc = grid_scene(polarity=polarity, seed=seed, **HARSHER)
            for edge in err:
                det = detect_targets(sc.image, polarity, min_diameter=4, max_diameter=60,
                                     edge=edge)
                e, _, j, ok = _errors(sc, det, det.xy)
                assert len(set(j)) == len(sc.XY)
                err[edge].append(e[sc.diameter_px[j] >= 10])
        rms = {k: _rms(np.vstack(v)) for k, v in err.items()}
        print(f"harsher, {polarity}: mid level {rms['mid']:.4f} px, blurred step {rms['erf']:.4f} px")
        assert rms["erf"] < rms["mid"]
        assert rms["erf"] <= 0.075               # measured 0.054-0.064; goal 0.05 not met here
    with pytest.raises(ValueError):
        detect_targets(scenes["good"].image, "dark", edge="gradient")


def test_nearest_claim_wins_keeps_the_nearest_of_each_detection():
    """One-to-one numbering: of predictions claiming the same detection only
    the nearest keeps it; unclaimed stay -1."""
    from photogram.measure.label import nearest_claim_wins
    claims = np.array([3, 3, -1, 5, 3, 5, 7])
    dist = np.array([0.4, 0.1, 0.0, 0.9, 0.2, 0.3, 2.0])
    assert nearest_claim_wins(claims, dist).tolist() == [-1, 3, -1, -1, -1, 5, 7]
    assert nearest_claim_wins(np.array([], dtype=int), np.array([])).tolist() == []


def test_degrade_blur_noise_jpeg():
    """The camera's degradation: a flat image stays flat without noise, the
    noise has the asked sigma, blur keeps the mean, JPEG returns 8 bits."""
    from photogram.measure.render import degrade
    flat = np.full((64, 64), 100.0)
    assert (degrade(flat) == 100).all()
    noisy = degrade(flat, noise=5.0, seed=1).astype(float)
    assert abs(noisy.std() - 5.0) < 0.3 and abs(noisy.mean() - 100) < 0.3
    step = np.zeros((64, 64)); step[:, 32:] = 200.0
    blurred = degrade(step, blur=2.0).astype(float)
    assert abs(blurred.mean() - 100) < 1 and 0 < blurred[0, 31] < 200
    assert degrade(step, jpeg=50).dtype == np.uint8
