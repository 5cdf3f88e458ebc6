"""The aicon (AICON 3D Studio / Australis, forward form) camera model: the
published formulas, its conventions, its conversions (to and from brown
and opencv where exact, the balancing radius r0) and a bundle adjustment
with it. Its Jacobians are checked with the other models in
tests/test_camera_models.py."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import (aicon_to_brown, aicon_to_opencv, brown_to_aicon,
                                camera_model, change_r0, fit_distortion, format_grid,
                                opencv_to_aicon, rescale_parameters)
from photogram.geometry.aicon_conversions import aicon_invariants

SIZE = (640, 480)
# c = 1420 px on 640 x 480, r0 = 250 px: 1-7 px of distortion at the corners
AICON = np.array([1420.0, 321.5, 238.2, -1.5e-7, 3.0e-13, -5.0e-19,
                  5.0e-6, -4.0e-6, 3.0e-4, -2.0e-4, 250.0])
M = camera_model("aicon")


def rays(n=300, seed=2):
    """Normalised rays covering the 640 x 480 format of a c = 1420 camera."""
    return np.random.default_rng(seed).uniform([-0.24, -0.18], [0.24, 0.18], (n, 2))


def literal(X_cam, p):
    """The model as written in Luhmann et al. (image plane y up, distortion
    added to the projected coordinates), point by point, then turned into
    photogram's y-down frame."""
    c, xh, yh, A1, A2, A3, B1, B2, C1, C2, r0 = p
    out = []
    for X, Y, Z in X_cam:
        x = -c * X / Z                      # image plane at z = -c, y up
        y = -c * Y / Z
        r = np.hypot(x, y)
        dr = (A1 * r * (r ** 2 - r0 ** 2) + A2 * r * (r ** 4 - r0 ** 4)
              + A3 * r * (r ** 6 - r0 ** 6))
        dx = x * dr / r + B1 * (r ** 2 + 2 * x ** 2) + 2 * B2 * x * y + C1 * x + C2 * y
        dy = y * dr / r + B2 * (r ** 2 + 2 * y ** 2) + 2 * B1 * x * y
        out.append((xh + x + dx, yh - (y + dy)))
    return np.array(out)


def test_project_is_the_published_form():
    t = rays(40)
    X_cam = np.stack([t[:, 0] * 7.0, -t[:, 1] * 7.0, -7.0 * np.ones(40)], -1)
    ours = M.project(X_cam, np.zeros(3), np.zeros(3), AICON)
    np.testing.assert_allclose(ours, literal(X_cam, AICON), rtol=0, atol=1e-10)
    # noticeable distortion at the corners
    ideal = AICON[1:3] + AICON[0] * t
    assert np.abs(ours - ideal).max() > 2.0


def test_radial_distortion_vanishes_at_r0_and_changes_sign():
    p = AICON.copy()
    p[6:10] = 0.0                                        # radial only
    angle = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    for radius, sign in ((p[10], 0), (150.0, 1), (380.0, -1)):
        t = radius / p[0] * np.stack([np.cos(angle), np.sin(angle)], -1)
        d = M.ray_to_image(t, p) - p[1:3] - p[0] * t
        radial = np.sum(d * t, axis=1) / np.linalg.norm(t, axis=1)
        if sign == 0:
            assert np.abs(d).max() < 1e-12
        else:     # A1 < 0 dominates: outwards inside r0, inwards outside
            assert np.all(np.sign(radial) == sign)
            assert np.allclose(d - radial[:, None] * t / np.linalg.norm(t, axis=1)[:, None], 0,
                               atol=1e-12)


def test_sign_conventions_of_b_and_c():
    """y-up parameters in a y-down image: B1 > 0 moves a point on the x
    axis right by 3 B1 r^2; B2 > 0 moves a point on the y axis *up* (y
    decreases) by 3 B2 r^2; C1 > 0 stretches x; C2 > 0 moves points above
    the principal point (y up > 0, image y smaller) to the right."""
    base = np.zeros(11)
    base[:3] = 1000.0, 320.0, 240.0
    r = 200.0
    on_x, above = np.array([[r / 1000, 0.0]]), np.array([[0.0, -r / 1000]])
    for name, value, t, shift in (("B1", 1e-6, on_x, (3e-6 * r * r, 0)),
                                  ("B2", 1e-6, above, (0, -3e-6 * r * r)),
                                  ("C1", 1e-3, on_x, (1e-3 * r, 0)),
                                  ("C2", 1e-3, above, (1e-3 * r, 0))):
        p = base.copy()
        p[M.index(name)] = value
        d = M.ray_to_image(t, p) - M.ray_to_image(t, base)
        np.testing.assert_allclose(d[0], shift, atol=1e-12, err_msg=name)


