"""Moving points over exposures (:class:`Trajectories`), as the exporters
read them from a results folder: of ``photogram intersect``
(:mod:`photogram.io.trajectories`) or of ``photogram mocap``
(:mod:`photogram.io.mocap_results`). Its own module, so that both loaders
import it and neither imports the other back.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Trajectories"]


@dataclass
class Trajectories:
    """Moving points over exposures, in metres, project axes (Z up)."""

    times: np.ndarray                                  # (n,) s
    exposures: list[str]
    markers: dict[str, np.ndarray]                     # name -> (n, 3) m, NaN = gap
    sigma: dict[str, np.ndarray]                       # name -> (n, 3) m
    cameras: dict[str, np.ndarray] = field(default_factory=dict)   # name -> (n,) bit mask
    stations: list[str] = field(default_factory=list)
    angles: object = None                              # pandas DataFrame or None
    angle_unit: str = "deg"
    length_unit: str = "m"                             # of the source (all here is metres)
    name: str = "photogram"
    mot: dict | None = None                            # .mot columns (deg, m, m/s) if given
    fps: float | None = None                           # the source's frame rate, if it says

    @property
    def rate(self) -> float:
        if self.fps is not None and np.isfinite(self.fps) and self.fps > 0:
            return float(self.fps)
        d = np.diff(self.times)
        # times are printed with 10 digits: round the rate to 7
        return float(f"{1.0 / np.median(d):.7g}") if d.size else 1.0
