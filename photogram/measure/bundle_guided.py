"""Guided measurement from a bundle adjustment: predict every missing
target in every image with the adjusted cameras and measure it.

The per-image guided measurement (:mod:`photogram.measure.guided`) predicts
with a plane's homography, and the network step
(:mod:`photogram.measure.network`) with linear projection matrices: neither
has lens distortion. After a first bundle adjustment every camera is known
with its distortion, so the classical "predict again to add what was
missed" (Luhmann et al., Close-Range Photogrammetry, sec. 4.4.3) can use
the full camera model:

1. adjust the project (:func:`photogram.adjust.build.build_problem`,
   :func:`photogram.adjust.solver.solve`); tie points seen in one image
   only wait with their given coordinates;
2. for every image and every target with coordinates that the image has
   no observation of: project 36 points of the target's circle (centre,
   radius, normal: ``[targets]`` of the project) with the adjusted
   orientation and camera, lens distortion included, and fit an ellipse to
   them (Halir & Flusser 1998): the predicted image of the target, kept if
   it lies inside the image, in front of the camera, not too oblique
   (``|cos| >= min_cos`` between the normal and the ray) and its minor
   axis at least ``min_diameter / 2``;
3. fit the ellipse to subpixel edge points started from the prediction
   (:func:`photogram.measure.centre.edge_ellipse`, no segmentation), and
   accept it when the edge fit converged with a residual below
   ``max_residual`` px and a contrast of ``min_contrast`` grey levels, its
   centre lies within ``max(gate px, gate_axis x`` the predicted semi-minor
   axis) of the predicted one (a point still at its approximate
   coordinates is predicted a pixel or two off; a neighbouring target is
   several diameters away), its axes within a
   factor 0.7-1.4 of the predicted ones, and no observation of the image is
   closer than the predicted minor axis;
4. add the accepted ellipse centres (sigma: the fit's, with ``sigma_floor``
   in quadrature) and repeat from 1 until a round adds nothing;
5. after each adjustment, an added observation farther from the adjusted
   prediction of its ellipse centre than ``max_misfit`` times the median
   misfit of its image's observations (and 0.05 px) is removed and never
   predicted again (a partly hidden or merged outline that the edge fit
   accepted), and the project adjusted again.

The new observations are ellipse centres: the adjustment corrects their
eccentricity when the project's ``[targets]`` is on
(:mod:`photogram.adjust.eccentric_blocks`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace

import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, solve
from photogram.errors import InputError
from photogram.geometry import camera_model, matrix_to_opk, opk_to_matrix
from photogram.measure.centre import edge_ellipse
from photogram.measure.ellipse import conic_axes, conic_centres, fit_ellipses

__all__ = ["BundleGuided", "predict_ellipses", "guided_from_bundle"]


@dataclass
class BundleGuided:
    """What :func:`guided_from_bundle` did: per round the number of
    predicted and of accepted targets, of added observations removed
    after the round's adjustment, and the sigma0 of each adjustment."""

    predicted: list = field(default_factory=list)
    added: list = field(default_factory=list)
    removed: list = field(default_factory=list)
    sigma0: list = field(default_factory=list)
    round_of: dict = field(default_factory=dict)    # (station, point) index -> round added

    @property
    def rounds(self) -> int:
        return len(self.added)


def _circle_basis(n):
    a = np.cross(n, [0.0, 0.0, 1.0])
    alt = np.cross(n, [1.0, 0.0, 0.0])
    small = np.linalg.norm(a, axis=1) < 0.1
    a[small] = alt[small]
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    return a, np.cross(n, a)


def predict_ellipses(model, io, R, X0, X, normal, radius, n_edge: int = 36):
    """Images of circles through the full camera model (lens distortion
    included): centres (n, 2), semi-axes (n, 2, major first), angles (n,),
    and ``|cos|`` of the angle between each circle's normal and its ray.

    ``io`` (n, p), ``R`` (n, 3, 3), ``X0``, ``X``, ``normal`` (n, 3),
    ``radius`` (n,). The ellipse is the least-squares ellipse through
    ``n_edge`` projected points of the circle (Halir & Flusser 1998)."""
    n = len(X)
    nv = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    a, b = _circle_basis(nv)
    t = np.linspace(0, 2 * np.pi, n_edge, endpoint=False)
    edge = X[:, None] + radius[:, None, None] * (np.cos(t)[None, :, None] * a[:, None]
                                                 + np.sin(t)[None, :, None] * b[:, None])
    rep = np.repeat(np.arange(n), n_edge)
    xy = model.project(edge.reshape(-1, 3), matrix_to_opk(R[rep]), X0[rep],
                       io[rep]).reshape(n, n_edge, 2)
    conics, ok = fit_ellipses(xy[:, :, 0], xy[:, :, 1], np.ones((n, n_edge)))
    centre = conic_centres(conics)
    axes = np.full((n, 2), np.nan)
    angle = np.full(n, np.nan)
    for k in np.flatnonzero(np.isfinite(centre).all(axis=1)):
        try:
            A, B, th = conic_axes(conics[k])
        except (ValueError, np.linalg.LinAlgError):
            continue
        axes[k] = A, B
        angle[k] = th
    ray = X0 - X
    cos = np.abs(np.einsum("ni,ni->n", ray, nv)) / np.linalg.norm(ray, axis=1)
    return centre, axes, angle, cos