def test_units_mm_and_px_are_equivalent():
    size = 0.0055                                        # mm per px
    p_mm = rescale_parameters("aicon", AICON, size)
    assert p_mm[10] == pytest.approx(250 * size)
    t = rays(50)
    np.testing.assert_allclose(M.ray_to_image(t, p_mm), M.ray_to_image(t, AICON) * size,
                               rtol=1e-13, atol=1e-13)


def test_image_to_ray_inverts_ray_to_image():
    t = rays()
    xy = M.ray_to_image(t, AICON)
    np.testing.assert_allclose(M.image_to_ray(xy, AICON), t, rtol=0, atol=1e-14)
    distortion, partials = M.distortion(*(AICON[0] * t).T, AICON)
    np.testing.assert_allclose(distortion, xy - AICON[1:3] - AICON[0] * t, atol=1e-12)
    assert set(partials) == {"xy", "io"}


# ---------------------------------------------------------------- conversions
OPENCV_EXACT = aicon_to_opencv(np.r_[AICON[:8], 0.0, 0.0, AICON[10]])   # C1 = C2 = 0


def same_projection(model_a, pa, model_b, pb, atol=1e-9):
    t = rays()
    np.testing.assert_allclose(camera_model(model_a).ray_to_image(t, pa),
                               camera_model(model_b).ray_to_image(t, pb), rtol=0, atol=atol)


def test_r0_reparametrisation_is_exact_and_round_trips():
    for r0 in (0.0, 180.0, 300.0):
        q = change_r0(AICON, r0)
        assert q[10] == r0 and q[1] == AICON[1] and q[2] == AICON[2]
        same_projection("aicon", AICON, "aicon", q)
        back = change_r0(q, AICON[10])
        np.testing.assert_allclose(back, AICON, rtol=1e-12, atol=0)
        np.testing.assert_allclose(aicon_invariants(q), aicon_invariants(AICON), rtol=1e-13)
    assert change_r0(AICON, 0.0)[0] != AICON[0]          # c absorbs the linear term
    with pytest.raises(InputError, match="r0 must be >= 0"):
        change_r0(AICON, -1.0)


def test_r0_covariance_is_propagated_by_the_jacobian_of_the_map():
    rng = np.random.default_rng(5)
    scale = np.array([1.0, 0.5, 0.5, 1e-9, 1e-14, 1e-20, 1e-7, 1e-7, 1e-5, 1e-5])
    L = rng.normal(size=(10, 10)) * scale[:, None]
    Q = np.zeros((11, 11))
    Q[:10, :10] = L @ L.T
    q, Q_new, J = change_r0(AICON, 120.0, covariance=Q)
    # the Jacobian against central differences of the map
    for j in range(10):
        h = 1e-6 * max(abs(AICON[j]), scale[j])
        e = np.zeros(11)
        e[j] = h
        fd = (change_r0(AICON + e, 120.0) - change_r0(AICON - e, 120.0))[:10] / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())
    np.testing.assert_allclose(Q_new[:10, :10], J @ Q[:10, :10] @ J.T)
    assert np.all(Q_new[10] == 0) and np.all(Q_new[:, 10] == 0)
    # the camera is the same, so is the precision of every projected point
    t = rays(30)
    _, _, J_old = M._forward(t, np.broadcast_to(AICON, (30, 11)))
    _, _, J_new = M._forward(t, np.broadcast_to(q, (30, 11)))
    var_old = np.einsum("nip,pq,njq->nij", J_old, Q, J_old)
    var_new = np.einsum("nip,pq,njq->nij", J_new, Q_new, J_new)
    np.testing.assert_allclose(var_new, var_old, rtol=1e-7, atol=1e-12 * np.abs(var_old).max())


