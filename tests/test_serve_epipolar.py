"""Epipolar curves, predicted points and predicted ski lines
(photogram/serve/epipolar.py) against the true geometry of the lab: the
lab copy's results-typed/ holds the true cameras and stations, so the
image of a ray is known exactly (truth/image_points.csv, truth/points.csv)."""

from __future__ import annotations

import numpy as np
import pytest

from serve_fixtures import Running, lab_copy, truth_cameras, truth_points, truth_xyz


@pytest.fixture
def lab(tmp_path):
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab")
    with Session(prj) as s:
        yield s, prj.parent


def _ray_distance(cam, xy, X0, d):
    """Shortest distance (m) between the ray of image point xy in cam and the
    line X0 + t d."""
    e = cam.rays(cam.ideal(np.atleast_2d(xy)))[0]
    n = np.cross(e, d)
    return abs((X0 - cam.X0) @ n) / np.linalg.norm(n)


def test_epipolar_curve_is_the_image_of_the_true_ray(lab):
    """Every vertex of the curve in every other view sees the true ray of
    the clicked point (T17 in K1a at its true image position), and the curve
    passes through the true image of T17 in each view."""
    session, folder = lab
    from photogram.serve.epipolar import epipolar_help
    truth, cams, xyz = truth_points(folder), truth_cameras(folder), truth_xyz(folder)
    click = truth[("K1a", "T17")]
    out = epipolar_help(session, view=session.view("K1a"), xy=tuple(click))
    assert [c["view"] for c in out["lines"]] == ["K1b", "K1c", "K2a", "K2b", "K2c",
                                                 "K3a", "K3b", "K3c"]
    d = xyz["T17"] - cams["K1a"].X0
    d /= np.linalg.norm(d)
    for curve in out["lines"]:
        pts = np.array(curve["points"])
        assert len(pts) >= 20
        assert (pts >= 0).all() and (pts[:, 0] <= 640).all() and (pts[:, 1] <= 480).all()
        # ends on the image border (clipped, not stopped short)
        for end in (pts[0], pts[-1]):
            assert min(end[0], end[1], 640 - end[0], 480 - end[1]) < 1e-6
        cam = cams[curve["view"]]
        far = max(_ray_distance(cam, p, cams["K1a"].X0, d) for p in pts)
        assert far < 1e-7          # m: at 2-4 m, a few 1e-5 px
        a, seg = pts[:-1], np.diff(pts, axis=0)
        t = np.clip(((truth[(curve["view"], "T17")] - a) * seg).sum(1) / (seg * seg).sum(1), 0, 1)
        gap = np.hypot(*(a + t[:, None] * seg - truth[(curve["view"], "T17")]).T).min()
        assert gap < 1e-3          # px: the chords of the (distorted) curve


def test_prediction_from_two_true_rays_is_the_true_image(lab):
    """T17's observations reduced to two, moved to their true positions: the
    predicted positions in the other seven views are the true image points
    (the midpoint of two exact rays is the true point)."""
    session, folder = lab
    from photogram.serve.epipolar import epipolar_help
    truth = truth_points(folder)
    rows = [r for r in session.points_table.rows if r.cells["point"] == "T17"]
    for r in rows:
        if r.cells["station"] in ("K1a", "K3b"):
            x, y = truth[(r.cells["station"], "T17")]
            session.edit({"op": "move", "oid": r.oid, "x": x, "y": y})
        else:
            session.edit({"op": "delete", "oid": r.oid})
    out = epipolar_help(session, view=session.view("K2a"), point="T17")
    assert out["lines"] == []
    assert sorted(p["view"] for p in out["predicted"]) == ["K1b", "K1c", "K2a", "K2b", "K2c",
                                                           "K3a", "K3c"]
    for p in out["predicted"]:
        # 4 decimals in the table: 5e-5 px per coordinate
        assert np.hypot(p["x"] - truth[(p["view"], "T17")][0],
                        p["y"] - truth[(p["view"], "T17")][1]) < 2e-3


def test_prediction_from_the_typed_observations(lab):
    """With the typed observations (N(0, 0.33 px) noise, README) in eight
    views and a click at the true position in the ninth, the predictions
    are within 1 px (3 sigma of one observation; the triangulated point
    averages nine rays) of the true image points, and the click's own view
    gets no prediction."""
    session, folder = lab
    from photogram.serve.epipolar import epipolar_help
    truth = truth_points(folder)
    rows = {r.cells["station"]: r for r in session.points_table.rows if r.cells["point"] == "T23"}
    session.edit({"op": "delete", "oid": rows["K2c"].oid})
    click = truth[("K2c", "T23")]
    out = epipolar_help(session, view=session.view("K2c"), xy=tuple(click), point="T23")
    assert len(out["predicted"]) == 8 and "K2c" not in {p["view"] for p in out["predicted"]}
    err = [np.hypot(p["x"] - truth[(p["view"], "T23")][0], p["y"] - truth[(p["view"], "T23")][1])
           for p in out["predicted"]]
    assert max(err) < 1.0


def test_epipolar_endpoint_by_oid_and_not_oriented(tmp_path):
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab")
    s = Session(prj)
    with Running(s) as r:
        status, body = r.request("GET", "/api/epipolar?oid=0")     # K1a T01
        assert status == 200 and len(body["lines"]) == 8
        # T01 images outside one format: 7 predictions, none in K1a itself
        assert len(body["predicted"]) == 7 and "K1a" not in {p["view"] for p in body["predicted"]}
        assert r.request("GET", "/api/epipolar?oid=99999")[0] == 400
        assert r.request("GET", "/api/epipolar?view=K1a")[0] == 400
    s.close()
    (prj.parent / "results-typed" / "summary.json").unlink()
    s = Session(prj)
    try:
        assert not s.body()["oriented"]
        assert s.body()["orientation_note"].startswith("stations not oriented: run photogram "
                                                      "orient/calibrate first; no epipolar help")
        from photogram.serve.epipolar import epipolar_help
        out = epipolar_help(s, oid=0)
        assert out["lines"] == [] and out["predicted"] == [] and "not oriented" in out["note"]
    finally:
        s.close()


