"""What the pipeline produces, before a command writes it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import GeometryError
from photogram.stats.reliability import normalized_residuals


@dataclass
class BundleResult:
    """Everything a command produces, before it is written."""

    project: object                     # Project with the estimated values
    summary: dict
    camera_sigma: dict
    station_sigma: np.ndarray           # (n_s, 6), angles in radians
    point_sigma: np.ndarray             # (n_p, 3)
    residuals: dict                     # column -> array
    covariances: dict = field(default_factory=dict)
    point_extra: dict = field(default_factory=dict)   # further points.csv columns


def residual_columns(problem, redundancy):
    """One row per image observation: residuals, normalized residuals and
    redundancy numbers."""
    w = normalized_residuals(problem, redundancy)
    cols = {k: [] for k in ("station", "point", "x", "y", "vx", "vy", "wx", "wy", "rx", "ry", "used")}
    for k, blk in enumerate(problem.blocks):
        if blk.name != "image points":
            continue
        e, _ = blk.evaluate(problem.state, jacobians=False)      # residuals only
        cols["station"].append(blk.station)
        cols["point"].append(blk.point)
        cols["x"].append(blk.xy[:, 0])
        cols["y"].append(blk.xy[:, 1])
        cols["vx"].append(e[:, 0])
        cols["vy"].append(e[:, 1])
        cols["wx"].append(w[k][:, 0])
        cols["wy"].append(w[k][:, 1])
        cols["rx"].append(redundancy[k][:, 0])
        cols["ry"].append(redundancy[k][:, 1])
        cols["used"].append(problem.active[k].astype(int))
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items()}


def check_finite(result):
    """Never write NaN or infinity as an estimate."""
    p = result.project
    seen = np.bincount(p.image_points.point, minlength=len(p.points)) > 0
    arrays = {"points": p.points.xyz[seen], "stations": p.stations.position,
              "angles": p.stations.angles, "point sigmas": result.point_sigma[seen],
              "station sigmas": result.station_sigma}
    bad = [k for k, a in arrays.items() if not np.all(np.isfinite(a))]
    bad += [f"camera {n}" for n, c in p.cameras.items() if not np.all(np.isfinite(c.values()))]
    if bad:
        raise GeometryError(f"the adjustment produced non-finite {', '.join(bad)}",
                            hint="the network is too weak or the start too far off")
