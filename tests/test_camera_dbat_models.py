"""DBAT's lens models -1, 1, 2, 4 and 5 (photogram.geometry.dbat_models).

1. Literal transcriptions of DBAT's residuals (brown_euler_cam4.m: the
   forward branch of model -1, the legacy branch of model 1,
   res_euler_brown_0/2/3.m for models 2/4/5; DBAT's internal signs) equal
   ours up to the documented sign of the residual, v = (-r_x, r_y).
2. The exact relations between the models: models 1 and 2 are brown with
   B1 = B2 = 0; model 5 with B2 = 0 is brown with x0 / (1 + B1); model 4
   with B1 = B2 = 0 is brown; the forward model inverts brown to first
   order.
3. The .prj route: ``lens_model`` of a ``from_dbat`` camera and the XML's
   ``<model>`` choose the model; bad values are one-line input errors.

The analytic Jacobians of the three new models are checked against
central differences with every other model in tests/test_camera_models.py.
"""

from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import (aspect_first_to_brown, brown_to_aspect_first, camera_model,
                                rescale_parameters)
from photogram.project import read_project

# CAMCAL's model-3 result (dbat-report.txt), skew made non-zero to exercise it:
# cc, px, py, K1, K2, K3, P1, P2, as, sk in mm (DBAT's reported signs)
IO = np.array([7.457, 3.61546, 2.61329, 0.00458861, -4.51351e-05, -2.05253e-06,
               -6.12803e-05, -4.41171e-05, 0.000389598, 2e-4])
PIXEL = 5.43764 / 1704