def test_opencv_conversion_is_exact_and_round_trips():
    p = np.r_[AICON[:8], 0.0, 0.0, AICON[10]]
    o = aicon_to_opencv(p)
    same_projection("aicon", p, "opencv", o)
    np.testing.assert_allclose(opencv_to_aicon(o, r0=p[10]), p, rtol=1e-12, atol=0)
    np.testing.assert_allclose(aicon_to_opencv(opencv_to_aicon(o)), o, rtol=1e-12, atol=0)
    # an affinity alone converts (fx != fy)
    a = np.r_[AICON[:3], np.zeros(5), 3e-4, 0.0, 0.0]
    oa = aicon_to_opencv(a)
    assert oa[0] == pytest.approx(1420 * 1.0003) and oa[1] == 1420.0
    same_projection("aicon", a, "opencv", oa)
    np.testing.assert_allclose(opencv_to_aicon(oa), a, rtol=1e-12, atol=1e-18)


def test_inexact_opencv_conversions_are_refused_naming_the_parameter():
    with pytest.raises(InputError, match="C2"):
        aicon_to_opencv(AICON)
    with pytest.raises(InputError, match=r"C1, A1, A2, A3, B1, B2"):
        aicon_to_opencv(np.r_[AICON[:9], 0.0, AICON[10]])
    o = OPENCV_EXACT.copy()
    o[0] *= 1.001
    with pytest.raises(InputError, match="k1, k2, k3, p1, p2.*fx != fy"):
        opencv_to_aicon(o)
    assert np.all(np.isfinite(aicon_to_opencv(AICON, strict=False)))


def test_brown_conversion_is_exact_and_round_trips():
    a = np.r_[AICON[:3], np.zeros(5), 3e-4, -2e-4, 0.0]          # affinity and shear
    b = aicon_to_brown(a)
    same_projection("aicon", a, "brown", b)
    np.testing.assert_allclose(brown_to_aicon(b), a, rtol=1e-12, atol=1e-19)
    np.testing.assert_allclose(aicon_to_brown(brown_to_aicon(b)), b, rtol=1e-12, atol=1e-19)
    with pytest.raises(InputError, match="A1, A2, A3, B1, B2"):
        aicon_to_brown(AICON)
    brown = np.array([1420.0, 321.5, 238.2, 2.3e-7, 0, 0, 6.0e-6, 0, 4.0e-4, -3.0e-4])
    with pytest.raises(InputError, match="K1, P1"):
        brown_to_aicon(brown)


