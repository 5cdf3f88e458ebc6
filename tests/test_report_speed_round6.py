"""Round 6 of the report's speed (issue 23, item 1): each faster helper
gives the very numbers of the code it replaced."""

import numpy as np
import pytest

from photogram.geometry.camera import camera_model
from photogram.report.pdf.axes import Transform
from photogram.report.pdf.canvas import text_width
from photogram.report.pdf.fontdata import WIDTHS
from photogram.report.shapes import (convex_grid_mask, convex_hull, coverage_fraction,
                                     unique_rows)


@pytest.mark.parametrize("seed", range(4))
def test_unique_rows_equals_numpy_unique(seed):
    rng = np.random.default_rng(seed)
    for n in (0, 1, 2, 5, 100, 3000):
        xy = np.round(rng.normal(size=(n, 2)) * 3)          # many repeats and ties in x
        got = unique_rows(xy)
        assert got.shape[1] == 2
        assert np.array_equal(got, np.unique(xy, axis=0).reshape(-1, 2))


def _coverage_by_masks(hulls, fmt, n=200):
    """The previous formulation: one mask per polygon, or-ed."""
    w, h = fmt
    xs, ys = (np.arange(n) + 0.5) * w / n, (np.arange(n) + 0.5) * h / n
    inside = np.zeros((n, n), bool)
    for poly in hulls:
        if len(poly) >= 3:
            inside |= convex_grid_mask(poly, xs, ys)
    return float(inside.mean())


@pytest.mark.parametrize("seed", range(6))
def test_coverage_of_all_hulls_at_once_equals_mask_per_hull(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        w, h = rng.uniform(10, 6000, 2)
        hulls = []
        for _ in range(int(rng.integers(0, 8))):
            m = int(rng.integers(1, 80))
            xy = rng.uniform(0, 1, 2) * (w, h) + rng.normal(size=(m, 2)) * rng.uniform(
                0.01, 0.7, 2) * (w, h)
            if seed % 2:                      # vertices on grid rows and columns
                xy = np.round(xy / (w / 200)) * (w / 200)
            hulls.append(convex_hull(xy))
        assert coverage_fraction(hulls, (w, h)) == _coverage_by_masks(hulls, (w, h))


def test_coverage_of_known_shapes():
    w, h = 400.0, 300.0
    left_half = np.array([[0, 0], [200, 0], [200, 300], [0, 300]], float)
    assert coverage_fraction([left_half], (w, h)) == 0.5
    # the same half twice and a quarter inside it: still a half
    quarter = np.array([[0, 0], [100, 0], [100, 300], [0, 300]], float)
    assert coverage_fraction([left_half, quarter, left_half], (w, h)) == 0.5
    right_quarter = np.array([[300, 0], [400, 0], [400, 300], [300, 300]], float)
    assert coverage_fraction([left_half, right_quarter], (w, h)) == 0.75
    assert coverage_fraction([], (w, h)) == 0.0
    assert coverage_fraction([left_half[:2]], (w, h)) == 0.0


def test_brown_correct_without_jacobians_is_the_same_as_with():
    model = camera_model("brown")
    io = np.array([50.0, 12.1, 8.3, -3e-5, 2e-8, -1e-11, 4e-6, -2e-6, 1e-4, -3e-4])
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 24, (500, 2))
    plain = model.correct(xy, io)
    full, jac = model.correct(xy, io, jacobians=True)
    assert np.array_equal(plain, full)
    assert jac["io"].shape == (500, 2, 10)


@pytest.mark.parametrize("logy", [False, True])
def test_transform_of_points_equals_its_x_and_y(logy):
    rng = np.random.default_rng(8)
    tr = Transform((40.0, 60.0, 300.0, 200.0), (-3.7, 11.2), (0.01, 950.0), logy)
    xy = rng.uniform(-5, 1000, (400, 2))
    xy[3] = np.nan
    got = tr(xy)
    assert np.array_equal(got, np.stack([tr.x(xy[:, 0]), tr.y(xy[:, 1])], axis=1),
                          equal_nan=True)


