"""The report of the approximation chain: how every station and point was
reached (or why not), as an object, a JSON-friendly dict and console lines.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ChainReport"]


def _f(x):
    """JSON-friendly float (None for NaN)."""
    x = float(x)
    return x if np.isfinite(x) else None


@dataclass
class ChainReport:
    """What the approximation chain reached, how, and what it could not.

    Attributes
    ----------
    frame : str
        ``"control"`` (the project's object frame, fixed by control/given
        points or given stations), ``"model"`` (the arbitrary frame of a
        relative orientation: left camera at the origin with ``R = I``,
        baseline ``|b_x| = 1``) or ``"none"`` (nothing reached).
    stations : dict
        Station name -> dict with ``how`` ("given", "resection",
        "relative orientation"), ``round`` and details (points used,
        residual RMS in image units).
    points : dict
        Point id -> dict with ``how`` ("control", "given", "intersection"),
        ``round``, ``rays``, ``max_angle_deg``.
    unreached_stations, unreached_points : dict
        Name -> reason.
    relative_orientation : dict or None
        The pair, number of points, sigma0 and candidates tried.
    helmert : dict or None
        The transformation into the control frame (points, scale, RMS).
    rounds : int
    messages : list of str
    """

    frame: str = "none"
    stations: dict = field(default_factory=dict)
    points: dict = field(default_factory=dict)
    unreached_stations: dict = field(default_factory=dict)
    unreached_points: dict = field(default_factory=dict)
    relative_orientation: dict | None = None
    helmert: dict | None = None
    rounds: int = 0
    messages: list = field(default_factory=list)

    @property
    def complete(self) -> bool:
        """True when every station and point was reached."""
        return not self.unreached_stations and not self.unreached_points

    def to_dict(self) -> dict:
        """A JSON-serialisable dict (for summary.json)."""
        return {
            "frame": self.frame,
            "rounds": int(self.rounds),
            "complete": self.complete,
            "counts": {
                "stations_reached": len(self.stations),
                "stations_unreached": len(self.unreached_stations),
                "points_reached": len(self.points),
                "points_unreached": len(self.unreached_points),
                "stations_by_method": _count(self.stations),
                "points_by_method": _count(self.points),
            },
            "stations": {k: dict(v) for k, v in self.stations.items()},
            "points": {k: dict(v) for k, v in self.points.items()},
            "unreached_stations": dict(self.unreached_stations),
            "unreached_points": dict(self.unreached_points),
            "relative_orientation": self.relative_orientation,
            "helmert": self.helmert,
            "messages": list(self.messages),
        }

    def summary(self) -> str:
        """A few lines for the console."""
        d = self.to_dict()["counts"]
        lines = [f"approximation chain ({self.frame} frame, {self.rounds} rounds): "
                 f"{d['stations_reached']} stations {d['stations_by_method']}, "
                 f"{d['points_reached']} points {d['points_by_method']}"]
        lines += [f"  {v}" for v in self.unreached_stations.values()]
        lines += [f"  {v}" for v in self.unreached_points.values()]
        lines += [f"  {m}" for m in self.messages]
        return "\n".join(lines)


def _count(d: dict) -> dict:
    out: dict = {}
    for v in d.values():
        out[v["how"]] = out.get(v["how"], 0) + 1
    return out
