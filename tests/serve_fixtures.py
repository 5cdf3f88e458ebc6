"""A copy of projects/lab for the tests of ``photogram measure --serve``
(tests/test_serve_*.py): the rendered photographs with their truth, the
typed observations (``lab-typed.prj`` reads ``lab_image_points.csv``) and,
when ``oriented``, a results folder ``results-typed/`` whose cameras and
stations (and points) are the *true* ones (truth/cameras.csv, truth/stations.csv), so
that epipolar curves and predictions can be checked against the true
geometry; its residuals.csv holds three made-up rows with known w."""

from __future__ import annotations

import csv
import json
import shutil
import threading
from pathlib import Path

import numpy as np

LAB = Path(__file__).resolve().parents[1] / "projects" / "lab"


def _rows(path: Path) -> list[dict]:
    with open(path, encoding="utf-8") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def truth_points(folder: Path) -> dict:
    """(station, point) -> true image xy (noise-free projection of the
    target centre), from truth/image_points.csv."""
    return {(r["station"], r["point"]): np.array([float(r["x"]), float(r["y"])])
            for r in _rows(Path(folder) / "truth" / "image_points.csv")}


def truth_xyz(folder: Path) -> dict:
    """point -> true object coordinates (m), truth/points.csv."""
    return {r["id"]: np.array([float(r["X"]), float(r["Y"]), float(r["Z"])])
            for r in _rows(Path(folder) / "truth" / "points.csv")}


def truth_cameras(folder: Path) -> dict:
    """station -> photogram.lines.views.ViewCamera of the true geometry."""
    from photogram.lines.views import ViewCamera
    folder = Path(folder)
    cams = {r["camera"]: r for r in _rows(folder / "truth" / "cameras.csv")}
    out = {}
    for r in _rows(folder / "truth" / "stations.csv"):
        c = cams[r["camera"]]
        io = [float(c[k]) for k in ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2")]
        ang = np.array([float(r[k]) for k in ("omega", "phi", "kappa")]) * np.pi / 200
        out[r["station"]] = ViewCamera.from_angles(
            ang, [float(r[k]) for k in ("X0", "Y0", "Z0")], io, "brown", r["station"])
    return out


def lab_copy(dest: Path, *, oriented: bool = True) -> Path:
    """Copy projects/lab (no results folders) to ``dest``; with
    ``oriented`` write results-typed/ from the truth (module doc). Returns
    the path of lab-typed.prj."""
    dest = Path(dest)
    shutil.copytree(LAB, dest, ignore=shutil.ignore_patterns("results", "results-*", ".*"))
    if oriented:
        out = dest / "results-typed"
        out.mkdir()
        cams = _rows(dest / "truth" / "cameras.csv")
        text = ['[project]', 'image_unit = "px"', '']
        for c in cams:
            text += [f'[cameras.{c["camera"]}]', 'model = "brown"', "image_size = [640, 480]",
                     "pixel_size = [0.01, 0.01]"]
            text += [f"{k} = {float(c[k])!r}" for k in
                     ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2")] + [""]
        (out / "cameras.toml").write_text("\n".join(text), encoding="utf-8")
        shutil.copy(dest / "truth" / "stations.csv", out / "stations.csv")
        shutil.copy(dest / "truth" / "points.csv", out / "points.csv")
        (out / "summary.json").write_text(json.dumps({"command": "calibrate", "sigma0": 1.25}),
                                          encoding="utf-8")
        (out / "residuals.csv").write_text(
            "station,point,x,y,vx,vy,wx,wy,rx,ry,used\n"
            "K1a,T01,185.08,193.69,0.1,-0.2,0.5,-1.5,0.7,0.7,1\n"
            "K1b,T02,0,0,0.3,0.4,4.0,-0.5,0.7,0.7,1\n"
            "K2a,T03,0,0,-0.05,0.02,-0.2,2.5,0.7,0.7,1\n", encoding="utf-8")
    return dest / "lab-typed.prj"


class Running:
    """A server over a session in a thread (``with Running(session) as r``:
    ``r.port``, ``r.token``, ``r.request(...)``)."""

    def __init__(self, session):
        from photogram.serve.server import make_server
        self.server = make_server(session, 0)
        self.port = self.server.server_address[1]
        self.token = self.server.token

    def __enter__(self):
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.server.shutdown()
        self.server.server_close()

    def request(self, method: str, path: str, body=None, *, token=True, host=None):
        """(status, parsed JSON or bytes) of one request."""
        import http.client
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=30)
        headers = {"Host": host or f"127.0.0.1:{self.port}"}
        if token:
            headers["X-Photogram-Token"] = self.token if token is True else token
        data = None if body is None else json.dumps(body).encode()
        if data is not None:
            headers["Content-Type"] = "application/json"
        conn.request(method, path, body=data, headers=headers)
        r = conn.getresponse()
        raw = r.read()
        conn.close()
        ctype = r.getheader("Content-Type", "")
        return r.status, (json.loads(raw) if ctype.startswith("application/json") else raw)


TINY_TRACK_PRJ = """[project]
name = "tiny-track"
length_unit = "m"
angle_unit = "gon"
image_unit = "px"

[cameras.K]
model = "brown"
image_size = [64, 48]
pixel_size = [0.01, 0.01]
c = 60.0
x0 = 32.0
y0 = 24.0

[stations]
file = "stations.csv"

[track]
videos = { S1 = "video/S1", S2 = "video/S2" }
seeds = "seeds.csv"
exposures = "frames.csv"
offsets = { S2 = 2 }
"""


def tiny_video_project(folder) -> Path:
    """A small made-up track project in ``folder`` (created): two stations
    whose recordings are folders of PNG frames (frame k uniform grey level
    10 k, so the frame shown is known exactly), the tracked tables in
    results/; returns its .prj."""
    import cv2

    folder.mkdir()
    (folder / "track.prj").write_text(TINY_TRACK_PRJ, encoding="utf-8")
    (folder / "stations.csv").write_text(
        "station,camera,X0,Y0,Z0,omega,phi,kappa\nS1,K,0,0,10,0,0,0\nS2,K,2,0,10,0,0,0\n",
        encoding="utf-8")
    (folder / "seeds.csv").write_text("station,frame,marker,x,y\nS1,0,P1,10,10\n",
                                      encoding="utf-8")
    (folder / "frames.csv").write_text("exposure,frame\n001,3\n002,4\n", encoding="utf-8")
    for st in ("S1", "S2"):
        (folder / "video" / st).mkdir(parents=True)
        for k in range(8):
            img = np.full((48, 64, 3), 10 * k, np.uint8)
            cv2.imwrite(str(folder / "video" / st / f"{k:06d}.png"), img)
    out = folder / "results"
    out.mkdir()
    (out / "jumper_points.csv").write_text(
        "# tracked\nexposure,station,point,x,y,sigma\n001,S1,P1,32.0,24.0,0.05\n"
        "001,S2,P1,20.0,24.0,0.05\n002,S1,P1,33.0,24.0,0.05\n", encoding="utf-8")
    (out / "ski_lines.csv").write_text(
        "exposure,station,line,x,y,sigma\n001,S1,L1,10,30,0.2\n001,S1,L1,50,32,0.2\n",
        encoding="utf-8")
    return folder / "track.prj"
