"""The native PDF writer of the report (photogram/report/pdf, issue 23 item
1): file structure, text layer, glyph widths against Adobe's AFM files,
tick choice against matplotlib's MaxNLocator, the data -> page transform,
vectorized paths against a loop, and calibrate's report drawn without
matplotlib (same pages as the matplotlib layout; fallback for text outside
cp1252)."""

from __future__ import annotations

import io
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from photogram.report.native import NativeDocument
from photogram.report.pdf import make_fontdata
from photogram.report.pdf.axes import Transform
from photogram.report.pdf.canvas import CIRCLE, Canvas, fmt_points, text_width
from photogram.report.pdf.file import PdfFile
from photogram.report.pdf.fontdata import WIDTHS
from photogram.report.pdf.ticks import nice_ticks, tick_labels
from photogram.report.shapes import convex_grid_mask, convex_hull

pypdf = pytest.importorskip("pypdf")
ROOT = Path(__file__).resolve().parents[1]


def _document():
    doc = NativeDocument(header="photogram test report: native", info={"Title": "t"})
    doc.start_section("Section one", intro="A paragraph (with brackets) and a backslash \\.")
    doc.table(["name", "value", "sigma"], [["c", "2336.81", "0.33"], ["K1", "4.673e-08",
                                                                       "2.3e-10"]],
              title="Parameters")
    ax, = doc.axes(2.5)
    ax.plot([0, 1, 2], [1, 10, 100], "o-", label="cost")
    ax.set_yscale("log")
    ax.legend()
    doc.start_section("Section two", landscape=True)
    ax2, = doc.axes(3.0)
    ax2.hist(np.random.default_rng(0).normal(size=500), bins=20, density=True, alpha=0.7)
    ax2.axvline(3.3, ls="--")
    ax2.imshow(np.arange(12.0).reshape(3, 4), extent=(0, 4, 0, 3), cmap="viridis")
    doc.finish("footer line")
    return doc.tobytes()


def test_pdf_parses_with_a_correct_xref_and_text_layer():
    raw = _document()
    assert raw.startswith(b"%PDF-1.4") and raw.endswith(b"%%EOF\n")
    # every xref offset points at its object
    start = int(re.search(rb"startxref\n(\d+)", raw).group(1))
    assert raw[start:start + 4] == b"xref"
    lines = raw[start:].split(b"\n")
    n = int(lines[1].split()[1])
    for i, line in enumerate(lines[3:3 + n - 1], 1):
        offset = int(line[:10])
        assert raw[offset:offset + len(f"{i} 0 obj")] == f"{i} 0 obj".encode()
    reader = pypdf.PdfReader(io.BytesIO(raw), strict=True)
    assert len(reader.pages) == 2
    assert [float(v) for v in reader.pages[1].mediabox[2:]] == pytest.approx([841.68, 595.44])
    text = reader.pages[0].extract_text()
    assert "Section one" in text and "(with brackets)" in text and "backslash \\" in text
    assert re.search(r"K1\s+4\.673e-08\s+2\.3e-10", text)
    assert "page 1 of 2" in text and "footer line" in text
    assert "page 2 of 2" in reader.pages[1].extract_text()
    assert _document() == raw                                # reproducible


def test_glyph_widths_are_those_of_the_afm_files():
    afm = make_fontdata.afm_dir()
    for font, name in make_fontdata.FILES.items():
        widths = make_fontdata.afm_widths(afm / name)
        table = WIDTHS[font]
        assert table[ord("A")] == widths["A"] and table[ord("1")] == widths["one"]
        assert table[ord(" ")] == widths["space"] and table[0xE9] == widths["eacute"]
        assert list(table) == make_fontdata.winansi_widths(
            widths, 600 if font == "Courier" else 556)
    # Helvetica: "Wi" = W 944 + i 222 per 1000 em
    assert text_width("Wi", 10.0) == pytest.approx(11.66)
    assert text_width("abc", 8.0, "Courier") == pytest.approx(3 * 0.6 * 8)


