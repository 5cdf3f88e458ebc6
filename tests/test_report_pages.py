"""The report's pieces: the section registry and its hooks, the layout, the
numbers and shapes, and the distortion and coverage computations."""

from __future__ import annotations

import json
from contextlib import ExitStack

import numpy as np
import pytest

from photogram.project.model import Camera, Parameter
from photogram.report import load, registry, section, sections, write_report
from photogram.report.layout import Document, char_width
from photogram.report.numbers import num, pair
from photogram.report.pages_cameras import displacement
from photogram.report.shapes import convex_hull, coverage_fraction, ellipse, nice, polygon_area
from photogram.report.writer import _style, build_report

pypdf = pytest.importorskip("pypdf")


def test_numbers():
    assert pair(1418.5609, 4.4008) == ("1418.6", "4.4")
    assert pair(1.0266e-08, 3.954e-08) == ("1.0e-08", "4.0e-08")
    assert pair(2.0, None) == ("2", "-")
    assert pair(float("nan"), 0.1) == ("-", "0.10")
    assert num(0.33265442) == "0.3327" and num(None) == "-" and num(123456789) == "1.235e+08"


def test_shapes():
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [1, 1], [1, 0]], float)
    hull = convex_hull(square)
    assert len(hull) == 4 and polygon_area(hull) == pytest.approx(4.0)
    assert coverage_fraction([hull], (4, 2), n=100) == pytest.approx(0.5, abs=0.02)
    a, b, angle = ellipse([[1.0, 0.0], [0.0, 9.0]])
    assert (a, b) == pytest.approx((3.0, 1.0)) and abs(angle) == pytest.approx(90.0)
    assert [nice(x) for x in (0.037, 730, 1.0, 2.5)] == [0.02, 500, 1.0, 2.0]


def _brown(**values):
    params = dict(c=1000.0, x0=320.0, y0=240.0, K1=0.0, K2=0.0, K3=0.0, P1=0.0, P2=0.0,
                  B1=0.0, B2=0.0)
    params.update(values)
    return Camera("K", "brown", {k: Parameter(v) for k, v in params.items()}, (640, 480))


def test_distortion_is_zero_at_the_principal_point_and_radial_outwards():
    cam = _brown(K1=1e-7)
    xy = np.array([[320.0, 240.0], [620.0, 240.0], [320.0, 40.0]])
    d = displacement(cam, xy)
    assert np.allclose(d[0], 0)
    # the correction pushes points outwards, so measured points lie inside:
    # their displacement from the distortion-free position points inwards
    assert d[1, 0] < 0 and abs(d[1, 1]) < 1e-9 and d[2, 1] > 0
    assert np.hypot(*d[1]) == pytest.approx(1e-7 * 300 ** 3, rel=1e-9)


def test_tables_fit_the_page_and_flow_over_pages():
    doc = Document(header="test")
    with ExitStack() as stack:
        _style(stack)
        doc.start_section("A table")
        rows = [[f"row {i}"] + [f"{i * 1.5:.3f}"] * 12 for i in range(150)]
        doc.table(["name"] + [f"column {j}" for j in range(12)], rows)
        figs = doc.finish("footer")
    mono = [t for f in figs for t in f.texts if t.get_fontfamily()[0] == "monospace"]
    assert len(figs) >= 2 and len(mono) == 150 + len(figs)     # rows + a header per page
    assert all(t.get_text().startswith("name") for t in mono if "column 11" in t.get_text())
    widest = max(len(t.get_text()) * char_width(t.get_fontsize()) for t in mono)
    assert widest <= 8.27 - 2 * 0.6 + 1e-6                     # the font was made smaller
    assert f"page {len(figs)} of {len(figs)}" in [t.get_text() for t in figs[-1].texts]


def _summary_only(tmp_path, summary, files=()):
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    for name, text in files:
        (tmp_path / name).write_text(text)
    return tmp_path


def test_monte_carlo_and_mocap_hooks_apply_when_their_outputs_exist(tmp_path):
    mc = _summary_only(tmp_path / "mc", {"command": "montecarlo", "runs": 200, "failed": 0,
                                         "headline": {"station": 1.02}, "warnings": []},
                       [("table1.csv", "quantity,sigma_mc,sigma_prop,ratio\nS1.X0,0.1,0.1,1.0\n")])
    outline = []
    path = write_report(mc, outline=outline)
    assert [t for t, _ in outline] == ["Summary", "Monte Carlo"]
    text = "\n".join(p.extract_text() for p in pypdf.PdfReader(str(path)).pages)
    # the Monte Carlo pages (photogram/report/pages_montecarlo.py) replace the generic
    # hook; without summary.csv they say so instead of dumping summary.json
    assert "table1.csv" in text and "summary.csv is missing" in " ".join(text.split())
    mocap = _summary_only(tmp_path / "mocap", {"command": "mocap", "warnings": []},
                          [("mocap_markers.csv", "frame,x\n0,1.0\n1,2.0\n")])
    outline = []
    write_report(mocap, outline=outline)
    assert [t for t, _ in outline] == ["Summary", "Motion capture"]


def test_a_later_command_adds_its_pages_with_one_registration(tmp_path, monkeypatch):
    monkeypatch.setattr(registry, "SECTIONS", dict(registry.SECTIONS))
    folder = _summary_only(tmp_path / "r", {"command": "simulate", "warnings": []},
                           [("design.csv", "a\n1\n")])

    @section("design", "Network design", 88, applies=lambda d: d.has("design.csv"))
    def build(doc, data):
        doc.start_section("Network design")
        doc.text("planned network")

    assert "design" in {s.name for s in sections(load(folder))}
    with ExitStack() as stack:
        _style(stack)
        figures, outline = build_report(load(folder))
    assert outline == [("Summary", 1), ("Network design", 1)] and len(figures) == 2
    (folder / "design.csv").unlink()
    assert "design" not in {s.name for s in sections(load(folder))}
