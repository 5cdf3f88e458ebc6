"""The mocap report drawn by the native PDF writer (issue 23, item 2):
native, the matplotlib layout's page breaks, the camera bars and median
residual vectors drawn (bars one path per colour, arrows with open heads),
the bone labels rotated; SIMULATED results of tests/test_report_mocap_pages."""

from __future__ import annotations

import io
from contextlib import ExitStack

import numpy as np
import pytest

pypdf = pytest.importorskip("pypdf")


def test_mocap_report_is_native_with_the_matplotlib_layout(tmp_path):
    from test_report_mocap_pages import _folder

    from photogram.report.data import load
    from photogram.report.registry import all_native, sections
    from photogram.report.writer import _style, build_report, report_units

    folder, _ = _folder(tmp_path / "m", {"A": 1.0, "B": 1.2, "C": 9.0})
    raw = (folder / "report.pdf").read_bytes()
    assert b"Matplotlib" not in raw
    data = load(folder)
    data.extra["units"] = report_units(data)
    assert all_native(sections(data))
    with ExitStack() as stack:
        _style(stack)
        figures, _ = build_report(data)
    pages = pypdf.PdfReader(io.BytesIO(raw)).pages
    assert len(pages) == len(figures)
    text = "\n".join(p.extract_text() for p in pages)
    assert "STANDS OUT" in text and "median residual vector" in text
    assert "hip-knee" in text


def _axes():
    from photogram.report.pdf.axes import Axes
    from photogram.report.pdf.canvas import Canvas
    from photogram.report.pdf.file import PdfFile

    canvas = Canvas(PdfFile({}), 400, 300)
    return canvas, Axes(canvas, (50, 50, 300, 200))


def test_bars_one_path_per_colour_and_limits_from_zero():
    canvas, ax = _axes()
    ax.bar(np.arange(3), [1.0, 4.0, 2.0], color=["tab:blue", "tab:red", "tab:blue"])
    xl, yl = ax.get_xlim(), ax.get_ylim()
    assert xl[0] < -0.4 and xl[1] > 2.4 and yl[0] == 0.0 and yl[1] >= 4.0
    ax.render()
    ops = "".join(canvas._ops)
    assert ops.count(" re\n") == 3               # three bars (frame and clip: "re S", "re W n")
    assert ops.count("re\nf\n") == 2             # one fill per colour


def test_arrow_head_at_the_end():
    canvas, ax = _axes()
    ax.set_xlim(-1, 1)
    ax.set_ylim(-1, 1)
    ax.arrow(0.0, 0.0, 1.0, 0.0, color="tab:red", head=4.0)
    ax.render()
    tr = ax.transform()
    tip = tr([[1.0, 0.0]])[0]
    ops = "".join(canvas._ops)
    # the two strokes of the head end at the tip, 4 pt behind it, 2 pt to either side
    for dy in (2.0, -2.0):
        assert f"{tip[0] - 4:.2f} {tip[1] + dy:.2f} m {tip[0]:.2f} {tip[1]:.2f} l" in ops
