"""Degenerate and weak geometry (issue 12, item 3).

Every case goes through the library and through the command line: a clear
one-line message naming the stations/points and what is missing, exit code
2, and never NaN or infinity in a file that is written (if a results folder
is written at all, it is a valid one). Points whose largest intersection
angle is below :data:`photogram.stats.geometry.WEAK_ANGLE_DEG` are flagged.
"""

import dataclasses
import json
import math

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.errors import GeometryError, InputError
from photogram.init.chain import approximate
from photogram.init.dlt import dlt
from photogram.project import write_project
from photogram.simulation.network import frame_network, look_at, observe, ring_stations, to_project
from photogram.stats.geometry import (
    WEAK_ANGLE_DEG, intersection_angles, weak_angle_warning, weak_points)
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

IO = np.array((1420.0, 320.0, 240.0, -5e-8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


# ----------------------------------------------------------------- helpers
def write(tmp_path, prj, datum="control"):
    prj.adjustment.datum = datum
    k = len(list(tmp_path.glob("net*")))
    path = tmp_path / f"net{k}" / "net.prj"
    path.parent.mkdir()
    write_project(prj, path)
    return path


def run(capsys, tmp_path, prj, command="orient", datum="control"):
    out = tmp_path / f"r{len(list(tmp_path.glob('net*')))}"
    code = main([command, "--no-report", str(write(tmp_path, prj, datum)), "--output", str(out)])
    err = capsys.readouterr().err
    return code, err, out


def one_line(err):
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "internal error" not in err, err
    return err


def assert_no_nan_written(folder):
    """Every text file of a results folder is free of NaN/inf; summary.json
    is strict JSON; the folder reads back."""
    if not folder.exists():
        return
    from photogram.project.results import read_results
    for path in folder.iterdir():
        if path.suffix in (".json", ".csv", ".toml", ".txt"):
            text = path.read_text(encoding="utf-8").lower()
            for bad in ("nan", "inf"):
                # whole tokens only (a station may be called "Info")
                tokens = text.replace(",", " ").replace("\"", " ").replace("=", " ").split()
                assert not any(t.strip("-+:;()[]") in (bad, "infinity") for t in tokens), \
                    f"{bad} in {path.name}"
    summary = json.loads((folder / "summary.json").read_text(),
                         parse_constant=lambda c: pytest.fail(f"{c} in summary.json"))
    assert summary["status"]
    read_results(folder)


def frame(**kw):
    net = frame_network(sigma=0.3, n_stations=6, n_points=30, seed=1)
    return net, to_project(net, control=[0, 1, 2, 3], rng=np.random.default_rng(0), **kw)


def drop_observations(prj, keep):
    ip = prj.image_points
    prj.image_points = dataclasses.replace(
        ip, station=ip.station[keep], point=ip.point[keep], xy=ip.xy[keep],
        sigma=ip.sigma[keep], record=ip.record[keep])
    return prj


# ---------------------------------------------- coplanar control for DLT
def coplanar_network():
    """Ring of stations over a flat target field (all points on z = 0)."""
    rng = np.random.default_rng(3)
    pts = np.c_[rng.uniform(-0.25, 0.25, (30, 2)), np.zeros(30)]
    X0, R = ring_stations(6, 2.0, 1.0, np.array([0.0, 0.0, 0.0]), jitter=0.05, rng=rng)
    net = observe("brown", IO, np.zeros(6, int), R, X0, pts, (640, 480), sigma=0.3, rng=rng)
    return net, to_project(net, control=range(8), rng=rng)


def test_coplanar_control_dlt_refuses_and_chain_falls_back(tmp_path, capsys):
    net, prj = coplanar_network()
    rows = net.station == 0
    with pytest.raises(GeometryError, match="non-coplanar control points; the 30 points lie"):
        dlt(net.points[net.point[rows]], net.xy[rows])
    # the chain does not need the DLT: planar resection of every station
    prj.stations.position[:] = np.nan
    prj.stations.angles[:] = np.nan
    prj.points.xyz[prj.points.kind == "tie"] = np.nan
    out, rep = approximate(prj)
    assert rep.complete and rep.frame == "control"
    assert {v["how"] for v in rep.stations.values()} == {"resection"}
    assert np.all(np.isfinite(out.stations.position))
    # orient (interior fixed) through the command: runs, exit 0, no NaN
    code, err, folder = run(capsys, tmp_path, prj, "orient")
    assert code == 0, err
    assert_no_nan_written(folder)
    s = json.loads((folder / "summary.json").read_text())
    assert s["approximation"]["counts"]["stations_by_method"] == {"resection": 6}


# --------------------------------------------------- all stations on one line
def line_network():
    """Forward motion: 4 stations on the X axis, all looking along it; P1 lies
    on that line (its rays coincide), the other points are off it."""
    rng = np.random.default_rng(0)
    X0 = np.c_[np.linspace(0.0, 2.0, 4), np.zeros(4), np.zeros(4)]
    R = look_at(X0, X0 + [10.0, 0.0, 0.0])
    pts = np.c_[rng.uniform(7, 10, 30), rng.uniform(-1, 1, 30), rng.uniform(-0.8, 0.8, 30)]
    pts[0] = [8.0, 0.0, 0.0]
    net = observe("brown", IO, np.zeros(4, int), R, X0, pts, (640, 480), sigma=0.3, rng=rng)
    assert np.all(np.bincount(net.point) == 4)
    return net, to_project(net, control=range(1, 9), rng=rng)


def test_collinear_stations_point_on_the_baseline_is_named(tmp_path, capsys):
    net, prj = line_network()
    ang = intersection_angles(net.points, net.X0, net.station, net.point)
    assert ang[0] < 1e-6 and np.all(ang[1:] > 0.1)
    prj.points.xyz[0] = np.nan                     # P1 unknown: must be intersected
    out, rep = approximate(prj)
    assert "P1" in rep.unreached_points
    reason = rep.unreached_points["P1"]
    assert "rays nearly parallel" in reason and "S1, S2, S3, S4" in reason
    with pytest.raises(InputError, match=r"no approximate values for point\(s\) P1 \(P1: rays nearly parallel"):
        build_problem(out)
    code, err, folder = run(capsys, tmp_path, prj, "orient")
    assert code == 2
    one_line(err)
    assert "no approximate values" in err and "P1" in err and "rays nearly parallel" in err
    assert "S1, S2, S3, S4" in err
    assert not folder.exists()


# ------------------------------------------------- two rays almost parallel
def parallel_network():
    """The frame network plus S7 1 cm beside S1; P30 is measured only in S1
    and S7 (intersection angle about 0.3 deg); every other point is strong."""
    net = frame_network(sigma=0.3, n_stations=6, n_points=30, seed=1)
    X0 = np.vstack([net.X0, net.X0[0] + [0.0, 0.0, 0.01]])
    R = np.concatenate([net.R, net.R[:1]])
    rng = np.random.default_rng(5)
    big = observe("brown", IO, np.zeros(7, int), R, X0, net.points, (640, 480),
                  sigma=0.3, rng=rng)
    keep = (big.point != 29) | np.isin(big.station, [0, 6])
    keep &= (big.station != 6) | (big.point == 29) | (big.point < 12)
    big = dataclasses.replace(big, station=big.station[keep], point=big.point[keep],
                              xy=big.xy[keep], xy_true=big.xy_true[keep])
    return big, to_project(big, control=[0, 1, 2, 3], rng=rng)


def test_almost_parallel_rays(tmp_path, capsys):
    net, prj = parallel_network()
    ang = intersection_angles(net.points, net.X0, net.station, net.point)
    assert ang[29] < 1.0 and np.all(ang[:29] > 10)
    weak = weak_points(ang)
    assert weak.tolist() == [False] * 29 + [True]
    w = weak_angle_warning(prj.points.ids, ang)
    assert w.startswith("1 point(s) with intersection angle below 5 deg") and "P30" in w
    # without an approximate value the chain cannot intersect P30: one line,
    # naming the point, its two stations and the angle
    unknown = dataclasses.replace(prj, points=dataclasses.replace(prj.points,
                                                                  xyz=prj.points.xyz.copy()))
    unknown.points.xyz[29] = np.nan
    code, err, folder = run(capsys, tmp_path, unknown, "orient")
    assert code == 2
    one_line(err)
    assert "P30" in err and "rays nearly parallel" in err and "S1, S7" in err
    assert not folder.exists()


def test_almost_parallel_rays_with_approximation_is_flagged(tmp_path, capsys):
    net, prj = parallel_network()
    code, err, folder = run(capsys, tmp_path, prj, "orient")
    assert code == 0, err
    assert_no_nan_written(folder)
    # the report's angles (from the results folder) agree and flag P30 only
    from photogram.report.data import load
    from photogram.report.pages_geometry import weak_angle_points
    data = load(folder)
    assert data.rays.loc["P30", "angle"] < 1.0
    assert weak_angle_points(data) == ["P30"]


def test_almost_parallel_rays_flagged_by_intersection_with_fixed_stations():
    """The intersect step (photogram intersect: stations fixed) puts the
    weak points into its summary warnings, which go into summary.json."""
    from photogram.jump.pipeline import intersect_points
    net, prj = parallel_network()
    _, cov, _, summary = intersect_points(prj)
    weak = [w for w in summary["warnings"] if "intersection angle below" in w]
    assert len(weak) == 1 and "P30" in weak[0] and weak[0].startswith("1 point(s)")
    assert np.all(np.isfinite(cov))


def test_weak_point_flag_in_summary_and_points_csv(tmp_path, capsys):
    import pandas as pd
    net, prj = parallel_network()
    code, err, folder = run(capsys, tmp_path, prj, "orient")
    assert code == 0, err
    s = json.loads((folder / "summary.json").read_text())
    assert any("P30" in w and "intersection angle below" in w for w in s["warnings"])
    pts = pd.read_csv(folder / "points.csv", comment="#")
    flagged = pts.loc[pts["est_weak_angle"] == 1, "id"].tolist()
    assert flagged == ["P30"]
    assert pts.loc[pts["id"] == "P30", "est_angle"].iloc[0] < 1.0
    assert s["weak_points"] == {"threshold_deg": WEAK_ANGLE_DEG, "count": 1, "ids": ["P30"]}
    # points.csv stays valid as an input table (est_ columns are ignored)
    from photogram.project.tables import _ignored
    assert _ignored("est_angle") and _ignored("est_weak_angle")


# ------------------------------------------------ a station seeing nothing
def test_station_seeing_nothing_is_named(tmp_path, capsys):
    net, prj = frame()
    drop_observations(prj, prj.image_points.station != 2)
    with pytest.raises(GeometryError, match="station S3 sees nothing"):
        build_problem(prj)
    code, err, folder = run(capsys, tmp_path, prj, "calibrate")
    assert code == 2
    assert one_line(err).startswith("station S3 sees nothing: no image observations")
    assert not folder.exists()
    # also when S3 has no approximate values (the chain runs first)
    prj.stations.position[2] = np.nan
    prj.stations.angles[2] = np.nan
    code, err, folder = run(capsys, tmp_path, prj, "orient")
    assert code == 2 and one_line(err).startswith("station S3 sees nothing")


# --------------------------------------------------------- a datum defect
def test_datum_defect_names_what_is_missing(tmp_path, capsys):
    net, prj = frame()
    prj.points.kind[:] = "tie"
    with pytest.raises(GeometryError, match="datum defect 7: no control, no distance, "
                                            "no inner constraints"):
        from photogram.bundle import adjust
        adjust(prj)
    code, err, folder = run(capsys, tmp_path, prj, "calibrate")
    assert code == 2
    assert one_line(err).startswith("datum defect 7: no control, no distance, "
                                    "no inner constraints (undetermined: translation X")
    assert not folder.exists()


# ------------------------------------------------------- a divergent start
def test_divergent_start_names_the_worst_stations_and_points(tmp_path, capsys):
    net, prj = frame(perturb_points=5.0, perturb_stations=3.0)
    prj.adjustment.max_iterations = 5
    code, err, folder = run(capsys, tmp_path, prj, "orient")
    assert code == 2
    one_line(err)
    assert err.startswith("no convergence in 5 iterations; largest image residuals: stations S")
    assert "; points P" in err
    # the unconverged results are written, valid and without NaN
    assert_no_nan_written(folder)
    assert json.loads((folder / "summary.json").read_text())["status"] == "max_iterations"


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_non_finite_iteration_is_a_geometry_error_naming_observations():
    from photogram.adjust.solver import SolverOptions, solve
    net, prj = frame()
    built = build_problem(prj)
    built.problem.state.points[5] = built.problem.state.X0[0]     # point at a centre
    with pytest.raises(GeometryError, match="non-finite residuals .*S1/P6"):
        solve(built.problem, SolverOptions())


# --------------------------------------------------------- angle helpers
def test_intersection_angles_edge_cases():
    X = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [np.nan, 0, 0]])
    C = np.array([[0.0, 0.0, 10.0], [10.0, 0.0, 10.0], [0.0, 0.0, 10.0]])
    a = intersection_angles(X, C, [0, 1, 0, 0, 1], [0, 0, 1, 2, 2])
    assert math.isclose(a[0], 45.0)
    assert np.isnan(a[1]) and np.isnan(a[2])
    assert not weak_points(a).any()
    assert weak_angle_warning(["A", "B", "C"], a) is None
    assert WEAK_ANGLE_DEG == 5.0


def test_several_blind_stations_are_all_named():
    net, prj = frame()
    drop_observations(prj, ~np.isin(prj.image_points.station, [1, 4]))
    with pytest.raises(GeometryError, match="stations S2, S5 see nothing"):
        build_problem(prj)
