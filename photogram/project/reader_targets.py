"""``[targets]`` and the points table's ``diameter``, ``nX nY nZ``: circular
targets whose image points are ellipse centres (docs/project-files.md,
"Circular targets"; docs/adjustment.md, "Eccentricity of circular
targets").

A point is a circular target when it has a diameter (its own, or the
section's default) greater than zero; its normal is its own ``nX nY nZ`` or
the section's ``normal``. Without the section and without diameters in
the points table nothing changes (the adjustment predicts the projection of
each point, as before). ``eccentricity = false`` switches the correction
off while keeping the values.
"""

from __future__ import annotations

import math

import numpy as np

from photogram.errors import InputError
from photogram.project.model import Project, TargetSettings
from photogram.project.toml_source import Section

__all__ = ["TARGET_COLUMNS", "TARGETS_KEYS", "read_targets"]

TARGET_COLUMNS = ("diameter", "nX", "nY", "nZ")
TARGETS_KEYS = ("eccentricity", "diameter", "normal")


def _normal(sec: Section):
    if "normal" not in sec:
        return None
    v = sec.data["normal"]
    if (not isinstance(v, list) or len(v) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v)
            or not all(math.isfinite(x) for x in v) or math.hypot(*v) == 0):
        raise sec.error("normal", f"normal in [targets] must be 3 numbers, not all zero, "
                                  f"not {v!r}",
                        hint="e.g. normal = [0, 0, 1] for a sheet in the plane Z = 0")
    return tuple(float(x) for x in v)


def read_targets(sec: Section | None, project: Project) -> None:
    """Set ``project.targets`` (None when no point is a circular target)."""
    pts = project.points
    n = len(pts)
    settings = TargetSettings()
    if sec is not None:
        sec.check_keys(TARGETS_KEYS)
        settings = TargetSettings(
            eccentricity=sec.boolean("eccentricity", True),
            diameter=sec.number("diameter", None, nonnegative=True),
            normal=_normal(sec))
    own_d = pts.diameter if pts.diameter is not None else np.full(n, np.nan)
    own_n = pts.normal if pts.normal is not None else np.full((n, 3), np.nan)
    if sec is None and not np.isfinite(own_d).any():
        project.targets = None
        return
    d = np.where(np.isfinite(own_d), own_d,
                 np.nan if settings.diameter is None else settings.diameter)
    nv = own_n.copy()
    if settings.normal is not None:
        nv[~np.isfinite(nv).all(axis=1)] = settings.normal
    where = project.sources.get("points", project.path)
    bad = np.flatnonzero(np.isfinite(own_d) & (own_d < 0))
    if len(bad):
        raise _point_error(project, bad[0], f"point {pts.ids[bad[0]]}: negative diameter",
                           "diameters are >= 0 (0: not a circular target)", where)
    target = np.isfinite(d) & (d > 0)
    length = np.linalg.norm(nv, axis=1)
    lacking = np.flatnonzero(target & ~(np.isfinite(length) & (length > 0)))
    if len(lacking):
        i = lacking[0]
        raise _point_error(project, i, f"point {pts.ids[i]} is a circular target (diameter "
                                       f"{d[i]:g}) without a normal",
                           "give nX nY nZ in the points table or normal = [nX, nY, nZ] in "
                           "[targets]", where)
    settings.ids = list(pts.ids)
    settings.radius = np.where(target, d / 2.0, np.nan)
    settings.normals = np.where(target[:, None], nv / np.where(length > 0, length, 1.0)[:, None],
                                np.nan)
    project.targets = settings


def _point_error(project, i, what, hint, where):
    rec = project.points.record
    line = int(rec[i]) if rec is not None and len(rec) > i and rec[i] > 0 else None
    return InputError(what, file=where, line=line, hint=hint)
