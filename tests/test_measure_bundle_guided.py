"""Guided measurement from a bundle adjustment (photogram.measure.bundle_guided)
on rendered images with known truth where the first pass misses targets.

The sheet of tests/test_measure_eccentric_bundle.py (9 x 7 dots, six views,
k1 = -0.08) with 12 of the dots printed faintly (a quarter of the ink
contrast): the first pass (``detect_targets`` with ``min_contrast = 70``,
identified by the truth) misses them, and a quarter of the other
observations are dropped at random (a numbering that failed). The bundle
(opencv model, fx fy cx cy k1 k2 free, [targets] on) predicts them with
lens distortion; the guided ellipse fit measures them.
"""

import copy
import functools

import numpy as np

from photogram.geometry import camera_model, matrix_to_opk
from photogram.geometry.circle import ellipse_centre_point
from photogram.measure.bundle_guided import guided_from_bundle
from photogram.measure.detect import detect_targets
from photogram.measure.render import PlaneCamera, draw_sheet, look_at, render_plane
from photogram.project.model import TargetSettings
from photogram.simulation.network import SyntheticNetwork, to_project

from test_measure_eccentric_bundle import (CONTROL, COLS, F, FREE, K1, RADIUS, ROWS, SIZE,
                                           SPACING, VIEWS)
import pytest

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

FAINT = [3, 10, 14, 20, 25, 33, 38, 41, 47, 50, 57, 60]


def _scene():
    """(network, {station: image}, sigmas) of the rendered sheet: rendered
    and measured once per session (tests/test_measure_guided_cli.py uses it
    too), a deep copy for every caller."""
    return copy.deepcopy(_rendered_scene())


@functools.lru_cache(maxsize=1)
def _rendered_scene():
    gx, gy = np.meshgrid(np.arange(COLS) * SPACING, np.arange(ROWS) * SPACING)
    XY = np.column_stack([gx.ravel(), gy.ravel()])
    strong = np.setdiff1d(np.arange(len(XY)), FAINT)
    ext = (-0.2, -0.2, 1.0, 0.8)
    tex, org = draw_sheet(ext, 0.0005, np.column_stack([XY[strong], np.full(len(strong), RADIUS)]))
    faint, _ = draw_sheet(ext, 0.0005, np.column_stack([XY[FAINT], np.full(len(FAINT), RADIUS)]))
    tex = np.minimum(tex, 225 - 0.25 * (225.0 - faint)).astype(np.uint8)
    K = np.array([[F, 0, SIZE[0] / 2 - 0.5], [0, F, SIZE[1] / 2 - 0.5], [0, 0, 1]])
    rng = np.random.default_rng(3)
    images, R, X0, st, pt, xy, sig = {}, [], [], [], [], [], []
    for s, (eye, up) in enumerate(VIEWS):
        Rcv, t = look_at(eye, (0.4, 0.3, 0.0), up=up)
        cam = PlaneCamera(K, Rcv, t, SIZE, k1=K1)
        img = render_plane(tex, org, 0.0005, cam, ss=3, blur=0.7, noise=2.0, jpeg=90,
                           gradient=0.3, seed=s)
        images[f"S{s + 1}"] = img
        det = detect_targets(img, "dark", min_diameter=4, max_diameter=80, min_contrast=70)
        d = np.linalg.norm(det.xy[:, None] - cam.project(XY)[None], axis=2)
        ok = (d.min(axis=1) < 2.0) & (rng.uniform(size=len(d)) > 0.25)
        j = d.argmin(axis=1)[ok]
        R.append(np.diag([1.0, -1, -1]) @ Rcv)
        X0.append(-Rcv.T @ t)
        st += [s] * len(j)
        pt += list(j)
        xy.append(det.xy[ok] + 0.5)              # photogram measure's pixel convention
        sig.append(np.sqrt(det.sigma[ok] ** 2 + 0.02 ** 2))   # its sigmas too
    io = np.array([F, F, K[0, 2] + 0.5, K[1, 2] + 0.5, K1, 0, 0, 0, 0])
    pts = np.column_stack([XY, np.zeros(len(XY))])
    xy = np.vstack(xy)
    net = SyntheticNetwork("opencv", io[None], SIZE, np.zeros(len(R), int), np.array(R),
                           np.array(X0), pts, np.array(st), np.array(pt), xy, xy)
    return net, images, np.concatenate(sig)


def _true_ellipse_centres(net, station, point):
    m = camera_model("opencv")
    Xe = ellipse_centre_point(net.points[point], [0, 0, 1], RADIUS, net.R[station],
                              net.X0[station])
    return m.project(Xe, matrix_to_opk(net.R[station]), net.X0[station], net.io[0])


