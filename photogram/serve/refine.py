"""A click refined to a target centre by the detector of ``photogram
measure``.

The window around the click is searched by
:func:`photogram.measure.detect.detect_targets` (blobs, then the ellipse
fitted to the edge points of :mod:`photogram.measure.centre`), with the
target field's polarity, diameters and contrast when ``--field`` is given
(else both polarities with the detector's defaults); the detection whose
ellipse holds the click is measured again in a window centred on it (so it
is never cut by the window's border). The centre is converted to the
corner convention of the observation tables (+0.5 px,
:data:`photogram.measure.pipeline.PIXEL_OFFSET`) and its sigma is the
detector's with the field's floor, ``sqrt(sigma^2 + sigma_floor^2)``, as
:func:`photogram.measure.pipeline.measure_image` writes it.

Eccentricity (Ahn et al. 1999, :mod:`photogram.measure.eccentricity`).
*A plane field* (a grid, ring codes; no table of 3D targets): as
:func:`photogram.measure.pipeline.measure_image` does, the homography from
the field's plane to the view is fitted (plain least squares,
``cv2.findHomography`` method 0) to the view's observations of the field's
other targets (four or more; the clicked label left out) and the ellipse
centre of the labelled target is corrected with it; no orientation is
needed. *A 3D field* that gives the target diameter and normal, an
oriented view and a labelled point with coordinates (the field's, else
the project's): the plane of the target is mapped into the view by
``H = [P e1, P e2, P X]`` of the view's ideal projection matrix ``P``
(:class:`photogram.lines.views.ViewCamera`), as
``photogram.measure.pipeline._eccentricity_3d`` does with its DLT
matrix, and the ellipse centre is corrected to the image of the circle's
centre (method ``"ellipse+eccentricity"``). A project with ``[targets]``
(eccentricity modelled by the adjustment, docs/adjustment.md) takes the
uncorrected ellipse centres, as ``photogram measure --no-eccentricity``
writes them.

No target at the click: the point is kept as clicked (``refined`` false,
method ``"clicked"``, sigma :data:`MANUAL_SIGMA`).
"""

from __future__ import annotations

import numpy as np

from photogram.measure.detect import detect_targets
from photogram.measure.eccentricity import eccentricity
from photogram.measure.pipeline import PIXEL_OFFSET

__all__ = ["refine_click", "refine_at", "field_plane_eccentricity", "MANUAL_SIGMA"]

MANUAL_SIGMA = 0.5          # px: a point kept as clicked


def _detect(gray, cx, cy, half, settings):
    """Detections of a window of half-size ``half`` around (cx, cy) (OpenCV
    frame), as full-image coordinates: list of (xy, a, sigma)."""
    h, w = gray.shape
    x0, y0 = max(int(cx) - half, 0), max(int(cy) - half, 0)
    x1, y1 = min(int(cx) + half + 1, w), min(int(cy) + half + 1, h)
    if x1 - x0 < 8 or y1 - y0 < 8:
        return []
    win = np.ascontiguousarray(gray[y0:y1, x0:x1])
    out = []
    for polarity in settings["polarity"]:
        det = detect_targets(win, polarity, min_diameter=settings["min_diameter"],
                             max_diameter=settings["max_diameter"],
                             min_contrast=settings["min_contrast"])
        for i in range(len(det)):
            out.append((det.xy[i] + (x0, y0), float(det.axes[i, 0]), float(det.sigma[i])))
    return out


def refine_at(gray: np.ndarray, x: float, y: float, settings: dict):
    """The target centre nearest a click at (x, y) (corner convention).

    Parameters
    ----------
    gray : (h, w) uint8
    x, y : float
        The click, corner convention.
    settings : dict
        polarity (tuple of "dark"/"bright"), min_diameter, max_diameter,
        min_contrast (px, grey levels).

    Returns
    -------
    (xy, sigma) or None
        Centre in the corner convention and the detector's sigma, or None
        when no target's ellipse holds the click.
    """
    cx, cy = x - PIXEL_OFFSET, y - PIXEL_OFFSET
    half = int(np.ceil(settings["max_diameter"])) + 4
    found = [d for d in _detect(gray, cx, cy, half, settings)
             if np.hypot(*(d[0] - (cx, cy))) <= d[1] + 1.5]
    if not found:
        return None
    xy, a, _ = min(found, key=lambda d: np.hypot(*(d[0] - (cx, cy))))
    # again, centred on the target: the window's border cuts nothing of it
    half = int(np.ceil(max(2.5 * a, 8))) + 4
    again = [d for d in _detect(gray, xy[0], xy[1], half, settings)
             if np.hypot(*(d[0] - xy)) < 1.0]
    if again:
        xy, a, sigma = min(again, key=lambda d: np.hypot(*(d[0] - xy)))
    else:
        sigma = min(found, key=lambda d: np.hypot(*(d[0] - (cx, cy))))[2]
    return np.asarray(xy, float) + PIXEL_OFFSET, float(sigma)


