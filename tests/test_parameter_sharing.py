"""Issue 21, item 4: shared interior parameters in the engine, on simulated
networks with known truth (photogram.simulation.network).

* one principal point per station (DBAT's image-variant calibration)
  recovered within its sigmas, with the covariance's shape and labels;
* a tie fy = fx: equal to the bit, and the same adjustment as a model with
  one focal length (brown without distortion is the opencv pinhole with
  fx = fy = c);
* two cameras sharing c: one value, one unknown in the covariance;
* a group of one camera (the map's general path, nothing shared) gives the
  default adjustment to the last bit;
* the Jacobian of the gathered io vectors against finite differences, and
  the sparse normal equations against the dense J^T J with shared columns.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.adjust.dense import dense_jacobian
from photogram.bundle import adjust
from photogram.project.model import Camera, Parameter
from photogram.simulation.network import observe, ring_stations, to_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

BROWN = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2")


def _ring(io_rows, station_camera, model="brown", sigma=0.1, seed=1, n_points=80):
    """A convergent calibration network (a ring of rolled stations around
    a 0.5 x 0.5 x 0.3 m frame), with one truth io row per entry of
    ``io_rows`` and ``station_camera`` naming the row of each station."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-0.25, -0.25, 0.0], [0.25, 0.25, 0.3], (n_points, 3))
    X0, R = ring_stations(len(station_camera), 2.0, 1.0, np.array([0.0, 0.0, 0.15]),
                          jitter=0.05, rng=rng, rolls=[0, np.pi / 2, np.pi, -np.pi / 2])
    return observe(model, np.asarray(io_rows, float), np.asarray(station_camera), R, X0, pts,
                   (640, 480), sigma=sigma, rng=rng)


def _camera(name, model, names, values, free, **sharing):
    params = {p: Parameter(float(v), p in free) for p, v in zip(names, values)}
    return Camera(name, model, params, image_size=(640, 480), **sharing)


def _per_station_project(per_station=("x0", "y0")):
    """12 stations of one camera whose principal point moves per image
    (N(0, 3 px)); image noise 0.1 px."""
    S = 12
    rng = np.random.default_rng(7)
    truth = np.tile([1420.0, 320.0, 240.0, -5e-8, 0, 0, 0, 0, 0, 0], (S, 1))
    truth[:, 1:3] += rng.normal(0, 3.0, (S, 2))
    net = _ring(truth, np.arange(S))
    proj = to_project(net, control=range(12), sigma_image=0.1)
    start = [1400.0, 320.0, 240.0, 0, 0, 0, 0, 0, 0, 0]
    proj.cameras = {"K1": _camera("K1", "brown", BROWN, start, ("c", "x0", "y0", "K1"),
                                  per_station=tuple(per_station))}
    proj.stations.camera = ["K1"] * S
    return proj, truth


def test_per_station_principal_points_are_recovered_within_their_sigmas():
    proj, truth = _per_station_project()
    res = adjust(proj)
    assert res.summary["status"] == "converged"
    assert 0.85 < res.summary["sigma0"] < 1.15
    rows = res.summary["interior"]
    S = len(truth)
    for j, p in ((1, "x0"), (2, "y0")):
        got = [r for r in rows if r["parameter"] == p]
        assert [r["station"] for r in got] == [f"S{s + 1}" for s in range(S)]
        value = np.array([r["value"] for r in got])
        sigma = np.array([r["sigma"] for r in got])
        z = (value - truth[:, j]) / sigma
        assert np.all(np.abs(z) < 3.5), z
        assert np.mean(z ** 2) < 2.5, z          # chi-square of 12 / 12
    c = next(r for r in rows if r["parameter"] == "c")
    assert c["station"] is None and abs(c["value"] - 1420.0) < 3.5 * c["sigma"]
    # covariance: c, 12 x0, 12 y0, K1 free; K2 ... B2 fixed (columns kept)
    labels = res.covariances["interior_labels"]
    assert len(labels) == 1 + 2 * S + 7
    assert res.covariances["interior"].shape == (len(labels), len(labels))
    assert "K1.x0@S1" in labels and "K1.y0@S12" in labels and "K1.x0" not in labels
    assert res.summary["counts"]["interior"] == 1 + 2 * S + 1
    orient = res.covariances["orientation_labels"]
    assert orient[:1 + 2 * S] == ["K1.c"] + [f"K1.x0@S{s + 1}" for s in range(S)] + \
        [f"K1.y0@S{s + 1}" for s in range(S)]
    assert res.covariances["orientation"].shape == (len(orient), len(orient))
    # the camera's own x0 is the mean over its stations; no sigma of its own
    cam = res.project.cameras["K1"]
    assert cam.parameters["x0"].value == pytest.approx(
        np.mean(list(cam.station_values["x0"].values())), rel=1e-15)
    assert np.isnan(res.camera_sigma["K1"]["x0"])
    assert res.camera_sigma["K1"]["c"] == pytest.approx(c["sigma"], rel=1e-15)


