"""Intersection geometry of the adjusted points: the largest angle between
two rays of every point, and the points whose rays are nearly parallel.

A point's depth along its rays is determined only through the angle between
them: with a largest intersection angle ``gamma`` its depth sigma is roughly
``sigma_lateral / sin(gamma)``. Points below :data:`WEAK_ANGLE_DEG` are
*weak*: they are adjusted and written, but flagged (summary warnings, a
``weak_angle`` column in points.csv, the report's geometry page).

The report computes the same angle from a results folder
(:attr:`photogram.report.data.ReportData.rays`, the angle at the point
between the rays to the projection centres of its used observations); this
module computes it from arrays, for the commands.
"""

from __future__ import annotations

import numpy as np

__all__ = ["WEAK_ANGLE_DEG", "intersection_angles", "weak_points", "weak_angle_warning",
           "problem_intersection_angles"]

#: points whose largest intersection angle (degrees) is below this are weak
WEAK_ANGLE_DEG = 5.0


def intersection_angles(xyz, centres, station, point, n_points=None) -> np.ndarray:
    """Largest angle (degrees) at each point between two of its rays.

    Parameters
    ----------
    xyz : (n_points, 3) point coordinates
    centres : (n_stations, 3) projection centres
    station, point : (n_obs,) int, the station and point of every ray
    n_points : int, optional (default ``len(xyz)``)

    Returns
    -------
    (n_points,) float
        NaN for points with fewer than 2 rays or non-finite coordinates.
    """
    xyz = np.asarray(xyz, dtype=float).reshape(-1, 3)
    centres = np.asarray(centres, dtype=float).reshape(-1, 3)
    station = np.asarray(station, dtype=int)
    point = np.asarray(point, dtype=int)
    n = len(xyz) if n_points is None else int(n_points)
    out = np.full(n, np.nan)
    if not len(point):
        return out
    u = centres[station] - xyz[point]
    norm = np.linalg.norm(u, axis=1, keepdims=True)
    ok = np.all(np.isfinite(u), axis=1) & (norm[:, 0] > 0)
    u = np.where(ok[:, None], u / np.where(norm > 0, norm, 1.0), np.nan)
    order = np.argsort(point, kind="stable")
    p_sorted = point[order]
    starts = np.flatnonzero(np.r_[True, p_sorted[1:] != p_sorted[:-1]])
    ends = np.r_[starts[1:], len(p_sorted)]
    for a, b in zip(starts, ends):
        if b - a < 2:
            continue
        U = u[order[a:b]]
        U = U[np.all(np.isfinite(U), axis=1)]
        if len(U) < 2:
            continue
        cos = np.clip(U @ U.T, -1.0, 1.0)
        out[p_sorted[a]] = float(np.degrees(np.arccos(cos.min())))
    return out


def problem_intersection_angles(problem, active_only=True) -> np.ndarray:
    """:func:`intersection_angles` of an adjustment problem at its current
    state (image-point observations; rejected ones left out when
    ``active_only``)."""
    st, pt = [], []
    for k, blk in enumerate(problem.blocks):
        if blk.name != "image points":
            continue
        use = np.asarray(problem.active[k], dtype=bool) if active_only else \
            np.ones(len(blk.point), dtype=bool)
        st.append(np.asarray(blk.station)[use])
        pt.append(np.asarray(blk.point)[use])
    state = problem.state
    if not st:
        return np.full(len(state.points), np.nan)
    return intersection_angles(state.points, state.X0, np.concatenate(st), np.concatenate(pt))


def weak_points(angles, threshold: float = WEAK_ANGLE_DEG) -> np.ndarray:
    """Boolean mask of the points with 2+ rays whose largest intersection
    angle is below ``threshold`` degrees (NaN angles are not weak)."""
    a = np.asarray(angles, dtype=float)
    return np.isfinite(a) & (a < threshold)


def weak_angle_warning(ids, angles, threshold: float = WEAK_ANGLE_DEG, limit: int = 10):
    """The summary warning naming the weak points, or None."""
    weak = np.flatnonzero(weak_points(angles, threshold))
    if not len(weak):
        return None
    a = np.asarray(angles, dtype=float)
    weak = weak[np.argsort(a[weak], kind="stable")]
    names = ", ".join(f"{ids[i]} ({a[i]:.2g} deg)" for i in weak[:limit])
    more = f" and {len(weak) - limit} more" if len(weak) > limit else ""
    return (f"{len(weak)} point(s) with intersection angle below {threshold:g} deg "
            f"(weak depth): {names}{more}")
