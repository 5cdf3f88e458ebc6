"""Segment masses and centres of mass (de Leva 1996) for the ski skeleton.

The paper (appendix C.1) computes the athlete's centre of mass from
standard anthropometric tables. We use de Leva (1996), "Adjustments to
Zatsiorsky-Seluyanov's segment inertia parameters", J. Biomech. 29(9),
Table 4, **male** values (mass in % of body mass, CoM in % of the segment
length from the first end point):

============  ============================  ======  =======
segment       end points (ours)             mass %  CoM %
============  ============================  ======  =======
head + neck   head (VERT) -> neck (CERV)     6.94   50.02
trunk         mid-shoulders (SUPR) -> mid-hips (MIDH)  43.46  44.86
upper arm     shoulder -> elbow              2.71   57.72
forearm       elbow -> hand (wrist)          1.62   45.74
hand          wrist -> MET3 (see below)      0.61   79.00
thigh         hip -> knee                   14.16   40.95
shank         knee -> ankle (LMAL)           4.33   44.59
foot          heel -> toes (TTIP)            1.37   44.15
============  ============================  ======  =======

The masses add up to 100 %. Approximations (documented in docs/mocap.md):
the skeleton has no vertex-to-C7 line, so the head segment runs from the
``head`` joint (head top) to the ``neck`` joint; de Leva's suprasternale is
replaced by the midpoint of the shoulders; the hand's MET3 point is placed
on the prolongation of the forearm at de Leva's hand length, 0.3206 times
the forearm length (86.2 / 268.9 mm). Equipment (skis, boots, poles) is not
included: the CoM is the body's.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DE_LEVA_MALE", "segment_endpoints", "centre_of_mass"]

#: (segment, mass fraction, CoM fraction from the first end point)
DE_LEVA_MALE = {
    "head": (0.0694, 0.5002),
    "trunk": (0.4346, 0.4486),
    "upper_arm": (0.0271, 0.5772),
    "forearm": (0.0162, 0.4574),
    "hand": (0.0061, 0.7900),
    "thigh": (0.1416, 0.4095),
    "shank": (0.0433, 0.4459),
    "foot": (0.0137, 0.4415),
}
HAND_TO_FOREARM = 86.2 / 268.9


def segment_endpoints(J: dict) -> list[tuple[str, float, float, np.ndarray, np.ndarray]]:
    """The segments as ``(name, mass fraction, CoM fraction, proximal, distal)``.

    ``J`` maps SKI24 joint names to (..., 3) arrays.
    """
    out = []
    m, c = DE_LEVA_MALE["head"]
    out.append(("head", m, c, J["head"], J["neck"]))
    supr = 0.5 * (J["r_shoulder"] + J["l_shoulder"])
    midh = 0.5 * (J["r_hip"] + J["l_hip"])
    m, c = DE_LEVA_MALE["trunk"]
    out.append(("trunk", m, c, supr, midh))
    for s in ("r_", "l_"):
        for seg, a, b in (("upper_arm", "shoulder", "elbow"), ("forearm", "elbow", "hand"),
                          ("thigh", "hip", "knee"), ("shank", "knee", "ankle"),
                          ("foot", "heel", "toes")):
            m, c = DE_LEVA_MALE[seg]
            out.append((s + seg, m, c, J[s + a], J[s + b]))
        m, c = DE_LEVA_MALE["hand"]
        wrist = J[s + "hand"]
        met3 = wrist + HAND_TO_FOREARM * (wrist - J[s + "elbow"])
        out.append((s + "hand", m, c, wrist, met3))
    return out


def centre_of_mass(J: dict) -> np.ndarray:
    """Whole-body CoM (..., 3) from SKI24 joints ``J`` (name -> (..., 3)).

    NaN where any joint of a segment is NaN.
    """
    total = 0.0
    acc = None
    for _, m, c, a, b in segment_endpoints(J):
        p = m * (a + c * (b - a))
        acc = p if acc is None else acc + p
        total += m
    return acc / total