def rot(ang):
    """DBAT's eulerrotmat(ang, 123, false)."""
    def r(axis, a):
        c, s = np.cos(a), np.sin(a)
        return np.array({1: [[1, 0, 0], [0, c, -s], [0, s, c]],
                         2: [[c, 0, s], [0, 1, 0], [-s, 0, c]],
                         3: [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis])
    return r(1, ang[0]) @ r(2, ang[1]) @ r(3, ang[2])


def pinhole(Q, q0, ang, f):
    """eulerpinhole2(Q, q0, ang, f) = f W(1:2) / W(3), W = M' (Q - q0)."""
    W = rot(ang).T @ (Q - q0[:, None])
    return f * W[:2] / W[2]


def brown_dist(a, K, P):
    """brown_dist.m: a + a (K1 r^2 + K2 r^4 + K3 r^6) + P r^2 + 2 (P'a) a."""
    r2 = np.sum(a ** 2, 0)
    rad = a * (K[0] * r2 + K[1] * r2 ** 2 + K[2] * r2 ** 3)
    return a + rad + np.asarray(P)[:, None] * r2 + 2 * (np.asarray(P) @ a) * a


def browndist(s, pp, K, P):
    """The legacy cammodel/browndist.m: the distortion of w = s - pp alone."""
    return brown_dist(s - pp[:, None], K, P) - (s - pp[:, None])


def dbat_residual(lens, Q, q0, ang, f, u, sz, u0, K, P, b):
    """DBAT's image residual v of lens model ``lens`` (internal values)."""
    up = np.diag([1.0, -1.0]) @ (sz * u)                      # scale2, aniscale2 [1;-1]
    if lens == -1:                                            # forward branch
        xy = u0[:, None] + pinhole(Q, q0, ang, -f)            # proj(p0, f, T)
        return xy + browndist(xy, u0, K, P) - up              # ptDist - m
    if lens == 1:                                             # legacy backward branch
        xy = u0[:, None] + pinhole(Q, q0, ang, -f)
        return xy - (up - browndist(up, u0, K, P))            # xy - ptCorr
    lhs = pinhole(Q, q0, ang, -f)
    if lens == 2:                                             # res_euler_brown_0
        return lhs - brown_dist(up - u0[:, None], -K, -P)
    if lens == 4:                                             # res_euler_brown_2
        A = np.array([[1 + b[0], b[1]], [0, 1]])              # affine2
        return lhs - A @ brown_dist(up - u0[:, None], -K, -P)
    S = np.array([[1, b[1]], [0, 1]])                         # res_euler_brown_3: skew
    scaled = np.diag([1 + b[0], 1.0]) @ up                    # aniscale2b
    return lhs - S @ brown_dist(scaled - u0[:, None], -K, -P)


OURS = {-1: "brown_forward", 1: "brown", 2: "brown", 4: "brown_affine_after",
        5: "brown_aspect_first"}


@pytest.mark.parametrize("lens", sorted(OURS))
def test_transcribed_dbat_residual_equals_ours(lens):
    rng = np.random.default_rng(5 + lens)
    io = IO.copy()
    if lens in (-1, 1, 2):
        io[8:] = 0.0                       # these models have no aspect and skew
    n = 60
    ang = np.array([0.5, -0.1, 2.9])
    q0 = np.array([0.5, -0.5, 1.5])
    Q = np.stack([rng.uniform(-0.2, 1.2, n), rng.uniform(-0.2, 1.2, n),
                  rng.uniform(-0.05, 0.05, n)])
    u = rng.uniform([0, 0], [2272, 1704], (n, 2)).T          # pixels, y down
    # DBAT's internal values: the report flips py, K and P (bundle_result_file.m)
    u0_int = np.array([io[1], -io[2]])
    v = dbat_residual(lens, Q, q0, ang, io[0], u, PIXEL, u0_int, -io[3:6], -io[6:8], io[8:10])
    model = camera_model(OURS[lens])
    r = model.residuals(u.T * PIXEL, Q.T, ang, q0, io[:model.n_params], jacobians=False)
    assert np.max(np.abs(v)) > 1e-3                            # a real test (mm)
    np.testing.assert_allclose(v[0], -r[:, 0], rtol=0, atol=1e-13)
    np.testing.assert_allclose(v[1], r[:, 1], rtol=0, atol=1e-13)


def grid(n=15):
    x, y = np.meshgrid(np.linspace(0, 2272, n), np.linspace(0, 1704, n))
    return np.stack([x.ravel(), y.ravel()], -1)


def px(model, io_mm):
    return rescale_parameters(model, io_mm, 1 / PIXEL)


def test_aspect_first_without_skew_is_brown_with_scaled_x0():
    """Model 5 with sk = 0 is model 3 with px_3 = px_5 / (1 + as): the two
    CAMCAL reports differ only in px (3.61687 = 3.61546 (1 + 0.000389598))."""
    io5 = IO.copy()
    io5[9] = 0.0
    io3 = io5.copy()
    io3[1] = io5[1] / (1 + io5[8])
    xy = grid()
    c5 = camera_model("brown_aspect_first").correct(xy, px("brown", io5))
    c3 = camera_model("brown").correct(xy, px("brown", io3))
    np.testing.assert_allclose(c5, c3, rtol=0, atol=1e-9)


def test_aspect_first_converts_to_brown_exactly():
    """aspect_first_to_brown / brown_to_aspect_first: the same projections
    to 1e-9 px, a round trip to rounding, the covariance through the exact
    Jacobian of the map; a shear cannot be converted."""
    io5 = px("brown", IO)
    io5[9] = 0.0
    io3 = aspect_first_to_brown(io5)
    rng = np.random.default_rng(2)
    X = np.stack([rng.uniform(-0.4, 0.4, 50), rng.uniform(-0.3, 0.3, 50),
                  -np.ones(50)], -1)
    a = camera_model("brown_aspect_first").project(X, np.zeros(3), np.zeros(3), io5)
    b = camera_model("brown").project(X, np.zeros(3), np.zeros(3), io3)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    np.testing.assert_allclose(brown_to_aspect_first(io3), io5, rtol=1e-15, atol=0)
    cov = np.diag(np.abs(io5) * 1e-3 + 1e-12) ** 2
    _, cov3 = aspect_first_to_brown(io5, cov)
    J = np.zeros((10, 10))
    J[9, 9] = 1.0                            # B2 passes unchanged (and must be 0)
    for k in range(9):
        h = 1e-6 * max(abs(io5[k]), 1e-3)
        step = np.zeros(10)
        step[k] = h
        J[:, k] = (aspect_first_to_brown(io5 + step) - aspect_first_to_brown(io5 - step)) / (2 * h)
    np.testing.assert_allclose(cov3, J @ cov @ J.T, rtol=1e-6, atol=0)
    io5[9] = 1e-4
    with pytest.raises(InputError, match="shear B2"):
        aspect_first_to_brown(io5)


def test_affine_after_without_affinity_is_brown():
    io = IO.copy()
    io[8:] = 0.0
    xy = grid()
    a = camera_model("brown_affine_after").correct(xy, px("brown", io))
    b = camera_model("brown").correct(xy, px("brown", io))
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    io[8] = IO[8]              # with CAMCAL's aspect the order matters: 0.027 px
    a = camera_model("brown_affine_after").correct(xy, px("brown", io))
    b = camera_model("brown").correct(xy, px("brown", io))
    assert np.max(np.abs(a - b)) > 0.01


def test_forward_model_inverts_brown_to_first_order():
    """The forward model subtracts brown's correction polynomial at the ideal
    point: projecting with it and correcting with brown with the same
    coefficients leaves second-order terms only (7 px against 70 px of
    distortion with CAMCAL's coefficients; a tenth of the coefficients
    leaves a hundredth of that)."""
    fw = camera_model("brown_forward")
    ratios = []
    for scale in (1.0, 0.1):
        io8 = px("brown_forward", IO[:8])
        io8[3:] *= scale
        io10 = np.concatenate([io8, [0.0, 0.0]])
        t = camera_model("brown").image_to_ray(grid(), io10)
        xy = fw.ray_to_image(t, io8)
        ideal = t * io8[0]
        back = camera_model("brown").correct(xy, io10)
        ratios.append(np.max(np.abs(back - ideal)) / np.max(np.abs(xy - io8[1:3] - ideal)))
        np.testing.assert_allclose(fw.image_to_ray(xy, io8), t, rtol=0, atol=1e-12)
    assert ratios[0] < 0.12
    assert ratios[1] < 0.15 * ratios[0]


def test_forward_distortion_is_measured_minus_ideal():
    fw = camera_model("brown_forward")
    io8 = px("brown_forward", IO[:8])
    t = camera_model("brown").image_to_ray(grid(7), np.concatenate([io8, [0, 0]]))
    xy = fw.ray_to_image(t, io8)
    ideal = io8[0] * t
    d, part = fw.distortion(ideal[:, 0], ideal[:, 1], io8)
    np.testing.assert_allclose(ideal + d + io8[1:3], xy, rtol=0, atol=1e-9)
    h = 1e-3
    for k in range(2):
        step = np.zeros(2)
        step[k] = h
        fd = (fw.distortion(*(ideal + step).T, io8)[0]
              - fw.distortion(*(ideal - step).T, io8)[0]) / (2 * h)
        np.testing.assert_allclose(part["xy"][:, :, k], fd, rtol=0, atol=1e-9)


# ---------------------------------------------------------------- the .prj route
CAMCAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "dbat" / "camcal"

XML = """<?xml version="1.0" encoding="UTF-8"?>
<document dbat_camera_version="1.0"><cameras><camera>
  <id>1</id><name>cam</name><unit>mm</unit><sensor>auto,5.43764</sensor>
  <image>2272,1704</image><focal>7.5</focal><model>{model}</model>
  <K>0.0045,-4.5e-5,-2e-6</K><P>-6e-5,-4e-5</P>
</camera></cameras></document>
"""


def write_project(tmp_path, model=3, extra="", free='["c", "x0", "y0"]'):
    (tmp_path / "cam.xml").write_text(XML.format(model=model), encoding="utf-8")
    (tmp_path / "ctrl.txt").write_text("1001,a,0,1,0\n1002,b,1,1,0\n1003,c,0,0,0\n",
                                       encoding="utf-8")
    (tmp_path / "marks.txt").write_text("1,1001,100,100,0.1\n1,1002,900,100,0.1\n"
                                        "1,1003,100,900,0.1\n", encoding="utf-8")
    prj = tmp_path / "p.prj"
    prj.write_text(f"""[project]
name = "t"
image_unit = "px"
[cameras.C]
from_dbat = "cam.xml"
free = {free}
{extra}
[stations]
from_observations = true
[points]
file = "ctrl.txt"
format = "dbat"
[observations]
points = {{ file = "marks.txt", format = "dbat", columns = "im,id,x,y,sxy" }}
""", encoding="utf-8")
    return prj


@pytest.mark.parametrize("model,name", [(-1, "brown_forward"), (1, "brown"), (2, "brown"),
                                        (3, "brown"), (4, "brown_affine_after"),
                                        (5, "brown_aspect_first")])
def test_xml_model_chooses_the_camera_model(tmp_path, model, name):
    project = read_project(write_project(tmp_path, model=model))
    cam = project.cameras["C"]
    assert cam.model == name
    assert tuple(cam.parameters) == camera_model(name).parameter_names
    assert cam.parameters["K1"].value == pytest.approx(0.0045 * PIXEL ** 2)
    assert not any("lens distortion model" in w for w in project.warnings)


def test_lens_model_key_overrides_the_xml(tmp_path):
    project = read_project(write_project(tmp_path, model=3, extra="lens_model = -1"))
    assert project.cameras["C"].model == "brown_forward"


def test_unknown_xml_model_is_read_as_brown_with_a_warning(tmp_path):
    project = read_project(write_project(tmp_path, model=7))
    assert project.cameras["C"].model == "brown"
    assert any("lens distortion model 7" in w for w in project.warnings)


@pytest.mark.parametrize("extra,free,match", [
    ("lens_model = 6", '["c"]', "unknown DBAT lens model 6"),
    ("lens_model = 2", '["c", "B1"]', "B1 in free.*no aspect or skew"),
    ("lens_model = -1", '["c", "B1"]', "unknown parameter 'B1'"),
    ('lens_model = "4"', '["c"]', "integer"),
])
def test_bad_lens_model_settings_are_input_errors(tmp_path, extra, free, match):
    with pytest.raises(InputError, match=match) as err:
        read_project(write_project(tmp_path, extra=extra, free=free))
    assert "\n" not in str(err.value).split(" (hint")[0]


@pytest.mark.parametrize("name", ["brown_affine_after", "brown_aspect_first", "brown_forward"])
def test_report_draws_the_distortion_of_the_dbat_models(name):
    from photogram.project.model import Camera, Parameter
    from photogram.report.pages_cameras import displacement
    m = camera_model(name)
    io = px(name, IO[:m.n_params])
    cam = Camera("C", name, {n: Parameter(float(v)) for n, v in zip(m.parameter_names, io)})
    d = np.hypot(*displacement(cam, grid(9)).T)
    assert 50 < d.max() < 150                 # CAMCAL: up to ~100 px in the corners
    io[3:] = 0.0
    cam = Camera("C", name, {n: Parameter(float(v)) for n, v in zip(m.parameter_names, io)})
    np.testing.assert_allclose(displacement(cam, grid(9)), 0.0, atol=1e-9)
