"""Planes of image lines and the initial 3D line (ski-jump paper, appendix
C.3), with the checks for singular configurations.

Each image line ``l`` (ideal coordinates) and its view define the plane
``pi = P^T l`` through the projection centre (views.py). The object line is
the intersection of all such planes, i.e. the points ``X~`` with
``A X~ = 0`` for the stacked plane vectors ``A`` (k x 4). Two standard
closed forms (Hartley & Zisserman 2003, sec. 3.2.2, the span and null-space
representations of a line and its Plücker coordinates):

* ``method="svd"``: the line is the 2D (right) null space of ``A``, the two
  right singular vectors of the smallest singular values; they are two
  homogeneous points ``(x1, w1)``, ``(x2, w2)`` spanning the line, whose
  Plücker coordinates are ``d = w1 x2 - w2 x1``, ``m = x1 x x2``. Computed in
  coordinates centred on the projection centres and scaled by their spread.
* ``method="pair"``: the best-intersecting pair of planes (the largest angle
  between their normals) meets in ``d = n1 x n2``, ``m = d1 n2 - d2 n1`` for
  planes ``n . X + d = 0`` with unit normals.

Singular cases raise :class:`~photogram.errors.GeometryError`: a line in
fewer than two images, and planes that (nearly) coincide, which happens when
the object line is parallel to the baseline of a stereo pair or lies in one
of its epipolar planes (with three or more views: in one plane with all the
projection centres).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.lines.plucker import SpaceLine, line_from_plucker

__all__ = ["line_planes", "plane_angles", "check_plane_geometry", "initial_line_homogeneous"]


def _views(lines, cameras):
    """``(names, lines, cameras)`` from dicts keyed by station (the lines'
    keys select the cameras) or from aligned sequences."""
    if isinstance(lines, dict):
        names = list(lines)
        missing = [n for n in names if n not in cameras]
        if missing:
            raise InputError(f"no camera (orientation) for station(s) {', '.join(missing)}",
                             hint="pass a ViewCamera for every station that measured the line")
        return names, [lines[n] for n in names], [cameras[n] for n in names]
    lines, cameras = list(lines), list(cameras)
    if len(lines) != len(cameras):
        raise InputError(f"{len(lines)} image lines but {len(cameras)} cameras")
    names = [getattr(c, "name", "") or f"view {i + 1}" for i, c in enumerate(cameras)]
    return names, lines, cameras


def _homogeneous(line) -> np.ndarray:
    if hasattr(line, "homogeneous"):
        if getattr(line, "frame", "ideal") != "ideal":
            raise InputError(
                f"line {line.label or ''} in {line.station or 'a view'} was fitted in measured "
                "image coordinates",
                hint="fit it with fit_view_line (ideal, corrected coordinates relative to "
                     "the principal point)")
        return np.asarray(line.homogeneous, dtype=float)
    return np.asarray(line, dtype=float).reshape(3)


def line_planes(lines, cameras) -> np.ndarray:
    """Planes ``pi_j = P_j^T l_j`` (k, 4) with unit normals (``pi . (X, 1)``
    the signed distance of X)."""
    _, lines, cameras = _views(lines, cameras)
    return np.array([cam.plane(_homogeneous(l)) for l, cam in zip(lines, cameras)])


def plane_angles(planes) -> np.ndarray:
    """Angles (radians, in [0, pi/2]) between the normals of all pairs of
    planes (k, k)."""
    n = np.asarray(planes, dtype=float)[:, :3]
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    cr = np.linalg.norm(np.cross(n[:, None, :], n[None, :, :]), axis=-1)
    return np.arctan2(cr, np.abs(n @ n.T))


def check_plane_geometry(planes, names, label=None, min_angle_deg: float = 1.0):
    """Raise GeometryError for fewer than 2 planes or planes meeting at less
    than ``min_angle_deg``; return the best pair ``(i, j)`` and its angle."""
    what = f"line {label}" if label else "the line"
    k = len(planes)
    if k < 2:
        where = f" ({', '.join(names)})" if names else ""
        raise GeometryError(
            f"{what} is measured in {k} image{'' if k == 1 else 's'}{where}; "
            f"a 3D line needs at least 2 images",
            hint="measure it in a second (better a third) oriented image")
    ang = plane_angles(planes)
    i, j = np.unravel_index(int(np.argmax(ang)), ang.shape)
    i, j = (int(i), int(j)) if i < j else (int(j), int(i))
    best = float(ang[i, j])
    if best < np.radians(min_angle_deg):
        if k == 2:
            raise GeometryError(
                f"{what}: the planes of {names[0]} and {names[1]} meet at "
                f"{np.degrees(best):.3g} deg (< {min_angle_deg:g} deg): the line is (nearly) "
                f"parallel to the baseline {names[0]}-{names[1]} or lies in an epipolar "
                f"plane of the pair, and its depth along the baseline is undetermined",
                hint="measure it in a third image whose projection centre is off that plane")
        raise GeometryError(
            f"{what}: the planes of all {k} images ({', '.join(names)}) meet at no more "
            f"than {np.degrees(best):.3g} deg (< {min_angle_deg:g} deg): the line lies "
            f"(nearly) in one plane with their projection centres",
            hint="measure it in an image taken from outside that plane")
    return (i, j), best


def _conditioning(cameras):
    C = np.array([cam.X0 for cam in cameras])
    centre = C.mean(0)
    scale = np.sqrt(((C - centre) ** 2).sum(1).mean())
    return centre, (scale if scale > 0 else 1.0)


def initial_line_homogeneous(lines, cameras, *, method: str = "svd", label=None,
                             min_plane_angle_deg: float | None = 1.0) -> SpaceLine:
    """Initial 3D line from k >= 2 image lines (appendix C.3).

    Parameters
    ----------
    lines : dict {station: ImageLine} or sequence
        Image lines in ideal coordinates (:func:`fit_view_line`), or
        homogeneous ideal lines (3,).
    cameras : dict {station: ViewCamera} or sequence
    method : ``"svd"`` or ``"pair"``
        Null space of the stacked planes, or the intersection of the pair of
        planes with the largest angle between them (module docstring).
    label : str, optional
        Line name for messages.
    min_plane_angle_deg : float or None
        Raise GeometryError if no two planes meet at this angle (None: no
        check).

    Returns
    -------
    SpaceLine
        Without covariance; its point is the one closest to the centroid of
        the projection centres.
    """
    names, lines, cameras = _views(lines, cameras)
    if label is None:
        label = next((getattr(l, "label", None) for l in lines if getattr(l, "label", None)),
                     None)
    planes = line_planes(lines, cameras)
    if min_plane_angle_deg is not None:
        (i, j), _ = check_plane_geometry(planes, names, label, min_plane_angle_deg)
    elif len(planes) < 2:
        check_plane_geometry(planes, names, label, 0.0)
    else:
        ang = plane_angles(planes)
        i, j = np.unravel_index(int(np.argmax(ang)), ang.shape)
    centre, scale = _conditioning(cameras)
    # conditioned planes: X = centre + scale X'  ->  pi' = (scale n, n . centre + pi4)
    Pc = np.column_stack([planes[:, :3] * scale, planes[:, :3] @ centre + planes[:, 3]])
    Pc /= np.linalg.norm(Pc, axis=1, keepdims=True)
    if method == "svd":
        _, _, Vt = np.linalg.svd(Pc)
        x1, x2 = Vt[-2], Vt[-1]
        d = x1[3] * x2[:3] - x2[3] * x1[:3]
        m = np.cross(x1[:3], x2[:3])
    elif method == "pair":
        n1, n2 = Pc[i, :3], Pc[j, :3]
        d = np.cross(n1, n2)
        m = Pc[i, 3] * n2 - Pc[j, 3] * n1
    else:
        raise InputError(f"unknown method {method!r} for the initial line",
                         hint='use "svd" or "pair"')
    Lc = line_from_plucker(d, m)
    return SpaceLine(centre + scale * Lc.point, Lc.direction, label=label)
