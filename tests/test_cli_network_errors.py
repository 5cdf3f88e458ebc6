"""Networks that cannot be solved end with one clear line and exit code 2,
never with NaN in the results."""

import json

import numpy as np
import pytest

from photogram.project import write_project
from photogram.simulation.network import frame_network, to_project
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def write(tmp_path, prj):
    prj.adjustment.datum = "control"
    path = tmp_path / "net" / "net.prj"
    path.parent.mkdir()
    write_project(prj, path)
    return path


def network(**kw):
    net = frame_network(sigma=0.3, n_stations=6, n_points=30, seed=1)
    return to_project(net, control=[0, 1, 2, 3], free_interior=("c",),
                      rng=np.random.default_rng(0), **kw)


def run(capsys, *argv):
    code = main([argv[0], "--no-report", *argv[1:]])   # the report is not under test
    err = capsys.readouterr().err
    return code, err


def test_datum_defect_is_one_line(tmp_path, capsys):
    prj = network()
    prj.points.kind[:] = "tie"
    code, err = run(capsys, "calibrate", str(write(tmp_path, prj)), "--output", str(tmp_path / "r"))
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "datum defect 7: no control, no distance, no inner constraints" in err
    assert not (tmp_path / "r").exists()


def test_no_convergence_is_reported_and_results_hold_no_nan(tmp_path, capsys):
    prj = network(perturb_points=0.05, perturb_stations=0.05)
    prj.adjustment.max_iterations = 1
    out = tmp_path / "r"
    code, err = run(capsys, "calibrate", str(write(tmp_path, prj)), "--output", str(out))
    assert code == 2
    assert "no convergence in 1 iterations" in err and err.count("\n") == 1
    text = (out / "summary.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text)["status"] == "max_iterations"


def test_point_at_a_projection_centre_is_named(tmp_path, capsys):
    prj = network()
    i = int(np.flatnonzero(prj.points.kind == "tie")[0])
    prj.points.xyz[i] = prj.stations.position[0]
    code, err = run(capsys, "orient", str(write(tmp_path, prj)), "--output", str(tmp_path / "r"))
    assert code == 2 and err.count("\n") == 1
    assert "non-finite residuals" in err and prj.points.ids[i] in err


@pytest.mark.parametrize("command", ["calibrate", "orient"])
def test_good_network_runs_with_exit_zero(tmp_path, capsys, command):
    code, err = run(capsys, command, str(write(tmp_path, network())), "--output", str(tmp_path / "r"))
    assert code == 0, err
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["status"] == "converged" and 0.8 < s["sigma0"] < 1.2


def test_datum_defect_in_a_real_process_prints_exactly_one_line(tmp_path):
    import subprocess
    import sys
    prj = network()
    prj.points.kind[:] = "tie"
    path = write(tmp_path, prj)
    proc = subprocess.run([sys.executable, "-m", "photogram_cli", "calibrate", str(path),
                           "--output", str(tmp_path / "r")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("datum defect 7")
    assert proc.stdout == ""
