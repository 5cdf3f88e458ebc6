"""``interior.csv`` of a results folder: the interior unknowns of a project
whose cameras share parameters (docs/project-files.md, "Parameter
sharing"), one row per unknown: a parameter shared by several cameras or
tied to another (``fy = fx``) once, a per-station parameter once per
station. Written only when a camera shares a parameter (the rows are
``summary["interior"]``, :func:`photogram.bundle.shared_interior.interior_rows`).
"""

from __future__ import annotations

from photogram.project.tables import format_table

__all__ = ["INTERIOR_FILE", "interior_table"]

INTERIOR_FILE = "interior.csv"


def interior_table(rows) -> str:
    """CSV text of the interior unknowns: ``unknown`` (the covariance.npz
    ``interior_labels``), ``cameras`` (space-separated), ``parameter``,
    ``equal`` (parameters tied to it, space-separated), ``station`` (per
    station; else empty), ``group`` (shared across cameras; else empty),
    ``value``, ``free`` (0/1), ``est_sigma`` (a-posteriori; empty when
    fixed)."""
    cols = {"unknown": [r["label"] for r in rows],
            "cameras": [" ".join(r["cameras"]) for r in rows],
            "parameter": [r["parameter"] for r in rows],
            "equal": [" ".join(r["equal"]) for r in rows],
            "station": [r["station"] or "" for r in rows],
            "group": [r["group"] or "" for r in rows],
            "value": [float(r["value"]) for r in rows],
            "free": [int(bool(r["free"])) for r in rows],
            "est_sigma": [float("nan") if r["sigma"] is None else float(r["sigma"])
                          for r in rows]}
    return format_table(cols, comment="interior unknowns: shared parameters once, "
                                      "per-station parameters per station")
