"""3D lines from image lines (appendix C.2 steps B and one-step, C.3 initial
values) on the simulated field network (three cameras 55-80 m from the
flight zone, units dm)."""

import numpy as np
import pytest
from scipy.special import chdtri

from photogram.errors import GeometryError, InputError
from photogram.lines import (
    SpaceLine, ViewCamera, closest_point, distance_point_line, fit_view_line,
    initial_line_homogeneous, intersect_line, intersect_line_from_points,
    intersect_line_one_step, line_from_plucker, line_from_points, line_planes, plane_angles,
    point_on_line, project_line)
from photogram.simulation.ski_lines import field_cameras, measure_segment
from photogram.simulation.network import look_at

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

CAMS = field_cameras()
CENTRE = np.array([470.0, 7.0, -250.0])          # in the flight zone (dm)


def _directions():
    axes = list(np.eye(3))
    diag = [np.array(s, float) / np.sqrt(3) for s in
            ((1, 1, 1), (1, -1, 1), (1, 1, -1), (-1, 1, 1))]
    rng = np.random.default_rng(2)
    rand = list(rng.normal(size=(12, 3)))
    ski = [np.array([0.94, 0.17, -0.34])]           # along the flight, nearly || S1-S2
    return [d / np.linalg.norm(d) for d in axes + diag + rand + ski]


DIRECTIONS = _directions()


def _errors(est: SpaceLine, truth: SpaceLine):
    """Angle between the directions and the distance of the truth's point
    from the estimate (and back)."""
    ang = np.linalg.norm(np.cross(est.direction, truth.direction))
    pos = max(distance_point_line(est, truth.point), distance_point_line(truth, est.point))
    return ang, pos


def _exact_points(truth, cams=CAMS, n=15, half=12.5):
    ends = np.array([point_on_line(truth, -half), point_on_line(truth, half)])
    return {s: measure_segment(ends, cam, n) for s, cam in cams.items()}


# ---------------------------------------------------------------------------
# representation


def test_plucker_and_point_conversions():
    X1, X2 = np.array([1.0, 2.0, 3.0]), np.array([4.0, -2.0, 3.5])
    L = line_from_points(X1, X2)
    d, m = L.plucker[:3], L.plucker[3:]
    assert abs(d @ m) < 1e-12 and np.linalg.norm(d) == pytest.approx(1.0)
    np.testing.assert_allclose(point_on_line(L, np.linalg.norm(X2 - X1)), X2, atol=1e-12)
    L2 = line_from_plucker(3.0 * d, 3.0 * m)           # scale-invariant
    assert distance_point_line(L2, X1) < 1e-12 and distance_point_line(L2, X2) < 1e-12
    assert abs(L2.point @ L2.direction) < 1e-12         # the point nearest the origin
    P = np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 5.0]])
    C = closest_point(L, P)
    assert np.allclose((P - C) @ L.direction, 0.0, atol=1e-12)
    np.testing.assert_allclose(distance_point_line(L, P), np.linalg.norm(P - C, axis=1))
    with pytest.raises(GeometryError):
        line_from_points(X1, X1)


@pytest.mark.parametrize("D", DIRECTIONS[:7])
def test_local_update_and_error_are_inverse(D):
    L = SpaceLine(CENTRE, D)
    u, v = L.basis
    assert abs(u @ D) < 1e-15 and abs(v @ D) < 1e-15 and np.cross(u, v) @ D > 0.999999
    delta = np.array([0.01, -0.02, 0.3, -0.1])
    np.testing.assert_allclose(L.local_error(L.update(delta)), delta, atol=1e-13)
    # recentring transports the covariance consistently
    L.covariance = np.diag([1e-4, 4e-4, 0.01, 0.04])
    L2 = L.recentred(CENTRE + 7.0 * D)
    e1 = L.local_error(L.update(1e-6 * delta))
    e2 = L2.local_error(L.update(1e-6 * delta))
    T = np.eye(4)
    T[2, 0] = T[3, 1] = 7.0
    np.testing.assert_allclose(e2, T @ e1, rtol=1e-6, atol=1e-16)
    assert L.covariance_plucker.shape == (6, 6)
    assert np.linalg.matrix_rank(L.covariance_plucker, tol=1e-14) == 4