def test_guided_measurement_from_the_bundle_finds_what_the_first_pass_missed():
    net, images, sigma = _scene()
    # what a complete measurement would have: every target well inside every image
    S, P = len(net.X0), len(net.points)
    st_all, pt_all = np.repeat(np.arange(S), P), np.tile(np.arange(P), S)
    true_all = _true_ellipse_centres(net, st_all, pt_all)
    inside = np.all((true_all > 25) & (true_all < np.array(SIZE) - 25), axis=1)
    first = set(zip(net.station.tolist(), net.point.tolist()))
    missed = {(s, p) for s, p, i in zip(st_all, pt_all, inside) if i and (s, p) not in first}
    faint_missed = {(s, p) for s, p in missed if p in FAINT}
    assert len(missed) >= 100 and len(faint_missed) >= 50      # the first pass misses a lot

    prj = to_project(net, control=CONTROL, free_interior=FREE, sigma_image=0.05,
                     perturb_points=0.001, perturb_stations=0.01, rng=np.random.default_rng(1))
    prj.targets = TargetSettings(ids=list(prj.points.ids), radius=np.full(P, RADIUS),
                                 normals=np.tile([0.0, 0.0, 1.0], (P, 1)))
    prj.image_points.sigma = sigma
    n0 = len(prj.image_points)
    out, rep = guided_from_bundle(prj, images, polarity="dark")
    print(f"first pass {n0} observations, {len(missed)} missed ({len(faint_missed)} faint); "
          f"rounds {rep.rounds}: predicted {rep.predicted}, added {rep.added}, "
          f"sigma0 {[round(v, 3) for v in rep.sigma0]}")
    obs = out.image_points
    new = np.arange(n0, len(obs))
    pairs = set(zip(obs.station[new].tolist(), obs.point[new].tolist()))
    assert rep.added[-1] == 0 and rep.rounds >= 2               # iterated until nothing new
    assert len(pairs) == len(new)                               # one per target and image
    found = pairs & missed
    print(f"found {len(found)} of {len(missed)} missed, {len(pairs & faint_missed)} of "
          f"{len(faint_missed)} faint; {len(pairs - missed)} others")
    assert len(found) >= 0.95 * len(missed)
    assert len(pairs & faint_missed) >= 0.95 * len(faint_missed)
    # every added observation is its own target, measured to subpixel accuracy
    err = np.linalg.norm(obs.xy[new] - _true_ellipse_centres(net, obs.station[new],
                                                             obs.point[new]), axis=1)
    print(f"added: error RMS {np.sqrt((err ** 2).mean()):.4f} px, max {err.max():.3f} px")
    assert err.max() < 0.3 and np.sqrt((err ** 2).mean()) < 0.05
    # the adjusted camera: first pass only against all observations
    first_io = guided_from_bundle(prj, images, max_rounds=1)[0].cameras["K1"].values()
    io = out.cameras["K1"].values()
    e0, e1 = (np.abs(v[:2] - net.io[0][:2]).max() for v in (first_io, io))
    p0, p1 = (np.abs(v[2:4] - net.io[0][2:4]).max() for v in (first_io, io))
    print(f"fx, fy error: first pass {e0:.4f} px, with the guided observations {e1:.4f} px; "
          f"cx, cy {p0:.4f} / {p1:.4f} px")
    assert e1 < 0.05 and e1 < 0.5 * e0 and p1 < p0


def test_bad_input_is_one_input_error(tmp_path):
    import pytest
    from photogram.errors import InputError
    from photogram.init.chain import approximate
    from photogram.project import read_project
    from project_cases import append, make_project
    path = make_project(tmp_path)
    prj = approximate(read_project(path))[0]
    images = {s: np.zeros((1080, 1920), np.uint8) for s in prj.stations.names}
    with pytest.raises(InputError, match="diameter and normal"):
        guided_from_bundle(prj, images)
    append(path, "\n[targets]\ndiameter = 0.02\nnormal = [0, 1, 0]\n")
    prj = approximate(read_project(path))[0]
    with pytest.raises(InputError, match=f"no image for station {prj.stations.names[0]}"):
        guided_from_bundle(prj, {})
    # blank images: everything predicted, nothing measured, one round
    out, rep = guided_from_bundle(prj, images)
    assert rep.rounds == 1 and rep.added == [0] and rep.predicted[0] > 0
    assert len(out.image_points) == len(prj.image_points)
