"""``photogram import dbat``: a DBAT project (Börlin & Grussenmeyer's Damped
Bundle Adjustment Toolbox) as a photogram project. The parsers of DBAT's
text tables and camera XML live in :mod:`photogram.project.dbat_tables`
(the .prj reader accepts those tables as input; the project layer is below
io) and are re-exported here (the table formats and the camera XML are
described there).

:func:`load_dbat_project` assembles a :class:`photogram.project.model.Project`
with one camera of model ``"brown"`` in **pixel** units: ``c = cc / pixel
size``, ``x0, y0`` = the principal point in pixels (the image centre
``(W/2, H/2)`` for the default), lens distortion rescaled from camera units
to pixels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.dbat_tables import (  # noqa: F401  (re-exported)
    DbatCamera, DbatControlPoints, DbatImagePoints, _brown_camera, _ident, _slug,
    read_camera_xml, read_control_points, read_image_points)
from photogram.project.model import (AdjustmentSettings, ImagePoints, Points, Project,
                                     Stations, Units)

__all__ = ["DbatImagePoints", "DbatControlPoints", "DbatCamera", "read_image_points",
           "read_control_points", "read_camera_xml", "load_dbat_project"]


def _sort_key(s: str):
    try:
        return (0, float(s), s)
    except ValueError:
        return (1, 0.0, s)


def load_dbat_project(markpts, control, camera_xml, name: str = "camcal", *,
                      image_format: str = "im,id,x,y,sxy", sxy: float | None = None,
                      check_ids=(), length_unit: str = "m",
                      camera_name: str | None = None) -> Project:
    """Build a :class:`Project` from DBAT's image points, control points and
    camera XML.

    Stations are the image ids (sorted numerically), all of the one camera;
    their orientation is unknown (NaN). Points are the union of measured and
    control points (sorted numerically); control points have kind
    ``"control"`` (or ``"check"`` for ``check_ids``), their coordinates and
    sigmas (0: fixed); the others are ``"tie"`` points with NaN coordinates.

    Parameters
    ----------
    markpts : str or Path
        Image-point table (see :func:`read_image_points`).
    control : str or Path or None
        Control-point table (see :func:`read_control_points`).
    camera_xml : str or Path
        DBAT camera XML (the first camera is used).
    name : str
        Project name.
    image_format : str
        Column format of ``markpts``.
    sxy : float, optional
        Image sigma for tables without an ``sxy`` column.
    check_ids : iterable of str
        Control points to use as check points.
    length_unit : str
        Unit of the control coordinates.
    camera_name : str, optional
        Name of the camera in the project (default: the XML ``<name>`` with
        non-identifier characters replaced by ``_``).

    Returns
    -------
    Project
        Image unit ``px``; adjustment ``sigma_image`` set to the median
        image sigma.

    Raises
    ------
    InputError
        Unreadable or malformed files.
    """
    ip = read_image_points(markpts, image_format, sxy)
    cams = read_camera_xml(camera_xml)
    cam = cams[0]
    cname = camera_name or _slug(cam.name)
    from photogram.project.dbat_tables import DBAT_LENS_MODELS, dbat_lens_camera
    lens = 3 if cam.model is None or cam.model not in DBAT_LENS_MODELS else int(cam.model)
    camera = dbat_lens_camera(cam, cname, str(camera_xml), DBAT_LENS_MODELS[lens])

    st_names = sorted(set(ip.image), key=_sort_key)
    n_st = len(st_names)
    stations = Stations(names=st_names, camera=[cname] * n_st,
                        position=np.full((n_st, 3), np.nan), angles=np.full((n_st, 3), np.nan),
                        position_sigma=np.full((n_st, 3), np.nan),
                        angle_sigma=np.full((n_st, 3), np.nan))

    cp = read_control_points(control) if control is not None else None
    checks = {_ident(str(c)) for c in check_ids}
    ids = set(ip.point) | (set(cp.ids) if cp is not None else set())
    pt_ids = sorted(ids, key=_sort_key)
    m = len(pt_ids)
    pidx = {p: i for i, p in enumerate(pt_ids)}
    kind = np.array(["tie"] * m, dtype=object)
    xyz = np.full((m, 3), np.nan)
    sig = np.full((m, 3), np.nan)
    if cp is not None:
        for k, pid in enumerate(cp.ids):          # loop over control points (few)
            i = pidx[pid]
            kind[i] = "check" if pid in checks else "control"
            xyz[i] = cp.xyz[k]
            sig[i] = cp.sigma[k]
    points = Points(ids=pt_ids, kind=kind, xyz=xyz, sigma=sig)

    sidx = {s: i for i, s in enumerate(st_names)}
    station = np.array([sidx[s] for s in ip.image], dtype=int)
    point = np.array([pidx[p] for p in ip.point], dtype=int)
    key = station.astype(np.int64) * (m + 1) + point
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        k = int(first[np.argmax(counts > 1)])
        raise InputError(f"point {ip.point[k]} is measured twice in image {ip.image[k]}",
                         file=ip.path, line=int(ip.line[k]))
    image_points = ImagePoints(station=station, point=point, xy=ip.xy.copy(),
                               sigma=ip.sxy.copy(), record=ip.line.copy())
    finite = ip.sxy[np.isfinite(ip.sxy)]
    adj = AdjustmentSettings(datum="control" if cp is not None else "free")
    if len(finite):
        adj.sigma_image = float(np.median(finite))
    sources = {"image_points": Path(markpts), "camera": Path(camera_xml)}
    if control is not None:
        sources["control_points"] = Path(control)
    return Project(name=name, units=Units(length=length_unit, angle="deg", image="px"),
                   cameras={cname: camera}, stations=stations, points=points,
                   image_points=image_points, adjustment=adj, sources=sources)