@pytest.mark.parametrize("D", DIRECTIONS[:7])
def test_project_line_and_its_jacobian(D):
    L = SpaceLine(CENTRE, D)
    for cam in CAMS.values():
        l, J = project_line(L, cam, jacobian=True)
        xy = cam.project_ideal(point_on_line(L, np.array([-10.0, 0.0, 10.0])))
        assert np.abs(xy @ l[:2] + l[2]).max() < 1e-9
        assert (xy[2] - xy[0]) @ np.array([l[1], -l[0]]) > 0   # oriented like D
        h = 1e-5
        num = np.column_stack([(project_line(L.update(h * e), cam)
                                - project_line(L.update(-h * e), cam)) / (2 * h)
                               for e in np.eye(4)])
        np.testing.assert_allclose(J, num, rtol=1e-6, atol=1e-7)


# ---------------------------------------------------------------------------
# noise-free: every estimator is exact


@pytest.mark.parametrize("D", DIRECTIONS)
def test_noise_free_recovery_in_every_direction(D):
    truth = SpaceLine(CENTRE, D)
    pts = _exact_points(truth)
    lines = {s: fit_view_line(xy, CAMS[s], 0.33, label="L1") for s, xy in pts.items()}
    for method in ("svd", "pair"):
        ang, pos = _errors(initial_line_homogeneous(lines, CAMS, method=method), truth)
        assert ang < 1e-8 and pos < 1e-8, (method, ang, pos)
    B = intersect_line(lines, CAMS)
    O = intersect_line_one_step(pts, CAMS, 0.33, label="L1", initial=B)
    for r in (B, O):
        ang, pos = _errors(r.line, truth)
        assert ang < 1e-8 and pos < 1e-8, (r.method, ang, pos)
        assert r.converged and r.chi2 < 1e-12
        assert r.line.covariance.shape == (4, 4)
        assert np.all(np.linalg.eigvalsh(r.line.covariance) > 0)
    assert B.label == "L1" and B.stations == ["S1", "S2", "S3"] and B.redundancy == 2
    assert O.redundancy == 3 * 15 - 4
    # the measured segment: 25 dm between the end points
    assert B.length == pytest.approx(25.0, abs=1e-6)
    assert max(abs(r).max() for r in B.residuals.values()) < 1e-8


def test_two_views_and_other_models():
    """Two views suffice; the OpenCV model and a ring of cameras work too."""
    truth = SpaceLine([0.1, -0.2, 0.3], [0.3, 0.8, -0.5])
    X0 = np.array([[6.0, 0.0, 2.0], [0.0, 6.0, 2.5], [-6.0, 1.0, 1.5]])
    R = look_at(X0, np.zeros(3))
    io = np.array([1400.0, 1410.0, 320.0, 240.0, -0.12, 0.03, 5e-4, -3e-4, 0.0])
    cams = {f"C{i}": ViewCamera(R[i], X0[i], io, "opencv", f"C{i}") for i in range(3)}
    pts = _exact_points(truth, cams, half=0.5)
    for use in (["C0", "C1"], ["C0", "C1", "C2"]):
        sub = {s: pts[s] for s in use}
        for method in ("two-step", "one-step"):
            r = intersect_line_from_points(sub, cams, 0.3, label="rod", method=method)
            ang, pos = _errors(r.line, truth)
            assert ang < 1e-8 and pos < 1e-8


def test_planes_contain_the_line_and_the_centres():
    truth = SpaceLine(CENTRE, DIRECTIONS[3])
    pts = _exact_points(truth)
    lines = {s: fit_view_line(xy, CAMS[s]) for s, xy in pts.items()}
    planes = line_planes(lines, CAMS)
    for pi, cam in zip(planes, CAMS.values()):
        assert abs(pi[:3] @ cam.X0 + pi[3]) < 1e-9
        for t in (-10.0, 10.0):
            assert abs(pi[:3] @ point_on_line(truth, t) + pi[3]) < 1e-8
    ang = plane_angles(planes)
    assert np.allclose(np.diag(ang), 0) and np.allclose(ang, ang.T)


# ---------------------------------------------------------------------------
# noise: the errors agree with the propagated covariance


