"""Refinement at a click (photogram/serve/refine.py) on the rendered lab
photographs, against truth: truth/image_points.csv holds the noise-free
projections of the target *centres*, so the refined ellipse centre is
compared with it after the eccentricity correction (the lab copy's
results-typed/ holds the true orientation, frame.toml the diameter and
normal of the dots)."""

from __future__ import annotations

import numpy as np
import pytest

from serve_fixtures import Running, lab_copy, truth_points


@pytest.fixture
def lab(tmp_path):
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab")
    with Session(prj, field=prj.parent / "frame.toml") as s:
        yield s, truth_points(prj.parent)


def test_click_near_a_target_refines_to_the_true_centre(lab):
    session, truth = lab
    from photogram.serve.refine import refine_click
    view = session.view("K2a")
    errors = {}
    for (st, pt), xy in truth.items():
        if st != "K2a":
            continue
        # a click 1.4 px off the centre (the dots are ~11 px across)
        r = refine_click(session, view, xy[0] + 1.2, xy[1] - 0.7, pt)
        if r["refined"]:
            assert r["method"] == "ellipse+eccentricity"
            assert 0.02 <= r["sigma"] < 0.1
            errors[pt] = np.hypot(r["x"] - xy[0], r["y"] - xy[1])
    assert len(errors) >= 38          # the markers (T01, T05, ...) are no circles
    for pt in ("T04", "T07", "T17", "T39", "T41", "SB1", "SB2"):
        assert errors[pt] < 0.05, (pt, errors[pt])
    # noise 2 grey levels, JPEG 92, blur 0.7 px: a few 0.01 px per centre
    assert np.median(list(errors.values())) < 0.03


def test_eccentricity_needs_orientation_and_label(lab):
    session, truth = lab
    from photogram.serve.refine import refine_click
    xy = truth[("K2a", "T17")]
    with_label = refine_click(session, session.view("K2a"), xy[0] + 1, xy[1], "T17")
    without = refine_click(session, session.view("K2a"), xy[0] + 1, xy[1], None)
    assert without["method"] == "ellipse" and "no label" in without["note"]
    shift = np.subtract([without["x"], without["y"]], [with_label["x"], with_label["y"]])
    # the eccentricity of a 16 mm dot seen from 2 m: about 0.01 px, mostly in y
    assert 0.005 < np.hypot(*shift) < 0.02
    marker = truth[("K2a", "T01")]       # an ArUco marker, not a circle
    r = refine_click(session, session.view("K2a"), marker[0], marker[1], "T01")
    assert r["method"] != "ellipse+eccentricity"


def test_no_target_keeps_the_click(lab):
    session, _ = lab
    from photogram.serve.refine import refine_click
    r = refine_click(session, session.view("K1a"), 12.25, 20.5, "T20")
    assert r == {"x": 12.25, "y": 20.5, "sigma": 0.5, "refined": False, "method": "clicked",
                 "note": "no target at the click: kept as clicked (manual, sigma 0.5 px)"}


def test_refine_endpoint_without_field_and_orientation(tmp_path):
    """Not oriented, no --field: both polarities with the detector's
    defaults; the ellipse centre (no eccentricity) within 0.05 px."""
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab", oriented=False)
    truth = truth_points(prj.parent)
    s = Session(prj)
    try:
        with Running(s) as r:
            xy = truth[("K1c", "T30")]
            status, body = r.request("POST", "/api/refine", {"view": "K1c", "x": xy[0] - 1.0,
                                                             "y": xy[1] + 1.0, "point": "T30"})
            assert status == 200 and body["refined"] and body["method"] == "ellipse"
            assert "not oriented" in body["note"]
            assert np.hypot(body["x"] - xy[0], body["y"] - xy[1]) < 0.05
            status, body = r.request("POST", "/api/refine", {"view": "K1c", "x": "a", "y": 1})
            assert status == 400 and "x must be a number" in body["error"]
    finally:
        s.close()


@pytest.mark.slow
def test_same_centres_as_photogram_measure(tmp_path):
    """The page's refinement is photogram measure's detector: at the
    automatic measurement's own centres (+ a 1.2 px offset click), the
    refined centres agree with results-measure/image_points.csv to a few
    0.001 px (the eccentricity from the true orientation instead of the
    measurement's DLT)."""
    import csv

    from lab_stage import copy_measured_lab
    from photogram.serve.refine import refine_click
    from photogram.serve.session import Session
    folder = copy_measured_lab(tmp_path / "lab")
    prj = lab_copy(tmp_path / "typed")
    import shutil
    shutil.copytree(prj.parent / "results-typed", folder / "results-typed")
    s = Session(folder / "lab-typed.prj", field=folder / "frame.toml")
    try:
        with open(folder / "results-measure" / "image_points.csv", encoding="utf-8") as f:
            rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
        diff = []
        for row in rows:
            m = np.array([float(row["x"]), float(row["y"])])
            r = refine_click(s, s.view(row["station"]), m[0] + 1.0, m[1] + 0.7, row["point"])
            if r["refined"]:
                diff.append(np.hypot(r["x"] - m[0], r["y"] - m[1]))
        assert len(diff) >= 300
        assert np.percentile(diff, 50) < 0.005 and np.percentile(diff, 90) < 0.01
    finally:
        s.close()


def test_no_correction_when_the_adjustment_models_eccentricity(lab):
    """With [targets] (eccentricity in the adjustment) the table takes the
    plain ellipse centre."""
    session, truth = lab
    from photogram.project.model import TargetSettings
    from photogram.serve.refine import refine_click
    xy = truth[("K2a", "T17")]
    corrected = refine_click(session, session.view("K2a"), xy[0] + 1, xy[1], "T17")
    session.project.targets = TargetSettings(eccentricity=True, diameter=0.016)
    plain = refine_click(session, session.view("K2a"), xy[0] + 1, xy[1], "T17")
    assert corrected["method"] == "ellipse+eccentricity" and plain["method"] == "ellipse"
    assert "[targets] models it in the adjustment" in plain["note"]
    assert 0.005 < np.hypot(plain["x"] - corrected["x"], plain["y"] - corrected["y"]) < 0.02
