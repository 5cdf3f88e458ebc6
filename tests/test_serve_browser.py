"""The measuring page of ``photogram measure --serve`` in a real browser
(issue 24): headless Chromium from the distribution's packages (Debian's
``chromium`` and ``chromium-driver``, installed by .ci/run) driven through
WebDriver by selenium (the test extra of setup.cfg).

One browser session and one server for the module (a copy of the lab
example, its rendered photographs measured and calibrated as `make demo`
does), the steps in order:

* the page loads with its nine views, every observation of the table drawn,
  the orientation note and the list of the largest standardized residuals;
* an observation is selected by a real mouse click and deleted with the
  Delete key, then re-added by a real click a few pixels off the target
  (ActionChains at the screen position of an image coordinate from the
  SVG's ``getScreenCTM``): the server refines the centre, *save* writes the
  table and keeps the original as ``image_points.csv.~1~`` (byte for byte);
  the saved centre is within 0.05 px of the truth: ``truth/image_points.csv``,
  the true projections of the target centres (the rendering's noise-free
  image coordinates; the refinement corrects the eccentricity with the
  field ``frame.toml``);
* Ctrl+Z undoes the addition: the cross disappears from the page and the
  next save has no such row (and keeps the first save as ``.~2~``);
* selecting an observation draws its epipolar polylines in the other views:
  every vertex lies on the projection, computed here with photogram's own
  camera model (:class:`photogram.lines.views.ViewCamera`) from the
  oriented results (results/stations.csv + cameras.toml), of the ray of
  that observation; the line passes through the point's true image in the
  other view, and the predicted positions (the point's rays triangulated)
  agree with the truth;
* the run button runs ``photogram calibrate`` on the saved table and the
  page shows sigma0 and the worst residuals;
* bad input (a second server on another copy): an unreadable photograph's
  reason shown in its view, "not oriented" and no epipolar lines without
  results;
* a video project (a third server: the tiny track project of
  tests/serve_fixtures.py): the exposure selector, a ski-line point added
  by a click and saved to ski_lines.csv.

Skipped with the reason when selenium, chromium or chromedriver is missing.
"""

from __future__ import annotations

import csv
import shutil
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

INSTALL = "apt-get install chromium chromium-driver; pip install selenium"
WAIT_S = 20.0           # generous: a loaded 2-core machine


def _browser_paths():
    """(chromium, chromedriver) or skip naming what is missing."""
    missing = []
    try:
        import selenium  # noqa: F401
    except ImportError:
        missing.append("selenium")
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if chromium is None:
        missing.append("chromium")
    if driver is None:
        missing.append("chromedriver")
    if missing:
        pytest.skip(f"no chromium/chromedriver ({', '.join(missing)} missing): {INSTALL}")
    return chromium, driver


