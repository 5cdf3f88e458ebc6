"""Epipolar help of ``photogram measure --serve``: epipolar curves,
predicted points and predicted ski lines in the oriented views.

**Epipolar curve.** The epipolar line of an image point in another view is
the image of its ray (Hartley & Zisserman 2003, sec. 9.1): the points
``X(lambda) = X0 + lambda d`` (``lambda >= 0``) of the ray from projection
centre ``X0`` in direction ``d``. In homogeneous ideal coordinates of the
other view, ``x(s) = (1 - s) P (X0, 1) + s P (d, 0)`` for ``s in [0, 1)``
runs from the epipole to the vanishing point of ``d``
(``lambda = s / (1 - s)``) along one ideal line; only points in front of
that camera are kept. The line is sampled uniformly along its chord in the
disk of ideal points that can image inside the format (1.05 times the
corrected border's largest radius), not uniformly in ``s`` (which crowds
the far part of a long ray, the whole visible ray of a distant scene,
into a sliver of ``s``), each chord point mapped back to its ``s`` to keep
it on the half-line. With lens distortion the image of the ray is a curve:
the ideal points are distorted by the camera model
(:meth:`photogram.lines.views.ViewCamera.measured`), the ends found where
the curve leaves the image (or the ray ends), and the curve drawn as a
polyline of at least 20 vertices equally spaced along it. Ideal points
beyond the disk are never distorted, so a distortion polynomial never
folds them back into the picture (and a point whose inversion fails is
left out, not the curve).

**Predicted point.** A label with two or more rays among the table's
observations of the exposure (and the click) is triangulated
(:func:`photogram.track.rays.triangulate`, the midpoint of k rays) and
projected into the other views.

**Predicted ski line.** A line measured in two or more views (two or more
points each) is fitted per view in ideal coordinates
(:func:`photogram.lines.views.fit_view_line`), its planes intersected
(:func:`photogram.lines.initial.initial_line_homogeneous`, appendix C.3 of
the ski-jump paper), and the 3D line drawn into the views that do not
measure it, as a curve like the epipolar one.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError, PhotogramError
from photogram.lines.views import ViewCamera
from photogram.serve.results import NOT_ORIENTED
from photogram.track.rays import triangulate

__all__ = ["image_of_ray", "epipolar_help", "predicted_line", "MIN_VERTICES"]

MIN_VERTICES = 20


def _ideal_limit(camera: ViewCamera, width: float, height: float) -> float:
    """1.05 x the largest ideal radius of the image's border points: no
    ideal point beyond it images inside the format (a radial distortion
    monotonic over the format), and a strong distortion polynomial (a DBAT
    or PhotoModeler camera, defined from measured to ideal) need not be
    inverted far outside it, where it folds."""
    t = np.linspace(0, 1, 9)
    border = np.concatenate([np.column_stack([t * width, np.zeros(9)]),
                             np.column_stack([t * width, np.full(9, height)]),
                             np.column_stack([np.zeros(9), t * height]),
                             np.column_stack([np.full(9, width), t * height])])
    ideal = camera.ideal(border)
    return 1.05 * float(np.max(np.hypot(ideal[:, 0], ideal[:, 1])))


def _chord(start_h, end_h, limit):
    """The chord of the ideal line through the homogeneous points
    ``start_h``, ``end_h`` inside the disk of radius ``limit``: (foot, half
    vector), the chord being ``foot + (2 u - 1) half`` for u in [0, 1]; None
    if the line misses the disk (or the two points coincide)."""
    line = np.cross(start_h, end_h)
    norm = np.hypot(line[0], line[1])
    if not norm > 1e-300:
        return None
    foot = -line[2] * line[:2] / norm ** 2
    dist = abs(line[2]) / norm
    if dist >= limit:
        return None
    half = np.sqrt(limit ** 2 - dist ** 2) * np.array([-line[1], line[0]]) / norm
    return foot, half


def _points(camera, start_h, end_h, chord, u):
    """Measured image points (n, 2) at parameters u of the chord, NaN where
    the chord's point is not on the segment ``s in [0, 1)`` of ``(1 - s)
    start_h + s end_h`` or behind the camera (module doc)."""
    foot, half = chord
    ideal = foot + (2 * np.asarray(u, float)[:, None] - 1) * half
    # the s of each chord point: (1 - s) alpha + s beta = 0 (alpha, beta parallel)
    alpha = start_h[:2] - ideal * start_h[2]
    beta = end_h[:2] - ideal * end_h[2]
    diff = alpha - beta
    den = (diff * diff).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        sv = (alpha * diff).sum(axis=1) / den
    w = (1 - sv) * start_h[2] + sv * end_h[2]
    ok = (den > 0) & (sv >= 0) & (sv < 1) & (w < 0)      # the camera looks along -z
    out = np.full((len(ideal), 2), np.nan)
    if ok.any():
        out[ok] = _measured(camera, ideal[ok])
    return out


def _measured(camera, ideal):
    """``camera.measured`` of the ideal points (n, 2); where the model's
    inversion does not converge for some of them (a distortion polynomial
    that folds near the format's corners), point by point, NaN where it
    fails."""
    try:
        return camera.measured(ideal)
    except GeometryError:
        out = np.full((len(ideal), 2), np.nan)
        for i, p in enumerate(ideal):
            try:
                out[i] = camera.measured(p[None])[0]
            except GeometryError:
                pass
        return out


def image_of_ray(camera: ViewCamera, X0, d, width: float, height: float,
                 n: int = 64) -> list[list[float]]:
    """The image of the half-line ``X0 + lambda d`` (``lambda >= 0``) in
    ``camera``, clipped to the image ``[0, width] x [0, height]`` (corner
    convention), as a polyline of ``n`` vertices (module doc); [] if it
    does not cross the image."""
    P = camera.matrix
    start_h = P @ np.append(np.asarray(X0, float), 1.0)
    end_h = P @ np.append(np.asarray(d, float), 0.0)
    chord = _chord(start_h, end_h, _ideal_limit(camera, width, height))
    if chord is None:
        return []

    def inside(xy):
        return np.isfinite(xy).all(axis=1) & (xy[:, 0] >= 0) & (xy[:, 0] <= width) & \
            (xy[:, 1] >= 0) & (xy[:, 1] <= height)

    def image(u):
        return _points(camera, start_h, end_h, chord, u)

    u = np.linspace(0.0, 1.0, 1001)
    ins = inside(image(u))
    if not ins.any():
        return []
    i0, i1 = np.flatnonzero(ins)[[0, -1]]
    lo, hi = u[i0], u[i1]
    # the ends (the image's border, or the ray's ends: its start, the
    # vanishing point): the interval between the last outside and the
    # first inside sample narrowed 32-fold per pass, both ends in one call
    # of the camera model (6 passes: 1e-12 of the chord)
    sides = [(k, sign) for k, sign in ((i0, -1), (i1, 1)) if 0 <= k + sign < len(u)]
    if sides:
        a = np.array([u[k] for k, _ in sides])                  # inside
        b = np.array([u[k + sign] for k, sign in sides])        # outside
        t = np.linspace(0.0, 1.0, 33)[1:-1]
        rows = np.arange(len(a))
        for _ in range(6):
            m = a[:, None] + t[None, :] * (b - a)[:, None]      # (ends, 31)
            ok = inside(image(m.ravel())).reshape(m.shape)
            j = np.cumprod(ok, axis=1).sum(axis=1)    # samples inside before the first outside
            a, b = (np.where(j > 0, m[rows, np.maximum(j - 1, 0)], a),
                    np.where(j < m.shape[1], m[rows, np.minimum(j, m.shape[1] - 1)], b))
        for (_, sign), value in zip(sides, a):
            if sign < 0:
                lo = value
            else:
                hi = value
    # vertices equally spaced along the curve
    fine = np.linspace(lo, hi, 1001)
    pts = image(fine)
    ok = np.isfinite(pts).all(axis=1)
    fine, pts = fine[ok], pts[ok]
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    u_at = np.interp(np.linspace(0.0, arc[-1], max(n, MIN_VERTICES)), arc, fine)
    u_at[0], u_at[-1] = lo, hi
    xy = image(u_at)
    xy = xy[inside(xy)]
    return [[float(x), float(y)] for x, y in xy]


def _exposure_views(session, exposure):
    return [v for v in session.views if (v.exposure or "") == (exposure or "")]


def _rays_of(session, point: str, exposure: str, skip_station: str | None = None):
    """(cameras, xy) of the observations of ``point`` in oriented views of
    the exposure (``skip_station``'s left out)."""
    cams, xy = [], []
    for r in session.points_table.rows:
        c = r.cells
        if c["point"] != point or c.get("exposure", "") != (exposure or "") or \
                c["station"] == skip_station:
            continue
        cam = session.orientation.cameras.get(c["station"])
        try:
            p = [float(c["x"]), float(c["y"])]
        except ValueError:
            continue
        if cam is not None:
            cams.append(cam)
            xy.append(p)
    return cams, xy


def _predict(session, cams, xy, views, exclude) -> list[dict]:
    if len(cams) < 2:
        return []
    X, _ = triangulate(cams, np.asarray(xy, float)[:, None, :])
    if not np.isfinite(X[0]).all():
        return []
    out = []
    for v in views:
        cam = session.orientation.cameras.get(v.station)
        if cam is None or v.id in exclude:
            continue
        depth = (cam.R @ (X[0] - cam.X0))[2]
        if depth >= 0:                        # behind the camera
            continue
        p = cam.project(X[0])[0]
        if 0 <= p[0] <= v.width and 0 <= p[1] <= v.height:
            out.append({"view": v.id, "x": float(p[0]), "y": float(p[1])})
    return out


def epipolar_help(session, *, oid=None, view=None, xy=None, point=None) -> dict:
    """``GET /api/epipolar`` (docs/measure-serve.md): epipolar curves of
    a point (an observation ``oid``, or a click ``xy`` in ``view``) in the
    other oriented views of its exposure, and the predicted positions of
    its label; with ``view`` and ``point`` only, the predictions of the
    point from its existing rays in the views that do not measure it."""
    if oid is not None:
        table = session.table_of(oid)
        if table is not session.points_table:
            return {"lines": [], "predicted": [], "note": "epipolar help is for points"}
        row = table.find(oid)
        c = row.cells
        view = session.view(f"{c['exposure']}/{c['station']}" if c.get("exposure")
                            else c["station"])
        xy, point = (float(c["x"]), float(c["y"])), c["point"]
    if not session.orientation.oriented:
        return {"lines": [], "predicted": [], "note": session.orientation.note or NOT_ORIENTED}
    exposure = view.exposure or ""
    views = _exposure_views(session, exposure)
    src = session.orientation.cameras.get(view.station)
    lines, notes = [], []
    if xy is not None:
        if src is None:
            notes.append(f"view {view.id} is not oriented: no epipolar curves")
        else:
            d = src.rays(src.ideal(np.asarray([xy], float)))[0]
            for v in views:
                cam = session.orientation.cameras.get(v.station)
                if v.id == view.id or cam is None or not v.width:
                    continue
                pts = image_of_ray(cam, src.X0, d, v.width, v.height)
                if pts:
                    lines.append({"view": v.id, "points": pts})
    predicted = []
    if point:
        if xy is not None:
            cams, rays = _rays_of(session, point, exposure, skip_station=view.station)
            if src is not None:
                cams, rays = cams + [src], rays + [list(xy)]
            predicted = _predict(session, cams, rays, views, {view.id})
        else:
            cams, rays = _rays_of(session, point, exposure)
            measured = {f"{exposure}/{r.cells['station']}" if exposure else r.cells["station"]
                        for r in session.points_table.rows
                        if r.cells["point"] == point and r.cells.get("exposure", "") == exposure}
            predicted = _predict(session, cams, rays, views, measured)
        if len(cams) < 2:
            notes.append(f"{point}: fewer than 2 rays in oriented views, no prediction")
    note = "; ".join(notes) or f"{len(lines)} epipolar curves, {len(predicted)} predictions"
    return {"lines": lines, "predicted": predicted, "note": note}


def predicted_line(session, exposure: str, line: str) -> dict:
    """``GET /api/predict_line``: the 3D line of ski line ``line`` from the
    views that measure it, drawn into the oriented views that do not."""
    from photogram.lines.initial import initial_line_homogeneous
    from photogram.lines.views import fit_view_line
    table = session.lines_table
    if table is None or not session.orientation.oriented:
        return {"lines": []}
    by_station: dict[str, list] = {}
    for r in table.rows:
        c = r.cells
        if c["line"] == line and c.get("exposure", "") == (exposure or ""):
            try:
                by_station.setdefault(c["station"], []).append([float(c["x"]), float(c["y"])])
            except ValueError:
                continue
    cams = session.orientation.cameras
    fitted = {}
    for st, pts in by_station.items():
        if st in cams and len(pts) >= 2:
            try:
                fitted[st] = fit_view_line(np.asarray(pts), cams[st], label=line)
            except PhotogramError:
                continue
    if len(fitted) < 2:
        return {"lines": []}
    try:
        L = initial_line_homogeneous(fitted, {s: cams[s] for s in fitted}, label=line)
    except PhotogramError:
        return {"lines": []}
    out = []
    for v in _exposure_views(session, exposure):
        cam = cams.get(v.station)
        if cam is None or v.station in by_station or not v.width:
            continue
        back = image_of_ray(cam, L.point, -L.direction, v.width, v.height)
        ahead = image_of_ray(cam, L.point, L.direction, v.width, v.height)
        pts = back[::-1] + ahead[1:] if back and ahead else back[::-1] + ahead
        if len(pts) >= 2:
            out.append({"view": v.id, "points": pts})
    return {"lines": out}
