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

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import PhotogramError
from photogram.lines.views import ViewCamera, cameras_from_project

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
    summary_path = folder / "summary.json"
    if not summary_path.is_file():
        return Orientation(note=f"{NOT_ORIENTED} (no results in {folder})")
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
        sigma0 = summary.get("sigma0")
        sigma0 = float(sigma0) if isinstance(sigma0, (int, float)) else None
        command = str(summary.get("command", "adjustment"))
        residuals = _residuals(folder / "residuals.csv")
        cameras = _cameras(project, folder)
    except (PhotogramError, OSError, ValueError, KeyError) as exc:
        text = exc.one_line() if isinstance(exc, PhotogramError) else str(exc)
        return Orientation(note=f"{NOT_ORIENTED} (cannot read {folder}: {text})")
    if not cameras:
        return Orientation(note=f"{NOT_ORIENTED} (no stations in {folder / 'stations.csv'})",
                           sigma0=sigma0, residuals=residuals)
    s0 = f", sigma0 {sigma0:.2f}" if sigma0 is not None else ""
    return Orientation(cameras, f"stations oriented from {folder.name}/ ({command}{s0})",
                       sigma0, residuals)


def _cameras(project, folder: Path) -> dict[str, ViewCamera]:
    """ViewCameras of the stations of ``folder``/stations.csv with the
    cameras of ``folder``/cameras.toml."""
    from photogram.geometry import opk_to_matrix
    from photogram.project.camera_schema import invert_opk, load_cameras_file
    from photogram.project.results_read import read_results_table
    from photogram.project.tables import angle_to_rad
    _, cams = load_cameras_file(folder / "cameras.toml")
    table = read_results_table(folder / "stations.csv", ("station", "camera"))
    unit = project.units.angle
    out = {}
    for _, r in table.iterrows():
        cam = cams.get(r["camera"]) or project.cameras.get(r["camera"])
        if cam is None:
            continue
        angles = np.array([angle_to_rad(float(r[k]), unit) for k in ("omega", "phi", "kappa")])
        if project.rotation_direction == "camera_to_world":
            angles = invert_opk(angles[None])[0]
        X0 = np.array([float(r[k]) for k in ("X0", "Y0", "Z0")])
        if not (np.isfinite(angles).all() and np.isfinite(X0).all()):
            continue
        out[str(r["station"])] = ViewCamera(opk_to_matrix(angles), X0, cam.values(),
                                            cam.model, str(r["station"]))
    return out


def _residuals(path: Path) -> list[dict]:
    """Rows of residuals.csv: station, point, vx, vy, w = max(|wx|, |wy|)."""
    if not path.is_file():
        return []
    from photogram.project.results_read import read_results_table
    table = read_results_table(path, ("station", "point", "line"))
    if "point" not in table.columns:
        return []
    rows = []
    for _, r in table.iterrows():
        pt = r["point"]
        if not isinstance(pt, str) or not pt:
            continue
        wx, wy = float(r.get("wx", np.nan)), float(r.get("wy", np.nan))
        w = max(abs(wx), abs(wy)) if np.isfinite([wx, wy]).all() else 0.0
        rows.append({"view": str(r["station"]), "point": pt, "vx": float(r["vx"]),
                     "vy": float(r["vy"]), "w": w})
    return rows


def residual_rows(orientation: Orientation, oid_of) -> tuple[list[dict], list[dict]]:
    """The residuals with the oid of their observation (``oid_of(view,
    point)`` or None) and the 20 largest |w| (descending)."""
    rows = [{"oid": oid_of(r["view"], r["point"]), **r} for r in orientation.residuals]
    worst = sorted(rows, key=lambda r: -abs(r["w"]))[:20]
    return rows, worst