def guided_from_bundle(project, images: dict, *, polarity: str = "dark", offset: float = 0.5,
                       min_contrast: float = 20.0, max_residual: float = 0.5, gate: float = 1.0,
                       gate_axis: float = 0.3,
                       min_diameter: float = 5.0, min_cos: float = 0.3,
                       sigma_floor: float = 0.02, max_rounds: int = 8,
                       max_misfit: float = 5.0,
                       options: SolverOptions | None = None):
    """Adjust, predict the missing targets, measure them, repeat (module doc).

    Parameters
    ----------
    project : Project
        Approximate values for every station and point (points that no
        image sees keep their given coordinates and are predicted from
        them), and ``targets`` (diameter and normal of every circular
        target).
    images : dict
        Station name -> grey image (h, w) of that station.
    polarity : "dark" or "bright" targets
    max_misfit : float
        Step 5 (module doc).
    max_rounds : int
        Adjustments at most.
    offset : float
        Project image coordinates minus OpenCV pixel coordinates (0.5:
        ``photogram measure``'s convention, top-left corner at (0, 0)).

    Returns
    -------
    project : Project
        With the image points extended (new rows have ``record`` 0) and
        the stations and points at the last adjustment.
    report : BundleGuided
    """
    targets = getattr(project, "targets", None)
    if targets is None:
        raise InputError("guided measurement from the bundle needs the targets' diameter and "
                         "normal", file=project.path,
                         hint="give [targets] diameter and normal (or the points table's "
                              "diameter, nX, nY, nZ)")
    missing = [s for s in project.stations.names if s not in images]
    if missing:
        raise InputError(f"no image for station {missing[0]}", file=project.path,
                         hint="give one image per station, named like the station")
    report = BundleGuided()
    n_first = len(project.image_points.station)
    refused: set = set()
    for _ in range(max_rounds):
        built = build_problem(_two_rays(project))
        summary = solve(built.problem, options or SolverOptions(
            max_iterations=project.adjustment.max_iterations))
        report.sigma0.append(float(summary.sigma0))
        project = _with_state(project, built)
        bad = _off_the_bundle(project, n_first, max_misfit)
        report.removed.append(int(bad.sum()))
        if bad.any():
            # an added observation the adjustment does not fit (a partly hidden or merged
            # outline): removed, never predicted again, and the project adjusted without it
            obs = project.image_points
            refused |= set(zip(obs.station[bad].tolist(), obs.point[bad].tolist()))
            project = _without(project, bad)
            report.predicted.append(0)
            report.added.append(0)
            continue
        new = _measure_missing(project, images, polarity, offset, min_contrast, max_residual,
                               gate, gate_axis, min_diameter, min_cos, sigma_floor, refused)
        report.predicted.append(new.pop("predicted"))
        report.added.append(len(new["station"]))
        if not len(new["station"]):
            break
        for s_, p_ in zip(new["station"], new["point"]):
            report.round_of[(int(s_), int(p_))] = report.rounds
        project = _with_observations(project, new)
    for key in refused:
        report.round_of.pop(key, None)
    return project, report


def _off_the_bundle(project, n_first: int, max_misfit: float) -> np.ndarray:
    """Which observations (from ``n_first`` on: the added ones) lie farther
    from the adjusted prediction of their ellipse centre than ``max_misfit``
    times the median misfit of the image's observations (and 0.05 px)."""
    obs, st, pts = project.image_points, project.stations, project.points
    bad = np.zeros(len(obs.station), bool)
    if len(obs.station) <= n_first:
        return bad
    radius, normal = project.targets.for_points(pts.ids)
    for s in np.unique(obs.station[n_first:]):
        rows = np.flatnonzero((obs.station == s) & np.isfinite(radius[obs.point])
                              & (radius[obs.point] > 0))
        if not len(rows):
            continue
        cam = project.cameras[st.camera[s]]
        n = len(rows)
        c = predict_ellipses(camera_model(cam.model),
                             np.tile(np.asarray(cam.values(), float), (n, 1)),
                             np.tile(opk_to_matrix(st.angles[s]), (n, 1, 1)),
                             np.tile(st.position[s], (n, 1)), pts.xyz[obs.point[rows]],
                             normal[obs.point[rows]], radius[obs.point[rows]])[0]
        v = np.linalg.norm(obs.xy[rows] - c, axis=1)
        limit = max(0.05, max_misfit * float(np.nanmedian(v)))
        bad[rows[(rows >= n_first) & ~(v <= limit)]] = True
    return bad


def _without(project, drop):
    obs = project.image_points
    keep = ~drop
    sub = replace(obs, station=obs.station[keep], point=obs.point[keep], xy=obs.xy[keep],
                  sigma=obs.sigma[keep], record=obs.record[keep],
                  group=None if obs.group is None else obs.group[keep])
    return replace(project, image_points=sub)


