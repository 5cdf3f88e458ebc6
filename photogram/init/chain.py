"""The approximation chain: approximate values for every station and point.

Steps 1B and 2A of the ski-jump paper. Starting from the image observations,
the cameras' interior orientation and whatever is known (control and check
points, given approximations of stations and points):

1. stations that see at least 4 known points (planar or not) are resected:
   direct solution (:func:`photogram.init.resection.resect`) on ideal image
   coordinates, then least squares with the full camera model
   (:func:`photogram.init.resection.refine_resection`);
2. if no station can be resected and none is given, the best stereo pair
   (most common points, widest intersection angles) is relatively oriented
   (:func:`photogram.init.relative.relative_orientation`) and its points
   intersected; the chain then works in that model frame until at least 3
   known points have been intersected in it, when a Helmert transformation
   (:func:`photogram.init.helmert.helmert`) brings everything into the
   control frame;
3. points seen from at least 2 oriented stations are intersected
   (:func:`photogram.init.intersection.intersect_points`);
4. steps 1 and 3 repeat until nothing changes; finally every intersected
   point is re-intersected with all its oriented rays and every resected
   station re-resected with all its located points (one polishing pass).

Approximations given in the project (stations with finite position and
angles, points with finite coordinates) are kept as they are. The
:class:`ChainReport` says how every station and point was reached, and why
the others could not be.

This module runs the chain (:func:`approximate`); the steps are in
:mod:`photogram.init.chain_steps`, the report in
:mod:`photogram.init.chain_report`, the camera setup and ideal image
coordinates in :mod:`photogram.init.ideal`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from photogram.errors import InputError
from photogram.init.chain_report import ChainReport
from photogram.init.chain_steps import _Chain, _State
from photogram.init.ideal import camera_setup, to_ideal

__all__ = ["ChainReport", "approximate", "to_ideal", "camera_setup"]


def approximate(project, model=None, *, min_points: int = 4, min_angle_deg: float = 1.0,
                max_rounds: int = 1000, max_pairs: int = 6, polish: bool = True,
                sigma_image: float | None = None):
    """Approximate values of every station and point (paper steps 1B, 2A).

    Parameters
    ----------
    project : Project
        Image points, cameras (interior orientation used as it is) and
        whatever is known: control/check points and any point with finite
        coordinates; stations with finite position and angles.
    model : None, str or camera model
        Camera model for all cameras (default: each camera's own).
    min_points : int
        Located points a station must see to be resected (>= 4: the
        direct solution needs 4 for a unique answer, planar or not).
    min_angle_deg : float
        Smallest acceptable intersection angle of a point (degrees).
    max_rounds : int
        Safety limit of resection/intersection rounds.
    max_pairs : int
        Pairs (by number of common points) tried for a relative orientation.
    polish : bool
        Finish with one pass of re-intersection with all rays and
        re-resection with all located points.
    sigma_image : float, optional
        A-priori image sigma for the relative orientation's zero-baseline
        test and the resection weights (default: per-observation sigmas).

    Returns
    -------
    project : Project
        A copy with ``stations.position``/``angles`` and ``points.xyz``
        filled where reached (given values unchanged).
    report : ChainReport

    Raises
    ------
    InputError
        Inconsistent cameras (unknown model, wrong parameter count).
    """
    if min_points < 4:
        raise InputError(f"min_points must be at least 4, got {min_points}")
    ch = _Chain(project, model, min_points, min_angle_deg, max_rounds, max_pairs, sigma_image)
    rep = ch.report
    S = ch.world_state()
    world = True
    ch.run(S, world=True)
    if not S.oriented().any():
        M = ch.start_model()
        if M is not None:
            # model frame: the project's coordinates are unusable until Helmert
            ch.run(M, world=False)
            S = M
            if rep.helmert is not None:
                ch.run(S, world=True)
            else:
                world = False
    if polish and S.oriented().any():
        ch.polish(S)
    if world:
        rep.frame = "control" if (S.oriented().any()) else "none"
    else:
        rep.frame = "model"
        if ch.known.any():
            rep.messages.append(
                f"only {int((S.located() & ch.known).sum())} known point(s) located in the "
                f"model: it stays in the relative-orientation frame (needs 3 for a Helmert "
                f"transformation); given coordinates are kept but are in another frame")
    ch.finish(S)
    out = _updated_project(project, S, ch)
    # one warning per unreached station/point ("point P7: ..."), so that a
    # later "no approximate values" error can say why
    unreached = list(rep.unreached_stations.values()) + list(rep.unreached_points.values())
    if unreached:
        out = dataclasses.replace(out, warnings=list(project.warnings) + unreached)
    return out, rep


def _updated_project(project, S: _State, ch: _Chain):
    from photogram.geometry import matrix_to_opk
    st = project.stations
    pos = np.array(st.position, dtype=float).reshape(-1, 3).copy()
    ang = np.array(st.angles, dtype=float).reshape(-1, 3).copy()
    ori = S.oriented() & ~ch.given_station
    if ori.any():
        pos[ori] = S.X0[ori]
        ang[ori] = np.asarray(matrix_to_opk(S.R[ori]), dtype=float)
    xyz = np.array(project.points.xyz, dtype=float).reshape(-1, 3).copy()
    loc = S.located() & ~ch.known
    xyz[loc] = S.X[loc]
    stations = dataclasses.replace(st, position=pos, angles=ang)
    points = dataclasses.replace(project.points, xyz=xyz)
    return dataclasses.replace(project, stations=stations, points=points)
