"""The motion-capture pages of report.pdf, read back from the PDF's text
layer, on SIMULATED results folders written here (no reconstruction): the
header, the per-camera table and its warning rule, bone-length stability."""

import json
import re

import numpy as np
import pandas as pd
import pytest

import photogram
from photogram.mocap.evaluation.checks import (OUTLIER_FACTOR, OUTLIER_MIN_PX,
                                               check_outliers, outlier_cameras)
from photogram.report import write_report

# `make test-fast` leaves this module out (about 12-15 s: every test builds a report.pdf).
pytestmark = pytest.mark.slow

pypdf = pytest.importorskip("pypdf")

NAME = "mocap-pages-test"
FRAMES = 50


def _text(path):
    return "\n".join(p.extract_text() for p in pypdf.PdfReader(str(path)).pages)


def _folder(tmp, medians, project=None):
    """SIMULATED mocap results: two joints 0.40 m apart +- a known wobble,
    cameras with the given median errors; camera 'B' misses 10 frames."""
    tmp.mkdir(parents=True, exist_ok=True)
    t = np.arange(FRAMES) / 50.0
    length = 0.40 + 0.01 * np.sin(np.arange(FRAMES))          # known lengths
    j = pd.DataFrame({"frame": np.arange(FRAMES), "time": t,
                      "hip_X": t, "hip_Y": 0.0, "hip_Z": 1.0,
                      "knee_X": t, "knee_Y": 0.0, "knee_Z": 1.0 - length})
    j.to_csv(tmp / "joints3d.csv", index=False)
    cams = list(medians)
    pd.DataFrame({"camera": cams, "median_px": list(medians.values()),
                  "median_dx_px": [0.5] * len(cams), "median_dy_px": [-0.25] * len(cams),
                  "mean_px": list(medians.values()), "p90_px": list(medians.values()),
                  "n": [100] * len(cams)}).to_csv(tmp / "reprojection.csv", index=False)
    det = [(f, c, "hip", 1.0, 2.0, 0.9) for c in cams for f in range(FRAMES)
           if not (c == "B" and f < 10)]
    pd.DataFrame(det, columns=["frame", "camera", "joint", "x", "y", "confidence"]).to_csv(
        tmp / "detections.csv", index=False)
    pd.DataFrame({"frame": np.arange(FRAMES), "time": t, "speed": 2.0,
                  "knee_flexion_r": 30.0}).to_csv(tmp / "metrics.csv", index=False)
    summary = {"command": "mocap", "status": "ok", "software_version": photogram.__version__,
               "project": project if project is not None else
               {"name": NAME, "path": None, "length_unit": "m", "angle_unit": "deg",
                "image_unit": "px"},
               "counts": {"frames": FRAMES, "cameras": len(cams), "joints": 2},
               "fps": 50.0, "frames": [0, FRAMES - 1], "limb_lengths": {"hip-knee": 0.4},
               "warnings": []}
    (tmp / "summary.json").write_text(json.dumps(summary))
    write_report(tmp)
    return tmp, length


def test_outlier_rule():
    assert outlier_cameras({"A": 6.6, "B": 7.2, "C": 21.5, "D": 7.6}) == {"C": (21.5, 7.2)}
    assert outlier_cameras({"A": 3.0, "B": 2.9, "C": 3.1}) == {}
    # both conditions: 2.5 x but less than 5 px above the others is no outlier
    assert outlier_cameras({"A": 1.0, "B": 1.0, "C": 4.0}) == {}
    assert outlier_cameras({"A": 10.0, "B": 10.0, "C": OUTLIER_FACTOR * 10 + 0.1}) != {}
    assert outlier_cameras({"A": 10.0, "B": 10.0, "C": OUTLIER_FACTOR * 10 - 0.1}) == {}
    assert OUTLIER_MIN_PX == 5.0
    assert outlier_cameras({"A": 1.0, "B": 30.0}) == {}          # needs two others
    assert check_outliers({"A": {"median_px": 6.0}, "B": {"median_px": 6.5},
                           "C": {"median_px": 26.0}})[0].count("C 26.0 px") == 1


def test_bad_camera_warned_good_ones_not(tmp_path):
    folder, _ = _folder(tmp_path / "bad", {"A": 6.0, "B": 6.5, "C": 26.0, "D": 7.0})
    text = _text(folder / "report.pdf")
    rows = {m.group(1): m.group(0) for m in re.finditer(r"^([ABCD])\s.*$", text, re.M)
            if "%" in m.group(0)}
    assert rows["C"].endswith("STANDS OUT")
    assert all(rows[c].endswith("ok") for c in "ABD")
    flat = " ".join(text.split())
    assert "camera residuals stand out" in flat and "C 26.0 px (others 6.5 px)" in flat
    assert "(+0.5, -0.2)" in rows["A"] or "(+0.5, -0.3)" in rows["A"]   # median vector
    assert re.search(r"^B\s+80\.0 %", rows["B"])                 # 40 of 50 frames tracked
    assert re.search(r"^A\s+100\.0 %", rows["A"])


def test_good_cameras_no_warning(tmp_path):
    folder, _ = _folder(tmp_path / "good", {"A": 6.0, "B": 6.5, "C": 7.5, "D": 7.0})
    text = _text(folder / "report.pdf")
    assert "STANDS OUT" not in text and "residuals stand out (" not in " ".join(text.split())


def test_header_units_and_bones(tmp_path):
    folder, length = _folder(tmp_path / "b", {"A": 6.0, "B": 6.5, "C": 7.5})
    text = _text(folder / "report.pdf")
    n_pages = len(pypdf.PdfReader(str(folder / "report.pdf")).pages)
    assert text.count(f"photogram {photogram.__version__} mocap report: {NAME}") == n_pages
    assert f"computed by photogram {photogram.__version__}" in " ".join(text.split())
    assert "length m, angles deg, image px" in text
    row = next(ln for ln in text.splitlines() if ln.startswith("hip-knee "))
    cells = row.split()
    assert int(cells[1]) == FRAMES
    assert float(cells[4]) == pytest.approx(length.std(ddof=1), rel=0.01)      # sd [m]
    assert float(cells[7]) == pytest.approx(np.ptp(length), rel=0.01)          # range [m]
    assert "sd [m]" in text and "range [m]" in text
    assert re.search(r"^speed\s+m/s\s", text, re.M)
    assert re.search(r"^knee flexion r\s+deg\s", text, re.M)


def test_old_summary_with_project_name_only(tmp_path):
    """A results folder of an older photogram (project: a plain name, no
    version) still gets the right name and says the version is unknown."""
    folder, _ = _folder(tmp_path / "old", {"A": 6.0, "B": 6.5, "C": 7.5}, project=NAME)
    doc = json.loads((folder / "summary.json").read_text())
    del doc["software_version"]
    (folder / "summary.json").write_text(json.dumps(doc))
    write_report(folder)
    text = " ".join(_text(folder / "report.pdf").split())
    assert f"mocap report: {NAME}" in text
    assert "version not recorded in summary.json" in text and "photogram ?" not in text