@pytest.mark.parametrize("seed", range(5))
def test_ticks_are_matplotlibs(seed):
    from matplotlib.ticker import MaxNLocator

    rng = np.random.default_rng(seed)
    for _ in range(40):
        lo = rng.normal() * 10.0 ** rng.integers(-3, 4)
        hi = lo + abs(rng.normal()) * 10.0 ** rng.integers(-3, 4)
        n = int(rng.integers(3, 10))
        ref = MaxNLocator(nbins=n, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi)
        span = hi - lo
        ref = ref[(ref >= lo - 1e-9 * span) & (ref <= hi + 1e-9 * span)]
        if len(ref) >= 2:
            np.testing.assert_allclose(nice_ticks(lo, hi, n), ref, rtol=0,
                                       atol=1e-9 * span)
    assert tick_labels([-0.5, -1e-17, 0.5, 1.0]) == ["-0.5", "0.0", "0.5", "1.0"]
    assert tick_labels([0, 500, 1000]) == ["0", "500", "1000"]
    assert list(nice_ticks(15.5, 21.5, 9, integer=True)) == [16, 17, 18, 19, 20, 21]


def test_transform_maps_limits_to_the_box():
    tr = Transform((100, 50, 200, 100), (0, 10), (5, -5))          # y down
    np.testing.assert_allclose(tr([[0, 5], [10, -5], [5, 0]]),
                               [[100, 50], [300, 150], [200, 100]])
    log = Transform((0, 0, 100, 300), (0, 1), (1, 1000), logy=True)
    np.testing.assert_allclose(log.y([1, 10, 100, 1000]), [0, 100, 200, 300])
    assert np.isnan(log.y([-1.0])[0])


def test_vectorized_paths_equal_a_loop():
    rng = np.random.default_rng(3)
    a, b = rng.uniform(0, 500, (50, 2)), rng.uniform(0, 500, (50, 2))
    loop = "".join("%.2f %.2f m %.2f %.2f l\n" % (*p, *q) for p, q in zip(a, b))
    assert fmt_points("%.2f %.2f m %.2f %.2f l\n", np.hstack([a, b])) == loop
    c = Canvas(PdfFile(), 100, 100)
    c.segments(a, b)
    assert c.content().decode() == loop + "S\n"
    c = Canvas(PdfFile(), 100, 100)
    c.polyline(np.vstack([a[:3], [[np.nan, np.nan]], a[3:5]]))
    expected = ("%.2f %.2f m %.2f %.2f l %.2f %.2f l %.2f %.2f m %.2f %.2f l" % (
        *a[0], *a[1], *a[2], *a[3], *a[4])) + " S\n"
    assert c.content().decode() == expected
    c = Canvas(PdfFile(), 100, 100)
    c.markers(a[:4], "o", 6.0, filled=False)
    circles = "".join(
        ("%.2f %.2f m " + "%.2f %.2f %.2f %.2f %.2f %.2f c " * 4 + "h\n")
        % tuple((p + 3.0 * CIRCLE).ravel()) for p in a[:4])
    assert c.content().decode() == circles + "S\n"
    # filled discs: zero-length round-capped lines as wide as disc and edge
    c = Canvas(PdfFile(), 100, 100)
    c.fill_style("tab:red")
    c.stroke_style("tab:red", 0.5)
    start = len(c.content())
    c.markers(a[:4], "o", 6.0)
    discs = "".join("%.2f %.2f m %.2f %.2f l\n" % (*p, *p) for p in a[:4])
    assert c.content().decode()[start:] == "q 6.5 w 1 J 0.839 0.153 0.157 RG\n" + discs + "S Q\n"
    # more than DENSE rows: 0.1 pt
    many = rng.uniform(0, 500, (3000, 2))
    assert fmt_points("%.2f %.2f l\n", many) == "".join("%.1f %.1f l\n" % tuple(p)
                                                         for p in many)


def test_convex_grid_mask_is_matplotlibs_contains_points():
    from matplotlib.path import Path as MplPath

    rng = np.random.default_rng(7)
    xs = (np.arange(120) + 0.5) * 100 / 120
    gx, gy = np.meshgrid(xs, xs)
    grid = np.stack([gx.ravel(), gy.ravel()], -1)
    for _ in range(30):
        hull = convex_hull(rng.uniform(0, 100, (int(rng.integers(3, 40)), 2)))
        if len(hull) < 3:
            continue
        ref = MplPath(hull).contains_points(grid).reshape(120, 120)
        assert np.array_equal(convex_grid_mask(hull, xs, xs), ref)


