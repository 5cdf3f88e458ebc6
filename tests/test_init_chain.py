"""The approximation chain (paper steps 1B and 2A): resection from control,
relative orientation when there is none, Helmert into the control frame,
intersection, and the report of what could not be reached."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model, matrix_to_opk, opk_to_matrix, rescale_parameters
from photogram.init.chain import ChainReport, approximate, to_ideal
from photogram.init.helmert import helmert
from photogram.init.intersection import project_ideal
from photogram.project.model import Camera, ImagePoints, Parameter, Points, Project, Stations
from photogram.simulation.network import look_at as simulated_look_at

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

DBAT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "dbat"
CAMCAL = DBAT / "camcal"

BROWN = camera_model("brown")
# c, x0, y0 (px), a little radial and decentring distortion, no affinity
IO = np.array([1420.0, 321.5, 238.5, 2e-7, 0.0, 0.0, 1e-6, -5e-7, 0.0, 0.0])
TARGET = np.array([0.25, 0.25, 0.15])


def look_at(X0, target=TARGET, up=(0.0, 0.0, 1.0)):
    """World-to-camera rotation of one camera at X0 looking at target."""
    return simulated_look_at(X0, target, up)[0]


def ring_stations(n=6, radius=3.0, height=1.0, phase=0.0):
    az = np.radians(phase) + np.linspace(0, 2 * np.pi, n, endpoint=False)
    X0 = TARGET + np.c_[radius * np.cos(az), radius * np.sin(az), height + 0.3 * np.sin(3 * az)]
    return X0, az


def scene(seed=0, n_points=60, n_control=6, control_sector=None, sector=100.0,
          noise=0.0, stations=None):
    """A ring of 6 stations around a 0.5 m frame. Points at azimuth a are
    seen by stations within ``sector`` degrees of a. Control points are
    spread over all azimuths, or within ``control_sector`` (deg) of
    azimuth 0."""
    rng = np.random.default_rng(seed)
    X0, az_st = ring_stations() if stations is None else stations
    R = np.array([look_at(x) for x in X0])
    a = rng.uniform(0, 2 * np.pi, n_points)
    if control_sector is not None:
        a[:n_control] = np.radians(rng.uniform(-control_sector, control_sector, n_control))
    r = rng.uniform(0.1, 0.3, n_points)
    P = TARGET + np.c_[r * np.cos(a), r * np.sin(a), rng.uniform(-0.15, 0.15, n_points)]
    diff = np.angle(np.exp(1j * (a[None, :] - az_st[:, None])))
    vis = np.abs(np.degrees(diff)) < sector
    st, pt = np.nonzero(vis)
    return build(P, R, X0, st, pt, n_control, noise, rng)


def build(P, R, X0, st, pt, n_control, noise, rng):
    angles = matrix_to_opk(R)
    xy = BROWN.project(P[pt], angles[st], X0[st], IO)
    xy = xy + rng.normal(0, noise, xy.shape) if noise else xy
    n_st, n_pt = len(R), len(P)
    kind = np.array(["control"] * n_control + ["tie"] * (n_pt - n_control), dtype=object)
    xyz = np.full((n_pt, 3), np.nan)
    xyz[:n_control] = P[:n_control]
    cam = Camera("cam", "brown", {n: Parameter(float(v)) for n, v in
                                   zip(BROWN.parameter_names, IO)}, image_size=(640, 480))
    nan3 = np.full((n_st, 3), np.nan)
    project = Project(
        name="synthetic", cameras={"cam": cam},
        stations=Stations([f"S{i}" for i in range(n_st)], ["cam"] * n_st,
                          nan3.copy(), nan3.copy(), nan3.copy(), nan3.copy()),
        points=Points([f"P{j}" for j in range(n_pt)], kind, xyz, np.full((n_pt, 3), np.nan)),
        image_points=ImagePoints(st, pt, xy, np.full(len(st), 0.3), np.arange(len(st)) + 2))
    return project, P, R, X0


def errors(out, P, R, X0):
    pos = np.abs(out.stations.position - X0).max()
    Ro = opk_to_matrix(out.stations.angles)
    rot = np.abs(Ro - R).max()
    pts = np.abs(out.points.xyz - P).max()
    return pos, rot, pts


def drop_obs(project, keep):
    o = project.image_points
    ip = ImagePoints(o.station[keep], o.point[keep], o.xy[keep], o.sigma[keep], o.record[keep])
    return dataclasses.replace(project, image_points=ip)


# ----------------------------------------------------------------- synthetic --

def test_to_ideal_removes_distortion_and_principal_point():
    project, P, R, X0 = scene(1)
    xy, c = to_ideal(project)
    o = project.image_points
    want = project_ideal(P[o.point], R[o.station], X0[o.station], IO[0])
    assert np.abs(xy - want).max() < 1e-9
    assert np.all(c == IO[0])
    # explicit interior orientation values override the camera's
    io2 = IO.copy()
    io2[1] += 10.0
    xy2, _ = to_ideal(project, camera_values={"cam": io2})
    assert np.allclose(xy2, BROWN.correct(o.xy, io2), rtol=0, atol=1e-12)
    assert np.abs(xy2 - xy).max() > 9.0


def test_control_everywhere_noise_free():
    project, P, R, X0 = scene(2, control_sector=None, sector=181)
    out, rep = approximate(project)
    assert rep.frame == "control" and rep.complete
    assert rep.to_dict()["counts"]["stations_by_method"] == {"resection": 6}
    assert rep.to_dict()["counts"]["points_by_method"] == {"control": 6, "intersection": 54}
    pos, rot, pts = errors(out, P, R, X0)
    assert pos < 1e-8 and rot < 1e-9 and pts < 1e-8
    json.dumps(rep.to_dict())                        # serialisable for summary.json
    # the input project is not modified
    assert np.isnan(project.stations.position).all()
    assert np.isnan(project.points.xyz[6:]).all()
    # control coordinates are kept as they are
    assert np.array_equal(out.points.xyz[:6], project.points.xyz[:6])


def test_chain_propagates_over_rounds():
    """Control seen only near azimuth 0: the far stations are reached via
    intersected points in later rounds."""
    project, P, R, X0 = scene(3, n_points=80, n_control=5, control_sector=30, sector=100)
    o = project.image_points
    far = [s for s in range(6) if np.isin(np.arange(5), o.point[o.station == s]).sum() < 4]
    assert len(far) >= 2
    out, rep = approximate(project)
    assert rep.complete and rep.frame == "control"
    assert rep.rounds >= 2
    assert all(rep.stations[f"S{s}"]["round"] >= 2 for s in far)
    pos, rot, pts = errors(out, P, R, X0)
    assert pos < 1e-7 and rot < 1e-8 and pts < 1e-7


def test_no_control_relative_orientation_frame():
    project, P, R, X0 = scene(4, n_control=0, sector=120)
    out, rep = approximate(project)
    assert rep.frame == "model" and rep.complete
    assert rep.relative_orientation is not None
    a, b = rep.relative_orientation["pair"]
    assert rep.stations[a]["how"] == rep.stations[b]["how"] == "relative orientation"
    ia = project.stations.names.index(a)
    assert np.allclose(out.stations.position[ia], 0, atol=1e-12)
    assert np.allclose(out.stations.angles[ia], 0, atol=1e-12)
    # arbitrary frame: compare after a Helmert transformation to the truth
    h = helmert(np.r_[out.stations.position, out.points.xyz], np.r_[X0, P])
    assert np.abs(h.residuals).max() < 1e-7
    Rw = opk_to_matrix(out.stations.angles) @ h.R.T
    assert np.abs(Rw - R).max() < 1e-8


def test_three_control_points_helmert_into_control_frame():
    """No station sees 4 control points: relative orientation, then Helmert
    on the 3 control points."""
    project, P, R, X0 = scene(5, n_control=3, sector=181)
    out, rep = approximate(project)
    assert rep.frame == "control" and rep.complete
    assert rep.helmert is not None and len(rep.helmert["points"]) == 3
    assert rep.helmert["rms"] < 1e-8
    pos, rot, pts = errors(out, P, R, X0)
    assert pos < 1e-7 and rot < 1e-8 and pts < 1e-7


def test_noise_approximations_close_to_truth():
    project, P, R, X0 = scene(6, n_points=80, n_control=6, sector=120, noise=0.3)
    out, rep = approximate(project)
    assert rep.complete
    pos, rot, pts = errors(out, P, R, X0)
    # a 0.5 m object at 3 m: the resected distances are the weak part
    assert pos < 0.05 and rot < 0.015 and pts < 5e-3


def test_station_seeing_too_few_points_is_reported():
    project, P, R, X0 = scene(7, sector=181)
    o = project.image_points
    rows = np.nonzero(o.station == 2)[0]
    keep = np.ones(len(o.station), dtype=bool)
    keep[rows[2:]] = False                           # station S2 keeps 2 observations
    project = drop_obs(project, keep)
    out, rep = approximate(project)
    assert rep.unreached_stations == {"S2": "station S2: sees only 2 oriented points, needs 4"}
    assert "S2" not in rep.stations and len(rep.stations) == 5
    assert np.isnan(out.stations.position[2]).all()
    assert not rep.complete and "sees only 2" in rep.summary()
    pos = np.abs(np.delete(out.stations.position, 2, 0) - np.delete(X0, 2, 0)).max()
    assert pos < 1e-7


def test_point_seen_from_one_station_is_reported():
    project, P, R, X0 = scene(8, sector=181)
    o = project.image_points
    keep = ~((o.point == 10) & (o.station > 0))      # P10 only in S0
    keep &= ~(o.point == 11)                         # P11 nowhere
    project = drop_obs(project, keep)
    out, rep = approximate(project)
    assert rep.unreached_points["P10"] == (
        "point P10: seen from 1 oriented station (measured in 1 image), needs 2")
    assert rep.unreached_points["P11"] == "point P11: not measured in any image"
    assert np.isnan(out.points.xyz[[10, 11]]).all()
    assert len(rep.stations) == 6


def test_given_approximations_are_kept():
    project, P, R, X0 = scene(9, n_control=0, sector=181)
    st = project.stations
    pos, ang = st.position.copy(), st.angles.copy()
    pos[0] = X0[0] + 0.01                            # a given (slightly wrong) station
    ang[0] = matrix_to_opk(R[0]) + 0.001
    pos[1], ang[1] = X0[1], matrix_to_opk(R[1])
    xyz = project.points.xyz.copy()
    xyz[:5] = P[:5]                                  # given tie-point approximations
    project = dataclasses.replace(
        project, stations=dataclasses.replace(st, position=pos, angles=ang),
        points=dataclasses.replace(project.points, xyz=xyz))
    out, rep = approximate(project)
    assert rep.frame == "control" and rep.complete
    assert rep.stations["S0"]["how"] == rep.stations["S1"]["how"] == "given"
    assert np.array_equal(out.stations.position[:2], pos[:2])
    assert np.array_equal(out.stations.angles[:2], ang[:2])
    assert np.array_equal(out.points.xyz[:5], xyz[:5])
    assert rep.points["P0"]["how"] == "given"
    assert np.abs(out.stations.position[2:] - X0[2:]).max() < 0.05


def test_nothing_reachable_is_reported_not_raised():
    project, P, R, X0 = scene(10, n_points=12, n_control=0, sector=181)
    o = project.image_points
    keep = (o.point % 6) == (o.station % 6)          # no two stations share a point
    project = drop_obs(project, keep)
    out, rep = approximate(project)
    assert rep.frame == "none"
    assert len(rep.unreached_stations) == 6 and len(rep.unreached_points) == 12
    assert any("no pair of stations shares 5 points" in m for m in rep.messages)
    assert np.isnan(out.stations.position).all()
    json.dumps(rep.to_dict())


def test_bad_arguments():
    project, *_ = scene(11)
    with pytest.raises(InputError, match="min_points"):
        approximate(project, min_points=3)
    bad = dataclasses.replace(project, cameras={"cam": Camera(
        "cam", "brown", {"c": Parameter(1420.0)})})
    with pytest.raises(InputError, match="interior-orientation values"):
        approximate(bad)


def test_report_dataclass_defaults():
    rep = ChainReport()
    d = rep.to_dict()
    assert d["frame"] == "none" and d["complete"]
    json.dumps(d)


# ----------------------------------------------------------------- real data --

needs_camcal = pytest.mark.skipif(not (CAMCAL / "markpts.txt").exists(),
                                  reason="DBAT camcal data not available")

# DBAT's adjusted interior orientation (dbat-report.txt; mm, model 3):
# cc, px, py, K1, K2, K3, P1, P2, aspect (B1), skew (B2)
DBAT_IO_MM = np.array([7.457, 3.61546, 2.61329, 0.00458861, -4.51351e-05, -2.05253e-06,
                       -6.12803e-05, -4.41171e-05, 0.000389598, 0.0])


def camcal(control=True, calibrated=False):
    from photogram.io.dbat import load_dbat_project
    p = load_dbat_project(CAMCAL / "markpts.txt",
                          CAMCAL / "camcal-fixed.txt" if control else None,
                          CAMCAL / "c4040z.xml")
    if calibrated:
        cam = next(iter(p.cameras.values()))
        io = rescale_parameters("brown", DBAT_IO_MM, 1.0 / cam.pixel_size[0])
        for name, v in zip(cam.parameters, io):
            cam.parameters[name].value = float(v)
    return p


def dbat_stations():
    # "EO number, EO id, x, y, z, omega, phi, kappa, ...": the header says
    # degrees but the angles are radians (kappa = -3.14 for -179.8 deg)
    ref = np.loadtxt(CAMCAL / "dbat-camera_stations.txt", delimiter=",", comments="#",
                     usecols=range(2, 8))
    assert np.abs(ref[:, 3:]).max() < 3.3
    return ref[:, :3], opk_to_matrix(ref[:, 3:])


def rotation_errors_deg(A, B):
    c = (np.einsum("nij,nij->n", A, B) - 1) / 2
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


@needs_camcal
def test_camcal_nominal_camera_reaches_everything():
    project = camcal()
    assert len(project.stations) == 21 and len(project.image_points) == 2074
    out, rep = approximate(project)
    assert rep.complete and rep.frame == "control"
    assert len(rep.stations) == 21 and len(rep.points) == 100
    pos_ref, R_ref = dbat_stations()
    d = np.linalg.norm(out.stations.position - pos_ref, axis=1)
    # uncalibrated camera (nominal c, no distortion; DBAT finds 116 px of it):
    # measured max 0.116 m, median 0.061 m at 1.8-2.3 m distance
    assert d.max() < 0.15 and np.median(d) < 0.08
    ang = rotation_errors_deg(opk_to_matrix(out.stations.angles), R_ref)
    assert ang.max() < 4.0                           # measured 2.9 deg
    json.dumps(rep.to_dict())


@needs_camcal
def test_camcal_calibrated_camera_matches_dbat():
    """With DBAT's own interior orientation the chain's approximations are
    within 2 mm of DBAT's adjusted stations (which the convention checks:
    angles, image y axis, principal point, distortion signs)."""
    out, rep = approximate(camcal(calibrated=True))
    assert rep.complete
    pos_ref, R_ref = dbat_stations()
    d = np.linalg.norm(out.stations.position - pos_ref, axis=1)
    assert d.max() < 0.003                           # measured 1.5 mm
    ang = rotation_errors_deg(opk_to_matrix(out.stations.angles), R_ref)
    assert ang.max() < 0.1


@needs_camcal
def test_camcal_without_control_via_relative_orientation():
    out, rep = approximate(camcal(control=False, calibrated=True))
    assert rep.frame == "model" and rep.complete
    assert len(rep.stations) == 21 and len(rep.points) == 100   # 1001-1004 as tie points
    pos_ref, _ = dbat_stations()
    h = helmert(out.stations.position, pos_ref)
    rms = np.sqrt(np.mean(np.sum(h.residuals ** 2, axis=1)))
    assert rms < 0.002                               # measured 0.6 mm
