"""Issue 21, item 4 in the .prj and the results folder: the per_station,
tie and shared keys of [cameras.NAME] (docs/project-files.md, "Parameter
sharing"), one-line errors with exit 2, and the outputs of a calibration
with shared parameters (interior.csv, covariance.npz, cameras.toml,
report.pdf) on a simulated network with known truth."""

from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.project import read_project, write_project
from photogram.project.results import read_results
from photogram.project.results_read import read_covariance

from project_cases import make_project, replace

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

sys.path.insert(0, str(Path(__file__).parent))
from test_parameter_sharing import _per_station_project  # noqa: E402


def _run(argv):
    from photogram_cli.main import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue() + err.getvalue()


K1_OLD = "P1 = 0.0\n"


def _lab(tmp_path, extra_k1="", extra_k2="", k2_c=None):
    prj = make_project(tmp_path)
    if extra_k1:
        replace(prj, K1_OLD, K1_OLD + extra_k1)
    if k2_c is not None:
        replace(prj, "c  = { value = 1400.0, free = true, sigma = 20.0 }", k2_c)
    if extra_k2:
        replace(prj, 'K1 = { value = 0.0, free = true }\n\n[stations]',
                'K1 = { value = 0.0, free = true }\n' + extra_k2 + '\n[stations]')
    return prj


def test_sharing_keys_are_read(tmp_path):
    prj = _lab(tmp_path, 'per_station = ["x0", "y0"]\nshared = { c = "lens" }\n',
               'shared = { c = "lens" }\n',
               k2_c="c  = { value = 1420.0, free = true }")
    project = read_project(prj)
    k1, k2 = project.cameras["K1"], project.cameras["K2"]
    assert k1.per_station == ("x0", "y0") and k1.shared == {"c": "lens"}
    assert k2.shared == {"c": "lens"} and k2.per_station == () and k2.ties == {}


def test_a_default_camera_shares_nothing(tmp_path):
    project = read_project(make_project(tmp_path))
    assert not any(c.shares() for c in project.cameras.values())


def test_tie_takes_the_value_and_state_of_its_parameter(tmp_path):
    prj = make_project(tmp_path)
    replace(prj, '[cameras.K2]\nmodel = "brown"',
            '[cameras.K2]\nmodel = "opencv"\nfx = { value = 1400.0, free = true }\n'
            'tie = { fy = "fx" }')
    replace(prj, 'c  = { value = 1400.0, free = true, sigma = 20.0 }\n'
                 'x0 = { value = 960.0, free = true }\ny0 = { value = 540.0, free = true }\n'
                 'K1 = { value = 0.0, free = true }\n', 'cx = 960.0\ncy = 540.0\n')
    cam = read_project(prj).cameras["K2"]
    assert cam.ties == {"fy": "fx"}
    assert cam.parameters["fy"] == cam.parameters["fx"]
    assert cam.parameters["fy"].free and cam.parameters["fy"].value == 1400.0


BAD = [
    ("unknown parameter", 'per_station = ["xo"]\n', None, "per_station",
     ("unknown parameter 'xo'", "x0")),
    ("tie to itself", 'tie = { K2 = "K2" }\n', None, "tie", ("tied to itself",)),
    ("tie across units", 'tie = { K1 = "c" }\n', None, "tie", ("different units",)),
    ("tie chain", 'tie = { K1 = "K2", K2 = "K3" }\n', None, "tie", ("itself tied",)),
    ("tie unknown", 'tie = { fy = "fx" }\n', None, "tie", ("unknown parameter 'fy'",)),
    ("per-station fixed", 'per_station = ["P1"]\n', None, "per_station",
     ("per station but fixed", "free = true")),
    ("per-station and shared", 'per_station = ["c"]\nshared = { c = "lens" }\n', None,
     "shared", ("both per_station and shared",)),
    ("tied and per-station", 'per_station = ["y0"]\ntie = { y0 = "x0" }\n', None, "tie",
     ("also in per_station",)),
    ("tie not a table", 'tie = "fx"\n', None, "tie", ("inline table",)),
    ("group names two", 'shared = { x0 = "g", y0 = "g" }\n', None, "shared",
     ("names x0 and y0",)),
]


@pytest.mark.parametrize("case", BAD, ids=[c[0] for c in BAD])
def test_bad_sharing_is_one_line_with_its_line(tmp_path, case):
    _, k1, k2, key, words = case
    prj = _lab(tmp_path, k1, k2 or "")
    with pytest.raises(InputError) as info:
        read_project(prj)
    err = info.value
    text = err.one_line()
    assert "\n" not in text and err.hint and err.file.endswith("lab.prj")
    lines = prj.read_text().splitlines()
    assert lines[err.line - 1].startswith(key), (text, lines[err.line - 1])
    for w in words:
        assert w in text, text


def test_tied_parameter_given_differently(tmp_path):
    prj = _lab(tmp_path, 'P2 = 1e-9\ntie = { P2 = "P1" }\n')
    with pytest.raises(InputError, match="tied to P1 but given differently"):
        read_project(prj)


