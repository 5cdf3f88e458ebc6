"""Issue 23, item 2: the intersect report (projects/jumps on the oriented
lab and field results, SIMULATED) and the camera pages of fixed cameras.

Read back through the PDF's text layer (pypdf): no repeated input pages,
the rays and intersection angles of the jumper points equal to what
residuals.csv, points.csv and stations.csv give, Fig. 8 drawn as vector
graphics with labels of at least 7 pt, and the camera pages of fixed
cameras saying why they have no sigmas and whose correlations they show.
"""

from __future__ import annotations

import math
import re
import shutil

import numpy as np
import pandas as pd
import pytest

pypdf = pytest.importorskip("pypdf")

pytestmark = pytest.mark.slow


def _pages(path):
    return [p.extract_text() or "" for p in pypdf.PdfReader(str(path)).pages]


def _title(text):
    """The section title of a page (the header line: '<report name> <title>')."""
    first = text.splitlines()
    return next((ln for ln in first if ln.startswith("photogram ") and " report: " in ln), "")


@pytest.fixture(scope="module")
def jump(jumps_report):
    """The intersect results of projects/jumps (SIMULATED) in a fresh folder
    (the session's, conftest.py ``jumps_report``)."""
    return jumps_report


def _largest_angles(folder):
    """Rays and largest intersection angle (deg) per point, from the CSVs."""
    res = pd.read_csv(folder / "residuals.csv", comment="#", dtype={"point": str})
    res = res[res["used"] == 1]
    pts = pd.read_csv(folder / "points.csv", comment="#", dtype={"id": str}).set_index("id")
    st = pd.read_csv(folder / "stations.csv", comment="#").set_index("station")
    out = {}
    for pid, g in res.groupby("point"):
        X = pts.loc[pid, ["X", "Y", "Z"]].to_numpy(float)
        d = st.loc[g["station"], ["X0", "Y0", "Z0"]].to_numpy(float) - X
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        cos = np.clip(d @ d.T, -1, 1)
        out[pid] = (len(g), float(np.degrees(np.arccos(cos.min()))))
    return out


def test_no_input_page_is_repeated(jump):
    pages = _pages(jump / "report.pdf")
    titles = [_title(t) for t in pages]
    assert not any(re.search(r"Camera K\d$", t) for t in titles), titles
    assert not any(t.endswith("Stations (exterior orientation)") for t in titles), titles
    assert sum(t.endswith("Input orientation (fixed)") for t in titles) == 1, titles
    inputs = pages[[t.endswith("Input orientation (fixed)") for t in titles].index(True)]
    for name in ("K1", "K2", "K3", "S1", "S2", "S3"):
        assert re.search(rf"^{name}\s", inputs, re.M), name
    bodies = ["\n".join(t.splitlines()[1:]) for t in pages]
    assert len(set(bodies)) == len(bodies)


def test_rays_and_angles_of_the_jumper_points_equal_the_results(jump):
    pages = _pages(jump / "report.pdf")
    page = next(t for t in pages if _title(t).endswith("Jumper points and ski lines"))
    truth = _largest_angles(jump)
    for name in ("P1", "P2", "P3", "P4"):
        row = re.search(rf"^{name}\s+(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s", page, re.M)
        assert row, name
        exposures, rays, low, mean = row.groups()
        mine = [v for k, v in truth.items() if k.split("@")[0] == name]
        assert int(exposures) == len(mine) == 24
        n = sorted({r for r, _ in mine})
        assert rays == (str(n[0]) if len(n) == 1 else f"{n[0]}-{n[-1]}")
        angles = np.array([a for _, a in mine])
        assert float(low) == pytest.approx(angles.min(), abs=0.051)
        assert float(mean) == pytest.approx(angles.mean(), abs=0.051)
    assert " - " not in page.split("Jumper points", 1)[1].split("Ski lines")[0]


def test_fig8_is_vector_with_readable_labels(jump):
    reader = pypdf.PdfReader(str(jump / "report.pdf"))
    page = next(p for p in reader.pages if _title(p.extract_text()).endswith("(Fig. 8)"))
    assert len(page.images) == 0                  # no raster picture on the page
    sizes, texts = [], []

    def visit(text, cm, tm, font, size):
        if text.strip():
            texts.append(text.strip())
            sizes.append(size * math.hypot(tm[0], tm[1]) * math.hypot(cm[0], cm[1]))

    page.extract_text(visitor_text=visit)
    assert min(sizes) >= 7.0 - 1e-6
    e = pd.read_csv(jump / "exposures.csv", dtype={"exposure": str})
    v = e["v"].to_numpy(float)
    for i in range(0, len(v), 3):                 # every 3rd exposure annotated
        assert f"{v[i]:.1f} dm/s" in texts


def test_network_text_matches_the_rays_drawn(jump):
    page = next(t for t in _pages(jump / "report.pdf") if _title(t).endswith("Network"))
    used = pd.read_csv(jump / "residuals.csv", comment="#")["used"].sum()
    assert used == 288                            # 24 exposures x 4 points x 3 images
    assert "every ray from a camera to a point it measured" in " ".join(page.split())
    assert "no rays are drawn" not in " ".join(page.split())


def test_fixed_cameras_say_why_they_have_no_sigmas(oriented_projects, tmp_path):
    """The field report (orient, cameras fixed from the lab calibration whose
    covariance is propagated), and a copy whose K3 has no distortion and no
    input covariance."""
    from photogram.report import write_report
    field = oriented_projects / "field" / "results"
    first = tmp_path / "field-report"           # the fixture's orient ran with --no-report
    write_report(field, output=first)
    pages = _pages(first / "report.pdf")
    cams = [t for t in pages if re.search(r"Camera K\d$", _title(t))]
    assert len(cams) == 3
    for text in cams:
        flat = " ".join(text.split())
        assert "Every parameter of this camera is fixed in this adjustment" in flat
        assert "they are not estimated here" in flat
        assert "(of the input calibration)" in flat
    copy = tmp_path / "results"
    shutil.copytree(field, copy)
    (copy / "covariance.npz").unlink()
    import json
    summary = json.loads((copy / "summary.json").read_text())
    summary.pop("interior_covariance")
    (copy / "summary.json").write_text(json.dumps(summary))
    toml = (copy / "cameras.toml").read_text()
    head, k3 = toml.split("[cameras.K3]")
    k3 = re.sub(r"^(K[12]) = \{ value = [^,]+,", r"\1 = { value = 0.0,", k3, flags=re.M)
    (copy / "cameras.toml").write_text(head + "[cameras.K3]" + k3)
    write_report(copy)
    pages = _pages(copy / "report.pdf")
    k3_page = " ".join(next(t for t in pages if _title(t).endswith("Camera K3")).split())
    assert "A fixed camera has no estimated correlations." in k3_page
    assert "parameter with correlation" not in k3_page        # no table of them
    assert "No distortion: the lens distortion of this camera is fixed at 0" in k3_page
    assert "Largest distortion" not in k3_page
    k1_page = " ".join(next(t for t in pages if _title(t).endswith("Camera K1")).split())
    assert "Largest distortion" in k1_page
