"""DBAT's text tables and camera XML (Börlin & Grussenmeyer's Damped Bundle
Adjustment Toolbox) as input tables of a project.

The .prj schema accepts DBAT's image-point and control-point tables and its
camera XML as they are (docs/project-files.md, "Reading DBAT projects"), so
their parsers belong to the project reader
(:mod:`photogram.project.reader_dbat`). The converter
:mod:`photogram.io.dbat` (``photogram import dbat``) uses the same parsers
from here.

* Image points: comma-separated, ``#`` comments, columns named by a DBAT
  format string, by default ``"im,id,x,y,sxy"`` (image id, point id, pixel
  coordinates x right / y down, sigma); DBAT's aerial examples use
  ``"id,im,x,y"`` with the sigma given separately.
* Control points: ``id,label,x,y,z``, ``id,label,x,y,z,sxyz`` or
  ``id,label,x,y,z,sx,sy,sz`` (recognised by the number of columns).
* Camera XML: a ``<camera>`` element (in a camera file such as
  ``c4040z.xml`` or in a DBAT script's ``<input><cameras>``) with ``unit``,
  ``sensor`` ("w,h" or "auto,h"), ``image`` ("W,H" px), ``focal``, optional
  ``cc`` and ``pp`` (``0``/``default``/``focal`` or absent: the focal length
  and the sensor centre), ``K``, ``P``, ``model``.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.project.model import Camera, Parameter
from photogram.project.text_input import decode_utf8

__all__ = ["DbatImagePoints", "DbatControlPoints", "DbatCamera", "read_image_points",
           "read_control_points", "read_camera_xml", "DBAT_LENS_MODELS", "DBAT_NO_AFFINITY",
           "dbat_lens_camera"]

# ---------------------------------------------------------------------------
# tables


def _rows(path: Path):
    """(line number, fields) of the non-empty, non-comment lines."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise InputError(f"cannot read {path}: {e.strerror or e}", file=path) from None
    text = decode_utf8(data, path)
    for no, line in enumerate(text.splitlines(), start=1):
        s = line.split("#", 1)[0].strip()
        if s:
            yield no, [f.strip() for f in s.split(",")]


def _float(s: str, path, no, what) -> float:
    try:
        value = float(s)
    except ValueError:
        raise InputError(f"{what} is not a number: {s!r}", file=path, line=no) from None
    if not math.isfinite(value):
        raise InputError(f"{what} is not a finite number: {s!r}", file=path, line=no,
                         hint="NaN and infinity are not allowed") from None
    return value


def _ident(s: str) -> str:
    """Normalise a numeric id ("0017" -> "17", "17.0" -> "17")."""
    try:
        f = float(s)
    except ValueError:
        return s
    return str(int(f)) if math.isfinite(f) and f == int(f) else s


@dataclass
class DbatImagePoints:
    """Image measurements as read (one row per line)."""

    image: list[str]
    point: list[str]
    xy: np.ndarray            # (n, 2) pixels
    sxy: np.ndarray           # (n,) NaN where not given
    line: np.ndarray          # (n,) 1-based line numbers
    path: Path | None = None


def _idents(cells: list[str]) -> list[str]:
    """:func:`_ident` of each cell, once per distinct cell."""
    seen: dict[str, str] = {}
    return [seen[c] if c in seen else seen.setdefault(c, _ident(c)) for c in cells]


def _image_points_at_once(rows, ci, n_cols, sxy):
    """The columns of :func:`read_image_points` for rows without a problem,
    whole columns at a time; None if any row has one (the row-by-row loop
    then raises the first problem's error)."""
    if not rows or any(len(f) < n_cols for _, f in rows):
        return None
    try:
        xy = np.array([(float(f[ci["x"]]), float(f[ci["y"]])) for _, f in rows], dtype=float)
        if "sxy" in ci:
            sg = np.array([float(f[ci["sxy"]]) for _, f in rows], dtype=float)
        else:
            sg = np.full(len(rows), float(sxy) if sxy is not None else np.nan)
    except ValueError:
        return None
    if not np.all(np.isfinite(xy)) or ("sxy" in ci and not np.all(np.isfinite(sg))) or \
            not np.all(np.isnan(sg) | (sg > 0)):
        return None
    return (_idents([f[ci["im"]] for _, f in rows]), _idents([f[ci["id"]] for _, f in rows]),
            xy, sg, np.array([no for no, _ in rows], dtype=int))