def test_chi_square_of_the_line_parameters():
    """200 seeded trials, 0.33 px on 15 points per ski and view: the
    chi-square of the 4 line parameters (truth against estimate, with the
    estimate's covariance) has mean ~4 for step B and for the one-step
    solution, within the 99 % band of the mean of 200 chi2(4) values."""
    rng = np.random.default_rng(20250103)
    truth = SpaceLine(CENTRE, DIRECTIONS[-1])
    exact = _exact_points(truth)
    chi_b, chi_o, s0, diff = [], [], [], []
    for _ in range(200):
        pts = {s: xy + rng.normal(0.0, 0.33, xy.shape) for s, xy in exact.items()}
        B = intersect_line_from_points(pts, CAMS, 0.33, label="L1")
        O = intersect_line_one_step(pts, CAMS, 0.33, label="L1", initial=B)
        for r, out in ((B, chi_b), (O, chi_o)):
            e = r.line.local_error(truth)
            out.append(e @ np.linalg.solve(r.line.covariance, e))
        s0.append(B.chi2 / B.redundancy)
        e = B.line.local_error(O.line)
        diff.append(e @ np.linalg.solve(B.line.covariance, e))
    half = 2.576 * np.sqrt(8 / 200)              # chi2(4): variance 8
    for chis in (chi_b, chi_o):
        assert 4 - half < np.mean(chis) < 4 + half, np.mean(chis)
        assert np.sum(np.array(chis) > chdtri(4, 0.01)) <= 6
    assert 1 - 2.576 * np.sqrt(1 / 200) < np.mean(s0) < 1 + 2.576 * np.sqrt(1 / 200)
    # both estimators are the same to first order: far inside the noise
    assert np.median(diff) < 0.05


# ---------------------------------------------------------------------------
# singular cases


def test_line_in_one_image():
    truth = SpaceLine(CENTRE, DIRECTIONS[0])
    pts = _exact_points(truth)
    with pytest.raises(GeometryError) as exc:
        intersect_line_from_points({"S2": pts["S2"]}, CAMS, 0.33, label="L1")
    assert "line L1 is measured in 1 image (S2); a 3D line needs at least 2 images" in str(exc.value)
    with pytest.raises(GeometryError, match=r"line L1 is measured in 1 image \(S2\)"):
        intersect_line({"S2": fit_view_line(pts["S2"], CAMS["S2"], label="L1")}, CAMS)
    with pytest.raises(GeometryError, match="1 image"):
        intersect_line_one_step({"S2": pts["S2"]}, CAMS, label="L1")


@pytest.mark.parametrize("kind", ["baseline", "epipolar"])
def test_line_in_an_epipolar_plane_of_a_stereo_pair(kind):
    S1, S2 = CAMS["S1"].X0, CAMS["S2"].X0
    if kind == "baseline":
        D = S2 - S1                                      # parallel to the baseline
    else:
        D = 0.3 * (S1 - CENTRE) + 0.7 * (S2 - CENTRE)    # in the plane (S1, S2, CENTRE)
    truth = SpaceLine(CENTRE, D)
    pts = _exact_points(truth)
    two = {s: pts[s] for s in ("S1", "S2")}
    with pytest.raises(GeometryError) as exc:
        intersect_line_from_points(two, CAMS, 0.33, label="L2")
    msg = str(exc.value)
    assert "line L2" in msg and "S1 and S2" in msg and "baseline S1-S2" in msg
    assert "third image" in exc.value.hint
    lines = {s: fit_view_line(xy, CAMS[s], label="L2") for s, xy in two.items()}
    with pytest.raises(GeometryError, match="S1 and S2"):
        initial_line_homogeneous(lines, CAMS)
    # a third image resolves it
    r = intersect_line_from_points(pts, CAMS, 0.33, label="L2")
    ang, pos = _errors(r.line, truth)
    assert ang < 1e-8 and pos < 1e-8
    assert r.best_pair != ("S1", "S2")


def test_line_in_the_plane_of_all_centres_and_bad_input():
    C = np.array([c.X0 for c in CAMS.values()])
    n = np.cross(C[1] - C[0], C[2] - C[0])
    n /= np.linalg.norm(n)
    P = CENTRE - ((CENTRE - C[0]) @ n) * n              # 4.4 m from the flight zone
    truth = SpaceLine(P, np.cross(n, [0.0, 0.0, 1.0]))  # in the plane of the centres
    lines = {}
    for s, cam in CAMS.items():
        xy = cam.project_ideal(point_on_line(truth, np.linspace(-5, 5, 10)))
        lines[s] = fit_view_line(cam.measured(xy), cam, label="L3")
    with pytest.raises(GeometryError, match="one plane with their projection centres"):
        intersect_line(lines, CAMS)
    with pytest.raises(InputError, match="fitted in measured"):
        from photogram.lines import fit_image_line
        intersect_line({"S1": fit_image_line(np.eye(2)), "S2": lines["S2"]}, CAMS)
    with pytest.raises(InputError, match="no camera"):
        intersect_line({"S1": lines["S1"], "X": lines["S2"]}, CAMS)
    with pytest.raises(InputError):
        intersect_line_from_points({"S1": np.zeros((3, 2)), "S2": np.zeros((3, 2))}, CAMS,
                                   method="three-step")
