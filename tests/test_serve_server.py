"""The HTTP server of photogram measure --serve (photogram/serve/server.py,
api.py): token and Host checks, the project body, images, errors as one
JSON line; against a server on port 0 in a thread (no browser)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from serve_fixtures import Running, lab_copy


@pytest.fixture
def session(tmp_path):
    from photogram.serve.session import Session
    with Session(lab_copy(tmp_path / "lab")) as s:
        yield s


def test_token_and_host_are_checked(session):
    with Running(session) as r:
        assert r.server.server_address[0] == "127.0.0.1"
        assert r.request("GET", "/api/project")[0] == 200
        status, body = r.request("GET", "/api/project", token=False)
        assert status == 403 and "token" in body["error"]
        assert r.request("GET", "/api/project", token="x" * 32)[0] == 403
        # DNS rebinding: the right token from a page served under another name
        status, body = r.request("GET", "/api/project", host=f"evil.example:{r.port}")
        assert status == 403 and "Host" in body["error"]
        assert r.request("GET", "/api/project", host="127.0.0.1:1")[0] == 403
        assert r.request("GET", "/api/project", host=f"localhost:{r.port}")[0] == 200
        # a POST without the token changes nothing
        status, _ = r.request("POST", "/api/edit", {"op": "delete", "oid": 0}, token=False)
        assert status == 403
        assert len(session.points_table.rows) == 446 and not session.dirty
        # images take the token in the query
        status, png = r.request("GET", f"/api/image?view=K1a&token={r.token}", token=False)
        assert status == 200 and png[:8] == b"\x89PNG\r\n\x1a\n"
        assert r.request("GET", "/api/image?view=K1a&token=wrong", token=False)[0] == 403


def test_project_body_and_image(session):
    with Running(session) as r:
        status, body = r.request("GET", "/api/project")
        assert status == 200
        assert body["name"] == "lab" and body["exposures"] is None
        assert body["table"].endswith("lab_image_points.csv") and body["lines_table"] is None
        assert [v["id"] for v in body["views"]] == ["K1a", "K1b", "K1c", "K2a", "K2b", "K2c",
                                                     "K3a", "K3b", "K3c"]
        assert all(v["ok"] and (v["width"], v["height"]) == (640, 480) for v in body["views"])
        assert body["oriented"] and "sigma0 1.25" in body["orientation_note"]
        assert len(body["points"]) == 50 and len(body["observations"]) == 446
        first = body["observations"][0]     # the first row of lab_image_points.csv
        assert first == {"oid": 0, "view": "K1a", "point": "T01", "x": 185.08, "y": 193.69,
                         "sigma": None, "manual": False}
        # residuals: w = max(|wx|, |wy|); worst sorted by |w|, with the oid of the row
        assert [(w["view"], w["point"], w["w"]) for w in body["worst"]] == \
            [("K1b", "T02", 4.0), ("K2a", "T03", 2.5), ("K1a", "T01", 1.5)]
        assert body["worst"][2]["oid"] == 0
        assert not body["dirty"] and not body["can_undo"]
        status, png = r.request("GET", f"/api/image?view=K2b&token={r.token}")
        img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
        ref = cv2.imread(str(session.views[4].path), cv2.IMREAD_COLOR)
        assert np.array_equal(img, ref)      # full resolution, colour, lossless


def test_errors_are_one_json_line(session, tmp_path):
    with Running(session) as r:
        status, body = r.request("GET", "/api/image?view=../../etc/passwd")
        assert status == 400 and "no view '../../etc/passwd'" in body["error"]
        status, body = r.request("GET", "/api/nothing")
        assert status == 404 and "\n" not in body["error"]
        import http.client
        conn = http.client.HTTPConnection("127.0.0.1", r.port, timeout=10)
        conn.request("POST", "/api/edit", body=b"{not json",
                     headers={"X-Photogram-Token": r.token})
        resp = conn.getresponse()
        assert resp.status == 400 and b"not JSON" in resp.read()
        status, body = r.request("POST", "/api/edit", {"op": "explode"})
        assert status == 400 and "unknown edit op" in body["error"]
        assert r.request("GET", "/static/../serve_fixtures.py", token=False)[0] == 404


def test_index_page_is_served_without_token(session, tmp_path):
    page = tmp_path / "index.html"
    page.write_text("<!doctype html><title>t</title>", encoding="utf-8")
    with Running(session) as r:
        r.server.static = {"index.html": page}
        status, data = r.request("GET", "/", token=False)
        assert status == 200 and data.startswith(b"<!doctype html>")
        assert r.request("GET", "/static/index.html", token=False)[0] == 200
        assert r.request("GET", "/", token=False, host="evil.example")[0] == 403
