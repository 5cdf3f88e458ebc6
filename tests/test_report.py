"""report.pdf: written by calibrate, orient and intersect, rebuilt
byte-identical by `photogram report`, pages with content and a searchable
text layer (read with pypdf)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import photogram
from photogram.report import write_report
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

pypdf = pytest.importorskip("pypdf")

DATA = Path(__file__).parent / "data"
PROJECTS = Path(photogram.__file__).resolve().parents[1] / "projects"

ADJUSTMENT = ["Summary", "Cameras (interior orientation)", "Stations (exterior orientation)",
              "Residuals", "Residual vectors per image", "Point precision", "Error ellipses",
              "Control and check points", "Rays, intersection angles, coverage", "Network"]
SECTIONS = {
    "calibrate": ADJUSTMENT,
    "orient": ADJUSTMENT,
    # cameras and stations are fixed inputs of intersect: one page, not their full pages
    "intersect": ["Summary", "Input orientation (fixed)", "Residuals", "Residual vectors per image",
                  "Point precision", "Error ellipses", "Rays, intersection angles, coverage",
                  "Network", "Stick model (Fig. 8)", "Stick model over time",
                  "Stick model per exposure", "Jumper points and ski lines"],
}


def _jumps_project(tmp_path):
    """The generated jumps project with the true cameras and stations, so
    that it runs without calibrate and orient first (as tests/test_cli.py)."""
    for name in ("jumps", "field"):
        shutil.copytree(PROJECTS / name, tmp_path / name,
                        ignore=shutil.ignore_patterns("results*"))
    prj = tmp_path / "jumps" / "jumps.prj"
    text = prj.read_text()
    text = text.replace("../lab/results/cameras.toml", "../field/cameras-nominal.toml")
    text = text.replace("../field/results/stations.csv", "../field/truth/stations.csv")
    text = "\n".join(line for line in text.splitlines() if not line.startswith("orientation ="))
    prj.write_text(text)
    for table in ("jumper_points.csv", "ski_lines.csv"):      # 9 exposures are enough
        path = tmp_path / "jumps" / table
        lines = path.read_text().splitlines(keepends=True)
        path.write_text("".join(line for line in lines if not line[:3].isdigit()
                                or int(line[:3]) <= 9))
    return prj


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One results folder per command, written through the command line."""
    tmp = tmp_path_factory.mktemp("report")
    jobs = {"calibrate": DATA / "lab" / "lab.prj", "orient": DATA / "field" / "field.prj",
            "intersect": _jumps_project(tmp)}
    out = {}
    for command, prj in jobs.items():
        folder = tmp / f"{command}-results"
        assert main([command, "-q", str(prj), "--output", str(folder)]) == 0
        out[command] = folder
    return out


def _pages(path):
    return pypdf.PdfReader(str(path)).pages


@pytest.mark.parametrize("command", ["calibrate", "orient", "intersect"])
def test_every_command_ends_with_a_report_that_report_rebuilds(runs, command, capsys):
    folder = runs[command]
    pdf = folder / "report.pdf"
    before = pdf.read_bytes()
    assert before.startswith(b"%PDF") and b"CreationDate" not in before
    assert main(["report", str(folder)]) == 0
    assert pdf.read_bytes() == before                       # byte-identical
    assert not list(folder.glob(".report.pdf.*"))           # no temporary file left
    out = capsys.readouterr().out.strip()
    m = re.fullmatch(r"report: (\d+) pages \((.*)\) in (.*)", out)
    assert m and m.group(3) == str(pdf)
    assert m.group(2) == ", ".join(SECTIONS[command])
    assert int(m.group(1)) == len(_pages(pdf)) >= len(SECTIONS[command])


def test_text_layer_has_sigma0_and_redundancy(runs):
    for command, folder in runs.items():
        summary = json.loads((folder / "summary.json").read_text())
        text = _pages(folder / "report.pdf")[0].extract_text()
        assert f"photogram {command}" in text
        sigma0 = f"{summary['sigma0']:.5g}"
        assert re.search(r"a-posteriori sigma0\s+" + re.escape(sigma0[:6]), text), (sigma0, text)
        assert re.search(rf"redundancy\s+{summary['redundancy']}\b", text)
        if "sigma0_image" in summary:
            assert f"{summary['sigma0_image']:.4g}"[:5] in text