def _opencv_tied_and_brown():
    net = _ring([[1420.0, 320.0, 240.0, 0, 0, 0, 0, 0, 0, 0]], np.zeros(10, int), sigma=0.2,
                seed=3)
    brown = to_project(net, control=range(10), free_interior=("c", "x0", "y0"),
                       sigma_image=0.2)
    brown.cameras["K1"] = _camera("K1", "brown", BROWN, [1400, 322, 238, 0, 0, 0, 0, 0, 0, 0],
                                  ("c", "x0", "y0"))
    opencv = copy.deepcopy(brown)
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    opencv.cameras["K1"] = _camera("K1", "opencv", names, [1400, 1400, 322, 238, 0, 0, 0, 0, 0],
                                   ("fx", "fy", "cx", "cy"), ties={"fy": "fx"})
    return brown, opencv


def test_tie_fy_fx_is_exactly_equal_and_the_one_focal_model():
    brown, opencv = _opencv_tied_and_brown()
    rb, ro = adjust(brown), adjust(opencv)
    cam = ro.project.cameras["K1"].parameters
    assert cam["fx"].value == cam["fy"].value                     # to the bit
    assert ro.camera_sigma["K1"]["fx"] == ro.camera_sigma["K1"]["fy"]
    assert ro.summary["redundancy"] == rb.summary["redundancy"]
    assert ro.summary["counts"]["interior"] == 3
    assert ro.summary["sigma0"] == pytest.approx(rb.summary["sigma0"], rel=1e-9)
    cb = rb.project.cameras["K1"].parameters
    for a, b in (("fx", "c"), ("cx", "x0"), ("cy", "y0")):
        assert cam[a].value == pytest.approx(cb[b].value, rel=1e-10)
        assert ro.camera_sigma["K1"][a] == pytest.approx(rb.camera_sigma["K1"][b], rel=1e-6)
    assert np.allclose(ro.project.points.xyz, rb.project.points.xyz, atol=1e-10)
    # the tie is one unknown: fx's row names fy as equal
    row = next(r for r in ro.summary["interior"] if r["parameter"] == "fx")
    assert row["equal"] == ["fy"] and row["label"] == "K1.fx"
    assert not any(r["parameter"] == "fy" for r in ro.summary["interior"])


def _two_cameras(shared):
    """Two cameras of the same lens (c = 1420 px), different principal
    points, 8 stations each."""
    truth = [[1420.0, 318.0, 243.0, -5e-8, 0, 0, 0, 0, 0, 0],
             [1420.0, 325.0, 236.0, -5e-8, 0, 0, 0, 0, 0, 0]]
    net = _ring(truth, np.arange(16) % 2, sigma=0.2, seed=5)
    proj = to_project(net, control=range(12), sigma_image=0.2)
    start = [1400.0, 320.0, 240.0, 0, 0, 0, 0, 0, 0, 0]
    free = ("c", "x0", "y0", "K1")
    proj.cameras = {n: _camera(n, "brown", BROWN, start, free, shared=dict(shared))
                    for n in ("K1", "K2")}
    return proj


def test_two_cameras_sharing_c_have_one_value_and_one_unknown():
    res = adjust(_two_cameras({"c": "lens"}))
    sep = adjust(_two_cameras({}))
    c1 = res.project.cameras["K1"].parameters["c"].value
    c2 = res.project.cameras["K2"].parameters["c"].value
    assert c1 == c2
    labels = res.covariances["interior_labels"]
    assert labels.count("K1+K2.c") == 1 and "K1.c" not in labels and "K2.c" not in labels
    assert len(labels) == 1 + 2 * 9 and res.covariances["interior"].shape == (19, 19)
    assert res.summary["counts"]["interior"] == 1 + 2 * 3
    assert res.summary["redundancy"] == sep.summary["redundancy"] + 1
    sig = res.camera_sigma["K1"]["c"]
    assert res.camera_sigma["K2"]["c"] == sig
    assert abs(c1 - 1420.0) < 3.5 * sig
    assert sig < min(sep.camera_sigma[k]["c"] for k in ("K1", "K2"))
    # covariance.npz's orientation rows: each camera names its c (the same unknown)
    lab = res.covariances["orientation_labels"]
    cov = res.covariances["orientation"]
    i, j = lab.index("K1.c"), lab.index("K2.c")
    assert cov[i, j] == cov[i, i] == cov[j, j]