def test_group_with_different_values_or_names(tmp_path):
    prj = _lab(tmp_path, 'shared = { c = "lens" }\n', 'shared = { c = "lens" }\n')
    with pytest.raises(InputError, match="differs from c of camera K1 .* in group 'lens'") as info:
        read_project(prj)
    assert info.value.line == prj.read_text().splitlines().index(
        "c  = { value = 1400.0, free = true, sigma = 20.0 }") + 1
    prj = _lab(tmp_path / "b", 'shared = { x0 = "lens" }\n', 'shared = { y0 = "lens" }\n')
    with pytest.raises(InputError, match="ties x0 of camera K1 to y0 of camera K2"):
        read_project(prj)


def test_bad_sharing_exits_2_with_one_line(tmp_path):
    prj = _lab(tmp_path, 'per_station = ["P1"]\n')
    code, text = _run(["check", str(prj)])
    assert code == 2
    assert len(text.strip().splitlines()) == 1 and "per station but fixed" in text
    assert "Traceback" not in text


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A simulated network of one camera with a principal point per station,
    written as a .prj and calibrated from the command line."""
    folder = tmp_path_factory.mktemp("sharing")
    project, truth = _per_station_project()
    prj = write_project(project, folder / "sim.prj")
    code, text = _run(["calibrate", "-q", str(prj)])
    assert code == 0, text
    return prj, folder / "results", truth


def test_written_project_keeps_its_sharing(calibrated):
    prj, _, _ = calibrated
    assert read_project(prj).cameras["K1"].per_station == ("x0", "y0")


def test_results_list_per_station_parameters_per_station(calibrated):
    _, results, truth = calibrated
    lines = (results / "interior.csv").read_text().splitlines()
    assert lines[0].startswith("#")
    header = lines[1].split(",")
    assert header == ["unknown", "cameras", "parameter", "equal", "station", "group", "value",
                      "free", "est_sigma"]
    rows = [dict(zip(header, line.split(","))) for line in lines[2:]]
    x0 = [r for r in rows if r["parameter"] == "x0"]
    assert [r["station"] for r in x0] == [f"S{s + 1}" for s in range(len(truth))]
    z = [(float(r["value"]) - truth[s, 1]) / float(r["est_sigma"]) for s, r in enumerate(x0)]
    assert np.all(np.abs(z) < 3.5)
    c = [r for r in rows if r["parameter"] == "c"]
    assert len(c) == 1 and c[0]["station"] == "" and float(c[0]["est_sigma"]) > 0
    cov = read_covariance(results / "covariance.npz")
    assert list(cov["interior_labels"]) == [r["unknown"] for r in rows]
    assert cov["interior_matrix"].shape == (len(rows), len(rows))
    assert "K1.x0@S3" in list(cov["labels"])


def test_results_cameras_file_reads_back(calibrated):
    _, results, _ = calibrated
    res = read_results(results)
    cam = res.cameras["K1"]
    assert cam.per_station == ("x0", "y0")
    assert cam.parameters["x0"].sigma_estimated is None      # per station: in interior.csv
    assert cam.parameters["c"].sigma_estimated > 0
    assert (results / "report.pdf").stat().st_size > 10_000


def test_cameras_sharing_c_are_listed_once(tmp_path):
    from test_parameter_sharing import _two_cameras
    prj = write_project(_two_cameras({"c": "lens"}), tmp_path / "two.prj")
    assert read_project(prj).cameras["K2"].shared == {"c": "lens"}
    code, text = _run(["calibrate", "-q", str(prj)])
    assert code == 0, text
    lines = (tmp_path / "results" / "interior.csv").read_text().splitlines()[1:]
    header = lines[0].split(",")
    rows = [dict(zip(header, line.split(","))) for line in lines[1:]]
    c = [r for r in rows if r["parameter"] == "c"]
    assert len(c) == 1 and c[0]["unknown"] == "K1+K2.c" and c[0]["cameras"] == "K1 K2"
    assert c[0]["group"] == "lens"
    cams = read_results(tmp_path / "results").cameras
    assert cams["K1"].parameters["c"].value == cams["K2"].parameters["c"].value
    assert cams["K1"].parameters["c"].sigma_estimated == float(c[0]["est_sigma"])


def test_the_documented_example_reads(tmp_path):
    """The [cameras] example of docs/project-files.md, "Parameter sharing",
    in place of the lab project's cameras."""
    doc = (Path(__file__).parents[1] / "docs" / "project-files.md").read_text()
    part = doc[doc.index("### Parameter sharing"):]
    block = part[part.index("```toml\n") + 8:]
    block = block[:block.index("```")]
    prj = make_project(tmp_path)
    text = prj.read_text()
    start, end = text.index("[cameras.K1]"), text.index("[stations]")
    prj.write_text(text[:start] + block + "\n" + text[end:])
    project = read_project(prj)
    k1, k2, v1 = (project.cameras[n] for n in ("K1", "K2", "V1"))
    assert k1.per_station == ("x0", "y0") and k1.shared == k2.shared == {"c": "lens",
                                                                          "K1": "lens-K1"}
    assert v1.ties == {"fy": "fx"} and v1.parameters["fy"].value == 1000.0


def test_check_names_the_sharing(tmp_path):
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        "check_of_this_tree", Path(__file__).parents[1] / "cli" / "check.py")
    check = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(check)
    prj = _lab(tmp_path, 'per_station = ["x0", "y0"]\ntie = { P2 = "P1" }\n')
    text = "\n".join(check.summary_lines(read_project(prj)))
    assert "K1 (brown, 5 free, per station x0 y0, P2 = P1)" in text
