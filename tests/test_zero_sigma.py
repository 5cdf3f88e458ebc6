"""Issue 16, item 5: an a-priori sigma of 0 means "fixed", as the docs say
(station sigmas sX0 ... skappa, control sigmas sX sY sZ, sigma_control),
in the engine (which Monte Carlo runs too); it used to become weight
0 (the parameter free, or "datum defect 7")."""

import numpy as np
import pytest

from field_copy import field_copy
from photogram.adjust.build import build_problem
from photogram.adjust.datum import check_datum
from photogram.adjust.solver import solve
from photogram.bundle import adjust
from photogram.errors import InputError
from photogram.geometry import opk_to_matrix
from photogram.project import read_project
from photogram.simulation.network import frame_network, to_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _stations_fixed_by_sigma_zero():
    net = frame_network(sigma=0.3, n_stations=8, n_points=40, seed=4)
    prj = to_project(net, perturb_points=0.01, rng=np.random.default_rng(2))  # exact stations
    prj.adjustment.datum = "weighted"                   # no control points at all
    prj.stations.position_sigma = np.zeros((8, 3))
    prj.stations.angle_sigma = np.zeros((8, 3))
    return net, prj


def test_station_sigma_zero_fixes_the_stations():
    net, prj = _stations_fixed_by_sigma_zero()
    built = build_problem(prj)
    p = built.problem
    check_datum(p, built.present)          # was: datum defect 7 (weight 0 = free)
    s = solve(p)
    assert s.status == "converged"
    np.testing.assert_array_equal(p.state.X0, prj.stations.position)
    np.testing.assert_allclose(p.state.R, opk_to_matrix(prj.stations.angles), rtol=0, atol=1e-15)
    # the stations are fixed, not observed: r = 2 n_img - 3 n_points
    assert s.redundancy == 2 * len(prj.image_points) - 3 * len(prj.points)
    assert p.layout.free[p.layout.station_cols].sum() == 0
    # the points come out at the truth (0.3 px noise at 2 m: < 1 mm)
    assert np.max(np.abs(p.state.points - net.points)) < 1e-3


def test_one_zero_position_sigma_fixes_that_coordinate_only():
    net, prj = _stations_fixed_by_sigma_zero()
    prj.stations.position_sigma = np.full((8, 3), 0.01)
    prj.stations.angle_sigma = np.full((8, 3), 0.01)
    prj.stations.position_sigma[3, 2] = 0.0             # Z0 of S4 fixed
    prj.stations.position = prj.stations.position + 0.003
    built = build_problem(prj)
    solve(built.problem)
    X0 = built.problem.state.X0
    assert X0[3, 2] == prj.stations.position[3, 2]
    assert abs(X0[3, 1] - prj.stations.position[3, 1]) > 1e-6     # weighted: moves


def test_zero_sigma_for_some_angles_is_refused():
    _, prj = _stations_fixed_by_sigma_zero()
    prj.stations.angle_sigma = np.full((8, 3), np.nan)
    prj.stations.angle_sigma[1, 2] = 0.0
    prj.stations.record = np.arange(8) + 4
    with pytest.raises(InputError, match=r"station S2: a sigma of 0 .* somega sphi skappa") as e:
        build_problem(prj)
    assert e.value.line == 5


def _zero_sigmas(text):
    assert ",0.12,0.12,0.12" in text
    return text.replace(",0.12,0.12,0.12", ",0,0,0")


def _no_sigmas(text):
    return text.replace(",0.12,0.12,0.12", ",,,")


@pytest.mark.parametrize("how", ["table", "sigma_control"])
def test_control_sigma_zero_is_the_control_datum(tmp_path, how):
    ref = adjust(read_project(field_copy(tmp_path / "a", adjustment={"datum": '"control"'})),
                 fix_interior=True)
    if how == "table":
        prj = field_copy(tmp_path / "b", **{"field_points.csv": _zero_sigmas})
    else:
        prj = field_copy(tmp_path / "b", adjustment={"sigma_control": "0.0"},
                         **{"field_points.csv": _no_sigmas})
    project = read_project(prj)
    assert project.adjustment.datum == "weighted"
    res = adjust(project, fix_interior=True)         # was: "control point(s) ... have no sigma"
    control = np.asarray(project.points.kind) == "control"
    np.testing.assert_array_equal(res.project.points.xyz[control], project.points.xyz[control])
    np.testing.assert_allclose(res.project.stations.position, ref.project.stations.position,
                               rtol=0, atol=1e-8)
    np.testing.assert_allclose(res.project.points.xyz, ref.project.points.xyz, rtol=0, atol=1e-8)
    assert res.summary["redundancy"] == ref.summary["redundancy"]
    np.testing.assert_allclose(res.station_sigma, ref.station_sigma, rtol=1e-6)


def test_monte_carlo_bundle_holds_zero_sigma_stations(tmp_path):
    """Monte Carlo runs the engine's problem: a station sigma of 0 fixes
    the station (no column, no noise), as in photogram orient."""
    from photogram.montecarlo.adjustment import EngineBundle
    _, prj = _stations_fixed_by_sigma_zero()
    eb = EngineBundle(prj, fix_interior=True)
    assert len(eb.prior_stations) == 8
    assert np.all(eb.input_sigmas().station_prior == 0)
    assert not eb.layout.free[eb.station_cols].any()


# Issue 16, item 6: with datum = "control" the control sigmas are not used;
# the run says so in log.txt and summary.json.

def test_control_datum_says_that_control_sigmas_are_ignored(tmp_path, capsys):
    import json
    from photogram_cli.main import main
    prj = field_copy(tmp_path, adjustment={"datum": '"control"'})
    assert main(["orient", "--no-report", "-q", str(prj), "--output", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    text = [w for w in summary["warnings"] if w.startswith('datum = "control"')]
    assert len(text) == 1
    assert "sigmas sX sY sZ of 15 control point(s) (M1, M2, M3, M4, M5 ...)" in text[0]
    assert "not used" in text[0]
    assert "warning: " + text[0] in (tmp_path / "out" / "log.txt").read_text()


def test_weighted_datum_and_control_without_sigmas_do_not_warn(tmp_path):
    res = adjust(read_project(field_copy(tmp_path / "a")), fix_interior=True)
    assert not [w for w in res.summary["warnings"] if "not used" in w]
    res = adjust(read_project(field_copy(tmp_path / "b", adjustment={"datum": '"control"'},
                                         **{"field_points.csv": _no_sigmas})), fix_interior=True)
    assert not [w for w in res.summary["warnings"] if "not used" in w]