def test_predicted_ski_line_is_the_image_of_the_true_line(tmp_path):
    """A line through the true T01 and T25 measured (noise-free, 5 points)
    in K1a and K2b: its predicted image in the other views lies on the
    projection of the true 3D line."""
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab")
    folder = prj.parent
    cams, xyz = truth_cameras(folder), truth_xyz(folder)
    A, B = xyz["T01"], xyz["T25"]
    rows = ["station,line,x,y"]
    for st in ("K1a", "K2b"):
        for t in np.linspace(0.1, 0.9, 5):
            x, y = cams[st].project(A + t * (B - A))[0]
            rows.append(f"{st},E1,{x:.6f},{y:.6f}")
    (folder / "lines.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    text = prj.read_text(encoding="utf-8").replace(
        'points = "lab_image_points.csv"', 'points = "lab_image_points.csv"\nlines = "lines.csv"')
    prj.write_text(text, encoding="utf-8")
    s = Session(prj)
    try:
        assert s.body()["lines_table"].endswith("lines.csv") and len(s.body()["lines"]) == 10
        from photogram.serve.epipolar import predicted_line
        out = predicted_line(s, "", "E1")
        assert sorted(c["view"] for c in out["lines"]) == ["K1b", "K1c", "K2a", "K2c",
                                                           "K3a", "K3b", "K3c"]
        d = (B - A) / np.linalg.norm(B - A)
        for c in out["lines"]:
            pts = np.array(c["points"])
            assert len(pts) >= 2
            assert max(_ray_distance(cams[c["view"]], p, A, d) for p in pts) < 1e-5
        assert predicted_line(s, "", "nothing") == {"lines": []}
    finally:
        s.close()


def test_http_predictions_by_label_and_line_errors(lab):
    """GET /api/epipolar?view=..&point=.. and /api/predict_line through the
    server: T17 is measured in all nine views (no prediction left to make)
    until one observation is deleted; a line request without a name is 400."""
    session, folder = lab
    truth = truth_points(folder)
    with Running(session) as r:
        status, body = r.request("GET", "/api/epipolar?view=K2a&point=T17")
        assert status == 200 and body["predicted"] == [] and body["lines"] == []
        oid = next(o.oid for o in session.points_table.rows
                   if o.cells["station"] == "K2a" and o.cells["point"] == "T17")
        r.request("POST", "/api/edit", {"op": "delete", "oid": oid})
        status, body = r.request("GET", "/api/epipolar?view=K2a&point=T17")
        assert [p["view"] for p in body["predicted"]] == ["K2a"]
        p = body["predicted"][0]
        assert np.hypot(p["x"] - truth[("K2a", "T17")][0], p["y"] - truth[("K2a", "T17")][1]) < 1
        status, body = r.request("GET", "/api/predict_line?exposure=")
        assert status == 400 and "line=NAME" in body["error"]
        assert r.request("GET", "/api/predict_line?line=E1") == (200, {"lines": []})


def test_epipolar_curve_of_a_distant_scene():
    """A ray whose visible part is all far away (two stations 10 m apart
    looking at points 2 km off, a ski-jump hill seen from the valley): the
    curve is sampled along the image, not along the ray's parameter (which
    crowds the whole visible ray into its last 0.5 %), so it is found,
    spans the view and passes through the true image of each point."""
    from photogram.lines.views import ViewCamera
    from photogram.serve.epipolar import image_of_ray
    io = [1500.0, 320.0, 240.0, -2e-8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    # looking along +Y: omega = 100 gon turns the camera's -z axis to +Y
    a = ViewCamera.from_angles([np.pi / 2, 0.0, 0.0], [0.0, 0.0, 0.0], io)
    b = ViewCamera.from_angles([np.pi / 2, 0.0, 0.0], [10.0, 0.0, 0.0], io)
    for X in ([30.0, 2000.0, 5.0], [-40.0, 1500.0, -20.0], [5.0, 3000.0, 40.0]):
        X = np.array(X)
        d = X - a.X0
        d /= np.linalg.norm(d)
        truth_b = b.project(X[None])[0]
        assert 0 < truth_b[0] < 640 and 0 < truth_b[1] < 480
        pts = np.array(image_of_ray(b, a.X0, d, 640, 480))
        assert len(pts) >= 20
        seg = np.diff(pts, axis=0)
        t = np.clip(((truth_b - pts[:-1]) * seg).sum(1) / (seg * seg).sum(1), 0, 1)
        assert np.hypot(*(pts[:-1] + t[:, None] * seg - truth_b).T).min() < 1e-3
        # one end on the border (the epipole, the image of a's centre, is far
        # outside), the other at the vanishing point of d inside the view
        v = b.matrix[:, :3] @ d
        vanishing = b.measured((v[:2] / v[2])[None])[0]
        ends = sorted((pts[0], pts[-1]), key=lambda e: np.hypot(*(e - vanishing)))
        assert np.hypot(*(ends[0] - vanishing)) < 1e-6
        assert min(ends[1][0], ends[1][1], 640 - ends[1][0], 480 - ends[1][1]) < 1e-6

