"""The Monte Carlo pages of report.pdf, read back from the PDF's text layer.

The results folder is written by the real :func:`photogram.montecarlo.report.write_report`
from SIMULATED samples (normal draws of known sigma, no adjustment), so that
the header, the tables and the ratio band can be checked against numbers
computed here independently."""

import re
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from scipy.stats import chi2

import photogram
from photogram.montecarlo.report import ratio_band, write_report
from photogram.report import write_report as write_pdf
from photogram.report.numbers import num
from photogram.report.pages_montecarlo import MAX_ROWS

# `make test-fast` leaves this module out (about 12-15 s: every test builds a report.pdf).
pytestmark = pytest.mark.slow

pypdf = pytest.importorskip("pypdf")

RUNS, EXPOSURES, POINTS = 400, 40, 4
NAME = "mc-pages-test"


def _pages(path):
    return [p.extract_text() for p in pypdf.PdfReader(str(path)).pages]


def _chain():
    names, groups, units = [], [], []
    for s in ("S1", "S2", "S3"):
        for q, u in (("X0", "dm"), ("Y0", "dm"), ("Z0", "dm"), ("omega", "gon"),
                     ("phi", "gon"), ("kappa", "gon")):
            names.append(f"{s}.{q}"), groups.append("station"), units.append(u)
    for k in ("K1", "K2"):
        for q in ("c", "x0", "y0"):
            names.append(f"{k}.{q}"), groups.append("interior"), units.append("px")
    for e in range(1, EXPOSURES + 1):
        for p in range(1, POINTS + 1):
            for a in "XYZ":
                names.append(f"P{p}@{e:03d}.{a}"), groups.append("jumper"), units.append("dm")
    out = SimpleNamespace(names=names, groups=groups, units=units,
                          factor=np.ones(len(names)))
    settings = SimpleNamespace(perturb=["image", "reference"], truth="adjusted",
                               orient="field.prj", calibrate=None, intersect="jumps.prj",
                               interior_covariance=None, points=[], align="none")
    return SimpleNamespace(outputs=out, settings=settings, truth=np.zeros(len(names)))


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """SIMULATED: samples N(0, sigma_true); the 'propagated' sigma is right
    for the stations, interior and the first half of the jumper quantities
    and half the true sigma for the rest (those must fall outside the band)."""
    tmp = tmp_path_factory.mktemp("mc")
    chain = _chain()
    n = len(chain.outputs.names)
    rng = np.random.default_rng(3)
    sigma_true = rng.uniform(0.05, 0.5, n)
    samples = rng.standard_normal((RUNS, n)) * sigma_true
    sigma_prop = sigma_true.copy()
    jumper = np.flatnonzero(np.array(chain.outputs.groups) == "jumper")
    sigma_prop[jumper[len(jumper) // 2:]] *= 0.5
    project = SimpleNamespace(name=NAME, path=tmp / "mc.prj", warnings=[],
                              units=SimpleNamespace(length="dm", angle="gon", image="px"))
    failed = np.zeros(RUNS, bool)
    write_report(tmp, chain, samples, failed, sigma_prop, sigma_prop, {"seed": 3},
                 project=project)
    write_pdf(tmp)
    return tmp


def test_band_is_the_chi_square_interval():
    for n in (10, 200, 1000):
        lo, hi = ratio_band(n)
        want = np.sqrt(chi2.ppf([0.025, 0.975], n - 1) / (n - 1))
        assert lo == pytest.approx(want[0], rel=1e-10)
        assert hi == pytest.approx(want[1], rel=1e-10)
    assert np.all(np.isnan(ratio_band(1)))


def test_header_names_version_and_project(folder):
    pages = _pages(folder / "report.pdf")
    assert len(pages) >= 4
    header = f"photogram {photogram.__version__} montecarlo report: {NAME}"
    for i, text in enumerate(pages, 1):
        assert header in text, i
    assert f"computed by photogram {photogram.__version__}" in " ".join(pages[0].split())
    assert "photogram ?" not in pages[0] and str(folder / "mc.prj") in pages[0]


def test_band_printed_and_outside_count(folder):
    text = "\n".join(_pages(folder / "report.pdf"))
    lo, hi = np.sqrt(chi2.ppf([0.025, 0.975], RUNS - 1) / (RUNS - 1))
    assert f"{lo:.4f} .. {hi:.4f}" in text
    frame = pd.read_csv(folder / "summary.csv")
    outside = int(((frame.ratio < lo) | (frame.ratio > hi)).sum())
    assert outside > MAX_ROWS         # the halved sigmas: the omission note must appear
    assert f"Quantities outside the band: {outside}" in text
    m = re.search(r"(\d+) more rows omitted \(the first (\d+) shown\); all of them in "
                  r"summary\.csv", " ".join(text.split()))
    assert m and int(m.group(1)) == outside - MAX_ROWS and int(m.group(2)) == MAX_ROWS


def test_tables_hold_every_row(folder):
    text = "\n".join(_pages(folder / "report.pdf"))
    rows = [ln.split()[0] for ln in text.splitlines() if re.match(r"^\d{3}\s+4\s", ln)]
    assert rows == [f"{e:03d}" for e in range(1, EXPOSURES + 1)]   # Table 2: every exposure
    for s in ("S1", "S2", "S3", "K1", "K2"):                       # Table 1: every item
        assert re.search(rf"^{s}\s", text, re.M), s
    frame = pd.read_csv(folder / "summary.csv")
    q = frame.set_index("quantity")
    row = next(ln for ln in text.splitlines() if ln.startswith("S1 "))
    for name in ("S1.X0", "S1.kappa"):       # sigma_mc (sigma_prop), 2 significant digits
        mc, prop = q.loc[name, "sigma_mc"], q.loc[name, "sigma_prop"]
        assert f"{num(mc, 2)} ({num(prop, 2)})" in row, (name, row)
    assert "s_X0 [dm]" in text and "s_kappa [gon]" in text
