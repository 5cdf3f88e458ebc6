"""Turn a :class:`~photogram.project.model.Project` (with approximate values
for every station and point) into an engine :class:`Problem`.

Configuration, not computation: which blocks are free, which residual
blocks exist, and the datum:

* ``control``: control points (kind ``control``) are fixed;
* ``weighted``: control coordinates are weighted observations (eq. (D3b))
  with sX sY sZ (or ``sigma_control``);
* ``free``: inner constraints (minimum trace) over all points or the points
  named in ``inner_constraints``; 6 conditions when a distance fixes scale;
* ``dependent``: DBAT's dependent relative orientation: the exterior
  orientation of ``dependent_station`` (default: the first station) and one
  projection-centre coordinate of another station are held fixed
  (:func:`photogram.adjust.datum.dependent_orientation`); control points are
  adjusted like tie points.

Station priors (appendix D.2) and interior priors are added wherever the
project gives sigmas; distances and verticality wherever given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.adjust.build_rigs import check_dependent_datum, rig_plan, rig_warnings
from photogram.adjust.datum import dependent_orientation, inner_constraints
from photogram.adjust.eccentric_blocks import with_ellipse_centres
from photogram.adjust.interior_map import interior_map
from photogram.adjust.residual_blocks import (
    DistanceBlock, ImagePointBlock, InteriorPriorBlock, PointPriorBlock,
    StationPriorBlock, VerticalBlock)
from photogram.adjust.rig_blocks import RigImagePointBlock
from photogram.adjust.solver import Problem
from photogram.adjust.state import Layout, State
from photogram.errors import GeometryError, InputError
from photogram.geometry import camera_model, opk_to_matrix


@dataclass
class Built:
    problem: Problem
    camera_names: list
    present: dict            # flags for datum messages
    control: np.ndarray      # indices of control points
    check: np.ndarray        # indices of check points
    warnings: list = None    # what the configuration silently ignores
    interior: object = None  # InteriorMap when cameras share parameters (else None)
    rigs: object = None      # RigPlan when stations are tied by rigs (else None)


def _missing_approximations(project):
    st = project.stations
    bad_st = [n for n, ok in zip(st.names, np.all(np.isfinite(st.position), 1)
                                  & np.all(np.isfinite(st.angles), 1)) if not ok]
    bad_pt = [i for i, ok in zip(project.points.ids, np.all(np.isfinite(project.points.xyz), 1))
              if not ok]
    return bad_st, bad_pt


def _blind_stations(project):
    """Names of the stations without any image observation (point or line)."""
    n = len(project.stations)
    seen = np.zeros(n, dtype=bool)
    for table in (project.image_points, project.image_lines):
        st = np.asarray(getattr(table, "station", np.zeros(0, int)), dtype=int)
        seen[st[(st >= 0) & (st < n)]] = True
    return [name for name, ok in zip(project.stations.names, seen) if not ok]


def _check_blind_stations(project):
    """A station that sees nothing has 6 undetermined parameters: name it
    (instead of a singular normal matrix later)."""
    blind = _blind_stations(project)
    if blind:
        more = f" and {len(blind) - 5} more" if len(blind) > 5 else ""
        raise GeometryError(
            (f"station {blind[0]} sees nothing: no image observations, so its orientation "
             f"cannot be determined" if len(blind) == 1 else
             f"stations {', '.join(blind[:5])}{more} see nothing: no image observations, "
             f"so their orientation cannot be determined"),
            hint="measure points in their images or remove them from the stations table")


def _reasons(project, names):
    """Why the approximation chain could not reach ``names`` (the chain
    leaves one warning per unreached station/point, "point P7: ..."), as
    "P7: rays nearly parallel ...; S3: ..." (at most 3)."""
    out = []
    for name in names:
        for w in getattr(project, "warnings", []):
            for kind in ("point", "station"):
                head = f"{kind} {name}: "
                if w.startswith(head):
                    out.append(f"{name}: {w[len(head):]}")
                    break
            else:
                continue
            break
    return "; ".join(out[:3])


def _control_sigmas(project, control):
    """(n_control, 3) a-priori sigmas of the control coordinates for the
    weighted datum: the points table's sX sY sZ, empty cells
    ``sigma_control``; 0 means fixed. Raises when one has none."""
    pts, adj = project.points, project.adjustment
    sig = pts.sigma[control].astype(float).reshape(-1, 3)
    if adj.sigma_control is not None:
        sig = np.where(np.isfinite(sig), sig, adj.sigma_control)
    bad = [pts.ids[i] for i, s in zip(control, sig) if not np.all(np.isfinite(s) & (s >= 0))]
    if bad:
        raise InputError(f"weighted datum: control point(s) {', '.join(bad[:5])} have no sigma",
                         file=project.sources.get("points", project.path),
                         hint="give sX sY sZ in the points table (0: fixed) or "
                              "[adjustment] sigma_control")
    return sig


def _station_sigmas(project):
    """(n_s, 6) a-priori sigmas of the stations (X0 Y0 Z0, angles; NaN: no
    prior, 0: fixed). A rotation is fixed as a whole: 0 for one or two of
    the three angles is refused (the engine's rotation increment is not
    per omega-phi-kappa angle)."""
    st = project.stations
    sig = np.hstack([np.asarray(st.position_sigma, float).reshape(-1, 3),
                     np.asarray(st.angle_sigma, float).reshape(-1, 3)])
    zero = sig[:, 3:] == 0
    partial = np.flatnonzero(zero.any(1) & ~zero.all(1))
    if len(partial):
        i = int(partial[0])
        rec = st.record[i] if len(st.record) == len(st) else 0
        raise InputError(f"station {st.names[i]}: a sigma of 0 (fixed) for only some of "
                         f"somega sphi skappa", file=project.sources.get("stations", project.path),
                         line=int(rec) if rec else None,
                         hint="0 fixes the rotation as a whole: give 0 for all three angles, "
                              "or small sigmas (e.g. 1e-6) for the angles to hold")
    return sig


def build_problem(project, fix_interior=False, fix_stations=False) -> Built:
    """Build the engine problem of ``project``.

    Parameters
    ----------
    project : Project
        With finite approximate values for every station and point that
        has observations (run :func:`photogram.init.chain.approximate`
        first).
    fix_interior : bool
        Hold every interior parameter fixed (``photogram orient``).
    fix_stations : bool
        Hold every exterior orientation fixed (``photogram intersect``).
    """
    adj = project.adjustment
    _check_blind_stations(project)
    bad_st, bad_pt = _missing_approximations(project)
    if bad_st or bad_pt:
        what = " and ".join(f"{label}(s) {', '.join(names[:5])}"
                            + (f" and {len(names) - 5} more" if len(names) > 5 else "")
                            for label, names in (("station", bad_st), ("point", bad_pt)) if names)
        why = _reasons(project, bad_st + bad_pt)
        raise InputError(f"no approximate values for {what}" + (f" ({why})" if why else ""),
                         file=project.path,
                         hint="give them in the tables, or measure them so that the "
                              "approximation chain can reach them" if why else
                              "run the approximation chain or give them in the tables")
    cam_names = list(project.cameras)
    cam_index = {n: i for i, n in enumerate(cam_names)}
    cams = [project.cameras[n] for n in cam_names]
    models = [camera_model(c.model) for c in cams]
    st, pts, obs = project.stations, project.points, project.image_points
    n_s, n_p = len(st), len(pts)
    station_cam = np.array([cam_index[c] for c in st.camera], dtype=int)

    kinds = np.asarray(pts.kind, dtype=object)
    control = np.flatnonzero(kinds == "control")
    check = np.flatnonzero(kinds == "check")
    coupled = np.zeros(n_p, dtype=bool)
    pidx = pts.index()
    dist = [(pidx[d.point_a], pidx[d.point_b], d.value, d.sigma) for d in project.distances]
    vert = [(pidx[v.top], pidx[v.bottom], v.sigma) for v in project.verticals]
    for a, b, *_ in dist + vert:
        coupled[[a, b]] = True

    free_pt = np.ones((n_p, 3), dtype=bool)
    if adj.datum == "control":
        free_pt[control] = False
    control_sigma = _control_sigmas(project, control) if adj.datum == "weighted" else None
    if control_sigma is not None:
        # a sigma of 0 fixes that coordinate (docs/project-files.md)
        free_pt[control] &= control_sigma != 0
    # points that nothing observes stay at their values (no singular blocks)
    seen = np.bincount(obs.point, minlength=n_p) > 0
    if adj.datum == "weighted":
        seen[control] = True
    free_pt[~(seen | coupled)] = False
    station_sigma = _station_sigmas(project)
    # rigs (photogram.adjust.build_rigs): with the stations held fixed
    # (intersect) they change nothing
    R_start = opk_to_matrix(st.angles)
    plan = None if fix_stations else rig_plan(project, R_start, st.position)
    free_st = np.full((n_s, 6), not fix_stations)
    free_st &= station_sigma != 0               # a sigma of 0 fixes the parameter
    dependent = _dependent_fixed(project) if adj.datum == "dependent" else []
    for j, k in dependent:
        free_st[j, k] = False
    n_state = n_s
    if plan is not None:
        check_dependent_datum(project, plan, dependent)
        free_st[plan.derived] = False
        free_st = np.vstack([free_st, np.repeat(~plan.fixed[:, None], 6, axis=1)])
        n_state = n_s + plan.n_sensors
    free = {"camera": [np.zeros(len(c.parameters), bool) if fix_interior else c.free_mask()
                       for c in cams],
            "station": free_st,
            "point": free_pt}
    # shared interior parameters (per station, across cameras, ties); with
    # fix_interior every parameter is held at its value and nothing is shared
    imap = None if fix_interior else interior_map(cams, cam_names, st.names, station_cam)
    if imap is None:
        layout = Layout([len(c.parameters) for c in cams], n_state, n_p, coupled, free)
        io_start = [c.values() for c in cams]
    else:
        free["camera"] = [imap.free[c] for c in imap.columns]
        layout = Layout([], n_state, n_p, coupled, free, camera_columns=imap.columns,
                        n_camera_columns=imap.n_io)
        io_start = imap.instance_values()
    state = State(pts.xyz.astype(float).copy(), R_start, st.position.astype(float).copy(),
                  io_start)
    if plan is not None:
        state.R = np.concatenate([state.R, plan.R])
        state.X0 = np.concatenate([state.X0, plan.X0])
        layout.derived = (plan.derived, plan.frame, plan.sensor_station())
        state.compose(layout.derived)
    derived_frame = np.full(n_s, -1)
    derived_sensor = np.full(n_s, -1)
    if plan is not None:
        derived_frame[plan.derived] = plan.frame
        derived_sensor[plan.derived] = plan.sensor_station()

    blocks = []
    st_names, pt_ids = np.array(st.names, dtype=str), np.array(pts.ids, dtype=str)
    obs_cam = station_cam[obs.station]
    groups = obs.group if obs.group is not None else np.full(len(obs), "", dtype=object)
    for k, name in enumerate(cam_names):
        default = adj.sigma_image[name] if isinstance(adj.sigma_image, dict) else adj.sigma_image
        for group in sorted(set(groups[obs_cam == k])):
            rows = np.flatnonzero((obs_cam == k) & (groups == group))
            sig = np.where(np.isfinite(obs.sigma[rows]), obs.sigma[rows], default)
            labels = np.char.add(np.char.add(st_names[obs.station[rows]], "/"),
                                 pt_ids[obs.point[rows]])
            io_blocks, io_block = _io_blocks(imap, k, obs.station[rows])
            on_rig = derived_frame[obs.station[rows]] >= 0   # images of rig sensors
            for rig_rows in (False, True):
                part = on_rig == rig_rows
                if not part.any():
                    continue
                r = rows[part]
                if rig_rows:
                    blk = RigImagePointBlock(models[k], io_blocks, io_block[part],
                                             derived_frame[obs.station[r]],
                                             derived_sensor[obs.station[r]], obs.point[r],
                                             obs.xy[r], sig[part], layout, labels=labels[part])
                    blk.station = obs.station[r]
                else:
                    blk = ImagePointBlock(models[k], io_blocks, io_block[part], obs.station[r],
                                          obs.point[r], obs.xy[r], sig[part], layout,
                                          labels=labels[part])
                blk.group = f"image {group}" if group else f"image {name}"
                blk.rows = r
                blocks.append(blk)
    targets = getattr(project, "targets", None)
    if targets is not None and targets.eccentricity:       # ellipse centres (eq. (1) of
        blocks = with_ellipse_centres(blocks, *targets.for_points(pts.ids), layout)  # geometry.circle)

    if adj.datum == "weighted" and len(control):
        # fixed coordinates (sigma 0) are held at their values, not observed
        sig = np.where(control_sigma == 0, np.inf, control_sigma)
        blk = PointPriorBlock(control, pts.xyz[control], sig, layout)
        blk.labels = [pts.ids[i] for i in control]
        blocks.append(blk)

    has_prior = np.any(np.isfinite(station_sigma) & (station_sigma > 0), axis=1)
    if plan is not None:                # a rig image's pose is its frame's and sensor's
        has_prior[plan.derived] = False
    if has_prior.any() and not fix_stations:
        i = np.flatnonzero(has_prior)
        sig = station_sigma[i]
        sig = np.where(np.isfinite(sig) & (sig > 0), sig, np.inf)
        blk = StationPriorBlock(i, st.position[i], st.angles[i], sig, layout)
        blk.labels = [st.names[j] for j in i]
        blocks.append(blk)

    if not fix_interior:
        pri = [(k, j, p.value, p.sigma) for k, c in enumerate(cams)
               for j, p in enumerate(c.parameters.values())
               if p.free and p.sigma is not None and np.isfinite(p.sigma) and p.sigma > 0]
        if imap is not None:            # one prior per shared unknown
            pri = imap.prior_rows()
        if pri:
            k, j, v, s = map(np.array, zip(*pri))
            blocks.append(InteriorPriorBlock(k, j, v, s, layout))
    if dist:
        a, b, v, s = map(np.array, zip(*dist))
        blk = DistanceBlock(a, b, v, s, layout)
        blk.labels = [f"{d.point_a}-{d.point_b}" for d in project.distances]
        blocks.append(blk)
    if vert:
        a, b, s = map(np.array, zip(*vert))
        blk = VerticalBlock(a, b, s, layout)
        blk.labels = [f"{v.top}-{v.bottom}" for v in project.verticals]
        blocks.append(blk)

    G = None
    if adj.datum == "free":
        chosen = None
        if adj.inner_constraints:
            missing = [p for p in adj.inner_constraints if p not in pidx]
            if missing:
                raise InputError(f"inner_constraints names unknown point(s) {', '.join(missing[:5])}",
                                 file=project.path, hint="use ids from the points table")
            chosen = np.array([pidx[p] for p in adj.inner_constraints])
        G = inner_constraints(layout, state, chosen, scale=not dist)
    present = {"control": adj.datum in ("control", "weighted") and len(control) > 0,
               "distance": bool(dist), "inner": G is not None, "dependent": dependent}
    if G is not None:
        idx = chosen if chosen is not None else np.flatnonzero(free_pt.any(axis=1))
        present["inner_points"] = (idx, [pts.ids[i] for i in idx])
    problem = Problem(state, layout, blocks, G=G,
                      point_labels=[pts.ids[i] for i in np.flatnonzero(~coupled)])
    return Built(problem, cam_names, present, control, check,
                 warnings=_ignored_control_sigmas(project, control)
                 + _dependent_control(project, control)
                 + rig_warnings(plan, station_sigma, bool(targets and targets.eccentricity)),
                 interior=imap, rigs=plan)


def _dependent_fixed(project):
    """(station, parameter) pairs that ``datum = "dependent"`` holds fixed
    (DBAT's seteoest 'depend': :func:`~photogram.adjust.datum.dependent_orientation`)
    at the approximate projection centres."""
    adj, st = project.adjustment, project.stations
    name = getattr(adj, "dependent_station", None)
    if name is None:
        base = 0
    elif str(name) in st.names:
        base = st.names.index(str(name))
    else:
        raise InputError(f"dependent_station names unknown station {name!r}", file=project.path,
                         hint="use a name from the stations table")
    return dependent_orientation(st.position, base,
                                 getattr(adj, "dependent_coordinate", None) or "longest")


def _dependent_control(project, control):
    """With ``datum = "dependent"`` the control coordinates are only
    approximations: say so (0 or 1 warning)."""
    if project.adjustment.datum != "dependent" or not len(control):
        return []
    return [f'datum = "dependent" adjusts the {len(control)} control points like tie points: '
            f'their coordinates are approximate values only (datum = "control" or "weighted" '
            f'uses them)']


def _io_blocks(imap, k, stations):
    """The interior blocks (indices into ``state.io``) of camera ``k``'s
    observations at ``stations``, and each observation's block among them:
    the camera itself, or with shared parameters its instances
    (:mod:`photogram.adjust.interior_map`)."""
    if imap is None:
        return [k], np.zeros(len(stations), int)
    blocks, which = np.unique(imap.station_instance[stations], return_inverse=True)
    return blocks, which.astype(int).ravel()


def _ignored_control_sigmas(project, control):
    """With ``datum = "control"`` the control points are fixed: their
    sigmas (sX sY sZ, ``sigma_control``) are not used. Say so (a list of
    0 or 1 warning)."""
    adj = project.adjustment
    if adj.datum != "control" or not len(control):
        return []
    sig = np.asarray(project.points.sigma, float).reshape(-1, 3)[control]
    given = np.any(np.isfinite(sig) & (sig > 0), axis=1)
    if not given.any() and not adj.sigma_control:
        return []
    ids = [project.points.ids[i] for i in control[given]]
    what = (f"the sigmas sX sY sZ of {len(ids)} control point(s) "
            f"({', '.join(ids[:5])}{' ...' if len(ids) > 5 else ''})" if ids else "")
    if adj.sigma_control:
        what += (" and " if what else "") + f"sigma_control = {adj.sigma_control:g}"
    return [f'datum = "control" holds the {len(control)} control points fixed: {what} '
            f'are not used (datum = "weighted" uses them as weighted observations)']


def merged_image_blocks(problem) -> Problem:
    """The same problem with the plain image point blocks of one camera model
    merged into one block (one vectorized evaluation instead of one per
    camera and group), for re-solving a small problem many times (Monte
    Carlo). Only where every merged group has the same variance factor (1
    after the build): the weights, residuals and Jacobians are the same,
    the rows are in another order. The merged block keeps ``rows`` (the
    image point table's rows of its observations) and is in group
    ``"image"``; the other blocks, the state, layout and datum are shared."""
    image = [b for b in problem.blocks if type(b) is ImagePointBlock]
    by_model = {}
    for b in image:
        by_model.setdefault(b.model.name, []).append(b)
    if all(len(v) < 2 for v in by_model.values()):
        return problem
    factors = {problem.variance[b.group] for b in image}
    if len(factors) > 1:
        raise ValueError("merged_image_blocks: the image groups have different variance factors")
    lay = problem.layout
    new_blocks, done = [], set()
    for b in problem.blocks:
        if type(b) is not ImagePointBlock:
            new_blocks.append(b)
            continue
        name = b.model.name
        if name in done:
            continue
        done.add(name)
        parts = by_model[name]
        cams = sorted({int(k) for p in parts for k in p.cameras})
        where = {k: i for i, k in enumerate(cams)}
        camera = np.concatenate([[where[int(k)] for k in p.cameras[p.camera]] for p in parts])
        labels = None
        if all(p.labels is not None for p in parts):
            labels = np.concatenate([np.asarray(p.labels) for p in parts])
        blk = ImagePointBlock(parts[0].model, cams, camera.astype(int),
                              np.concatenate([p.station for p in parts]),
                              np.concatenate([p.point for p in parts]),
                              np.concatenate([p.xy for p in parts]),
                              np.concatenate([p.sigma[:, 0] for p in parts]), lay, labels=labels)
        blk.group = "image"
        if all(hasattr(p, "rows") for p in parts):
            blk.rows = np.concatenate([p.rows for p in parts])
        new_blocks.append(blk)
    out = Problem(problem.state.copy(), lay, new_blocks, G=problem.G,
                  point_labels=problem.point_labels)
    out.variance["image"] = factors.pop()
    return out
