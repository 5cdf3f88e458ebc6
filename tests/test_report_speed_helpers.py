"""Helpers of the faster report (issue 23, item 1): residual vectors averaged
per cell, segments as one path, the PDF standard fonts with their fallback,
text on a fixed baseline, point kinds without a loop."""

from __future__ import annotations

import io
from contextlib import ExitStack
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch

from photogram.report.layout import Document, line_height
from photogram.report.pages_geometry import _by_kind
from photogram.report.shapes import cell_means, segments_path
from photogram.report.writer import _style, core_fonts_fit

pypdf = pytest.importorskip("pypdf")


def test_cell_means_by_hand():
    # format 40 x 25, 4 columns: square cells of 10, 3 rows (the last one cut)
    xy = [[1, 1], [9, 9], [15, 2], [39.9, 24.9], [45, -3], [5, 12]]
    v = [[1, 2], [3, 4], [-1, 0], [2, 2], [4, 0], [0, -6]]
    centres, means, counts = cell_means(xy, v, (40, 25), ncols=4)
    assert counts.shape == (3, 4) and counts.sum() == 6
    # cell (row 0, col 0): points 0, 1; (0, 1): point 2; (0, 3): point 4 (outside,
    # clipped to the border); (1, 0): point 5; (2, 3): point 3
    expected = {(0, 0): [2, 3], (0, 1): [-1, 0], (0, 3): [4, 0], (1, 0): [0, -6],
                (2, 3): [2, 2]}
    assert [tuple(c) for c in np.argwhere(counts)] == list(expected)
    assert counts[0, 0] == 2 and counts[2, 3] == 1
    np.testing.assert_allclose(means, list(expected.values()))
    np.testing.assert_allclose(centres, [[5, 5], [15, 5], [35, 5], [5, 15], [35, 25]])


def test_cell_means_of_random_points_equal_a_loop():
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, [3000, 2000], (5000, 2))
    v = rng.normal(size=(5000, 2))
    centres, means, counts = cell_means(xy, v, (3000, 2000), ncols=24)
    cell = 3000 / 24
    for c, m in zip(centres, means):
        inside = np.all(np.abs(xy - c) < cell / 2, axis=1)
        np.testing.assert_allclose(m, v[inside].mean(axis=0), atol=1e-12)
    assert counts.sum() == 5000 and len(centres) == np.count_nonzero(counts)


def _pixels(add) -> np.ndarray:
    fig = Figure(figsize=(2, 2), dpi=50)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 10)
    ax.set_axis_off()
    add(ax)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba()).copy()


def test_segments_path_draws_like_a_line_collection():
    rng = np.random.default_rng(5)
    a = rng.uniform(1, 9, (40, 2))
    b = a + rng.normal(scale=0.5, size=(40, 2))
    path = segments_path(a, b)
    np.testing.assert_array_equal(path.vertices[0::2], a)
    np.testing.assert_array_equal(path.vertices[1::2], b)
    assert not path.should_simplify
    one = _pixels(lambda ax: ax.add_artist(PathPatch(path, fill=False, lw=0.9,
                                                     edgecolor="tab:blue", capstyle="butt")))
    many = _pixels(lambda ax: ax.add_collection(LineCollection(np.stack([a, b], axis=1),
                                                               colors="tab:blue", lw=0.9)))
    assert (one != 255).any()                      # something was drawn
    # the same pixels up to antialiasing where two segments cross
    assert np.mean(np.any(one != many, axis=2)) < 0.002


def _pdf(texts) -> bytes:
    buf = io.BytesIO()
    with ExitStack() as stack:
        _style(stack)
        import matplotlib
        fig = Figure(figsize=(3, 2))
        for i, t in enumerate(texts):
            fig.text(0.1, 0.8 - 0.2 * i, t)
        with PdfPages(buf) as pdf:
            with matplotlib.rc_context({"pdf.use14corefonts": core_fonts_fit(fig)}):
                pdf.savefig(fig)
    return buf.getvalue()


