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


#: inner constraints whose points fix the similarity motions with a condition
#: (smallest / largest singular value of the points' motions, centred on the
#: points and scaled by their spread) below DATUM_REFUSE are refused, below
#: DATUM_WARN warned about. Measured (tests/test_datum_condition.py): 3
#: points 1 mm off a 0.35 m line (condition 0.006) end "converged" 0.1-0.4 %
#: above the minimum; 3 mm off (0.017) reach it.
DATUM_REFUSE = 1e-2
DATUM_WARN = 5e-2


def inner_constraint_condition(points, free=None, scale=True):
    """How well inner constraints over ``points`` fix the datum.

    Parameters
    ----------
    points : (m, 3) coordinates of the points that carry the datum
    free : (m, 3) bool, optional
        Which coordinates are unknowns (only those take part).
    scale : bool
        Whether the constraints fix the scale too (7 motions, else 6).

    Returns
    -------
    condition : float
        Smallest over largest singular value of the points' displacements
        under the unit motions (about their own centroid, per unit of their
        RMS spread): about 0.3-0.6 for points that span 3D, 0 when they
        cannot fix every motion (collinear: a rotation; coincident: also
        the scale).
    weakest : list of str
        The motions (:data:`MOTIONS`) in the least fixed direction.
    """
    pts = np.asarray(points, dtype=float)
    ok = np.all(np.isfinite(pts), axis=1)
    pts = pts[ok]
    n_m = 7 if scale else 6
    if len(pts) == 0:
        return 0.0, list(MOTIONS[:n_m])
    centre = pts.mean(axis=0)
    size = float(np.sqrt(np.mean(np.sum((pts - centre) ** 2, axis=1)))) or 1.0
    T = _point_motions(pts, centre, size)[:, :, :n_m]
    if free is not None:
        T = T[np.asarray(free, dtype=bool)[ok]]
    else:
        T = T.reshape(-1, n_m)
    if T.shape[0] < n_m:
        return 0.0, list(MOTIONS[:n_m])
    _, sv, Vt = np.linalg.svd(T, full_matrices=False)
    condition = float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0
    weakest = [MOTIONS[i] for i in np.flatnonzero(Vt[-1] ** 2 > 0.1)]
    return condition, weakest


def check_datum_condition(problem, what_is_present):
    """Refuse (GeometryError) or warn about inner constraints on points that
    barely fix the datum (nearly collinear or coincident), naming them.

    ``what_is_present["inner_points"]``: (indices, ids) of the points of
    the inner constraints. Returns a list of warnings (0 or 1).
    """
    chosen = what_is_present.get("inner_points")
    if problem.G is None or chosen is None:
        return []
    idx, ids = chosen
    lay = problem.layout
    idx = np.asarray(idx, dtype=int)
    free = lay.free[lay.point_cols[idx]]
    cond, weakest = inner_constraint_condition(problem.state.points[idx], free,
                                               scale=problem.G.shape[1] == 7)
    if cond >= DATUM_WARN:
        return []
    names = ", ".join(ids[:10]) + (f" and {len(ids) - 10} more" if len(ids) > 10 else "")
    text = (f"the inner constraints on point(s) {names} barely fix the datum: condition "
            f"{cond:.2g} (the points are nearly collinear or coincident; weakest: "
            f"{', '.join(weakest)})")
    if cond < DATUM_REFUSE:
        raise GeometryError(text + f" < {DATUM_REFUSE:g}, the adjustment would not converge "
                                   f"reliably",
                            hint="list points in inner_constraints that span all three "
                                 "directions, or leave inner_constraints out to use all points")
    return [text + f" < {DATUM_WARN:g}: the free-datum sigmas are large and the iteration "
                   f"may be slow"]


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
    """Raise GeometryError naming what is missing if the datum is defective
    (or, with inner constraints, too weak: :func:`check_datum_condition`);
    return the warnings about a weak datum.

    The message reads e.g. "datum defect 7: no control, no distance, no
    inner constraints (free: translation X, ...)".

    ``what_is_present["gauge"] = True`` declares the gauge freedom on
    purpose (the BAL mode of :mod:`photogram.io.bal`, as Ceres' BAL
    example: nothing fixed, the trust-region damping keeps every step
    regular, and the cost does not depend on the datum); no error is raised
    then.
    """
    if what_is_present.get("gauge"):
        return []
    defect, names = datum_defect(problem, what_is_present)
    if defect == 0:
        return check_datum_condition(problem, what_is_present)
    missing = [f"no {k}" for k, label in (("control", "control"), ("distance", "distance"),
                                          ("inner constraints", "inner"))
               if not what_is_present.get(label, False)]
    text = f"datum defect {defect}: " + (", ".join(missing) if missing else "the datum elements do not fix")
    if names:
        text += f" (undetermined: {', '.join(names)})"
    raise GeometryError(text, hint="add control points (3 non-collinear), weighted station "
                                   "priors, a distance, or use datum = \"free\"")