def test_a_group_of_one_camera_is_the_default_adjustment_to_the_bit():
    """The interior map's general path (gather by index, columns numbered by
    the map) with nothing actually shared gives the same numbers."""
    plain = _two_cameras({})
    grouped = _two_cameras({})
    grouped.cameras["K1"].shared = {"c": "only-K1"}
    a, b = adjust(plain), adjust(grouped)
    assert a.summary["sigma0"] == b.summary["sigma0"]
    assert np.array_equal(a.project.points.xyz, b.project.points.xyz)
    for n in ("K1", "K2"):
        assert np.array_equal(a.project.cameras[n].values(), b.project.cameras[n].values())
    assert np.array_equal(a.covariances["orientation"], b.covariances["orientation"])
    assert a.covariances["orientation_labels"] == b.covariances["orientation_labels"]


def _mixed_problem(fixed_stations=False):
    """opencv cameras with fy = fx, a principal point per station in K1 and
    k1 shared by both cameras (``fixed_stations``: every station held by a
    sigma of 0, so that the rows of the normal equations are grouped by
    their interior columns alone)."""
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    truth = [[1420.0, 1420.0, 320.0, 240.0, -0.05, 0, 0, 0, 0],
             [1380.0, 1380.0, 322.0, 238.0, -0.05, 0, 0, 0, 0]]
    net = _ring(truth, np.arange(8) % 2, model="opencv", sigma=0.2, seed=11, n_points=30)
    proj = to_project(net, control=range(8), sigma_image=0.2)
    free = ("fx", "fy", "cx", "cy", "k1")
    proj.cameras = {
        "K1": _camera("K1", "opencv", names, truth[0], free, ties={"fy": "fx"},
                      per_station=("cx", "cy"), shared={"k1": "lens"}),
        "K2": _camera("K2", "opencv", names, truth[1], free, ties={"fy": "fx"},
                      shared={"k1": "lens"})}
    if fixed_stations:
        proj.stations.position_sigma[:] = 0.0
        proj.stations.angle_sigma[:] = 0.0
    built = build_problem(proj)
    return built.problem, built.interior


def test_gathered_io_jacobian_matches_finite_differences():
    problem, imap = _mixed_problem()
    lay, state = problem.layout, problem.state
    # K1: fx, 4 cx, 4 cy, k1 (shared), K2: fx, cx, cy, + fixed columns
    assert imap.n_io == (1 + 4 + 4 + 1 + 4) + (1 + 2 + 4)
    assert np.flatnonzero(imap.free).size == 10 + 3
    r0, _, Jall = dense_jacobian(problem, state, all_columns=True)
    io_cols = np.flatnonzero(imap.free)
    for c in io_cols:
        scale = max(abs(imap.values[c]), 1.0)
        h = 1e-6 * scale
        dx = np.zeros(lay.n_columns)
        dx[c] = h
        plus = dense_jacobian(problem, state.updated(lay, dx), residuals_only=True)
        minus = dense_jacobian(problem, state.updated(lay, -dx), residuals_only=True)
        numeric = (plus - minus) / (2 * h)
        analytic = Jall[:, c]
        err = np.max(np.abs(numeric - analytic)) / np.max(np.abs(analytic))
        assert err < 1e-6, (imap.labels[c], err)
    # a tie moves fx and fy together: both stay equal to the bit
    dx = np.zeros(lay.n_columns)
    dx[io_cols] = 0.37
    moved = state.updated(lay, dx)
    assert all(v[0] == v[1] for v in moved.io)


@pytest.mark.parametrize("fixed_stations", [False, True])
def test_sparse_normal_equations_match_dense_with_shared_columns(fixed_stations):
    problem, imap = _mixed_problem(fixed_stations)
    system = problem.linearize(problem.state)
    r, J = dense_jacobian(problem, problem.state)
    N = J.T @ J
    g = J.T @ r
    lay = problem.layout
    free = np.flatnonzero(lay.free)
    red = free[free < lay.n_reduced]            # interior, stations (reduced columns)
    pos = np.searchsorted(free, red)
    Ncc = system.Ncc[np.ix_(red, red)]
    assert np.allclose(Ncc, N[np.ix_(pos, pos)], rtol=1e-10, atol=1e-8 * np.abs(N).max())
    assert np.allclose(system.g[red], g[pos], rtol=1e-10, atol=1e-8 * np.abs(g).max())