# --------------------------------------------------------------------------
# calibrate's report


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    from photogram_cli.main import main

    folder = tmp_path_factory.mktemp("native") / "lab-results"
    prj = ROOT / "tests" / "data" / "lab" / "lab.prj"
    assert main(["calibrate", "-q", str(prj), "--output", str(folder)]) == 0
    return folder


def test_calibrate_report_is_native_with_the_matplotlib_layout(lab):
    from contextlib import ExitStack

    from photogram.report.data import load
    from photogram.report.registry import all_native, sections
    from photogram.report.writer import _style, build_report, report_units

    raw = (lab / "report.pdf").read_bytes()
    assert b"Matplotlib" not in raw and b"/BaseFont /Courier" in raw
    data = load(lab)
    data.extra["units"] = report_units(data)
    assert all_native(sections(data))
    with ExitStack() as stack:
        _style(stack)
        figures, outline = build_report(data)
    reader = pypdf.PdfReader(io.BytesIO(raw))
    assert len(reader.pages) == len(figures)              # the same page breaks
    for page, fig in zip(reader.pages, figures):
        w, h = (float(v) / 72 for v in page.mediabox[2:])
        assert (w, h) == pytest.approx(tuple(fig.get_size_inches()), abs=0.01)


@pytest.mark.slow
def test_report_without_matplotlib_and_fallback_outside_cp1252(lab, tmp_path):
    code = ("import sys; from photogram.report import write_report; "
            f"write_report({str(lab)!r}, output={str(tmp_path)!r}); "
            "print(any(m.startswith('matplotlib') for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": ""})
    assert out.stdout.strip() == "False"
    assert (tmp_path / "report.pdf").read_bytes() == (lab / "report.pdf").read_bytes()
    # a name outside cp1252: the same report drawn with matplotlib
    from photogram.report import write_report
    from photogram.report.data import load

    data = load(lab)
    data.summary["warnings"] = ["\u0394\u03b5\u03bb\u03c4\u03b1: a warning in Greek"]

    import photogram.report.writer as writer
    orig = writer.load
    try:
        writer.load = lambda folder, project=None, tables=None: data
        path = write_report(lab, output=tmp_path / "greek")
    finally:
        writer.load = orig
    assert b"Matplotlib" in path.read_bytes()


def test_dense_ellipses_are_one_image_of_their_outlines():
    from types import SimpleNamespace

    from photogram.report.pdf.artists import raster_ellipses

    c = Canvas(PdfFile(), 200, 200)
    tr = SimpleNamespace(box=(0.0, 0.0, 144.0, 144.0))            # 2 x 2 in: 300 x 300 px
    centre = np.array([[72.0, 72.0]])
    raster_ellipses(c, tr, centre, np.array([[36.0, 0.0]]), np.array([[0.0, 18.0]]), "black")
    obj = next(iter(c.images.values()))
    raw = c.pdf._objects[obj - 2]                                  # its soft mask, just before
    import zlib
    mask = np.frombuffer(zlib.decompress(raw.split(b"stream\n", 1)[1].rsplit(b"\nendstream",
                                                                              1)[0]),
                         np.uint8).reshape(300, 300)
    iy, ix = np.nonzero(mask)
    # pixel centres on the ellipse (a = 75 px, b = 37.5 px about the middle)
    x, y = (ix + 0.5 - 150) / 75.0, (299 - iy + 0.5 - 150) / 37.5
    r = np.hypot(x, y)
    assert len(ix) > 300 and np.all(np.abs(r - 1) < 0.06)


# the SIMULATED Monte Carlo results folder of tests/test_report_montecarlo_pages.py
from test_report_montecarlo_pages import folder  # noqa: E402,F401  (a fixture)


def test_monte_carlo_report_is_native_with_the_matplotlib_layout(folder):
    from contextlib import ExitStack

    from photogram.report.data import load
    from photogram.report.writer import _style, build_report, report_units

    raw = (folder / "report.pdf").read_bytes()
    assert b"Matplotlib" not in raw
    data = load(folder)
    data.extra["units"] = report_units(data)
    with ExitStack() as stack:
        _style(stack)
        figures, _ = build_report(data)
    pages = pypdf.PdfReader(io.BytesIO(raw)).pages
    assert len(pages) == len(figures)
    text = "\n".join(p.extract_text() for p in pages)
    assert "sigma_mc / sigma_prop of every quantity" in text and "95 % band" in text
