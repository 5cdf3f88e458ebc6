"""Rendered photographs of a simulated project's test frame (``projects/lab``).

The example projects are simulated: their true points, stations and
cameras are in ``truth/``. :func:`render_project` photographs the frame
with photogram's own camera model (the ``brown`` model of the truth, so that
the rendered images agree with ``truth/image_points.csv``): every point is
a target plate facing up (+Z) — a retro-reflective dot (white on a black
plate) or, for the points chosen as coded targets, an ArUco marker
(DICT_4X4_50) centred on the point — on a dark background. Each pixel is
split into ``ss x ss`` sub-samples traced back through the camera model
(``image_to_ray``, no iteration for the correction model) onto the plates
(nearest plate wins), then blur, noise and JPEG-free PNG output.

:func:`field_description` writes the target-field description that
``photogram measure`` needs: the markers with the project's **approximate**
coordinates (the points table of the .prj, not the truth) and that table as
the 3D layout of the uncoded targets.

Pixel convention: photogram's (top-left corner of the image at (0, 0)).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from photogram.measure.render3d import Plate, _texture

__all__ = ["read_truth", "render_project", "field_description", "choose_markers"]


def _rows(path: Path) -> list[dict]:
    lines = [ln for ln in Path(path).read_text(encoding="utf-8").splitlines()
             if ln.strip() and not ln.startswith("#")]
    return list(csv.DictReader(lines))


def read_truth(folder) -> dict:
    """The truth tables of a simulated project: points, stations (angles in
    gon, world-to-camera omega-phi-kappa), cameras (brown, px)."""
    folder = Path(folder)
    pts = {r["id"]: np.array([float(r["X"]), float(r["Y"]), float(r["Z"])])
           for r in _rows(folder / "points.csv")}
    gon = np.pi / 200
    st = {r["station"]: (r["camera"], np.array([float(r[k]) for k in ("X0", "Y0", "Z0")]),
                         np.array([float(r[k]) * gon for k in ("omega", "phi", "kappa")]))
          for r in _rows(folder / "stations.csv")}
    names = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2")
    cams = {r["camera"]: np.array([float(r[k]) for k in names])
            for r in _rows(folder / "cameras.csv")}
    return {"points": pts, "stations": st, "cameras": cams}


def choose_markers(points: dict, n_low: int = 5, n_high: int = 4) -> list[str]:
    """Coded points spread over the frame: the ``n_low`` lowest points
    farthest apart (greedy), then the ``n_high`` highest likewise, so that
    they are not in one plane."""
    ids = sorted(points)
    X = np.array([points[i] for i in ids])

    def spread(cand, k):
        chosen = [cand[np.argmin(X[cand, 0] + X[cand, 1])]]
        while len(chosen) < k and len(chosen) < len(cand):
            d = np.min(np.linalg.norm(X[cand][:, None, :2] - X[chosen][None, :, :2], axis=2),
                       axis=1)
            chosen.append(cand[int(np.argmax(d))])
        return chosen

    z = X[:, 2]
    low = np.nonzero(z <= np.percentile(z, 40) + 1e-9)[0]
    high = np.nonzero(z >= np.percentile(z, 85) - 1e-9)[0]
    return [ids[i] for i in spread(low, n_low) + spread(high, n_high)]


def render_project(truth: dict, markers: list[str], size=(640, 480), *, radius: float = 0.008,
                   side: float = 0.03, marker_side: float = 0.07, ss: int = 3,
                   background: float = 40.0, blur: float = 0.7, noise: float = 2.0,
                   seed: int = 0, stations=None) -> dict:
    """Images (uint8, by station) of the frame (module doc); ``stations``:
    only these (the noise of each image depends on the seed and its
    position in the truth's station list, not on this selection)."""
    import cv2
    from photogram.geometry import camera_model, opk_to_matrix
    model = camera_model("brown")
    plates = []
    for k, (pid, X) in enumerate(sorted(truth["points"].items())):
        if pid in markers:
            plates.append(Plate(pid, X, np.array([0, 0, 1.0]), "aruco", side=marker_side,
                                marker=markers.index(pid)))
        else:
            plates.append(Plate(pid, X, np.array([0, 0, 1.0]), "dot", radius=radius, side=side))
    textures = {p.id: _texture(p, 200) for p in plates}
    w, h = size
    out = {}
    e1, e2 = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    for k_st, (name, (cam, X0, angles)) in enumerate(truth["stations"].items()):
        if stations is not None and name not in stations:
            continue
        io = truth["cameras"][cam]
        R = opk_to_matrix(angles)
        buf = np.full((h * ss, w * ss), background, np.float32)
        best = np.full((h * ss, w * ss), np.inf)
        for p in plates:
            half = p.side / 2
            corners = np.array([p.X + a * half * e1 + b * half * e2
                                for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
            if np.any(((corners - X0) @ R.T)[:, 2] >= 0):
                continue                                  # behind the camera
            uv = model.project(corners, angles, X0, io)
            x0, y0 = np.floor(uv.min(axis=0) - 2).astype(int)
            x1, y1 = np.ceil(uv.max(axis=0) + 2).astype(int)
            x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
            if x1 <= x0 or y1 <= y0:
                continue
            yy, xx = np.mgrid[y0 * ss:y1 * ss, x0 * ss:x1 * ss]
            pix = np.column_stack([((xx + 0.5) / ss).ravel(), ((yy + 0.5) / ss).ravel()])
            t = model.image_to_ray(pix, io)
            d = np.column_stack([t[:, 0], -t[:, 1], -np.ones(len(t))]) @ R   # world rays
            with np.errstate(divide="ignore", invalid="ignore"):
                s = ((p.X - X0) @ p.normal) / (d @ p.normal)
            hit = X0 + s[:, None] * d
            a = (hit - p.X) @ e1
            b = (hit - p.X) @ e2
            sub_best = best[y0 * ss:y1 * ss, x0 * ss:x1 * ss].ravel()
            inside = (s > 0) & (np.abs(a) <= half) & (np.abs(b) <= half) & (s < sub_best)
            if not inside.any():
                continue
            mu = ((a[inside] + half) / p.side * 200 - 0.5).astype(np.float32)
            mv = ((half - b[inside]) / p.side * 200 - 0.5).astype(np.float32)
            val = cv2.remap(textures[p.id], mu.reshape(1, -1), mv.reshape(1, -1),
                            cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).ravel()
            region = buf[y0 * ss:y1 * ss, x0 * ss:x1 * ss].reshape(-1).copy()
            region[inside] = val
            buf[y0 * ss:y1 * ss, x0 * ss:x1 * ss] = region.reshape(yy.shape)
            sub_best[inside] = s[inside]
            best[y0 * ss:y1 * ss, x0 * ss:x1 * ss] = sub_best.reshape(yy.shape)
        img = buf.reshape(h, ss, w, ss).mean(axis=(1, 3)).astype(np.float64)
        if blur > 0:
            img = cv2.GaussianBlur(img, (0, 0), blur)
        if noise > 0:
            img += np.random.default_rng([seed, k_st]).normal(0, noise, img.shape)
        out[name] = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return out


def field_description(markers: list[str], approx: dict, *, points_file: str, images: str,
                      diameter: float = 0.016, name: str = "lab frame") -> str:
    """The target-field TOML of the rendered frame (module doc)."""
    lines = ["# Target field of the rendered lab frame (photogram/measure/scenes.py):",
             "# retro-reflective dots on black plates, ArUco markers on the coded points.",
             "# Coordinates: the project's approximate points table (truth + ~1 cm).",
             "[field]", f'name = "{name}"', f'images = "{images}"', 'polarity = "bright"',
             f"diameter = {diameter}", "min_diameter = 4", "max_diameter = 60", "",
             "[aruco]", 'dictionary = "DICT_4X4_50"', "sigma = 0.05", ""]
    for k, pid in enumerate(markers):
        X = approx[pid]
        lines += ["[[aruco.marker]]", f"id = {k}", f'point = "{pid}"',
                  f"xyz = [{float(X[0])!r}, {float(X[1])!r}, {float(X[2])!r}]", ""]
    lines += ["[targets]", f'file = "{points_file}"',
              "normal = [0, 0, 1]          # the plates face up (eccentricity correction)", ""]
    return "\n".join(lines)
