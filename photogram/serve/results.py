"""What ``photogram measure --serve`` takes from the project's results
folder: the oriented stations (for the epipolar help), sigma0 and the image
residuals of the last adjustment.

The folder is the project's ``[output] folder`` (default ``results/``), as
``photogram calibrate``/``orient``/``intersect`` write it
(:mod:`photogram.project.results`): ``summary.json`` (command, sigma0),
``cameras.toml`` (the interior orientation used or estimated),
``stations.csv`` (the adjusted exterior orientation, in the project's
length and angle units and rotation direction) and ``residuals.csv``
(``station, point, x, y, vx, vy, wx, wy, ...``; ``w`` the standardized
residuals). A project with ``[track]`` (videos) has oriented stations in
the project itself (the tracker needs them).

Anything missing or unreadable means "not oriented" with a note saying
why: the page then offers no epipolar help but still works.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import PhotogramError
from photogram.lines.views import ViewCamera, cameras_from_project
from photogram.project.results import read_results

__all__ = ["Orientation", "read_orientation", "residual_rows", "NOT_ORIENTED"]

NOT_ORIENTED = "stations not oriented: run photogram orient/calibrate first; no epipolar help"


@dataclass
class Orientation:
    """Oriented views (station -> ViewCamera; empty: not oriented), the note
    for the page, sigma0 and the residual rows of the last adjustment."""

    cameras: dict[str, ViewCamera] = field(default_factory=dict)
    note: str = NOT_ORIENTED
    sigma0: float | None = None
    residuals: list[dict] = field(default_factory=list)

    @property
    def oriented(self) -> bool:
        return bool(self.cameras)


def read_orientation(project) -> Orientation:
    """The orientation of ``project`` (module doc)."""
    if getattr(project, "track", None) is not None:
        src = project.sources.get("stations")
        return Orientation(cameras_from_project(project),
                           f"stations oriented from the project ({src})")
    folder = project.output_folder()
    if not (folder / "summary.json").is_file():
        return Orientation(note=f"{NOT_ORIENTED} (no results in {folder})")
    try:
        res = read_results(folder)
        residuals = _residuals(res.residuals)
        cameras = _cameras(project, res)
    except (PhotogramError, OSError, ValueError, KeyError) as exc:
        text = exc.one_line() if isinstance(exc, PhotogramError) else str(exc)
        return Orientation(note=f"{NOT_ORIENTED} (cannot read {folder}: {text})")
    sigma0 = res.summary.get("sigma0")
    sigma0 = float(sigma0) if isinstance(sigma0, (int, float)) else None
    if not cameras:
        return Orientation(note=f"{NOT_ORIENTED} (no stations in {folder / 'stations.csv'})",
                           sigma0=sigma0, residuals=residuals)
    s0 = f", sigma0 {sigma0:.2f}" if sigma0 is not None else ""
    command = str(res.summary.get("command", "adjustment"))
    return Orientation(cameras, f"stations oriented from {folder.name}/ ({command}{s0})",
                       sigma0, residuals)


def _cameras(project, res) -> dict[str, ViewCamera]:
    """ViewCameras of the stations of a results folder (its stations.csv
    with its cameras.toml, else the project's camera)."""
    from photogram.geometry import opk_to_matrix
    from photogram.project.camera_schema import invert_opk
    from photogram.project.tables import angle_to_rad
    table = res.stations
    unit = project.units.angle
    angles = np.column_stack([[angle_to_rad(float(v), unit) for v in table[k]]
                              for k in ("omega", "phi", "kappa")]).reshape(-1, 3)
    if project.rotation_direction == "camera_to_world" and len(angles):
        angles = invert_opk(angles)
    X0 = table[["X0", "Y0", "Z0"]].to_numpy(float).reshape(-1, 3)
    out = {}
    for station, camera, ang, x0 in zip(table["station"], table["camera"], angles, X0):
        cam = res.cameras.get(camera) or project.cameras.get(camera)
        if cam is None or not (np.isfinite(ang).all() and np.isfinite(x0).all()):
            continue
        out[str(station)] = ViewCamera(opk_to_matrix(ang), x0, cam.values(), cam.model,
                                       str(station))
    return out


def _residuals(table) -> list[dict]:
    """Rows of residuals.csv: station, point, vx, vy, w = max(|wx|, |wy|)
    (0 where the w-tests are missing); line rows left out."""
    if "point" not in table.columns or not len(table):
        return []
    keep = np.array([isinstance(p, str) and p != "" for p in table["point"]], bool)
    t = table[keep]
    nan = np.full(len(t), np.nan)
    wx = t["wx"].to_numpy(float) if "wx" in t.columns else nan
    wy = t["wy"].to_numpy(float) if "wy" in t.columns else nan
    w = np.where(np.isfinite(wx) & np.isfinite(wy), np.maximum(np.abs(wx), np.abs(wy)), 0.0)
    return [{"view": str(st), "point": pt, "vx": float(vx), "vy": float(vy), "w": float(wi)}
            for st, pt, vx, vy, wi in zip(t["station"], t["point"], t["vx"].to_numpy(float),
                                          t["vy"].to_numpy(float), w)]


def residual_rows(orientation: Orientation, oid_of) -> tuple[list[dict], list[dict]]:
    """The residuals with the oid of their observation (``oid_of(view,
    point)`` or None) and the 20 largest |w| (descending)."""
    rows = [{"oid": oid_of(r["view"], r["point"]), **r} for r in orientation.residuals]
    worst = sorted(rows, key=lambda r: -abs(r["w"]))[:20]
    return rows, worst
