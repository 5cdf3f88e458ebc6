"""The front of the example chain: projects/lab measured from its rendered
photographs (images/, written by projects/generate.py from truth/), as
`make demo` does it: numbered from ArUco markers over the 3D frame, the
measurement compared with the TRUE image points and with the typed table
lab_image_points.csv (the check), then calibrated (lab.prj) and compared
with the true cameras and with the calibration from the typed observations
(lab-typed.prj)."""

import json

import cv2
import numpy as np
import pytest

from lab_stage import LAB, stage_lab
from photogram.bundle import adjust
from photogram.measure.compare import compare_tables
from photogram.measure.scenes import _rows, read_truth, render_project
from photogram.project import read_project

MARKERS = ["T01", "T25", "T05", "T21", "T13", "T28", "T34", "T31", "T37"]


@pytest.fixture(scope="module")
def staged(tmp_path_factory):
    return stage_lab(tmp_path_factory.mktemp("measured") / "lab")


@pytest.fixture(scope="module")
def measured(staged):
    return staged / "results-measure"


def test_images_are_reproducible():
    truth = read_truth(LAB / "truth")
    img = render_project(truth, MARKERS, seed=20250101, stations=["K2b"])["K2b"]
    stored = cv2.imread(str(LAB / "images" / "K2b.jpg"), cv2.IMREAD_GRAYSCALE)
    assert stored.shape == img.shape
    assert np.abs(stored.astype(float) - img).mean() < 1.5      # JPEG 92


def test_frame_description_gives_the_approximate_points_not_the_truth():
    text = (LAB / "frame.toml").read_text()
    assert 'file = "lab_points.csv"' in text and 'images = "images"' in text
    approx = {r["id"]: float(r["X"]) for r in _rows(LAB / "lab_points.csv")}
    true = {r["id"]: float(r["X"]) for r in _rows(LAB / "truth" / "points.csv")}
    assert f"xyz = [{approx['T01']!r}," in text and approx["T01"] != true["T01"]


@pytest.mark.slow
def test_measured_against_the_true_image_points(measured):
    c = compare_tables(measured / "image_points.csv", LAB / "truth" / "image_points.csv")
    print(c.line(), f"max |z| {c.max_z:.1f}", c.beyond)
    assert c.extra == []                           # nothing outside the design
    assert c.wrong == [] and c.largest < 0.5       # no wrong label
    assert c.matched >= 0.84 * c.n_reference       # measured 385 of 446
    assert c.rms < 0.06                            # measured 0.034 (typed: 0.33)
    # within their sigmas: measured mean z^2 0.67, 99.7 % of |z| <= 3, 1 beyond 5
    assert 0.3 < c.mean_z2 < 1.5
    assert c.fraction_within_3 >= 0.98
    assert len(c.beyond) <= 0.01 * c.matched
    summary = json.loads((measured / "summary.json").read_text())
    assert summary["observations"] == c.n_measured
    assert summary["totals"]["codes"] >= 9 * 6 - 2
    # every target of the frame in at least 3 images (the calibration needs them)
    per_target = summary["per_target"]
    assert len(per_target) == 50 and min(per_target.values()) >= 3


def test_measured_against_the_typed_table(measured):
    """The check `make demo` prints: the typed observations (0.33 px noise)
    against the measured ones; z uses both sigmas."""
    c = compare_tables(measured / "image_points.csv", LAB / "lab_image_points.csv",
                       sigma_reference=0.33)
    print(c.line())
    assert c.extra == [] and c.wrong == [] and c.beyond == []
    n = 2 * c.matched                              # chi-square over n coordinates, 99 % band
    assert abs(c.mean_z2 - 1) < 2.58 * np.sqrt(2 / n)


def test_lab_prj_reads_the_measurement(staged, measured):
    prj = read_project(staged / "lab.prj")
    assert prj.sources["image_points"] == measured / "image_points.csv"
    assert len(prj.image_points) == compare_tables(measured / "image_points.csv",
                                                   LAB / "lab_image_points.csv").n_measured
    assert np.all(prj.image_points.sigma < 0.1)


def test_calibrate_from_the_measured_photographs(staged):
    ours = adjust(read_project(staged / "lab.prj"))
    typed = adjust(read_project(LAB / "lab-typed.prj"))
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
