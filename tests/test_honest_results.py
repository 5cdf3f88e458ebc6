"""Honest outputs (issue 16, items 2, 16, 20): sigmas of camera-to-world
angles propagated through the conversion, result files with the umask's
mode, user strings escaped in the headers of TOML, CSV and TRC files."""

from __future__ import annotations

import os
import stat
import tomllib

import numpy as np
import pytest

from photogram.project import read_project, read_results, write_results
from photogram.project.atomic import atomic_write_text
from photogram.project.results import RESULT_FILES

from project_cases import DATA

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


# ---------------------------------------------------------------- item 16


@pytest.fixture
def umask():
    """Set the process umask for one test, restore it afterwards."""
    old = os.umask(0o022)
    yield lambda mask: os.umask(mask)
    os.umask(old)


def _mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o027, 0o002])
def test_result_files_get_the_umask_mode_not_0600(tmp_path, umask, mask):
    umask(mask)
    project = read_project(DATA / "lab" / "lab.prj")
    folder = write_results(tmp_path / "results", project, {"status": "converged"})
    for name in RESULT_FILES:
        assert _mode(folder / name) == 0o666 & ~mask, name
    # a replaced file keeps the mode its owner gave it, as after an editor's save
    os.chmod(folder / "log.txt", 0o600)
    atomic_write_text(folder / "log.txt", "again\n")
    assert _mode(folder / "log.txt") == 0o600
    assert (folder / "log.txt").read_text() == "again\n"


def test_mocap_videos_and_rotation_differences_get_the_umask_mode(tmp_path, umask):
    """The two writers of mocap that call mkstemp themselves."""
    from photogram.mocap.motion.homography import RotationDifferences
    from photogram.mocap.motion.rotation_series import write_rotation_differences
    from photogram.simulation.ski.render import write_video
    umask(0o027)
    write_video(tmp_path / "c1.avi", [np.zeros((32, 48, 3), np.uint8)] * 3, 25)
    rd = RotationDifferences(dR=np.tile(np.eye(3), (2, 1, 1)), inliers=np.array([9, 9]),
                             matches=np.array([10, 10]), ok=np.array([True, True]),
                             seconds=0.0, frames=3)
    write_rotation_differences(tmp_path / "rd.csv", {"C1": rd})
    assert _mode(tmp_path / "c1.avi") == 0o640
    assert _mode(tmp_path / "rd.csv") == 0o640


# ---------------------------------------------------------------- item 20

HOSTILE = 'lab\nsecond line\r\x07 "quoted" \\ \u2028end'


def test_project_name_with_line_break_is_escaped_in_cameras_toml(tmp_path):
    """A project name with line breaks and control characters stays on its
    comment line of results/cameras.toml, which reads back (TOML forbids
    control characters in comments), with the name intact."""
    project = read_project(DATA / "lab" / "lab.prj")
    project.name = HOSTILE
    folder = write_results(tmp_path / "results", project, {"status": "converged"})
    text = (folder / "cameras.toml").read_text(encoding="utf-8")
    head = text.split("\n[", 1)[0].rstrip("\n").split("\n")
    assert len(head) == 2 and all(line.startswith("# ") for line in head), head
    assert head[0].endswith(r'from "lab\nsecond line\r\u0007 \"quoted\" \\ \u2028end"')
    doc = tomllib.loads(text)
    assert doc["project"]["name"] == HOSTILE
    back = read_results(folder)                      # the command re-reads its output
    assert set(back.cameras) == set(project.cameras)
    assert back.summary["project"]["name"] == HOSTILE


def test_comment_lines_of_csv_and_toml_escape_control_characters():
    from photogram.project.tables import format_table
    from photogram.project.toml_writer import dumps
    csv = format_table({"a": [1.0]}, comment="made from \x1b[31m" + HOSTILE)
    lines = csv.split("\n")
    # one comment line per "\n" of the comment; nothing else ends a line
    assert lines[0] == r"# made from \u001B[31mlab" and lines[1].startswith("# second line")
    assert lines[2] == "a" and len(csv.splitlines()) == 4
    toml = dumps({"x": {"y": 1}}, header="a\x00b", comments={("x",): "c\rd"})
    assert toml.splitlines()[0] == r"# a\u0000b" and r"# c\u000Dd" in toml
    assert tomllib.loads(toml) == {"x": {"y": 1}}


def test_trc_header_escapes_marker_and_file_names(tmp_path):
    from photogram.io.trc import read_trc, write_trc
    t = np.arange(3) / 50.0
    xyz = np.arange(9.0).reshape(3, 3)
    names = {"head\tleft": xyz, "knee\nR": xyz + 1, "plain": xyz + 2}
    path = write_trc(tmp_path / "jump\t1.trc", t, names, rotate_to_y_up=False)
    lines = path.read_text().split("\n")
    assert lines[0].split("\t") == ["PathFileType", "4", "(X/Y/Z)", r'"jump\t1.trc"']
    header = lines[3].split("\t")
    assert header == ["Frame#", "Time", r'"head\tleft"', "", "", r'"knee\nR"', "", "",
                      "plain", "", ""]
    back = read_trc(path)
    assert list(back.markers) == [r'"head\tleft"', r'"knee\nR"', "plain"]
    np.testing.assert_array_equal(back.markers["plain"], xyz + 2)
    np.testing.assert_array_equal(back.markers[r'"knee\nR"'], xyz + 1)


