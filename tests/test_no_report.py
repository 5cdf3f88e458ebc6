"""`--no-report` on the commands that write a results folder: the folder is
complete but for report.pdf, and `photogram report FOLDER` builds the same
report.pdf later (issue 23, item 1)."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from photogram_cli.main import build_parser, main

CAMCAL = Path(__file__).resolve().parents[1] / "projects" / "camcal" / "camcal.prj"
DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "dbat" / "camcal"


def _quiet(argv):
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(argv)


@pytest.mark.parametrize("command", ["calibrate", "orient", "intersect", "montecarlo", "mocap"])
def test_writers_accept_no_report(command):
    args = build_parser().parse_args([command, "x.prj", "--no-report"])
    assert args.no_report is True
    assert build_parser().parse_args([command, "x.prj"]).no_report is False


@pytest.mark.slow
@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/dbat/camcal is absent")
def test_calibrate_no_report_then_report_rebuilds_the_same_pdf(tmp_path):
    out = tmp_path / "results"
    assert _quiet(["calibrate", str(CAMCAL), "-q", "--output", str(out)]) == 0
    written = {p.name: p.read_bytes() for p in out.iterdir()}
    assert "report.pdf" in written
    # the same run again into the same folder, without the report
    assert _quiet(["calibrate", str(CAMCAL), "-q", "--force", "--no-report",
                   "--output", str(out)]) == 0
    assert not (out / "report.pdf").exists()
    assert sorted(p.name for p in out.iterdir()) == sorted(set(written) - {"report.pdf"})
    for name in ("points.csv", "stations.csv", "residuals.csv", "cameras.toml"):
        assert (out / name).read_bytes() == written[name], name
    # the later rebuild gives the report the command itself wrote
    assert _quiet(["report", str(out), "-q"]) == 0
    assert (out / "report.pdf").read_bytes() == written["report.pdf"]