def read_image_points(path, format: str = "im,id,x,y,sxy",
                      sxy: float | None = None) -> DbatImagePoints:
    """Read a DBAT image-point table.

    Parameters
    ----------
    path : str or Path
    format : str
        DBAT column names, comma-separated; ``im`` image id, ``id`` point
        id, ``x``, ``y`` pixel coordinates (x right, y down), ``sxy``
        (optional) sigma of both coordinates; other names are ignored.
    sxy : float, optional
        Sigma for rows without an ``sxy`` column (DBAT's ``sxy`` attribute).

    Returns
    -------
    DbatImagePoints

    Raises
    ------
    InputError
        Missing columns, non-numeric coordinates, non-positive sigma.
    """
    path = Path(path)
    cols = [c.strip().lower() for c in format.split(",")]
    for need in ("im", "id", "x", "y"):
        if need not in cols:
            raise InputError(f"image-point format {format!r} has no column {need!r}",
                             file=path, hint='e.g. "im,id,x,y,sxy" or "id,im,x,y"')
    ci = {c: cols.index(c) for c in cols}
    rows = list(_rows(path))
    fast = _image_points_at_once(rows, ci, len(cols), sxy)
    if fast is not None:
        im, pt, xy, sg, ln = fast
        return DbatImagePoints(image=im, point=pt, xy=xy, sxy=sg, line=ln, path=path)
    im, pt, xy, sg, ln = [], [], [], [], []
    for no, f in rows:
        if len(f) < len(cols):
            raise InputError(f"expected {len(cols)} columns ({format}), got {len(f)}",
                             file=path, line=no)
        im.append(_ident(f[ci["im"]]))
        pt.append(_ident(f[ci["id"]]))
        xy.append((_float(f[ci["x"]], path, no, "x"), _float(f[ci["y"]], path, no, "y")))
        s = _float(f[ci["sxy"]], path, no, "sxy") if "sxy" in ci else \
            (float(sxy) if sxy is not None else np.nan)
        if not (np.isnan(s) or s > 0):
            raise InputError(f"sigma must be positive, got {s:g}", file=path, line=no)
        sg.append(s)
        ln.append(no)
    if not im:
        raise InputError("no image points in file", file=path)
    return DbatImagePoints(image=im, point=pt, xy=np.array(xy, dtype=float),
                           sxy=np.array(sg, dtype=float), line=np.array(ln, dtype=int),
                           path=path)


@dataclass
class DbatControlPoints:
    """Control points as read."""

    ids: list[str]
    labels: list[str]
    xyz: np.ndarray           # (n, 3)
    sigma: np.ndarray         # (n, 3); 0 = fixed (no sigma column)
    line: np.ndarray
    path: Path | None = None


def read_control_points(path) -> DbatControlPoints:
    """Read a DBAT control-point table.

    Rows ``id,label,x,y,z`` (fixed control, sigma 0),
    ``id,label,x,y,z,sxyz`` (one sigma for all three) or
    ``id,label,x,y,z,sx,sy,sz``.

    Raises
    ------
    InputError
        Wrong number of columns, non-numeric values, duplicate ids.
    """
    path = Path(path)
    ids, labels, xyz, sig, ln = [], [], [], [], []
    for no, f in _rows(path):
        if len(f) not in (5, 6, 8):
            raise InputError(
                f"control point row needs 5, 6 or 8 columns, got {len(f)}", file=path,
                line=no, hint="id,label,x,y,z[,sxyz] or id,label,x,y,z,sx,sy,sz")
        pid = _ident(f[0])
        if pid in ids:
            raise InputError(f"duplicate control point {pid}", file=path, line=no)
        ids.append(pid)
        labels.append(f[1])
        xyz.append([_float(v, path, no, n) for v, n in zip(f[2:5], "xyz")])
        if len(f) == 5:
            s = [0.0, 0.0, 0.0]
        elif len(f) == 6:
            s = [_float(f[5], path, no, "sxyz")] * 3
        else:
            s = [_float(v, path, no, "sigma") for v in f[5:8]]
        if any(v < 0 for v in s):
            raise InputError("control point sigma must not be negative", file=path, line=no)
        sig.append(s)
        ln.append(no)
    if not ids:
        raise InputError("no control points in file", file=path)
    return DbatControlPoints(ids=ids, labels=labels, xyz=np.array(xyz, dtype=float),
                             sigma=np.array(sig, dtype=float), line=np.array(ln), path=path)