def test_mixed_sharing_recovers_the_truth():
    problem, imap = _mixed_problem()
    from photogram.adjust.solver import solve
    s = solve(problem)
    assert s.status == "converged" and 0.6 < s.sigma0 < 1.5
    k1 = [v[4] for v in problem.state.io]
    assert len(set(k1)) == 1                    # one k1 for every instance of both cameras


def test_weighted_shared_parameters_are_one_prior_per_unknown():
    """A weighted parameter shared by two cameras is one prior observation;
    a weighted per-station parameter one per station."""
    proj = _two_cameras({"c": "lens"})
    for cam in proj.cameras.values():
        cam.parameters["c"].sigma = 20.0
    blocks = [b for b in build_problem(proj).problem.blocks if b.name == "interior priors"]
    assert len(blocks) == 1 and len(blocks[0]) == 1
    proj, truth = _per_station_project()
    proj.cameras["K1"].parameters["x0"].sigma = 5.0
    built = build_problem(proj)
    prior = next(b for b in built.problem.blocks if b.name == "interior priors")
    assert len(prior) == len(truth)
    cols = prior.slot_cols[0].ravel()
    assert len(set(cols.tolist())) == len(truth)        # one column per station
    res = adjust(proj)
    plain = adjust(_per_station_project()[0])
    assert res.summary["redundancy"] == plain.summary["redundancy"] + len(truth)


ROOT = Path(__file__).resolve().parents[1]
DBAT = ROOT.parent / "shared" / "data" / "dbat"


@pytest.mark.skipif(not (DBAT / "camcal").is_dir(), reason=f"DBAT data not found at {DBAT}")
def test_camcal_with_a_principal_point_per_image():
    """Real data (DBAT's CAMCAL, 21 images of the C4040Z, read in place):
    a principal point per image is 42 unknowns instead of 2; the figures of
    docs/project-files.md, "Parameter sharing". (DBAT's own image-variant
    results for CAMCAL are not in ../shared/data: no reference to match.)"""
    from photogram.project import read_project
    prj = ROOT / "projects" / "camcal" / "camcal.prj"
    plain = adjust(read_project(prj))
    project = read_project(prj)
    project.cameras["C4040Z"].per_station = ("x0", "y0")
    res = adjust(project)
    assert res.summary["status"] == "converged"
    assert res.summary["redundancy"] == plain.summary["redundancy"] - 40
    assert plain.summary["sigma0"] == pytest.approx(1.6148, abs=1e-4)
    assert res.summary["sigma0"] == pytest.approx(1.1130, abs=1e-4)
    x0 = [r for r in res.summary["interior"] if r["parameter"] == "x0"]
    assert len(x0) == 21 and max(r["sigma"] for r in x0) < 1.5


def test_from_dbat_camera_takes_the_sharing_keys(tmp_path):
    """``per_station`` on a ``from_dbat`` camera in the .prj (DBAT's
    image-variant calibration): the same adjustment as setting it in code
    (REAL CAMCAL data, read in place; the .prj written beside the example
    with absolute paths)."""
    from photogram.project import read_project
    src = ROOT / "projects" / "camcal" / "camcal.prj"
    data = (ROOT / "projects" / "camcal" / "../../../shared/data").resolve()
    if not (data / "dbat" / "camcal" / "markpts.txt").is_file():
        pytest.skip("DBAT's CAMCAL data not found")
    text = src.read_text().replace("../../../shared/data", str(data)).replace(
        'free = ["c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1"]',
        'free = ["c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1"]\n'
        'per_station = ["x0", "y0"]')
    prj = tmp_path / "camcal.prj"
    prj.write_text(text)
    project = read_project(prj)
    assert project.cameras["C4040Z"].per_station == ("x0", "y0")
    res = adjust(project)
    assert res.summary["sigma0"] == pytest.approx(1.1130, abs=1e-4)
    bad = text.replace('per_station = ["x0", "y0"]', 'per_station = ["x9"]')
    prj.write_text(bad)
    from photogram.errors import InputError
    with pytest.raises(InputError, match="x9") as err:
        read_project(prj)
    assert err.value.line == bad.splitlines().index('per_station = ["x9"]') + 1