def _read_csv(path: Path) -> list[dict]:
    with open(path, encoding="utf-8", newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def _truth(lab: Path) -> dict:
    return {(r["station"], r["point"]): (float(r["x"]), float(r["y"]))
            for r in _read_csv(lab / "truth" / "image_points.csv")}


class Page:
    """The browser on the page: small helpers over the WebDriver."""

    def __init__(self, driver, lab: Path, url: str):
        self.d, self.lab, self.url = driver, lab, url

    def js(self, script, *args):
        return self.d.execute_script(script, *args)

    def wait(self, script, *args, what="the page"):
        """Until ``script`` returns a true value and no request is pending."""
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end:
            value = self.js("const s = window.photogramState;"
                            "if (!s || !s.ready || s.pending) return null;"
                            "if (s.error) return {pageError: s.error};" + script, *args)
            if isinstance(value, dict) and "pageError" in value:
                raise AssertionError(f"the page says: {value['pageError']} "
                                     f"(waiting for {what})")
            if value:
                return value
            time.sleep(0.1)
        raise AssertionError(f"timed out waiting for {what}; status: {self.status()!r}")

    def leave(self):
        """Let the page go without the unsaved-edits prompt (a prompt would
        block the next navigation, and driver.quit() would leave the browser
        running)."""
        self.js("const s = window.photogramState; if (s && s.project) s.project.dirty = false;")

    def goto(self, url):
        self.leave()
        self.d.get(url)

    def settle(self):
        self.wait("return true;", what="pending requests")

    def status(self) -> str:
        from selenium.webdriver.common.by import By
        return self.d.find_element(By.ID, "status").text

    def observation(self, view, point):
        return self.js("return window.photogramState.project.observations.find("
                       "o => o.view === arguments[0] && o.point === arguments[1]) || null;",
                       view, point)

    def screen(self, view, x, y):
        """Viewport (CSS px) position of image coordinate (x, y) in a view."""
        return self.js("""
            const svg = document.querySelector(`svg.view[data-view="${arguments[0]}"]`);
            const p = svg.createSVGPoint(); p.x = arguments[1]; p.y = arguments[2];
            const q = p.matrixTransform(svg.getScreenCTM());
            return [q.x, q.y];""", view, x, y)

    def click_image(self, view, x, y):
        """A real left click (WebDriver pointer actions) at image (x, y)."""
        from selenium.webdriver.common.action_chains import ActionChains
        sx, sy = self.screen(view, x, y)
        self.js("window.photogramState.error = null;")
        actions = ActionChains(self.d)
        actions.w3c_actions.pointer_action.move_to_location(round(sx), round(sy))
        actions.w3c_actions.pointer_action.click()
        actions.perform()

    def keys(self, *keys, ctrl=False):
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.keys import Keys
        self.js("window.photogramState.error = null;")
        a = ActionChains(self.d)
        if ctrl:
            a.key_down(Keys.CONTROL)
        a.send_keys(*keys)
        if ctrl:
            a.key_up(Keys.CONTROL)
        a.perform()

    def button(self, element_id):
        from selenium.webdriver.common.by import By
        self.js("window.photogramState.error = null;")
        self.d.find_element(By.ID, element_id).click()

    def crosses(self, view, point) -> int:
        return self.js("return document.querySelectorAll("
                       "`svg.view[data-view=\"${arguments[0]}\"] g.ob[data-point=\"${arguments[1]}\"]`"
                       ").length;", view, point)


@pytest.fixture(scope="module")
def page(request, tmp_path_factory):
    """The server (in this process, port 0) over a copy of the measured and
    calibrated lab, and one headless Chromium on its page."""
    chromium, driver_path = _browser_paths()          # skip before any work
    oriented_projects = request.getfixturevalue("oriented_projects")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    from photogram.serve.server import make_server
    from photogram.serve.session import Session

    lab = tmp_path_factory.mktemp("serve") / "lab"
    shutil.copytree(oriented_projects / "lab", lab)
    # the run button's command line (the CLI passes its own)
    session = Session(lab / "lab.prj", field=lab / "frame.toml",
                      run_argv=[sys.executable, "-m", "photogram_cli"])
    server = make_server(session, port=0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    # no sandbox (containers, root), no background services: the browser's
    # CPU for the whole module 2.0 s instead of 2.35 s with the first line only
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                "--in-process-gpu", "--renderer-process-limit=1", "--window-size=1400,1000",
                "--disable-extensions", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run",
                "--mute-audio", "--disable-breakpad",
                "--disable-features=Translate,MediaRouter,OptimizationHints"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(driver_path), options=options)
    try:
        driver.get(server.url)
        p = Page(driver, lab, server.url)
        p.wait("return true;", what="window.photogramState.ready")
        yield p
    finally:
        try:
            Page(driver, lab, server.url).leave()
        finally:
            driver.quit()
        server.shutdown()
        server.server_close()
        session.close()


def test_page_shows_the_project(page):
    table = _read_csv(page.lab / "results-measure" / "image_points.csv")
    assert page.js("return document.querySelectorAll('svg.view').length") == 9
    # every row of the table drawn as a cross with its label
    assert page.js("return document.querySelectorAll('g.obs g.ob').length") == len(table)
    first = table[0]
    assert page.crosses(first["station"], first["point"]) == 1
    note = page.d.find_element("id", "note").text
    assert "oriented" in note and "not oriented" not in note, note
    # the calibration's residuals: the list and the vectors
    worst = page.js("return [...document.querySelectorAll('#worst li[data-oid]')]"
                    ".map(li => li.textContent)")
    assert 1 <= len(worst) <= 20, worst
    residuals = _read_csv(page.lab / "results" / "residuals.csv")
    w_max = max(max(abs(float(r["wx"])), abs(float(r["wy"]))) for r in residuals)
    assert f"w {w_max:.2f}" in worst[0], (worst[0], w_max)
    assert page.js("return document.querySelectorAll('line.res').length") > 0.9 * len(table)


def test_click_refines_saves_with_backup_and_undo(page):
    view, point = "K1a", "T19"
    table = page.lab / "results-measure" / "image_points.csv"
    original = table.read_bytes()
    truth = _truth(page.lab)[(view, point)]
    ob = page.observation(view, point)
    assert ob is not None
    # select it by a click on its cross, delete it with the Delete key
    page.click_image(view, ob["x"], ob["y"])
    page.wait("return s.selected === arguments[0];", ob["oid"], what="the selection")
    page.keys("\ue017")                                     # Keys.DELETE
    page.wait("return !s.project.observations.some(o => o.oid === arguments[0]);",
              ob["oid"], what="the deletion")
    assert page.crosses(view, point) == 0
    # re-add it: type the label, click 2.2 px right and 1.6 px above the target
    label = page.d.find_element("id", "label")
    label.clear()
    label.send_keys(point)
    page.click_image(view, truth[0] + 2.2, truth[1] - 1.6)
    added = page.wait("return s.project.observations.find(o => o.view === arguments[0]"
                      " && o.point === arguments[1]);", view, point, what="the new observation")
    refine = page.js("return window.photogramState.lastRefine;")
    assert refine["refined"] and not added["manual"], refine
    assert page.crosses(view, point) == 1
    page.button("save")
    page.wait("return s.lastSave && !s.project.dirty;", what="the save")
    rows = {(r["station"], r["point"]): r for r in _read_csv(table)}
    x, y = float(rows[view, point]["x"]), float(rows[view, point]["y"])
    assert abs(x - truth[0]) < 0.05 and abs(y - truth[1]) < 0.05, ((x, y), truth, refine)
    assert len(rows) == len(_read_csv(Path(str(table) + ".~1~")))
    assert Path(str(table) + ".~1~").read_bytes() == original
    first_save = table.read_bytes()
    # undo the addition (Ctrl+Z on the page): gone from the page and the next save
    assert page.js("return document.activeElement !== document.getElementById('label');")
    page.keys("z", ctrl=True)
    page.wait("return !s.project.observations.some(o => o.view === arguments[0]"
              " && o.point === arguments[1]);", view, point, what="the undo")
    assert page.crosses(view, point) == 0
    page.button("save")
    page.wait("return !s.project.dirty && s.lastSave.backup.endsWith('.~2~');",
              what="the second save")
    assert (view, point) not in {(r["station"], r["point"]) for r in _read_csv(table)}
    assert Path(str(table) + ".~2~").read_bytes() == first_save
    assert Path(str(table) + ".~1~").read_bytes() == original


def _cameras(lab: Path) -> dict:
    """ViewCameras of the oriented stations (results/stations.csv +
    cameras.toml), with photogram's own camera model."""
    from photogram.geometry import to_radians
    from photogram.lines.views import ViewCamera
    from photogram.project import read_results
    res = read_results(lab / "results")
    unit = (res.summary.get("project") or {}).get("angle_unit", "gon")
    out = {}
    for r in res.stations.itertuples():
        cam = res.cameras[r.camera]
        angles = to_radians(np.array([r.omega, r.phi, r.kappa], dtype=float), unit)
        out[r.station] = ViewCamera.from_angles(angles, [r.X0, r.Y0, r.Z0], cam.values(),
                                                cam.model, r.station)
    return out


def _distance_to_curve(points: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Distance of each point (n, 2) to the polyline ``curve`` (m, 2)."""
    a, b = curve[:-1], curve[1:]
    ab = b - a
    t = np.einsum("mk,nmk->nm", ab, points[:, None] - a) / np.einsum("mk,mk->m", ab, ab)
    foot = a + np.clip(t, 0, 1)[..., None] * ab
    return np.linalg.norm(points[:, None] - foot, axis=2).min(axis=1)


def test_epipolar_lines_where_geometry_says(page):
    view, point = "K1a", "T45"
    page.js("window.photogramState.epipolar = null;")
    ob = page.observation(view, point)
    page.click_image(view, ob["x"], ob["y"])
    page.wait("return s.selected === arguments[0] && s.epipolar;", ob["oid"],
              what="the epipolar lines")
    lines = page.js("""return [...document.querySelectorAll('polyline.epi')].map(p =>
        [p.closest('svg.view').dataset.view, p.dataset.view, p.getAttribute('points')]);""")
    assert len(lines) >= 6, lines                # every other view (of 8) that sees the ray
    cams = _cameras(page.lab)
    a = cams[view]
    ray = a.rays(a.ideal(np.array([[ob["x"], ob["y"]]])))[0]
    depth = np.geomspace(0.02, 1e4, 5000)      # from just before the lens to the horizon
    truth = _truth(page.lab)
    checked = 0
    for svg_view, line_view, text in lines:
        assert svg_view == line_view
        xy = np.array([[float(c) for c in pair.split(",")] for pair in text.split()])
        assert len(xy) >= 20
        b = cams[line_view]
        X = a.X0 + depth[:, None] * ray
        X = X[(X - b.X0) @ b.R[2] < 0]             # in front of camera b (it looks along -z)
        ideal = b.project_ideal(X)
        curve = b.measured(ideal[np.abs(ideal).max(axis=1) < 1000])   # near the format
        d = _distance_to_curve(xy, curve)
        assert d.max() < 0.01, (line_view, d.max())     # measured: < 1e-4 px
        inside = (xy >= -1).all(axis=1) & (xy[:, 0] <= 641) & (xy[:, 1] <= 481)
        assert inside.all(), line_view            # clipped to the image
        if (line_view, point) in truth:           # passes through the point's true image
            t = np.array([truth[line_view, point]])
            assert _distance_to_curve(t, xy)[0] < 0.1, line_view   # measured: < 0.02 px
            checked += 1
    assert checked >= 6
    predicted = page.js("return [...document.querySelectorAll('circle.pred')].map(c =>"
                        "[c.dataset.view, +c.getAttribute('cx'), +c.getAttribute('cy')]);")
    assert predicted, "T45 has several rays: predicted positions expected"
    for pview, cx, cy in predicted:
        if (pview, point) in truth:
            tx, ty = truth[pview, point]
            assert np.hypot(cx - tx, cy - ty) < 0.1, (pview, (cx, cy), (tx, ty))  # < 0.02


def test_run_button_shows_sigma0_and_worst(page):
    page.js("document.getElementById('worst').innerHTML = '';"
            "window.photogramState.lastRun = null;")
    from selenium.webdriver.support.ui import Select
    Select(page.d.find_element("id", "run-command")).select_by_value("calibrate")
    page.button("run")
    run = page.wait("return s.lastRun;", what="photogram calibrate")
    assert run["rc"] == 0, run
    assert 0.5 < run["sigma0"] < 2.0, run
    assert f"sigma0 {run['sigma0']:.3f}" in page.status()
    assert page.js("return document.querySelectorAll('#worst li').length") >= 1


def test_unreadable_image_and_no_orientation_said_on_the_page(page, tmp_path):
    """Bad input on the page (the same browser, a second server, last in
    this module): a photograph that cannot be read shows its reason in its
    view and the message list; without a results folder the page says the
    stations are not oriented and draws no epipolar help."""
    from photogram.serve.server import make_server
    from photogram.serve.session import Session
    lab = tmp_path / "lab"
    shutil.copytree(page.lab, lab, ignore=shutil.ignore_patterns("results", ".*"))
    (lab / "images" / "K2b.jpg").write_bytes(b"not a JPEG file")
    session = Session(lab / "lab.prj", field=lab / "frame.toml")
    server = make_server(session, port=0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        page.goto(server.url)
        page.wait("return s.project && s.project.table.startsWith(arguments[0]);", str(lab),
                  what="the second project")
        note = page.d.find_element("id", "note").text
        assert "not oriented" in note, note
        error = page.js("const f = document.querySelector('svg.view[data-view=\"K2b\"]')"
                        ".closest('figure'); const e = f.querySelector('.view-error');"
                        "return e ? e.textContent : null;")
        assert error and "K2b.jpg" in error, error
        assert error in page.d.find_element("id", "messages").text
        assert page.js("return document.querySelectorAll('svg.view image').length") == 8
        ob = page.observation("K1a", "T45")
        page.click_image("K1a", ob["x"], ob["y"])
        page.wait("return s.selected === arguments[0];", ob["oid"], what="the selection")
        assert "not oriented" in page.d.find_element("id", "epi-note").text
        assert page.js("return document.querySelectorAll('polyline.epi, circle.pred').length") == 0
    finally:
        server.shutdown()
        server.server_close()
        session.close()


def test_video_project_exposures_and_ski_line_points(page, tmp_path):
    """A video project on the page (the tiny two-camera track project of
    tests/serve_fixtures.py): the exposure selector shows one exposure's
    frames; a ski-line label and a real click add a point of that line where
    clicked (an edge, not refined), which the save writes to the tracked
    ski_lines.csv (the original kept as ski_lines.csv.~1~)."""
    from selenium.webdriver.support.ui import Select
    from serve_fixtures import tiny_video_project

    from photogram.serve.server import make_server
    from photogram.serve.session import Session
    prj = tiny_video_project(tmp_path / "tiny")
    lines_csv = prj.parent / "results" / "ski_lines.csv"
    original = lines_csv.read_bytes()
    session = Session(prj)
    server = make_server(session, port=0)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    shown = "return [...document.querySelectorAll('svg.view')].map(v => v.dataset.view);"
    try:
        page.goto(server.url)
        page.wait("return s.project && s.project.exposures;", what="the video project")
        assert page.js(shown) == ["001/S1", "001/S2"]
        # the line of 001/S1 drawn through its two points
        assert page.js("return document.querySelector('svg.view[data-view=\"001/S1\"] "
                       ".lines polyline').getAttribute('points');") == "10,30 50,32"
        page.js("window.photogramState.error = null;")
        Select(page.d.find_element("id", "exposure")).select_by_value("002")
        page.wait("return document.querySelector('svg.view[data-view=\"002/S2\"]');",
                  what="exposure 002")
        assert page.js(shown) == ["002/S1", "002/S2"]
        label = page.d.find_element("id", "label")
        label.clear()
        label.send_keys("L1")
        page.click_image("002/S2", 40.3, 20.6)
        added = page.wait("return s.project.lines.find(p => p.view === '002/S2');",
                          what="the line point")
        assert added["line"] == "L1"
        # where clicked, to the rounding of the click to whole screen pixels
        k = page.js("return 1 / document.querySelector('svg.view[data-view=\"002/S2\"]')"
                    ".getScreenCTM().a;")
        assert abs(added["x"] - 40.3) <= k and abs(added["y"] - 20.6) <= k, (added, k)
        assert page.js("return document.querySelectorAll("
                       "'svg.view[data-view=\"002/S2\"] .lines circle').length") == 1
        page.button("save")
        page.wait("return s.lastSave && !s.project.dirty;", what="the save")
        rows = _read_csv(lines_csv)
        new = [r for r in rows if (r["exposure"], r["station"]) == ("002", "S2")]
        assert len(new) == 1 and new[0]["line"] == "L1"
        assert abs(float(new[0]["x"]) - added["x"]) < 1e-3
        assert Path(str(lines_csv) + ".~1~").read_bytes() == original
    finally:
        server.shutdown()
        server.server_close()
        session.close()