#: ``dependent_coordinate`` of the dependent relative orientation: which
#: coordinate offsets from the base station compete for the fixed one
DEPENDENT_COORDINATES = {"longest": (0, 1, 2), "x": (0,), "y": (1,), "z": (2,)}


def dependent_orientation(positions, base: int = 0, coordinate: str = "longest"):
    """The parameters held fixed by a dependent relative orientation, as
    DBAT's ``seteoest(s, 'depend', IMNO, [coord])`` chooses them (Börlin &
    Grussenmeyer, DBAT, ``code/bundle/seteoest.m``, local function
    ``setdepend``).

    The base station keeps all six exterior parameters fixed (3 translations
    and 3 rotations of the datum) and one projection-centre coordinate of
    one other station is fixed (the scale). That coordinate is the one with
    the **largest signed offset** from the base station,
    ``max_{j, i in C} (X0[j, i] - X0[base, i])`` over the stations ``j``
    and the allowed coordinates ``C`` (x, y, z for ``"longest"``, else the
    one named), evaluated at the approximate values. DBAT takes the signed
    maximum, not the largest absolute offset; on ties it fixes every tied
    coordinate (MATLAB's ``find(offset == max(offset(:)))``), and so does
    this function.

    Parameters
    ----------
    positions : (n_s, 3) projection centres (approximate values)
    base : int
        Index of the base station (DBAT's ``ref_cam`` minus one).
    coordinate : {"longest", "x", "y", "z"}

    Returns
    -------
    list of (station index, parameter index)
        The exterior parameters to hold fixed (parameter 0-2: X0 Y0 Z0,
        3-5: the rotation), the base station's six first.

    Raises
    ------
    GeometryError
        Fewer than two stations, or no station with a positive offset in
        the allowed coordinates from the base (then the fixed coordinate
        would be the base station's own and the scale stays free).
    """
    X0 = np.asarray(positions, dtype=float).reshape(-1, 3)
    n = len(X0)
    if coordinate not in DEPENDENT_COORDINATES:
        raise ValueError(f"dependent_coordinate must be one of {', '.join(DEPENDENT_COORDINATES)}")
    if n < 2 or not 0 <= base < n:
        raise GeometryError(f"a dependent relative orientation needs at least two stations and "
                            f"a base station among them (have {n}, base {base + 1})",
                            hint="name an existing station in dependent_station")
    cols = list(DEPENDENT_COORDINATES[coordinate])
    offset = X0[:, cols] - X0[base, cols]
    best = np.nanmax(offset)
    if not np.isfinite(best) or best <= 0:
        raise GeometryError(
            f"dependent relative orientation: no station lies in the positive "
            f"{'x, y or z' if coordinate == 'longest' else coordinate} direction from the base "
            f"station, so the fixed coordinate would be the base station's own and the scale "
            f"stays undetermined (DBAT takes the largest signed offset)",
            hint="choose another dependent_station (e.g. the one with the smallest coordinate) "
                 "or another dependent_coordinate")
    fixed = [(base, k) for k in range(6)]
    js, ks = np.nonzero(offset == best)
    fixed += [(int(j), cols[int(k)]) for j, k in zip(js, ks)]
    return fixed
