"""The intersect report drawn by the native PDF writer (issue 23, item 1
and 2): every section native, the matplotlib layout's page breaks, Fig. 8
drawn as vector paths (no image) with the stick model's segments and the
speeds, the landing-slope profile in its side view when the project gives
one; SIMULATED data (projects/jumps on the staged lab and field results)."""

from __future__ import annotations

import io
import re
from contextlib import ExitStack

import numpy as np
import pytest

pypdf = pytest.importorskip("pypdf")

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def jump(oriented_projects, jumps_report, tmp_path_factory):
    """The intersect results of projects/jumps (SIMULATED; the session's,
    conftest.py ``jumps_report``), and of the same project with the
    landing-slope profile of jumps-coach.prj."""
    from photogram.commands.intersect import intersect_and_write
    from photogram.project import read_project
    root = oriented_projects / "jumps"
    out = tmp_path_factory.mktemp("jumps-native")
    folder = jumps_report
    text = (root / "jumps.prj").read_text(encoding="utf-8")
    assert "[intersect]" in text
    assert (root / "landing_profile.csv").is_file()
    prj = root / "jumps-native-profile.prj"      # beside jumps.prj: its relative paths hold
    prj.write_text(text.replace("[intersect]", '[intersect]\nlanding_profile = '
                                '"landing_profile.csv"', 1), encoding="utf-8")
    with_profile, _ = intersect_and_write(read_project(prj), output=out / "profile")
    return folder, with_profile


def _page_of(raw, title):
    reader = pypdf.PdfReader(io.BytesIO(raw))
    for page in reader.pages:
        if title in (page.extract_text() or "").splitlines()[0]:
            return page
    raise AssertionError(f"no page titled {title}")


def test_intersect_report_is_native_with_the_matplotlib_layout(jump):
    from photogram.report.data import load
    from photogram.report.registry import all_native, sections
    from photogram.report.writer import _style, build_report, report_units

    folder, _ = jump
    raw = (folder / "report.pdf").read_bytes()
    assert b"Matplotlib" not in raw
    data = load(folder)
    data.extra["units"] = report_units(data)
    secs = sections(data)
    assert {"stick", "timeseries", "stick_table", "intersect_quality", "inputs"} <= \
        {s.name for s in secs}
    assert all_native(secs)
    with ExitStack() as stack:
        _style(stack)
        figures, _ = build_report(data)
    pages = pypdf.PdfReader(io.BytesIO(raw)).pages
    assert len(pages) == len(figures)                     # the same page breaks


def _speeds(folder):
    import pandas as pd
    from photogram.jump.figure import chosen_exposures
    from photogram.report.data import load
    from photogram.report.pages_stick import EVERY, stick_arrays

    ids, P, O, skis, v = stick_arrays(load(folder))
    idx = chosen_exposures(P, skis, EVERY)
    e = pd.read_csv(folder / "exposures.csv", comment="#", dtype={"exposure": str})
    return idx, [f"{x:.1f}" for x in e["v"].to_numpy(float)[idx]]


def test_fig8_is_vector_with_every_speed(jump):
    folder, _ = jump
    page = _page_of((folder / "report.pdf").read_bytes(), "(Fig. 8)")
    assert "/XObject" not in page["/Resources"]            # no picture on the page
    text = page.extract_text()
    idx, speeds = _speeds(folder)
    assert len(idx) >= 3
    for s in speeds:
        assert s in text
    ops = page.get_contents().get_data().decode("latin-1")
    # skis: 2 per drawn exposure per view, body: 4 per drawn exposure per view
    assert len(re.findall(r" m [-\d.]+ [-\d.]+ l\n", ops)) >= 2 * 6 * len(idx)


def test_fig8_shows_the_landing_slope_when_given(jump):
    plain, with_profile = jump
    text = _page_of((with_profile / "report.pdf").read_bytes(), "(Fig. 8)").extract_text()
    assert "landing slope (profile)" in text
    assert "landing slope" not in _page_of((plain / "report.pdf").read_bytes(),
                                           "(Fig. 8)").extract_text()


def test_ground_in_view_clips_and_interpolates():
    from photogram.report.pages_stick import _ground_in_view

    ground = (np.array([0.0, 10.0, 20.0]), np.array([0.0, -5.0, -20.0]))
    x, z = _ground_in_view(ground, 5.0, 15.0)
    np.testing.assert_allclose(x, [5.0, 10.0, 15.0])
    np.testing.assert_allclose(z, [-2.5, -5.0, -12.5])
    assert _ground_in_view(ground, 30.0, 40.0) is None
    assert _ground_in_view(None, 0.0, 1.0) is None


def test_fill_between_is_one_polygon_per_finite_run():
    from photogram.report.pdf.axes import Axes
    from photogram.report.pdf.canvas import Canvas
    from photogram.report.pdf.file import PdfFile

    ax = Axes(Canvas(PdfFile({}), 400, 300), (50, 50, 300, 200))
    x = np.arange(7.0)
    y = np.array([1, 2, np.nan, 3, 4, 5, np.nan])
    ax.fill_between(x, y - 0.5, y + 0.5, color="tab:blue", alpha=0.25)
    fills = [it for it in ax.items]
    assert len(fills) == 2          # runs 0-1 and 3-5; the lone NaN ends neither run early
