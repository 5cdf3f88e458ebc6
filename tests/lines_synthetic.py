"""Synthetic skis seen by the three field cameras (a test helper; it was
photogram/lines/synthetic.py, but it builds on photogram.simulation, which
sits above photogram.lines).

The views are the true orientations and interior orientations of
:func:`photogram.simulation.designs.field_design` (hill coordinates in dm:
X down the hill, Y to the left looking down the hill, Z up; cameras K1, K2
about 55 m and K3 about 80 m from the flight path, all on one side). Skis
are 2.5 m (25 dm) segments in a V below the jumper's flight path.
"""

from __future__ import annotations

import numpy as np

from photogram.lines.views import ViewCamera

__all__ = ["field_cameras", "ski_pair", "measure_segment", "flight_positions"]


def field_cameras(seed: int | None = None) -> dict[str, ViewCamera]:
    """True views S1, S2, S3 of the simulated field network."""
    from photogram.simulation.designs import FIELD_SEED, field_design, true_cameras
    _, truth = field_design(FIELD_SEED if seed is None else seed)
    st = truth["stations"]
    io = true_cameras()
    return {n: ViewCamera(R, X0, io[c], "brown", n)
            for n, c, R, X0 in zip(st["names"], st["camera"], st["R"], st["X0"])}


def flight_positions(n: int = 9) -> np.ndarray:
    """Centres (n, 3) of the skis along the simulated flight path (dm): the
    helmet path of ``field_design(alternative=2)`` lowered by 8 dm, up to
    X = 553 dm (farther down the skis leave the images of S2 and S3)."""
    from photogram.simulation.designs import slope_height
    t = np.linspace(0.05, 0.85, n)
    x = 400.0 + 180.0 * t
    return np.stack([x, 5.0 + 8.0 * t, slope_height(x) + 12.0 + 30.0 * np.sin(np.pi * t)],
                    axis=1)


def ski_pair(centre, *, heading_deg: float = 0.0, pitch_deg: float = -20.0,
             v_angle_deg: float = 35.0, roll_deg: float = 0.0, length: float = 25.0,
             tail_gap: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """End points (tail, tip) of the left and right ski (2, 3) each.

    The skis open in a V of ``v_angle_deg`` from tails ``tail_gap`` apart;
    the V's axis has the azimuth ``heading_deg`` from +X towards +Y and the
    elevation ``pitch_deg``; ``roll_deg`` turns the V's plane about its
    axis. ``centre`` is the middle of the V axis. Left is +Y (looking down
    the hill).
    """
    h, p, r = np.radians([heading_deg, pitch_deg, roll_deg])
    axis = np.array([np.cos(p) * np.cos(h), np.cos(p) * np.sin(h), np.sin(p)])
    side = np.array([-np.sin(h), np.cos(h), 0.0])           # to the left
    up = np.cross(axis, side)
    side = np.cos(r) * side + np.sin(r) * up
    half = np.radians(v_angle_deg) / 2
    centre = np.asarray(centre, dtype=float)
    tail = centre - 0.5 * length * np.cos(half) * axis
    out = []
    for s in (1.0, -1.0):
        d = np.cos(half) * axis + s * np.sin(half) * side
        t0 = tail + s * 0.5 * tail_gap * side
        out.append(np.array([t0, t0 + length * d]))
    return out[0], out[1]


def measure_segment(ends, camera: ViewCamera, n: int = 15, sigma: float = 0.0,
                    rng=None) -> np.ndarray:
    """Measured image points (n, 2) along a 3D segment ``ends`` (2, 3):
    equally spaced object points projected with the camera model (with its
    distortion) plus N(0, sigma) noise in both coordinates."""
    ends = np.asarray(ends, dtype=float)
    X = ends[0] + np.linspace(0.0, 1.0, n)[:, None] * (ends[1] - ends[0])
    xy = camera.project(X)
    if sigma > 0:
        rng = rng if rng is not None else np.random.default_rng(0)
        xy = xy + rng.normal(0.0, sigma, xy.shape)
    return xy
