"""Calibration from measured ellipse centres of rendered images with known
truth: the adjustment predicting the imaged ellipse centre (eccentricity of
the projected circle inside the adjustment, photogram.adjust.eccentric_blocks)
against the one predicting the circle centre's projection.

A sheet of 9 x 7 dark dots (radius 20 mm, spacing 100 mm) in six convergent,
rolled views (640 x 480 px, f = 720 px, k1 = -0.08), rendered with
photogram.measure.render and measured with detect_targets (ellipse centres,
no correction); 5 sheet points are control, the rest tie points; fx, fy, cx,
cy, k1, k2 free. Figures recorded in docs/measure.md.
"""

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.adjust.solver import solve
from photogram.geometry import camera_model, matrix_to_opk
from photogram.geometry.circle import ellipse_centre_point
from photogram.measure.detect import detect_targets
from photogram.measure.render import PlaneCamera, draw_sheet, look_at, render_plane
from photogram.project.model import TargetSettings
from photogram.simulation.network import SyntheticNetwork, to_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

COLS, ROWS, SPACING, RADIUS = 9, 7, 0.1, 0.02
SIZE, F, K1 = (640, 480), 720.0, -0.08
VIEWS = [((0.4, -0.5, 0.8), (0, 1, 0)), ((1.2, 0.3, 0.75), (1, 0.3, 0)),
         ((-0.4, 0.4, 0.8), (-0.2, 1, 0)), ((0.4, 1.1, 0.8), (1, 0, 0)),
         ((0.9, -0.3, 1.0), (0.7, 0.7, 0)), ((-0.1, 0.9, 0.9), (0.6, -0.8, 0))]
QUALITY = {"rendered": dict(blur=0.7, noise=2.0, jpeg=90, gradient=0.3),
           "harsh": dict(blur=1.3, noise=5.0, jpeg=50, gradient=0.5)}
CONTROL = [0, 8, 31, 54, 62]
FREE = ("fx", "fy", "cx", "cy", "k1", "k2")


def _measure(quality):
    gx, gy = np.meshgrid(np.arange(COLS) * SPACING, np.arange(ROWS) * SPACING)
    XY = np.column_stack([gx.ravel(), gy.ravel()])
    tex, org = draw_sheet((-0.2, -0.2, 1.0, 0.8), 0.0005,
                          np.column_stack([XY, np.full(len(XY), RADIUS)]))
    K = np.array([[F, 0, SIZE[0] / 2 - 0.5], [0, F, SIZE[1] / 2 - 0.5], [0, 0, 1]])
    R, X0, st, pt, xy = [], [], [], [], []
    for s, (eye, up) in enumerate(VIEWS):
        Rcv, t = look_at(eye, (0.4, 0.3, 0.0), up=up)
        cam = PlaneCamera(K, Rcv, t, SIZE, k1=K1)
        img = render_plane(tex, org, 0.0005, cam, ss=3, seed=s, **QUALITY[quality])
        det = detect_targets(img, "dark", min_diameter=4, max_diameter=80)
        d = np.linalg.norm(det.xy[:, None] - cam.project(XY)[None], axis=2)
        ok = d.min(axis=1) < 2.0                       # identify by the truth (numbering
        j = d.argmin(axis=1)[ok]                       # is not what is tested here)
        assert len(set(j)) == len(j) >= 45
        R.append(np.diag([1.0, -1, -1]) @ Rcv)
        X0.append(-Rcv.T @ t)
        st += [s] * len(j)
        pt += list(j)
        xy.append(det.xy[ok])
    io = np.array([F, F, K[0, 2], K[1, 2], K1, 0, 0, 0, 0])
    pts = np.column_stack([XY, np.zeros(len(XY))])
    xy = np.vstack(xy)
    return SyntheticNetwork("opencv", io[None], SIZE, np.zeros(len(R), int), np.array(R),
                            np.array(X0), pts, np.array(st), np.array(pt), xy, xy)


def _calibrate(net, corrected):
    prj = to_project(net, control=CONTROL, free_interior=FREE, sigma_image=0.05,
                     perturb_points=0.005, perturb_stations=0.01, rng=np.random.default_rng(1))
    for name, value in (("fx", 700.0), ("fy", 700.0), ("cx", 310.0), ("cy", 250.0), ("k1", 0.0)):
        prj.cameras["K1"].parameters[name].value = value
    if corrected:
        n = len(net.points)
        prj.targets = TargetSettings(ids=list(prj.points.ids), radius=np.full(n, RADIUS),
                                     normals=np.tile([0.0, 0.0, 1.0], (n, 1)))
    p = build_problem(prj).problem
    s = solve(p)
    assert s.status == "converged"
    tie = np.setdiff1d(np.arange(len(net.points)), CONTROL)
    return {"f": np.abs(p.state.io[0][:2] - net.io[0][:2]).max(),
            "pp": np.abs(p.state.io[0][2:4] - net.io[0][2:4]).max(),
            "X0": 1000 * np.linalg.norm(p.state.X0 - net.X0, axis=1).max(),
            "points": 1000 * np.sqrt(((p.state.points[tie] - net.points[tie]) ** 2).sum(1).mean())}


@pytest.mark.parametrize("quality", ["rendered", "harsh"])
def test_calibration_from_ellipse_centres_is_better_with_the_correction(quality):
    net = _measure(quality)
    m = camera_model("opencv")
    ang = matrix_to_opk(net.R[net.station])
    Xe = ellipse_centre_point(net.points[net.point], [0, 0, 1], RADIUS, net.R[net.station],
                              net.X0[net.station])
    ecc = np.linalg.norm(m.project(Xe, ang, net.X0[net.station], net.io[0])
                         - m.project(net.points[net.point], ang, net.X0[net.station], net.io[0]),
                         axis=1)
    without, with_ = _calibrate(net, False), _calibrate(net, True)
    print(f"{quality}: {len(net.point)} observations, eccentricity max {ecc.max():.3f} px, "
          f"rms {np.sqrt((ecc ** 2).mean()):.3f} px")
    for key, unit in (("f", "px"), ("pp", "px"), ("X0", "mm"), ("points", "mm")):
        print(f"  {key} error: without {without[key]:.4f} {unit}, with {with_[key]:.4f} {unit}")
    assert ecc.max() > 0.2                       # a real effect at this size and obliquity
    assert without["f"] > 0.15                   # the eccentricity biases the focal length
    assert with_["f"] < 0.1 and with_["f"] < 0.5 * without["f"]
    assert with_["X0"] < 0.5 * without["X0"]
    assert with_["points"] <= without["points"]