# ---------------------------------------------------------------------------
# camera XML


@dataclass
class DbatCamera:
    """A DBAT camera description (camera units, usually mm)."""

    id: str
    name: str
    unit: str
    sensor: tuple[float, float]          # width, height in camera units
    image: tuple[int, int]               # width, height in px
    focal: float
    cc: float                            # camera constant (focal if not given)
    pp: tuple[float, float]              # principal point in camera units
    K: tuple[float, ...] = ()
    P: tuple[float, ...] = ()
    model: int | None = None
    aspect: float = 1.0
    notes: list = field(default_factory=list)

    @property
    def pixel_size(self) -> tuple[float, float]:
        """Camera units per pixel (x, y)."""
        return (self.sensor[0] / self.image[0], self.sensor[1] / self.image[1])


def _numbers(text, path, what) -> list[float]:
    vals = [v.strip() for v in (text or "").split(",") if v.strip()]
    try:
        out = [float(v) for v in vals]
    except ValueError:
        out = None
    if out is None or not all(math.isfinite(v) for v in out):
        raise InputError(f"camera XML: <{what}> is not a list of finite numbers: {text!r}",
                         file=path, hint="comma-separated numbers") from None
    return out


def read_camera_xml(path) -> list[DbatCamera]:
    """Read the ``<camera>`` elements of a DBAT camera or script XML file.

    Defaults as in DBAT: ``sensor`` width ``auto`` is the height times the
    image aspect (square pixels, times ``aspect``); ``cc`` absent, ``focal``
    or 0 is the focal length; ``pp`` absent, ``default`` or ``0,0`` is the
    sensor centre. ``pp`` is taken as measured from the top-left corner of
    the sensor, x right and y down (our image frame).

    Raises
    ------
    InputError
        Unreadable XML, no camera, missing ``image``/``sensor``/``focal``.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        raise InputError(f"cannot read camera XML: {e}", file=path) from None
    cams = []
    for el in root.iter("camera"):
        def text(tag):
            e = el.find(tag)
            return None if e is None or e.text is None else e.text.strip()
        if text("image") is None and text("focal") is None:
            continue                       # e.g. a <camera> reference, not a description
        notes = []
        img = _numbers(text("image"), path, "image")
        if len(img) != 2:
            raise InputError("camera XML: <image> must be 'width,height' in pixels",
                             file=path)
        W, H = int(round(img[0])), int(round(img[1]))
        aspect_t = text("aspect")
        aspect = 1.0 if aspect_t in (None, "", "auto") else _numbers(aspect_t, path, "aspect")[0]
        sens = [s.strip() for s in (text("sensor") or "").split(",")]
        if len(sens) != 2:
            raise InputError("camera XML: <sensor> must be 'width,height' or 'auto,height'",
                             file=path)
        h = _numbers(sens[1], path, "sensor")[0]
        w = aspect * h * W / H if sens[0] == "auto" else _numbers(sens[0], path, "sensor")[0]
        focal_t = text("focal")
        if focal_t is None:
            raise InputError("camera XML: no <focal> length", file=path)
        focal = _numbers(focal_t, path, "focal")[0]
        cc_t = text("cc")
        cc = focal
        if cc_t not in (None, "", "focal", "default"):
            v = _numbers(cc_t, path, "cc")
            if v and v[0] > 0:
                cc = v[0]
        pp = (w / 2.0, h / 2.0)
        pp_t = text("pp")
        if pp_t not in (None, "", "default"):
            v = _numbers(pp_t, path, "pp")
            if len(v) == 2 and (v[0] != 0 or v[1] != 0):
                pp = (v[0], v[1])
        K = tuple(_numbers(text("K"), path, "K")) if text("K") else ()
        P = tuple(_numbers(text("P"), path, "P")) if text("P") else ()
        if abs(aspect - 1.0) > 1e-12:
            notes.append(f"aspect {aspect:g} is not modelled (brown has B1/B2 instead)")
        model_t = text("model")
        cams.append(DbatCamera(
            id=text("id") or str(len(cams) + 1), name=text("name") or f"camera{len(cams) + 1}",
            unit=text("unit") or "mm", sensor=(w, h), image=(W, H), focal=focal, cc=cc,
            pp=pp, K=K, P=P, model=int(float(model_t)) if model_t else None,
            aspect=aspect, notes=notes))
    if not cams:
        raise InputError("camera XML: no <camera> element with <image> and <focal>",
                         file=path)
    return cams


def _slug(name: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.-]+", "_", name.strip()).strip("_")
    return s or "camera"


#: DBAT's lens distortion model numbers -> photogram's camera models
#: (docs/camera-models.md, section 4.5). Models 1 and 2 are ``brown`` with
#: B1 = B2 = 0 held fixed (:data:`DBAT_NO_AFFINITY`).
DBAT_LENS_MODELS = {-1: "brown_forward", 1: "brown", 2: "brown", 3: "brown",
                    4: "brown_affine_after", 5: "brown_aspect_first"}
#: DBAT lens models without aspect and skew.
DBAT_NO_AFFINITY = (-1, 1, 2)


def _brown_camera(cam: DbatCamera, name: str, source: str) -> Camera:
    """The DBAT camera as a "brown" :class:`Camera` in pixel units.

    DBAT's model-3 parameters (cc, px, py, K1-K3, P1-P2 in camera units) are
    those of :class:`photogram.geometry.BrownModel` in mm; they are rescaled
    to pixels with :func:`photogram.geometry.rescale_parameters` and the
    pixel width (``c = cc / pixel width``, ``K_i * p^(2i)``, ``P_i * p``).
    """
    return dbat_lens_camera(cam, name, source, "brown")


def dbat_lens_camera(cam: DbatCamera, name: str, source: str, model_name: str) -> Camera:
    """The DBAT camera as a :class:`Camera` of photogram model
    ``model_name`` (a value of :data:`DBAT_LENS_MODELS`), in pixel units.

    The models of :mod:`photogram.geometry.dbat_models` and ``brown`` take
    DBAT's reported values (cc, px, py, K1-K3, P1-P2 in mm) as they are;
    parameters the model lacks (B1, B2 of ``brown_forward``) are left out.
    """
    from photogram.geometry import camera_model, rescale_parameters
    model = camera_model(model_name)
    names = tuple(model.parameter_names)
    px, py = cam.pixel_size
    mm = dict.fromkeys(names, 0.0)
    mm["c"], mm["x0"] = cam.cc, cam.pp[0]
    mm["y0"] = cam.pp[1] * px / py           # so that y0 / px = pp_y / pixel height
    for i, k in enumerate(cam.K[:3]):
        if np.isfinite(k):
            mm[f"K{i + 1}"] = float(k)
    for i, v in enumerate(cam.P[:2]):
        if np.isfinite(v):
            mm[f"P{i + 1}"] = float(v)
    values = rescale_parameters(model, np.array([mm[n] for n in names]), 1.0 / px)
    params = {n: Parameter(value=float(v)) for n, v in zip(names, values)}
    return Camera(name=name, model=model_name, parameters=params, image_size=cam.image,
                  pixel_size=(px, py), source=source)
