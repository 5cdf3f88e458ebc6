"""Datum: the 7 similarity motions of a network, inner constraints (free
network, minimum trace) and the detection of a datum defect before
iterating.

Image observations are invariant to a 3D similarity transformation of the
whole network (3 translations, 3 rotations, 1 scale). Only control
coordinates (fixed or weighted), station priors, distances, verticality and
inner constraints can fix these 7 degrees of freedom. The defect is the
number of motions that none of them fixes.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError

MOTIONS = ("translation X", "translation Y", "translation Z",
           "rotation about X", "rotation about Y", "rotation about Z", "scale")


def _point_motions(xyz, centre, size):
    """(n, 3, 7) displacement of points under the 7 unit motions."""
    d = (xyz - centre) / size
    n = len(d)
    T = np.zeros((n, 3, 7))
    T[:, [0, 1, 2], [0, 1, 2]] = 1.0
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    T[:, 1, 3], T[:, 2, 3] = -z, y
    T[:, 0, 4], T[:, 2, 4] = z, -x
    T[:, 0, 5], T[:, 1, 5] = -y, x
    T[:, :, 6] = d
    return T


def similarity_motions(layout, state, points=None):
    """The 7 similarity motions as columns over all unknowns (n_columns, 7).

    Points and projection centres move as points; a station rotation moves
    by ``delta = -R omega`` for a world rotation ``omega``; interior
    orientation does not move. Coordinates are centred and scaled by the
    network size for conditioning.
    """
    pts = state.points if points is None else points
    finite = np.all(np.isfinite(pts), axis=1)
    allxyz = np.vstack([pts[finite], state.X0])
    centre = allxyz.mean(axis=0)
    size = float(np.sqrt(np.mean(np.sum((allxyz - centre) ** 2, axis=1)))) or 1.0
    T = np.zeros((layout.n_columns, 7))
    Tp = _point_motions(np.where(np.isfinite(pts), pts, centre), centre, size)
    T[layout.point_cols.ravel()] = Tp.reshape(-1, 7)
    Ts = _point_motions(state.X0, centre, size)
    T[layout.station_cols[:, :3].ravel()] = Ts.reshape(-1, 7)
    rot = np.zeros((len(state.X0), 3, 7))
    rot[:, :, 3:6] = -state.R / size   # the unit rotation moves points by |X - c| / size
    T[layout.station_cols[:, 3:].ravel()] = rot.reshape(-1, 7)
    return T


def inner_constraints(layout, state, point_indices=None, scale=True):
    """Inner-constraint conditions ``G^T dx = 0`` of a free network
    (minimum trace over the chosen points): 7 columns, or 6 when the scale
    is fixed by a distance (``scale=False``).

    Parameters
    ----------
    point_indices : array of int, optional
        Points that carry the datum (default: all points).
    """
    T = similarity_motions(layout, state)
    G = np.zeros_like(T)
    idx = np.arange(len(state.points)) if point_indices is None else np.asarray(point_indices)
    cols = layout.point_cols[idx].ravel()
    G[cols] = T[cols]
    G[~layout.free] = 0.0
    return G if scale else G[:, :6]


def datum_defect(problem, what_is_present):
    """Number of similarity motions left free, and their names.

    Parameters
    ----------
    problem : Problem (at its approximate values)
    what_is_present : dict
        Flags ``control``, ``distance``, ``inner`` used to word the message.

    Returns
    -------
    defect : int
    free_motions : list of str
    """
    T = similarity_motions(problem.layout, problem.state)
    moves = np.linalg.norm(T, axis=1) > 0
    rows = []
    _, Js = problem.evaluate(problem.state)
    total, count = 0.0, 0
    for blk, J in zip(problem.blocks, Js):
        JT = 0.0
        for Jj, cols in zip(J, blk.slot_cols):
            JT = JT + np.einsum("nds,nsm->ndm", Jj, T[cols])
            m = np.broadcast_to(moves[cols][:, None, :], Jj.shape)
            total += float(np.sum(Jj[m] ** 2))
            count += int(np.count_nonzero(Jj[m]))
        rows.append(np.reshape(JT, (-1, 7)))
    # typical squared Jacobian entry of the coordinates that the motions move
    typical = total / max(count, 1)
    D = sum(r.T @ r for r in rows) if rows else np.zeros((7, 7))
    # hard conditions: fixed parameters must not move, inner constraints hold
    hard = [T[~problem.layout.free]]
    if problem.G is not None:
        hard.append(problem.G.T @ T)
    H = np.vstack(hard)
    H = H / max(np.abs(H).max(initial=0.0), 1e-300)
    _, sv, Vt = np.linalg.svd(H, full_matrices=True) if len(H) else (None, np.zeros(0), np.eye(7))
    rank = int(np.count_nonzero(sv > 1e-9))
    V0 = Vt[rank:].T                                   # motions the hard conditions allow
    w, U = np.linalg.eigh(V0.T @ D @ V0) if V0.shape[1] else (np.zeros(0), np.zeros((0, 0)))
    small = w <= 1e-10 * max(typical, 1e-300)
    defect = int(np.count_nonzero(small))
    names = []
    if defect:
        null = V0 @ U[:, small]
        strength = np.sum(null ** 2, axis=1)
        names = [MOTIONS[i] for i in np.flatnonzero(strength > 0.1)]
    return defect, names


def check_datum(problem, what_is_present):
    """Raise GeometryError naming what is missing if the datum is defective.

    The message reads e.g. "datum defect 7: no control, no distance, no
    inner constraints (free: translation X, ...)".

    ``what_is_present["gauge"] = True`` declares the gauge freedom on
    purpose (the BAL mode of :mod:`photogram.io.bal`, as Ceres' BAL
    example: nothing fixed, the trust-region damping keeps every step
    regular, and the cost does not depend on the datum); no error is raised
    then.
    """
    if what_is_present.get("gauge"):
        return
    defect, names = datum_defect(problem, what_is_present)
    if defect == 0:
        return
    missing = [f"no {k}" for k, label in (("control", "control"), ("distance", "distance"),
                                          ("inner constraints", "inner"))
               if not what_is_present.get(label, False)]
    text = f"datum defect {defect}: " + (", ".join(missing) if missing else "the datum elements do not fix")
    if names:
        text += f" (undetermined: {', '.join(names)})"
    raise GeometryError(text, hint="add control points (3 non-collinear), weighted station "
                                   "priors, a distance, or use datum = \"free\"")