@pytest.mark.parametrize("source,params,target,target_params,free", [
    # aicon (balanced, no affinity) refitted in opencv: all nine parameters
    ("aicon", np.r_[AICON[:8], 0.0, 0.0, AICON[10]], "opencv", None,
     ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")),
    # opencv refitted in aicon with r0 = 250 px
    ("opencv", OPENCV_EXACT, "aicon", np.r_[1400.0, 320.0, 240.0, np.zeros(7), 250.0],
     ("c", "xh", "yh", "A1", "A2", "A3", "B1", "B2", "C1", "C2")),
    # aicon with affinity and shear refitted in brown
    ("aicon", np.r_[AICON[:3], np.zeros(5), 3e-4, -2e-4, 0.0], "brown", None,
     ("c", "x0", "y0", "B1", "B2")),
    # brown without distortion refitted in aicon
    ("brown", np.array([1420.0, 321.5, 238.2, 0, 0, 0, 0, 0, 4.0e-4, -3.0e-4]), "aicon",
     np.r_[1400.0, 320.0, 240.0, np.zeros(7), 100.0], ("c", "xh", "yh", "C1", "C2")),
])
def test_refit_where_exact_gives_the_same_projections(source, params, target, target_params,
                                                      free):
    """Least squares over a grid of the format: same projections to 1e-9 px
    and (where the parametrisation is unique) the closed-form values."""
    fitted, rms = fit_distortion(source, params, target, SIZE, target_params=target_params,
                                 free=free)
    assert rms < 1e-9
    grid = format_grid(SIZE)
    t = camera_model(source).image_to_ray(grid, params)
    np.testing.assert_allclose(camera_model(target).ray_to_image(t, fitted), grid, rtol=0,
                               atol=1e-9)
    exact = {("aicon", "opencv"): lambda p: aicon_to_opencv(p),
             ("opencv", "aicon"): lambda p: opencv_to_aicon(p, r0=250.0),
             ("aicon", "brown"): lambda p: aicon_to_brown(p),
             ("brown", "aicon"): lambda p: brown_to_aicon(p, r0=100.0)}[source, target](params)
    # compared in units of 400 px (the corner radius): every parameter's
    # effect at the corners
    np.testing.assert_allclose(rescale_parameters(target, fitted, 1 / 400),
                               rescale_parameters(target, exact, 1 / 400), rtol=0, atol=1e-10)


# ---------------------------------------------------------------- projects
def aicon_prj(tmp_path, extra):
    from project_cases import make_project, replace
    prj = make_project(tmp_path)
    replace(prj, '[cameras.K2]\nmodel = "brown"', '[cameras.K2]\nmodel = "aicon"')
    replace(prj, 'sigma = 20.0 }\nx0 = { value = 960.0, free = true }\n'
                 'y0 = { value = 540.0, free = true }\nK1 = { value = 0.0, free = true }',
            'sigma = 20.0 }\nxh = { value = 960.0, free = true }\nyh = 540.0\n'
            'A1 = { value = 0.0, free = true }\nC2 = { value = 0.0, free = true, sigma = 1e-4 }\n'
            + extra)
    return prj


def test_aicon_camera_in_a_project(tmp_path):
    from photogram.project import read_project
    cam = read_project(aicon_prj(tmp_path, "r0 = 400.0\n")).cameras["K2"]
    assert list(cam.parameters) == list(M.parameter_names)
    assert cam.free_mask().tolist() == [True, True, False, True] + [False] * 5 + [True, False]
    assert cam.parameters["C2"].sigma == 1e-4 and cam.parameters["r0"].value == 400.0


@pytest.mark.parametrize("extra,message", [
    ("r0 = { value = 400.0, free = true }\n", "r0 of .* is a constant of the aicon model"),
    ("r0 = -3.0\n", "r0 of .* must be >= 0"),
])
def test_r0_must_be_a_fixed_non_negative_constant(tmp_path, extra, message):
    from photogram.project import read_project
    with pytest.raises(InputError, match=message) as info:
        read_project(aicon_prj(tmp_path, extra))
    assert info.value.line is not None


def test_bundle_self_calibration_with_aicon(tmp_path):
    """A simulated convergent network observed with the aicon model; free,
    fixed and weighted parameters through the .prj, the adjustment
    recovers the truth within its own sigmas and sigma0 ~ 1."""
    from photogram.bundle import adjust
    from photogram.project import read_project
    from photogram.project.model import Parameter
    from photogram.project.writer import write_project
    from photogram.simulation.network import observe, ring_stations, to_project
    rng = np.random.default_rng(4)
    pts = rng.uniform([-0.3, -0.3, 0.0], [0.3, 0.3, 0.35], (120, 3))
    X0, R = ring_stations(12, 1.6, 0.8, np.array([0.0, 0.0, 0.15]), jitter=0.05, rng=rng,
                          rolls=[0, np.pi / 2, np.pi, -np.pi / 2])
    truth = AICON.copy()
    net = observe("aicon", truth, np.zeros(12, int), R, X0, pts, SIZE, sigma=0.1, rng=rng)
    free = ("c", "xh", "yh", "A1", "A2", "B1", "B2", "C1", "C2")
    prj = to_project(net, control=range(6), point_sigma=1e-4, sigma_image=0.1,
                     free_interior=free, perturb_points=0.005, perturb_stations=0.005,
                     rng=np.random.default_rng(1))
    cam = prj.cameras["K1"]
    prior_C2 = truth[9] + 1e-5                      # weighted, 1e-5 off the truth
    cam.parameters["C2"] = Parameter(prior_C2, free=True, sigma=1e-7)
    for p, value in zip(free, (1400.0, 320.0, 240.0, 0, 0, 0, 0, 0)):
        cam.parameters[p].value = value                            # start off the truth
    path = write_project(prj, tmp_path / "aicon.prj")
    project = read_project(path)
    assert project.cameras["K1"].model == "aicon"
    res = adjust(project)
    assert 0.85 < res.summary["sigma0"] < 1.15
    est = res.project.cameras["K1"].parameters
    sig = res.camera_sigma["K1"]
    for p in ("c", "xh", "yh", "A1", "A2", "B1", "B2", "C1"):
        i = M.index(p)
        assert abs(est[p].value - truth[i]) < 3.5 * sig[p], (p, est[p].value, truth[i], sig[p])
    assert est["A3"].value == truth[5] and est["r0"].value == truth[10]   # fixed
    assert abs(est["C2"].value - prior_C2) < 3e-7 and sig["C2"] <= 1e-7   # weighted


def test_report_distortion_field_of_an_aicon_camera():
    """The report's displacement (measured minus distortion-free position)
    is the model's distortion of the ideal point; A1 > 0 with r0 = 0 pushes
    points outwards."""
    from photogram.project.model import Camera, Parameter
    from photogram.report.pages_cameras import _principal_point, displacement
    p = np.r_[1000.0, 320.0, 240.0, 1e-7, np.zeros(7)]
    cam = Camera("K", "aicon", {k: Parameter(v) for k, v in zip(M.parameter_names, p)},
                 (640, 480))
    xy = np.array([[320.0, 240.0], [620.0, 240.0], [320.0, 40.0]])
    d = displacement(cam, xy)
    assert np.allclose(d[0], 0) and d[1, 0] > 0 and d[2, 1] < 0
    ideal = xy - d - p[1:3]
    np.testing.assert_allclose(d, M.distortion(ideal[:, 0], ideal[:, 1], p)[0], atol=1e-12)
    assert np.array_equal(_principal_point(cam), [320.0, 240.0])


def test_r0_cannot_be_freed_in_a_camera_taken_from_a_file(tmp_path):
    from project_cases import make_project, replace
    from photogram.project import read_project
    prj = make_project(tmp_path)
    (prj.parent / "aicon_cameras.toml").write_text(
        '[project]\nimage_unit = "px"\n\n[cameras.K2]\nmodel = "aicon"\n'
        'image_size = [1920, 1080]\nc = 1400.0\nA1 = { value = 1e-9, free = true, '
        'sigma_estimated = 1e-10 }\nr0 = 400.0\n')
    text = prj.read_text()
    start = text.index("[cameras.K2]")
    end = text.index("[stations]")
    prj.write_text(text[:start] + '[cameras.K2]\nfrom = "aicon_cameras.toml"\n'
                   'free = ["c", "A1"]\n\n' + text[end:])
    cam = read_project(prj).cameras["K2"]
    assert cam.model == "aicon" and cam.parameters["r0"].value == 400.0
    assert [p for p, par in cam.parameters.items() if par.free] == ["c", "A1"]
    replace(prj, 'free = ["c", "A1"]', 'free = ["c", "r0"]')
    with pytest.raises(InputError, match="r0 of .* is a constant"):
        read_project(prj)


def test_schema_fallback_tables_match_the_model():
    from photogram.project.camera_schema import (CONSTANT_PARAMETERS, FALLBACK_DIMS,
                                                 FALLBACK_PARAMETERS, PRINCIPAL_POINT)
    assert FALLBACK_PARAMETERS["aicon"] == M.parameter_names
    assert FALLBACK_DIMS["aicon"] == M.parameter_dims
    assert CONSTANT_PARAMETERS["aicon"] == M.constant_parameters == ("r0",)
    assert PRINCIPAL_POINT["aicon"] == ("xh", "yh")


def test_export_to_opencv_is_exact_where_the_conversion_is():
    from photogram.io.exchange import opencv_intrinsics
    from photogram.project.model import Camera, Parameter

    def camera(p):
        return Camera("K", "aicon", {k: Parameter(v) for k, v in zip(M.parameter_names, p)},
                      SIZE)
    exact = np.r_[AICON[:8], 0.0, 0.0, AICON[10]]
    K, dist, misfit = opencv_intrinsics(camera(exact))
    o = aicon_to_opencv(exact)
    assert misfit == 0.0 and np.array_equal(K[[0, 1, 0, 1], [0, 1, 2, 2]], o[:4])
    assert np.array_equal(dist, o[4:9])
    # with shear: a fit over the format, its misfit reported
    K, dist, misfit = opencv_intrinsics(camera(AICON))
    assert 0.01 < misfit < 0.05


def test_first_order_relation_to_the_correction_form():
    """A mild aicon camera refitted in brown: K1 ~ -A1 (r0 = 0), P1 ~ -B1,
    P2 ~ -B2, brown's B1 ~ -C1, B2 ~ -C2 (docs/camera-models.md 5.3)."""
    a = np.zeros(11)
    a[:3] = 1420.0, 320.0, 240.0
    a[[3, 6, 7, 8, 9]] = 2e-8, 1e-7, -2e-7, 1e-5, -2e-5
    b, rms = fit_distortion("aicon", a, "brown", SIZE, free=(
        "c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2"))
    for brown_name, aicon_name in (("K1", "A1"), ("P1", "B1"), ("P2", "B2"), ("B1", "C1"),
                                   ("B2", "C2")):
        ratio = b[camera_model("brown").index(brown_name)] / -a[M.index(aicon_name)]
        assert ratio == pytest.approx(1.0, abs=0.02), (brown_name, ratio)
    assert rms < 1e-3
