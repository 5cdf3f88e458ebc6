"""A synthetic ski jumper with known parameters (tests, demos).

The jumper flies along a parabola ``O(t) = O0 + V t + G t^2 / 2`` (about
20 m in 20 exposures at 30 fps); the angles vary smoothly with time. The
points and ski directions are built *from* the chosen parameters (not with the
code under test), so that :func:`photogram.jump.stick_model` must recover them.
"""

from __future__ import annotations

import numpy as np

from photogram.project.model import LENGTH_UNITS

__all__ = ["synthetic_jumper"]


def synthetic_jumper(n: int = 20, fps: float = 30.0, length_unit: str = "m",
                     seed: int = 0) -> dict:
    """Points, directions and the true parameters of a synthetic jump.

    Returns
    -------
    dict with
        ``P`` (n, 4, 3), ``d1``, ``d2`` (n, 3) (not unit length), ``c1``,
        ``c2`` (n, 3) points on the ski lines, ``times`` (n,), ``truth``
        (dict name -> (n,) in radians / ``length_unit``), ``feet`` (n, 2, 3)
        the true binding points on the ski lines, ``u1``, ``u2`` the true unit
        directions, ``gravity`` the parabola's acceleration.
    """
    rng = np.random.default_rng(seed)
    s = 1.0 / LENGTH_UNITS[length_unit]            # metres -> length unit
    t = np.arange(n) / fps
    tau = t / max(t[-1], 1e-9)                      # 0..1 along the flight
    deg = np.pi / 180
    alpha = (14 - 4 * tau + 1.5 * np.sin(5 * tau)) * deg
    beta = (6 + 3 * tau) * deg
    delta_phi = (28 + 6 * np.sin(3 * tau)) * deg
    phi = (12 + 10 * tau) * deg                     # skis pointing downhill
    heading = (4 - 2 * tau) * deg
    roll = (3 + 2 * tau) * deg                      # Z' turned about X'
    kappa = (5 - 3 * tau) * deg                     # ski plane turned about X'
    L_leg, L_trunk, e = 0.95 * s, 0.80 * s, 0.03 * s  # e: lateral hip offset

    x = np.stack([np.cos(phi) * np.cos(heading), np.cos(phi) * np.sin(heading),
                  -np.sin(phi)], axis=1)
    z0 = np.stack([np.sin(phi) * np.cos(heading), np.sin(phi) * np.sin(heading),
                   np.cos(phi)], axis=1)
    y0 = np.cross(z0, x)
    z = np.cos(roll)[:, None] * z0 - np.sin(roll)[:, None] * y0
    y = np.cross(z, x)

    V = np.array([31.5, 2.0, -3.0]) * s
    G = np.array([0.0, 0.0, -6.0]) * s              # gravity minus lift
    O0 = np.array([10.0, -1.0, 40.0]) * s
    O = O0 + t[:, None] * V + 0.5 * t[:, None] ** 2 * G

    c, sn = np.cos(delta_phi / 2)[:, None], np.sin(delta_phi / 2)[:, None]
    side = np.cos(kappa)[:, None] * y - np.sin(kappa)[:, None] * z
    u1 = c * x - sn * side                          # right ski: tip to the right
    u2 = c * x + sn * side

    legs = (L_leg * (np.cos(alpha)[:, None] * x + np.sin(alpha)[:, None] * z) + e * y)
    trunk = (L_trunk * (np.cos(beta)[:, None] * x + np.sin(beta)[:, None] * z) - e * y)
    P2 = O + legs
    P1 = P2 + trunk
    foot = 0.06 * s * x + 0.02 * s * z
    P3 = O - 0.13 * s * y + foot
    P4 = O + 0.13 * s * y - foot
    P = np.stack([P1, P2, P3, P4], axis=1)

    # ski lines passing near (not through) the binding points
    feet, lines = [], []
    for Pb, u in ((P3, u1), (P4, u2)):
        off = rng.normal(size=(n, 3)) * 0.02 * s
        off -= np.einsum("ni,ni->n", off, u)[:, None] * u
        feet.append(Pb + off)
        lines.append(Pb + off + rng.uniform(-1, 1, size=(n, 1)) * s * u)
    cos_g = np.einsum("ni,ni->n", -legs, trunk) / (np.linalg.norm(legs, axis=1)
                                                    * np.linalg.norm(trunk, axis=1))
    vel = V + t[:, None] * G
    h = 1.0 / fps
    vel[0] = V + (t[0] + h / 2) * G                 # one-sided difference of a parabola
    vel[-1] = V + (t[-1] - h / 2) * G
    truth = {"alpha": alpha, "beta": beta, "gamma": np.arccos(cos_g),
             "delta_phi": delta_phi, "phi": phi, "heading": heading,
             "Z0": O[:, 2], "v": np.linalg.norm(vel, axis=1)}
    scale = rng.uniform(0.5, 2.0, size=(n, 2, 1))
    return {"P": P, "d1": u1 * scale[:, 0], "d2": u2 * scale[:, 1], "c1": lines[0],
            "c2": lines[1], "times": t, "truth": truth, "feet": np.stack(feet, axis=1),
            "u1": u1, "u2": u2, "O": O, "X": x, "Y": y, "Z": z, "gravity": G}