def test_camera_page_lists_every_parameter_with_sigma(runs):
    folder = runs["calibrate"]
    text = _pages(folder / "report.pdf")[1].extract_text()
    assert "Camera K1" in text and "Largest distortion" in text
    for name in ("c", "x0", "y0", "K1", "K2"):
        assert re.search(rf"^{name}\s+px\S*\s+\S+\s+\S+\s+estimated", text, re.M), name
    assert re.search(r"^P1\s+px\^-1\s+0\s+-\s+fixed", text, re.M)
    # the K1-K2 correlation summary.json warns about, from covariance.npz
    summary = json.loads((folder / "summary.json").read_text())
    a, b, r = summary["high_correlations"]["K1"][0]
    assert re.search(rf"K1\.{a}\s+K1\.{b}\s+{r:+.3f}", text)


def _body_ink(png: Path) -> float:
    """Share of non-white pixels between the running header and footer."""
    import matplotlib.image as mpimg

    img = mpimg.imread(png)
    if img.dtype == np.uint8:
        img = img / 255.0
    h = img.shape[0]
    body = img[int(0.07 * h):int(0.93 * h), :, :3]
    return float(np.mean(body.min(axis=2) < 0.9))


POPPLER = shutil.which("pdftoppm")


@pytest.mark.parametrize("command", ["calibrate", "orient", "intersect"])
def test_every_page_has_content(runs, command, tmp_path):
    """Every page rendered, nothing blank between header and footer: with
    pdftoppm (Debian's poppler-utils; .ci/run installs it) from the PDF that
    photogram's own writer wrote, where it is installed, and else with
    matplotlib's rasterizer from the same pages (write_report's png_folder)
    for calibrate and intersect."""
    pdf = runs[command] / "report.pdf"
    n_pages = len(_pages(pdf))
    if POPPLER:
        subprocess.run([POPPLER, "-r", "25", "-png", str(pdf), str(tmp_path / "p")],
                       check=True, capture_output=True, timeout=120)
        pages = sorted(tmp_path.glob("p-*.png"))
    elif command == "orient":
        pytest.skip("pdftoppm (poppler-utils) is not installed; calibrate has the same pages")
    else:
        outline = []
        path = write_report(runs[command], output=tmp_path, png_folder=tmp_path / "png",
                            dpi=25, outline=outline)
        assert path.read_bytes() == pdf.read_bytes()
        assert [title for title, _ in outline] == SECTIONS[command]
        assert sum(n for _, n in outline) == n_pages
        pages = sorted((tmp_path / "png").glob("page-*.png"))
    assert len(pages) == n_pages
    for png in pages:
        assert _body_ink(png) > 0.003, png.name


# --------------------------------------------------------------------------
# bad input


def _err(capsys):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err


def test_report_on_a_folder_without_results(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    err = _err(capsys)
    assert str(tmp_path) in err and "summary.json" in err and "missing" in err


def test_report_on_a_missing_folder_a_project_file_or_nothing(tmp_path, capsys):
    assert main(["report", str(tmp_path / "nowhere")]) == 2
    assert "nowhere" in _err(capsys)
    assert main(["report", str(DATA / "lab" / "lab.prj")]) == 2
    assert "lab.prj: a file, not a results folder" in _err(capsys)
    assert main(["report"]) == 2
    assert "which results folder" in _err(capsys)


def test_report_on_an_incomplete_results_folder(runs, tmp_path, capsys):
    folder = tmp_path / "copy"
    shutil.copytree(runs["calibrate"], folder)
    (folder / "residuals.csv").unlink()
    assert main(["report", str(folder)]) == 2
    err = _err(capsys)
    assert str(folder) in err and "residuals.csv" in err
    (folder / "summary.json").write_text("{ not json")
    assert main(["report", str(folder)]) == 2
    assert "summary.json" in _err(capsys)


def test_montecarlo_and_mocap_folders_get_a_report(tmp_path):
    """The report builds from the summary of any command (mocap writes the
    project's name, not a table, in summary.json)."""
    import json

    from photogram.report import write_report
    folder = tmp_path / "mocap"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"command": "mocap", "project": "ski-ptz",
                                                     "status": "done"}))
    assert write_report(folder).stat().st_size > 0