# ---------------------------------------------------------------- item 2


def _fd_inverse_jacobian(a, h=1e-6):
    """d invert_opk / d a by central differences (independent of the code)."""
    from photogram.project import invert_opk
    J = np.zeros((3, 3))
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        J[:, k] = (invert_opk(a + d)[0] - invert_opk(a - d)[0]) / (2 * h)
    return J


def test_inverse_angle_jacobian_matches_finite_differences():
    from photogram.geometry import opk_inverse_jacobian
    rng = np.random.default_rng(16)
    angles = np.vstack([rng.uniform(-1.3, 1.3, (40, 3)),
                        np.radians([[-84.3, -20.6, -193.1], [-107.6, 27.6, -197.0]]) * 0.9])
    J = opk_inverse_jacobian(angles)
    for a, Ja in zip(angles, J):
        np.testing.assert_allclose(Ja, _fd_inverse_jacobian(a), atol=2e-8)
    assert np.all(np.isnan(opk_inverse_jacobian([np.nan, 0.0, 0.0])))


def test_camera_to_world_station_sigmas_are_propagated_not_copied(tmp_path):
    """The field network (near-horizontal cameras, interior orientation from
    the lab with its covariance) oriented once with world-to-camera and once
    with camera-to-world angles in its stations table: the est_s* angle
    sigmas of the camera-to-world stations.csv are sqrt(diag(J C J^T)) with C
    the world-to-camera covariance of covariance.npz and J the
    finite-difference Jacobian of the inversion; positions are unchanged."""
    import shutil

    import pandas as pd

    from photogram.commands.bundle import calibrate, orient
    from photogram.project.results_read import read_orientation_covariance
    from photogram.geometry import from_radians, to_radians
    from photogram.project import invert_opk
    from photogram.project.tables import format_angle

    root = DATA.parents[1] / "projects"
    shutil.copytree(root / "field", tmp_path / "field",
                    ignore=shutil.ignore_patterns("results*", ".*"))
    from lab_stage import stage_lab
    stage_lab(tmp_path / "lab", measured_copy=True)   # copied, its photographs measured
    calibrate(read_project(tmp_path / "lab" / "lab.prj"), report=False)   # tables only
    field = tmp_path / "field"
    w2c_folder, _ = orient(read_project(field / "field.prj"), output=tmp_path / "w2c",
                          report=False)
    # the same network with camera-to-world angles in its stations table
    st = pd.read_csv(field / "field_stations.csv", comment="#", dtype={"station": str})
    a = to_radians(st[["omega", "phi", "kappa"]].to_numpy(float), "gon")
    b = invert_opk(a)
    for j, c in enumerate(("omega", "phi", "kappa")):
        st[c] = [format_angle(v, "gon") for v in b[:, j]]
    st.to_csv(field / "c2w_stations.csv", index=False)
    text = (field / "field.prj").read_text()
    text = text.replace('rotation_direction = "world_to_camera"',
                        'rotation_direction = "camera_to_world"')
    (field / "c2w.prj").write_text(text.replace("field_stations.csv", "c2w_stations.csv"))
    c2w_folder, res = orient(read_project(field / "c2w.prj"), output=tmp_path / "c2w",
                          report=False)

    angles = ["est_somega", "est_sphi", "est_skappa"]
    w2c = pd.read_csv(w2c_folder / "stations.csv", comment="#", dtype={"station": str})
    c2w = pd.read_csv(c2w_folder / "stations.csv", comment="#", dtype={"station": str})
    labels, cov = read_orientation_covariance(c2w_folder)
    index = {l: i for i, l in enumerate(labels)}
    ratios = []
    for k, name in enumerate(c2w["station"]):
        ix = [index[f"{name}.{p}"] for p in ("omega", "phi", "kappa")]
        C = cov[np.ix_(ix, ix)]
        a_est = res.project.stations.angles[k]          # world-to-camera, radians
        np.testing.assert_allclose(
            invert_opk(to_radians(c2w.loc[k, ["omega", "phi", "kappa"]].to_numpy(float),
                                  "gon"))[0], a_est, atol=1e-9)
        J = _fd_inverse_jacobian(a_est)
        expected = from_radians(np.sqrt(np.diag(J @ C @ J.T)), "gon")
        np.testing.assert_allclose(c2w.loc[k, angles].to_numpy(float), expected, rtol=1e-5)
        # the world-to-camera sigmas are those of the covariance, as before
        np.testing.assert_allclose(w2c.loc[k, angles].to_numpy(float),
                                   from_radians(np.sqrt(np.diag(C)), "gon"), rtol=1e-9)
        ratios.append(expected / w2c.loc[k, angles].to_numpy(float))
    np.testing.assert_allclose(c2w[["est_sX0", "est_sY0", "est_sZ0"]],
                               w2c[["est_sX0", "est_sY0", "est_sZ0"]], rtol=1e-9)
    # copying would be far off for these cameras (the symptom of the issue)
    print("ratio propagated / copied (omega, phi, kappa) per station:", np.round(ratios, 2))
    assert np.max(np.abs(np.log(np.array(ratios)))) > np.log(1.5), ratios
