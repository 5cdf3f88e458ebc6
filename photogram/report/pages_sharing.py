"""Shared interior parameters on the camera pages of the report
(docs/project-files.md, "Parameter sharing"): how each parameter is shared,
and the camera's rows of ``interior.csv`` (shared parameters once,
per-station parameters per station, with their sigmas)."""

from __future__ import annotations

import csv

from photogram.report.numbers import pair

__all__ = ["sharing_note", "per_station_label", "shared_table"]


def sharing_note(cam, pname: str) -> str:
    """``", per station"``, ``", = fx"``, ``", shared (lens)"`` or ``""``."""
    ties = getattr(cam, "ties", {}) or {}
    if pname in ties:
        return f", = {ties[pname]}"
    if pname in (getattr(cam, "per_station", ()) or ()):
        return ", per station (mean)"
    group = (getattr(cam, "shared", {}) or {}).get(pname)
    return f", shared ({group})" if group else ""


def per_station_label(label: str) -> bool:
    """A covariance label of a per-station parameter (``K1.x0@S3``)."""
    return "@" in label


def _rows(data, camera: str):
    path = data.folder / "interior.csv"
    if not path.is_file():
        return []
    with open(path, encoding="utf-8", newline="") as handle:
        lines = [line for line in handle if not line.startswith("#")]
    return [r for r in csv.DictReader(lines) if camera in r["cameras"].split()]


def shared_table(doc, data, camera: str, cam) -> None:
    """The camera's interior unknowns from interior.csv, when it shares any."""
    if not (getattr(cam, "shares", None) and cam.shares()):
        return
    rows = []
    order = {p: i for i, p in enumerate(cam.parameters)}
    stations = {}
    # only what sharing changes (per station, ties, groups), grouped by parameter
    chosen = [r for r in _rows(data, camera) if r["station"] or r["equal"] or r["group"]]
    for r in chosen:
        stations.setdefault(r["station"], len(stations))
    chosen.sort(key=lambda r: (order.get(r["parameter"], len(order)), stations[r["station"]]))
    for r in chosen:
        sigma = float(r["est_sigma"]) if r["est_sigma"] else None
        v, s = pair(float(r["value"]), sigma)
        what = (f"= {r['equal']}" if r["equal"] else "") + \
            (f" group {r['group']}: cameras {r['cameras']}" if r["group"] else "")
        rows.append([r["parameter"], r["station"] or "-", v, s, what.strip()])
    doc.table(["parameter", "station", "value", "sigma", "shared"], rows, align="llrrl",
              title="Shared parameters (interior.csv): per station, tied (=) and shared "
                    "by cameras")