def test_text_width_from_the_font_tables():
    size = 7.0
    want = sum(WIDTHS["Helvetica"][c] for c in "10.5".encode("cp1252")) * size / 1000.0
    assert text_width("10.5", size) == want
    assert text_width("10.5", size) == want            # again, from the cache
    assert text_width("10.5", 2 * size, "Courier") == 4 * 600 * 2 * size / 1000.0


def _streams(pdf: bytes) -> list:
    """The decompressed content of every Flate stream of a PDF, in order."""
    import re
    import zlib
    out = []
    for m in re.finditer(rb"/Length (\d+) >>\nstream\n", pdf):
        start = m.end()
        out.append(zlib.decompress(pdf[start:start + int(m.group(1))]))
    return out


def test_flate_level_changes_the_compression_only(tmp_path, monkeypatch):
    """The report at FLATE_LEVEL holds the very page content and images of
    the same report compressed at level 3 (the level before round 6)."""
    import photogram.report.pdf.file as pdf_file
    from photogram.report.pdf.canvas import Canvas

    def draw():
        pdf = pdf_file.PdfFile({"Title": "t"})
        c = Canvas(pdf, 200, 100)
        c.text(10, 10, "flate 1.25", 8)
        c.segments(np.random.default_rng(0).uniform(0, 100, (300, 2)), np.ones((300, 2)))
        c.image(np.arange(60 * 40 * 3, dtype=np.uint8).reshape(40, 60, 3) % 251, 0, 0, 60, 40)
        c.finish()
        return pdf.tobytes()

    assert pdf_file.FLATE_LEVEL == 1
    fast = draw()
    monkeypatch.setattr(pdf_file, "FLATE_LEVEL", 3)
    before = draw()
    assert fast != before and len(fast) > len(before)
    assert len(_streams(fast)) == len(_streams(before)) >= 2
    assert _streams(fast) == _streams(before)


def test_tick_labels_cached_are_those_computed():
    from photogram.report.pdf.ticks import _decimals, tick_labels

    def plain(ticks):
        d = _decimals(ticks)
        out = []
        for t in np.asarray(ticks, float):
            s = f"{t:.{d}f}"
            out.append(s.lstrip("-") if s.strip("-0.") == "" else s)
        return out

    for ticks in ([0.0, 0.5, 1.0], [-0.0, 2.5, 5.0], [1e-4, 2e-4], [-2.0, -1.0, 0.0, 1.0],
                  [0.0, 1500.0, 3000.0], [0.0, 1500.0, 3000.0]):
        assert tick_labels(ticks) == plain(ticks)
    assert tick_labels([-0.0, 1.0]) == ["0", "1"] == tick_labels([0.0, 1.0])
    labels = tick_labels([0.0, 0.25])
    labels.append("x")                              # the cached labels stay as they are
    assert tick_labels([0.0, 0.25]) == ["0.00", "0.25"]


def test_stroke_styles_cached_are_those_formatted():
    from photogram.report.pdf.canvas import Canvas
    from photogram.report.pdf.file import PdfFile

    c = Canvas(PdfFile(), 100, 100)
    c.stroke_style("tab:blue", 1.5, [3.7, 1.6])
    c.stroke_style(np.array([0.1, 0.2, 0.3]), 0.8)        # unhashable: formatted directly
    c.stroke_style((0.1, 0.2, 0.3), 0.8, cap=1)
    ops = "".join(c._ops)
    assert "0.122 0.467 0.706 RG 1.5 w 0 J 1 j [3.7 1.6] 0 d" in ops
    assert "0.1 0.2 0.3 RG 0.8 w 0 J 1 j [] 0 d" in ops
    assert "0.1 0.2 0.3 RG 0.8 w 1 J 1 j [] 0 d" in ops
