"""``photogram mocap --no-figures`` (batch runs, issue 23 item 6): the
results folder without its PNG figures, summary.json saying so, and a
report built then or later (`photogram report FOLDER`) saying in its Run
table that the figures were not drawn, without the figures section."""

import contextlib
import io
import json

import pytest

from photogram.simulation.ski.simproject import write_simulated_project
from photogram.simulation.ski.simulate import simulate_session
from photogram_cli.main import build_parser, main

FIGURES = {"trajectory.png", "angles.png", "reprojection.png", "skeletons.png"}
#: the results folder of a simulated pan-tilt run without figures (with report.pdf;
#: joints3d.c3d when the c3d package is installed; .photogram-files: the manifest)
TABLES = {"joints3d.csv", "joints3d.trc", "metrics.csv", "angles.mot", "camera_rotations.mot",
          "detections.csv", "reprojection.csv", "bones.csv", "summary.json", "log.txt",
          "report.pdf", ".photogram-files"}
NOTE = "not drawn (photogram mocap --no-figures)"


def _quiet(argv):
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(argv)


def _text(path):
    pypdf = pytest.importorskip("pypdf")
    return " ".join(" ".join(p.extract_text() for p in pypdf.PdfReader(str(path)).pages).split())


def test_the_option_is_mocap_only():
    parser = build_parser()
    assert parser.parse_args(["mocap", "x.prj", "--no-figures"]).no_figures is True
    assert parser.parse_args(["mocap", "x.prj"]).no_figures is False
    with pytest.raises(SystemExit) as exc, contextlib.redirect_stderr(io.StringIO()):
        parser.parse_args(["intersect", "x.prj", "--no-figures"])
    assert exc.value.code == 2


@pytest.mark.slow
def test_no_figures_writes_no_png_and_the_report_says_so(tmp_path):
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=20)
    write_simulated_project(sim, tmp_path, name="ski")
    assert _quiet(["mocap", "--no-figures", "-q", str(tmp_path / "ski.prj")]) == 0
    out = tmp_path / "results"
    names = {p.name for p in out.iterdir()}
    assert not names & FIGURES and not any(n.endswith(".png") for n in names)
    assert names - {"joints3d.c3d"} == TABLES
    assert not any(n.endswith(".png") for n in (out / ".photogram-files").read_text().split())
    summary = json.loads((out / "summary.json").read_text())
    assert summary["figures"] is False and summary["counts"]["frames"] == 20
    text = _text(out / "report.pdf")                # written with the run (no --no-report)
    assert NOTE in text and "Motion capture: figures" not in text
    # built later from the folder: the same note
    (out / "report.pdf").unlink()
    assert _quiet(["report", str(out), "-q"]) == 0
    assert NOTE in _text(out / "report.pdf")
