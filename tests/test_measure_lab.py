"""The lab example measured from rendered photographs (projects/lab-photos/images,
written by projects/lab-photos/render_images.py from projects/lab/truth):
numbered from ArUco markers over the 3D frame, compared with the true image
points, then calibrated (projects/lab-photos/lab-photos.prj) and compared
with the true cameras and with the calibration from the typed observations."""

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from photogram.commands.bundle import adjust
from photogram.measure.scenes import _rows, read_truth, render_project
from photogram.project import read_project
from photogram_cli.main import main

LAB = Path(__file__).resolve().parents[1] / "projects" / "lab"
PHOTOS = LAB.parent / "lab-photos"
MARKERS = ["T01", "T25", "T05", "T21", "T13", "T28", "T34", "T31", "T37"]


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    out = tmp_path_factory.mktemp("lab") / "measured"
    assert main(["measure", str(PHOTOS / "frame.toml"), "--output", str(out), "-q",
                 "--no-report"]) == 0
    return out


def test_images_are_reproducible():
    truth = read_truth(LAB / "truth")
    img = render_project(truth, MARKERS, seed=20250101, stations=["K2b"])["K2b"]
    stored = cv2.imread(str(PHOTOS / "images" / "K2b.jpg"), cv2.IMREAD_GRAYSCALE)
    assert stored.shape == img.shape
    assert np.abs(stored.astype(float) - img).mean() < 1.5      # JPEG 92


def test_measured_against_the_true_image_points(measured):
    truth = {(r["station"], r["point"]): (float(r["x"]), float(r["y"]))
             for r in _rows(LAB / "truth" / "image_points.csv")}
    rows = [r for r in _rows(measured / "image_points.csv")]
    err = []
    for r in rows:
        key = (r["station"], r["point"])
        assert key in truth, key                       # nothing outside the design
        err.append(np.array([float(r["x"]), float(r["y"])]) - truth[key])
    err = np.array(err)
    dist = np.hypot(*err.T)
    rms = float(np.sqrt((dist ** 2).mean()))
    print(f"{len(rows)} of {len(truth)} true observations measured "
          f"({100 * len(rows) / len(truth):.1f} %), RMS {rms:.4f} px, largest {dist.max():.3f} px")
    assert dist.max() < 0.5                            # no wrong label
    assert len(rows) >= 0.84 * len(truth)              # measured 385 of 446
    assert rms < 0.06                                  # measured 0.035 (typed: 0.33)
    summary = json.loads((measured / "summary.json").read_text())
    assert summary["totals"]["codes"] >= 9 * 6 - 2


def test_calibrate_from_the_measured_photographs(measured, tmp_path):
    text = (PHOTOS / "lab-photos.prj").read_text()
    text = text.replace('"results-measure/image_points.csv"',
                        json.dumps(str(measured / "image_points.csv")))
    text = re.sub(r'folder = "results-measured"', f'folder = "{tmp_path / "out"}"', text)
    for name in ("lab_stations.csv", "lab_points.csv"):
        text = text.replace(f'"../lab/{name}"', json.dumps(str(LAB / name)))
    (tmp_path / "lab-photos.prj").write_text(text)
    ours = adjust(read_project(tmp_path / "lab-photos.prj"))
    typed = adjust(read_project(LAB / "lab.prj"))
    true = {r["camera"]: r for r in _rows(LAB / "truth" / "cameras.csv")}
    for cam in ("K1", "K2", "K3"):
        for p in ("c", "x0", "y0"):
            v = ours.project.cameras[cam].parameters[p].value
            s = ours.camera_sigma[cam][p]
            s_typed = typed.camera_sigma[cam][p]
            dev = (v - float(true[cam][p])) / s
            print(f"{cam} {p}: {v:.2f} +- {s:.2f} (true {true[cam][p]}, {dev:+.1f} sd); "
                  f"typed observations: +- {s_typed:.2f}")
            assert abs(dev) < 3
            assert s < s_typed / 3                     # measured far better than typed
    assert ours.summary["status"] == "converged"