def _two_rays(project):
    """The project without the observations of tie points seen in one image
    only (undetermined; they keep their given coordinates this round)."""
    obs, pts = project.image_points, project.points
    rays = np.bincount(obs.point, minlength=len(pts))
    keep = (rays[obs.point] >= 2) | (np.asarray(pts.kind, dtype=object)[obs.point] != "tie")
    if keep.all():
        return project
    sub = replace(obs, station=obs.station[keep], point=obs.point[keep], xy=obs.xy[keep],
                  sigma=obs.sigma[keep], record=obs.record[keep],
                  group=None if obs.group is None else obs.group[keep])
    return replace(project, image_points=sub)


def _with_state(project, built):
    """The project with stations and points at the adjusted values."""
    st = built.problem.state
    stations = replace(project.stations, position=st.X0.copy(), angles=matrix_to_opk(st.R))
    points = replace(project.points, xyz=st.points.copy())
    out = replace(project, stations=stations, points=points,
                  cameras=copy.deepcopy(project.cameras))
    io = st.io
    if built.interior is not None:      # shared parameters: each camera's first instance
        io = [st.io[built.interior.instances_of(k)[0]] for k in range(len(built.camera_names))]
    for name, values in zip(built.camera_names, io):
        cam = out.cameras[name]
        for p, v in zip(cam.parameters.values(), values):
            p.value = float(v)
    return out


def _measure_missing(project, images, polarity, offset, min_contrast, max_residual, gate,
                     gate_axis, min_diameter, min_cos, sigma_floor, refused=frozenset()):
    st, pts, obs = project.stations, project.points, project.image_points
    radius, normal = project.targets.for_points(pts.ids)
    seen = np.zeros((len(st), len(pts)), bool)
    seen[obs.station, obs.point] = True
    for s_, p_ in refused:
        seen[s_, p_] = True
    new = {"station": [], "point": [], "xy": [], "sigma": [], "predicted": 0}
    for s, name in enumerate(st.names):
        cam = project.cameras[st.camera[s]]
        model = camera_model(cam.model)
        io = np.asarray(cam.values(), float)
        cand = np.flatnonzero(~seen[s] & np.isfinite(radius) & (radius > 0)
                              & np.isfinite(pts.xyz).all(axis=1))
        if not len(cand):
            continue
        R = opk_to_matrix(st.angles[s])
        X = pts.xyz[cand]
        front = (X - st.position[s]) @ R[2] < 0
        cand, X = cand[front], X[front]
        n = len(cand)
        if not n:
            continue
        c, ax, ang, cos = predict_ellipses(model, np.tile(io, (n, 1)), np.tile(R, (n, 1, 1)),
                                           np.tile(st.position[s], (n, 1)), X, normal[cand],
                                           radius[cand])
        gray = np.asarray(images[name], np.float32)
        t = 255.0 - gray if polarity == "dark" else gray
        h, w = t.shape
        c = c - offset                                   # into OpenCV pixel coordinates
        reach = 1.6 * ax[:, 0] + 3
        ok = (np.isfinite(c).all(axis=1) & np.isfinite(ax).all(axis=1) & (cos >= min_cos)
              & (2 * ax[:, 1] >= min_diameter) & (c[:, 0] - reach > 0) & (c[:, 1] - reach > 0)
              & (c[:, 0] + reach < w - 1) & (c[:, 1] + reach < h - 1))
        mine = obs.xy[obs.station == s] - offset
        if len(mine):
            near = np.linalg.norm(c[:, None] - mine[None], axis=2).min(axis=1)
            ok &= near >= np.nan_to_num(ax[:, 1], nan=0.0)
        sel = np.flatnonzero(ok)
        new["predicted"] += len(sel)
        if not len(sel):
            continue
        fit = edge_ellipse(t, c[sel], ax[sel, 0], ax[sel, 1], ang[sel])
        with np.errstate(invalid="ignore"):
            ratio = fit["axes"] / ax[sel]
            good = (fit["ok_edge"] & fit["ok_fit"] & (fit["residual"] <= max_residual)
                    & (fit["contrast"] >= min_contrast)
                    & (np.linalg.norm(fit["xy"] - c[sel], axis=1)
                       <= np.maximum(gate, gate_axis * ax[sel, 1]))
                    & np.all((ratio > 0.7) & (ratio < 1.4), axis=1))
        k = np.flatnonzero(good)
        new["station"] += [s] * len(k)
        new["point"] += list(cand[sel[k]])
        new["xy"].append(fit["xy"][k] + offset)
        new["sigma"].append(np.sqrt(fit["sigma"][k] ** 2 + sigma_floor ** 2))
    return new


def _with_observations(project, new):
    obs = project.image_points
    cat = np.concatenate
    k = len(new["station"])
    group = None if obs.group is None else cat([obs.group, np.full(k, "", dtype=object)])
    image_points = replace(obs, station=cat([obs.station, new["station"]]).astype(int),
                           point=cat([obs.point, new["point"]]).astype(int),
                           xy=cat([obs.xy] + new["xy"]), sigma=cat([obs.sigma] + new["sigma"]),
                           record=cat([obs.record, np.zeros(k, int)]), group=group)
    return replace(project, image_points=image_points)