def test_standard_fonts_and_the_fallback_for_other_characters():
    ascii_fig = Figure()
    ascii_fig.text(0, 0, "value 1.5 ± 0.2 px, 3 deg")
    greek_fig = Figure()
    greek_fig.text(0, 0, "sigma σ")
    assert core_fonts_fit(ascii_fig) and not core_fonts_fit(greek_fig)
    plain = _pdf(["value 1.5 ± 0.2 px"])
    assert b"/Helvetica" in plain and b"DejaVu" not in plain
    greek = _pdf(["project Δέλτα", "sigma σ"])
    assert b"DejaVu" in greek
    text = pypdf.PdfReader(io.BytesIO(greek)).pages[0].extract_text()
    assert "Δέλτα" in text and "σ" in text                       # not '?'
    assert "1.5 ± 0.2" in pypdf.PdfReader(io.BytesIO(plain)).pages[0].extract_text()


def test_table_rows_are_evenly_spaced_whatever_their_glyphs():
    doc = Document(header="test")
    with ExitStack() as stack:
        _style(stack)
        doc.start_section("A table")
        doc.table(["name", "unit"], [["K1", "px^-2"], ["B1", "-"], ["y0", "|x|"], ["c", "px"]])
        fig = doc.finish("footer")[0]
    rows = [t for t in fig.texts if t.get_fontfamily() == ["monospace"]]
    assert len(rows) == 5 and all(t.get_va() == "baseline" for t in rows)
    y = np.array([t.get_position()[1] for t in rows[1:]]) * fig.get_figheight()
    np.testing.assert_allclose(-np.diff(y), line_height(8.0), rtol=1e-12)


def test_point_kinds_without_a_loop_equal_the_loop():
    from photogram.report.table import Table

    ids = ["1", "2", "3", "4", "5"]
    kinds = ["control", "tie", "check", "tie", np.nan]
    points = Table({"id": np.array(ids, dtype=object), "kind": np.array(kinds, dtype=object)},
                   "id")
    ray_ids = ["1", "2", "3", "4", "5", "99"]
    angle = {"1": 10.0, "2": 20.0, "3": 30.0, "4": 40.0, "5": 50.0, "99": 60.0}
    rays = Table({"point": np.array(ray_ids, dtype=object), "rays": np.arange(2, 8),
                  "angle": np.array([angle[p] for p in ray_ids])}, "point")
    got = _by_kind(SimpleNamespace(points=points), rays)
    kind_of = dict(zip(ids, kinds))
    for kind in ("control", "check", "tie"):
        want = [p for p in ray_ids if str(kind_of.get(p, "tie")) == kind]
        assert list(got[kind][1]) == [angle[p] for p in want]    # the angles name the points
        assert list(got[kind][0]) == [ray_ids.index(p) + 2 for p in want]
    assert list(got) == ["control", "check", "tie"]
    assert list(got["tie"][1]) == [20.0, 40.0, 60.0]     # "5" has kind nan


def test_a_passed_project_gives_the_same_report_and_is_used_only_for_its_file(tmp_path):
    import copy
    import shutil
    from pathlib import Path

    from photogram.project import read_project
    from photogram.report import load, write_report
    from photogram_cli.main import main

    src = Path(__file__).parent / "data" / "lab"
    shutil.copytree(src, tmp_path / "lab", ignore=shutil.ignore_patterns("results*"))
    prj_file = tmp_path / "lab" / "lab.prj"
    folder = tmp_path / "results"
    assert main(["calibrate", "-q", str(prj_file), "--output", str(folder)]) == 0
    project = read_project(prj_file)
    assert load(folder, project).project is project
    other = copy.copy(project)
    other.path = tmp_path / "elsewhere.prj"
    data = load(folder, other)
    assert data.project is not other and data.project is not None
    a = write_report(folder, output=tmp_path / "a")
    b = write_report(folder, output=tmp_path / "b", project=project)
    assert a.read_bytes() == b.read_bytes()
