"""Issue 16, item 10 (mocap): detections that locate no joint are refused
(one line, exit 2), camera angles in the wrong unit are refused (radians
declared, degrees given) or warned about (degrees declared, radians given),
and a reconstruction that does not fit a camera says so."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.mocap.evaluation.checks import POOR_FIT, check_angle_unit, check_coverage, check_fit
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    from photogram.simulation.ski.simproject import write_simulated_project
    from photogram.simulation.ski.simulate import simulate_session
    folder = tmp_path_factory.mktemp("ski-base")
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=20)
    write_simulated_project(sim, folder, name="ski")
    return folder


@pytest.fixture
def project(base, tmp_path):
    shutil.copytree(base, tmp_path / "p")
    return tmp_path / "p" / "ski.prj"


def _edit_rows(path, edit):
    """Apply ``edit(header, fields)`` to every data row of a CSV with comments."""
    out, header = [], None
    for line in path.read_text().splitlines():
        if line.startswith("#"):
            out.append(line)
        elif header is None:
            header = line.split(",")
            out.append(line)
        else:
            fields = edit(header, line.split(","))
            if fields is not None:
                out.append(",".join(fields))
    path.write_text("\n".join(out) + "\n")


def _to_radians(header, f):
    for k in ("omega", "phi", "kappa"):
        i = header.index(k)
        f[i] = f"{math.radians(float(f[i])):.9f}"
    return f


def _run_error(prj, capsys):
    capsys.readouterr()
    assert main(["mocap", "--no-report", str(prj)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.splitlines() == [err.strip()], err
    return err.strip()


def test_a_good_project_has_no_warnings(project, capsys):
    assert main(["mocap", "--no-report", "--no-figures", "-q", str(project)]) == 0
    s = json.loads((project.parent / "results" / "summary.json").read_text())
    assert s["warnings"] == []                    # no false alarm on a correct project
    assert s["accuracy"]["mpjpe"] < 0.05


def test_detections_of_one_camera_are_refused(project, capsys):
    det = project.parent / "detections.csv"
    _edit_rows(det, lambda h, f: f if f[h.index("camera")] == "C1" else None)
    err = _run_error(project, capsys)
    assert err.startswith(f"{det}: nothing to reconstruct: only camera C1 has detections")
    assert "none from C2, C3, C4, C5, C6" in err
    assert not (project.parent / "results").exists()


def test_every_confidence_zero_is_refused(project, capsys):
    det = project.parent / "detections.csv"
    _edit_rows(det, lambda h, f: f[:h.index("confidence")] + ["0"])
    err = _run_error(project, capsys)
    assert err.startswith(f"{det}: nothing to reconstruct: no detection of cameras C1, C2, C3, "
                          f"C4, C5, C6 in frames 0..19 has a confidence > 0")


def test_cameras_that_never_see_a_joint_together_are_refused(project, capsys):
    """C1 sees frames 0-9, C2 frames 10-19, no other camera: no joint-frame
    has two cameras (the count of each camera's detections is named)."""
    det = project.parent / "detections.csv"
    counts = {"C1": 0, "C2": 0}

    def keep(h, f):
        cam, frame = f[h.index("camera")], int(f[h.index("frame")])
        if (cam == "C1" and frame < 10) or (cam == "C2" and frame >= 10):
            counts[cam] += float(f[h.index("confidence")]) > 0
            return f
        return None
    _edit_rows(det, keep)
    err = _run_error(project, capsys)
    assert "no joint is seen by two cameras in the same frame" in err
    assert f"C1 {counts['C1']}, C2 {counts['C2']}, C3 0" in err


def test_degrees_declared_as_radians_are_refused(project, capsys):
    text = project.read_text()
    project.write_text(text.replace('angle_unit = "deg"', 'angle_unit = "rad"'))
    st = project.parent / "stations.csv"
    rows = [ln.split(",") for ln in st.read_text().splitlines() if not ln.startswith("#")]
    values = np.array([[float(v) for v in r[5:8]] for r in rows[1:]])
    line = 5 + int(np.argmax(np.abs(values).max(axis=1)))    # 3 comments, header, rows
    err = _run_error(project, capsys)
    assert err.startswith(f"{st}:{line}: an angle of the stations table is "
                          f"{np.abs(values).max():g} but angle_unit is rad")
    assert 'set angle_unit = "deg"' in err
    # stations in radians, camera_frames still in degrees: refused at camera_frames.csv
    _edit_rows(st, _to_radians)
    cf = project.parent / "camera_frames.csv"
    err = _run_error(project, capsys)
    assert err.startswith(f"{cf}:") and "camera_frames.csv (omega, phi, kappa)" in err


def test_radians_declared_as_degrees_are_warned_and_the_misfit_named(project, capsys):
    _edit_rows(project.parent / "stations.csv", _to_radians)
    _edit_rows(project.parent / "camera_frames.csv", _to_radians)
    assert main(["mocap", "--no-report", "--no-figures", str(project)]) == 0
    out = capsys.readouterr().out
    w = json.loads((project.parent / "results" / "summary.json").read_text())["warnings"]
    # the seventh, "camera residuals stand out" (check_outliers), compares
    # the cameras with each other: here every camera is wrong (median errors
    # 48-244 px), so whether C1 stands out among them is not decided by the
    # wrong unit; it did on one machine and not on another (2026-12-04, an
    # AVX-512 BLAS). The six warnings about the unit and the misfit are the
    # point of this test, and are always there.
    assert len(w) in (6, 7)
    assert f"{len(w)} warning(s) in summary.json" in out
    assert w[0].startswith("every angle of the stations table is within 2 pi") and \
        "look like radians" in w[0]
    assert w[1].startswith("every angle of camera_frames.csv (omega, phi, kappa) is within 2 pi")
    # joints the wrong cameras put behind themselves or cannot fit are gaps
    # (issue 22), which splits the post-filter's runs
    assert "are gaps" in w[2] and "behind the cameras" in w[2] and "cameras disagree" in w[2]
    assert w[3].startswith("filter: ")
    assert w[4].startswith(f"median reprojection error above {100 * POOR_FIT:g} % of the image "
                           f"width: C1 ")
    assert w[5].startswith("static bias")
    if len(w) == 7:
        assert w[6].startswith("camera residuals stand out") and "C1 " in w[6]   # check_outliers


def test_coverage_counts_a_pair_of_cameras_above_min_confidence():
    F, C, J = 3, 3, 4
    obs = np.full((F, C, J, 3), np.nan)
    obs[..., 2] = 0.0
    obs[1, 0, 2] = (10, 20, 0.9)                   # joint 2, frame 1: cameras 0 and 2
    obs[1, 2, 2] = (11, 21, 0.4)
    obs[0, 1, 0] = (5, 5, 0.9)                     # camera 1 alone
    names, joints = ["A", "B", "C"], ["j0", "j1", "j2", "j3"]
    warnings = check_coverage(obs, names, joints, np.arange(F), 0.0)
    assert warnings[0].startswith("3 joint(s) never seen by two cameras at once") and \
        "(j0, j1, j3)" in warnings[0]
    assert len(warnings) == 1                      # every camera has a detection that counts
    with pytest.raises(InputError, match="no joint is seen by two cameras"):
        check_coverage(obs, names, joints, np.arange(F), 0.5)    # camera C's 0.4 no longer counts
    obs[1, 2, 2, 0] = np.nan                       # a confidence without a position
    with pytest.raises(InputError):
        check_coverage(obs, names, joints, np.arange(F), 0.0)


def test_angle_unit_limits():
    assert check_angle_unit([[0.1, -6.28, 3.0]], "rad", "t") is None
    with pytest.raises(InputError, match="look like degrees") as exc:
        check_angle_unit([[0.1, 0.2, 0.3], [90.0, 1.0, 2.0]], "rad", "t", "f.csv", [7, 8])
    assert exc.value.line == 8
    with pytest.raises(InputError, match="look like gon or degrees"):
        check_angle_unit([[390.0, 0, 0]], "rad", "t")
    assert "look like radians" in check_angle_unit([[1.5, -3.1, 0.2]], "deg", "t")
    assert check_angle_unit([[1.5, -3.1, 90.0]], "deg", "t") is None
    assert check_angle_unit([[0.0, 0.0, 0.0]], "gon", "t") is None     # nothing to judge


def test_fit_threshold_is_five_percent_of_the_width():
    rep = {"A": {"median_px": 0.05 * 1920}, "B": {"median_px": 0.05 * 1920 + 1},
           "C": {"median_px": None}, "D": {"median_px": 5000.0}}
    w = check_fit(rep, np.array([1920.0, 1920.0, 1920.0, np.nan]))
    assert len(w) == 1 and ": B 97 px (5 %);" in w[0] and "A " not in w[0]