def detector_settings(field) -> dict:
    """The detector's settings of a target field (None: both polarities,
    the detector's defaults with diameters 4-80 px)."""
    if field is None:
        return {"polarity": ("bright", "dark"), "min_diameter": 4.0, "max_diameter": 80.0,
                "min_contrast": 20.0, "sigma_floor": 0.02, "channel": "green"}
    return {"polarity": (field.polarity,), "min_diameter": float(field.min_diameter),
            "max_diameter": float(field.max_diameter),
            "min_contrast": float(field.min_contrast), "sigma_floor": float(field.sigma_floor),
            "channel": field.channel}


def target_plane(field, project, point):
    """(X, normal, radius) of a labelled circular target of a 3D field,
    ``"plane"`` for a target of a plane field (corrected through the
    field's homography, :func:`field_plane_eccentricity`), or a reason
    (str) why its eccentricity cannot be corrected."""
    targets = getattr(project, "targets", None)
    if targets is not None and targets.eccentricity:
        # the adjustment predicts ellipse centres: the table holds them uncorrected
        return "the project's [targets] models it in the adjustment"
    if field is None:
        return "no --field (target diameter and normal unknown)"
    if not point:
        return "no label"
    if field.diameter <= 0 or field.shape != "circle":
        return "the field gives no circle diameter"
    if point in set(field.markers.values()):
        return f"{point} is a marker, not a circle"
    if not field.spatial:
        ids = field.layout()[0]
        if point not in ids:
            return f"{point} is not a target of the field"
        return "plane"
    if point in field.target_ids and field.target_normal is not None:
        i = field.target_ids.index(point)
        return field.target_xyz[i], field.target_normal[i], field.diameter / 2
    return f"the field gives no normal for {point}"


def field_plane_eccentricity(field, observations, point):
    """Ellipse centre minus image of the centre of target ``point`` of a
    plane field (module doc), px, or a reason (str) when it cannot be
    corrected.

    Parameters
    ----------
    field : TargetField
        A plane field (``field.layout()``: ids and plane coordinates).
    observations : iterable of (label, x, y)
        The view's observations (corner convention); ``point``'s own are
        left out, so do labels that are not the field's.
    point : str
        A target of the field.
    """
    import cv2
    ids, XY = field.layout()
    pos = {k: i for i, k in enumerate(ids)}
    src, dst = [], []
    for label, x, y in observations:
        if label != point and label in pos and np.isfinite(x) and np.isfinite(y):
            src.append(XY[pos[label]])
            dst.append((x - PIXEL_OFFSET, y - PIXEL_OFFSET))
    if len(src) < 4:
        return (f"{len(src)} other targets of the field measured in this view "
                f"(4 are needed for its homography)")
    H, _ = cv2.findHomography(np.asarray(src, float), np.asarray(dst, float), 0)
    if H is None:
        return "the field's homography could not be fitted to this view's observations"
    return eccentricity(H, XY[[pos[point]]], field.diameter / 2)[0]


def _view_observations(session, view):
    """(label, x, y) of the points table's rows of ``view``."""
    table = getattr(session, "points_table", None)
    out = []
    for row in (table.rows if table is not None else ()):
        c = row.cells
        if c.get("station") != view.station or c.get("exposure", "") not in ("", view.exposure or ""):
            continue
        try:
            out.append((c.get(table.label, ""), float(c["x"]), float(c["y"])))
        except (KeyError, ValueError):
            continue
    return out


def plane_eccentricity(camera, X, normal, radius) -> np.ndarray:
    """Ellipse centre minus image of the centre of a circle (centre X,
    unit normal, radius) in an oriented view (module doc), px."""
    P = camera.matrix
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    up = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(up, n)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    H = np.column_stack([P[:, :3] @ e1, P[:, :3] @ e2, P[:, :3] @ np.asarray(X, float) + P[:, 3]])
    return eccentricity(H, np.zeros((1, 2)), radius)[0]


def refine_click(session, view, x: float, y: float, point=None) -> dict:
    """``POST /api/refine``: the refined centre at a click (module doc)."""
    settings = detector_settings(session.field)
    gray = session.images.gray(view.id, settings["channel"])
    hit = refine_at(gray, x, y, settings)
    if hit is None:
        return {"x": float(x), "y": float(y), "sigma": MANUAL_SIGMA, "refined": False,
                "method": "clicked",
                "note": "no target at the click: kept as clicked (manual, sigma 0.5 px)"}
    xy, sigma = hit
    sigma = float(np.hypot(sigma, settings["sigma_floor"]))
    method, note = "ellipse", "ellipse centre (photogram measure's detector)"
    camera = session.orientation.cameras.get(view.station)
    plane = target_plane(session.field, session.project, point)
    e = None
    if isinstance(plane, str) and plane == "plane":
        e = field_plane_eccentricity(session.field, _view_observations(session, view), point)
        if isinstance(e, str):
            note += f"; no eccentricity correction: {e}"
            e = None
    elif camera is None:
        note += "; no eccentricity correction: the view is not oriented"
    elif isinstance(plane, str):
        note += f"; no eccentricity correction: {plane}"
    else:
        e = plane_eccentricity(camera, *plane)
    if e is not None:
        xy = xy - e
        method = "ellipse+eccentricity"
        note += f"; eccentricity ({e[0]:.3f}, {e[1]:.3f}) px corrected"
    return {"x": float(xy[0]), "y": float(xy[1]), "sigma": sigma, "refined": True,
            "method": method, "note": note}
