"""The stick model's definitions, in one place (docs/stick-model.md).

These are **our** reading of the ski-jump paper's stick model (its Fig. 6 is
not available): change a definition here and the values, the analytic
Jacobians (hence the propagated sigmas), the table and the figures follow.

Points (rows of ``P``)::

    P1  helmet / head
    P2  hip
    P3  right binding (ankle), on the right ski line L1
    P4  left binding (ankle), on the left ski line L2

Ski lines ``L1``, ``L2`` have directions ``d1``, ``d2`` oriented from tail to
tip (along the flight). The jumper frame:

    O  = (P3 + P4) / 2
    X' = unit(u1 + u2)            u1, u2 = unit(d1), unit(d2)
    Z' = unit(part of P1 - O orthogonal to X')     (so that Y'(P1) = 0)
    Y' = Z' x X'                  (right-handed; points to the jumper's left)

World Z is up.
"""

from __future__ import annotations

import numpy as np

from photogram.jump import diff as D
# the results schema (exposures.csv columns) lives in the project layer, so
# that exporters below jump (photogram.io) can read it
from photogram.project.results_schema import ANGLE_PARAMETERS, LENGTH_PARAMETERS, PARAMETERS

__all__ = ["POINT_NAMES", "POINT_ROLES", "PARAMETERS", "ANGLE_PARAMETERS",
           "LENGTH_PARAMETERS", "N_INPUTS", "frame", "parameters"]

POINT_NAMES = ("P1", "P2", "P3", "P4")
POINT_ROLES = {"P1": "head", "P2": "hip", "P3": "right binding", "P4": "left binding"}

#: PARAMETERS: per-exposure parameters, in the order of the covariance
#: matrices (``v``, the speed of O, is added by :mod:`photogram.jump.propagate`
#: and is always last); ANGLE_PARAMETERS and LENGTH_PARAMETERS (and v in
#: length unit per second): :mod:`photogram.project.results_schema`.

DESCRIPTIONS = {
    "alpha": "legs O->P2 against X' (signed, in the X'Z' plane, + when P2 above X')",
    "beta": "trunk P2->P1 against X' (signed, in the X'Z' plane, + when P1 above P2)",
    "gamma": "hip angle at P2 between P2->O and P2->P1 (3D, 0..pi)",
    "delta_phi": "V angle between the skis d1 and d2 (3D, 0..pi)",
    "phi": "ski slope: inclination of X' below the horizontal (+ downhill)",
    "heading": "direction of X' in plan, from world X towards world Y",
    "Z0": "height of O (world Z, or above the ground if one is given)",
    "v": "speed of O from neighbouring exposures",
}

#: Inputs of one exposure, in the column order of every Jacobian:
#: P1, P2, P3, P4 (12 numbers) then d1, d2 (6 numbers).
N_INPUTS = 18


def frame(P1: D.Q, P3: D.Q, P4: D.Q, d1: D.Q, d2: D.Q) -> dict[str, D.Q]:
    """The jumper frame O, X', Y', Z' and the unit ski directions."""
    O = D.mean(P3, P4)
    u1, u2 = D.normalize(d1), D.normalize(d2)
    X = D.normalize(D.add(u1, u2))
    Z = D.normalize(D.reject(D.sub(P1, O), X))
    Y = D.cross(Z, X)
    return {"O": O, "X": X, "Y": Y, "Z": Z, "u1": u1, "u2": u2}


def _in_plane_angle(w: D.Q, X: D.Q, Z: D.Q) -> D.Q:
    """Signed angle of ``w`` from X' towards Z' in the X'Z' plane (the
    Y' component of ``w`` is ignored)."""
    return D.atan2(D.dot(w, Z), D.dot(w, X))


def parameters(P: np.ndarray, d1: np.ndarray, d2: np.ndarray,
               ground=None) -> tuple[dict[str, D.Q], dict[str, D.Q]]:
    """Every per-exposure parameter except ``v``, with its Jacobian with
    respect to the 18 inputs (P1..P4, d1, d2) of its exposure.

    Parameters
    ----------
    P : ndarray (n, 4, 3)
    d1, d2 : ndarray (n, 3)
    ground : object with ``height(O) -> (h (n,), dh/dO (n, 3))``, optional
        Z0 becomes the height above it (:class:`photogram.jump.stick.PlaneGround`,
        :class:`~photogram.jump.stick.ProfileGround`).

    Returns
    -------
    params : dict name -> Q (scalar)
    frame : dict name -> Q (vector): O, X, Y, Z, u1, u2
    """
    P1, P2, P3, P4, e1, e2 = D.inputs([P[:, 0], P[:, 1], P[:, 2], P[:, 3], d1, d2])
    f = frame(P1, P3, P4, e1, e2)
    O, X, Z = f["O"], f["X"], f["Z"]
    legs = D.sub(P2, O)            # O -> P2
    trunk = D.sub(P1, P2)          # P2 -> P1
    if ground is None:
        Z0 = D.component(O, 2)
    else:
        h, dh = ground.height(O.v)
        Z0 = D.Q(np.asarray(h, dtype=float), np.einsum("ni,nim->nm", dh, O.J))
    out = {
        "alpha": _in_plane_angle(legs, X, Z),
        "beta": _in_plane_angle(trunk, X, Z),
        "gamma": D.angle(D.neg(legs), trunk),
        "delta_phi": D.angle(f["u1"], f["u2"]),
        "phi": D.asin(D.neg(D.component(X, 2))),
        "heading": D.atan2(D.component(X, 1), D.component(X, 0)),
        "Z0": Z0,
    }
    return out, f
