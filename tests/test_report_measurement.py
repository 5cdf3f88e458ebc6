"""The measurement page of report.pdf: the lab calibrated from its measured
photographs (tests/lab_stage.py) gets a page with the measurement's counts
per image and per target next to what the adjustment used; the calibration
from the typed table (lab-typed.prj) gets none."""

import json
import re

import pandas as pd
import pytest

from lab_stage import stage_lab
from photogram.commands.bundle import calibrate
from photogram.project import read_project
from photogram.report import write_report

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

pypdf = pytest.importorskip("pypdf")


def _pages(path):
    return [p.extract_text() for p in pypdf.PdfReader(str(path)).pages]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    return stage_lab(tmp_path_factory.mktemp("report") / "lab", calibrate=True, report=True,
                     measured_copy=True)


def _measurement_text(pages):
    found = [t for t in pages if "Measurement (photogram measure)" in t.splitlines()[1]]
    return "\n".join(found)


def test_measured_calibration_has_the_measurement_page(lab):
    pages = _pages(lab / "results" / "report.pdf")
    text = _measurement_text(pages)
    assert text, "no measurement page"
    summary = json.loads((lab / "results-measure" / "summary.json").read_text())
    measured = pd.read_csv(lab / "results-measure" / "image_points.csv", comment="#")
    res = pd.read_csv(lab / "results" / "residuals.csv")
    assert f"observations measured  {len(measured)}" in text
    assert "measurement            ../results-measure" in text
    assert f"in the adjustment      {int(res['used'].sum())} used" in text
    assert "the adjustment's observations are the measured table" in text
    # per image: the measurement's counts, and the adjustment's used observations
    for name, c in summary["per_image"].items():
        row = re.search(rf"^{name}\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)",
                        text, re.M)
        assert row, name
        got = [int(v) for v in row.groups()]
        assert got[:3] == [c["accepted"], c["numbered"], c["codes"]]
        assert got[1] == int((measured["station"] == name).sum())
        assert got[6] == int(((res["station"] == name) & (res["used"] == 1)).sum())
    # per target: images measured
    for pid, n in summary["per_target"].items():
        assert re.search(rf"(^|\s){pid}\s+{n}\s", text, re.M), pid
    for problem in summary["problems"]:
        assert problem.split(":")[0] in text


def test_typed_calibration_has_no_measurement_page(tmp_path, lab):
    project = read_project(lab / "lab-typed.prj")
    folder, _ = calibrate(project, output=tmp_path / "typed")
    assert not _measurement_text(_pages(folder / "report.pdf"))


def test_measured_again_after_the_adjustment_is_said(tmp_path, lab):
    """The page reads the measurement at report time; when its table no
    longer is what the adjustment used, the page says so."""
    import shutil
    copy = tmp_path / "lab"
    shutil.copytree(lab, copy)
    table = copy / "results-measure" / "image_points.csv"
    lines = table.read_text().splitlines(keepends=True)
    table.write_text("".join(lines[:-1]))            # one observation fewer
    summary = copy / "results" / "summary.json"      # the copy's results name the copy
    data = json.loads(summary.read_text())
    data["project"]["path"] = str(copy / "lab.prj")
    summary.write_text(json.dumps(data))
    write_report(copy / "results", output=tmp_path / "again")
    text = _measurement_text(_pages(tmp_path / "again" / "report.pdf"))
    assert "measured again" in text
