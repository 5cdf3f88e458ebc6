"""BAL problems (Bundle Adjustment in the Large) into a photogram project.

The file is read by :func:`photogram.io.bal.read_bal` (the engine's BAL
reader); this module only turns it into a project: one camera of model
``bal`` (f, k1, k2, all free) and one station per BAL camera (``C0``,
``S0``, ...), ``R = rodrigues(r)``, ``X0 = -R^T t`` (BAL's camera looks along
-z like photogram's), image coordinates ``(x, -y)`` (BAL's y is up; origin at
the image centre, in px), the points as tie points with BAL's coordinates as
approximations, unit image sigmas, free datum. Points seen by fewer than two
cameras cannot be adjusted and are left out with their observation.

Lost: nothing of the problem; the image size is unknown (BAL has none).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

__all__ = ["bal_project"]

log = logging.getLogger("photogram")


def bal_project(path, name: str | None = None):
    """The project of a BAL problem file (plain, .bz2 or .gz)."""
    from photogram.geometry import matrix_to_opk, rodrigues_to_matrix
    from photogram.io.bal import read_bal
    from photogram.io.exchange import build_project
    from photogram.project.model import Camera, Parameter
    bal = read_bal(path)
    n_c = bal.n_cameras
    R = rodrigues_to_matrix(bal.cameras[:, :3])
    X0 = -np.einsum("nji,nj->ni", R, bal.cameras[:, 3:6])
    cameras = {f"C{k}": Camera(f"C{k}", "bal", {n: Parameter(float(v), free=True) for n, v in
                                               zip(("f", "k1", "k2"), bal.cameras[k, 6:9])},
                               source=str(path)) for k in range(n_c)}
    rays = np.bincount(bal.point, minlength=bal.n_points)
    keep = rays[bal.point] >= 2
    if not keep.all():
        log.warning("%s: %d point(s) seen by one camera left out", path,
                    int(np.sum(rays == 1)))
    used = np.flatnonzero(rays >= 2)
    return build_project(name or bal.name or Path(path).stem, cameras,
                         stations=[f"S{k}" for k in range(n_c)],
                         station_camera=[f"C{k}" for k in range(n_c)],
                         angles=matrix_to_opk(R), X0=X0, point_ids=[str(i) for i in used],
                         xyz=bal.points[used], obs_station=[f"S{c}" for c in bal.camera[keep]],
                         obs_point=[str(p) for p in bal.point[keep]],
                         obs_xy=bal.xy[keep] * np.array([1.0, -1.0]), datum="free",
                         sigma_image=1.0)
