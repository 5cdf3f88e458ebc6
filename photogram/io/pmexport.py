"""PhotoModeler text exports, as PhotoModeler writes them and DBAT reads
them (``loadpm.m`` and ``prob2dbatstruct.m`` of niclasborlin/dbat).

Layout (numbers separated by blanks; a blank line ends a block)::

    TITLE
    TOL MAXITER [WIDTH HEIGHT]                 image size in px (optional)
    default sigmas (photo coordinates, control, object, camera ...)
    c xp yp xs ys K1 K2 K3 P1 P2               default camera, mm
    sigmas of the default camera
    N FILE_NAME                                one block of 6 lines per photo,
    N X Y Z KAPPA PHI OMEGA                    N zero-based; angles in degrees
    N sX sY sZ sKAPPA sPHI sOMEGA
    [N cXY cXZ cYZ]                            covariances: often an EMPTY line
    N c xp yp xs ys K1 K2 K3 P1 P2             the photo's camera (not used)
    N sigmas of it
    <blank>
    ID X Y Z sX sY sZ                          control points (often none)
    <blank>
    ID X Y Z sX sY sZ                          all object points as PM adjusted them
    <blank>
    PHOTO ID X Y sX sY                         marked points: x, y and sigmas in px
    [<blank> features ...]                     ignored

What PhotoModeler writes and DBAT accepts, and so does this reader: the
covariance line of a photo block may be empty (``loadpm`` reads it as
NaN); file names in Latin-1 (PhotoModeler is a Windows program: the file is
read as UTF-8 and, failing that, as Latin-1); no WIDTH HEIGHT on line 2
(``loadpm`` then reads the size of the first photo's image file; so does
:func:`pmexport_project` when the file is found beside the export, else
``image_size`` must be given).

DBAT's reading (``prob2dbatstruct``), taken over:

* marked-point sigmas are in **pixels** (``loadpm``'s comment says mm, its
  use is px); one sigma per observation, ``(sx + sy) / 2``. If every sigma
  of the file is 0 (PhotoModeler's smart points), DBAT uses 1 px for all;
  so does this reader. A file that mixes zero and non-zero sigmas: DBAT
  0.9.2 keeps each observation's own sigma (its warning "Using prior
  sigma==1" is not acted on; older DBAT used 1 for all) and a zero sigma
  has no finite weight; here the zero ones get 1 px, with a warning;
* control comes from a control file (DBAT's ``id,label,x,y,z[,sx,sy,sz]``
  table, ``control=``), not from PhotoModeler's adjusted coordinates: those
  are approximate values only. Without a control file, the export's own
  control block is used; without either, the datum is ``free``;
* the default camera is used for all photos and stays **fixed** unless
  ``free`` names the parameters to estimate (DBAT's camcal runs free
  ``c x0 y0 B1 K1 K2 K3 P1 P2``: ``free="all"``);
* marks on photo ``i`` (zero-based, in the order of the photo blocks) and
  of an id that is not an object point are not used.

Conversion (docs/camera-models.md, 4.1 and 4.2): with ``pw = xs / WIDTH``
and ``ph = ys / HEIGHT`` photogram works in pixels of height ``ph``:
``c = c_mm / ph``, ``x0 = xp / pw``, ``y0 = yp / ph``, ``K_i * ph^(2i)``,
``P_i * ph``, ``B1 = pw / ph - 1`` (DBAT reads xp in units of ph: 0.04 %
of xp, 0.45 px, on the CAMCAL camera; a fixed camera differs by that).
Stations are named ``1 .. n`` (DBAT's photo numbers, the image ids of
DBAT's scripts), with PhotoModeler's positions and world-to-camera
omega-phi-kappa angles as approximate values.

Not taken over: the per-photo cameras, the default sigmas of line 3, the
station sigmas and covariances, PhotoModeler's smart-point renumbering,
features; object points without marks are left out (DBAT keeps them as
unknowns and fails: "structurally rank deficient").
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from photogram.io.exchange import LineText, build_project

__all__ = ["read_pmexport", "pmexport_project", "DBAT_CALIBRATION"]

log = logging.getLogger("photogram")

#: the parameters DBAT's camcal runs estimate ("Calibration: yes (cc px py as
#: K1 K2 K3 P1 P2)"): ``free="all"``
DBAT_CALIBRATION = ("c", "x0", "y0", "B1", "K1", "K2", "K3", "P1", "P2")

_BLOCK_HINT = ("each photo block has 6 lines: 'N FILE_NAME', 'N X Y Z KAPPA PHI OMEGA', their "
               "sigmas, the covariances (may be empty), the camera (10 values), its sigmas")


def _fields(s: str) -> list[str]:
    return s.replace(",", " ").split()


def _photo_block(text, k: int, number: int) -> list:
    """The 5 lines after 'N FILE_NAME' (k: its 0-based index): outer,
    outer sigmas, covariances (may be empty), camera, camera sigmas."""
    lines, n = text.lines, len(text.lines)
    out = []
    for j, (what, count) in enumerate((("X Y Z KAPPA PHI OMEGA", 6), ("their sigmas", 6),
                                       ("covariances", None), ("camera", 10),
                                       ("camera sigmas", None)), start=1):
        if k + j >= n:
            raise text.error(n, f"photo {number}: its block of 6 lines is truncated",
                             hint=_BLOCK_HINT)
        fields = _fields(lines[k + j])
        if what == "covariances" and not fields:
            out.append([])                              # PhotoModeler's empty line
            continue
        if not fields or fields[0] != str(number):
            raise text.error(k + j + 1, f"photo {number}: expected a line starting with "
                                        f"{number} ({what}), found "
                                        f"{lines[k + j].strip()[:40]!r}", hint=_BLOCK_HINT)
        vals = text.numbers(k + j + 1, fields, what=what)
        if vals[0] != number:
            raise text.error(k + j + 1, f"photo {number}: expected a line starting with "
                                        f"{number} ({what}), found "
                                        f"{lines[k + j].strip()[:40]!r}", hint=_BLOCK_HINT)
        if count is not None and len(vals) - 1 != count:
            raise text.error(k + j + 1, f"photo {number}: expected {count} values "
                                        f"({what}), found {len(vals) - 1}", hint=_BLOCK_HINT)
        out.append(vals[1:])
    return out


def _table(text, start: int, width: int, what: str):
    """Rows of ``width`` numbers from line index ``start`` to a blank line."""
    lines, n = text.lines, len(text.lines)
    rows, nos = [], []
    i = start
    while i < n and lines[i].strip():
        rows.append(text.numbers(i + 1, _fields(lines[i]), width, what=what))
        nos.append(i + 1)
        i += 1
    return np.array(rows, float).reshape(-1, width), nos, i + 1


def read_pmexport(path) -> dict:
    """Parse a PhotoModeler export (see the module doc) into plain arrays.

    Raises
    ------
    InputError
        Missing header lines, a broken or truncated photo block, bad
        numbers: with the line and what the line should hold.
    """
    text = LineText(path, "PhotoModeler export", fallback="latin-1")
    lines = text.lines
    n = len(lines)
    if n < 5:
        raise text.error(n or 1, "the header needs 5 lines (title, tolerance, default "
                                 "sigmas, default camera, its sigmas)",
                         hint="the file is truncated or not a PhotoModeler export")
    tol = text.numbers(2, _fields(lines[1]), what="TOL MAXITER [WIDTH HEIGHT]", minimum=2)
    if len(tol) not in (2, 4):
        raise text.error(2, f"expected TOL MAXITER or TOL MAXITER WIDTH HEIGHT, found "
                            f"{len(tol)} values")
    size = (int(tol[2]), int(tol[3])) if len(tol) == 4 else None
    cam = text.numbers(4, _fields(lines[3]), 10, what="default camera c xp yp xs ys K1 K2 K3 "
                                                      "P1 P2")
    cam_std = text.numbers(5, _fields(lines[4]), what="default camera sigmas")
    k = 5
    photos = []
    while k < n and lines[k].strip():
        f = lines[k].split(maxsplit=1)
        try:
            number = int(f[0])
        except ValueError:
            raise text.error(k + 1, f"expected a photo block 'N FILE_NAME', found {f[0]!r}",
                             hint=_BLOCK_HINT) from None
        outer, outer_std, _cov, _cam, _cam_std = _photo_block(text, k, number)
        photos.append({"number": number, "name": f[1].strip() if len(f) > 1 else str(number),
                       "outer": np.array(outer), "outer_std": np.array(outer_std),
                       "line": k + 1})
        k += 6
    if not photos:
        raise text.error(min(k + 1, n), "no photo blocks after the header", hint=_BLOCK_HINT)
    ctrl, ctrl_no, k = _table(text, k + 1, 7, "ID X Y Z sX sY sZ of a control point")
    objs, obj_no, k = _table(text, k, 7, "ID X Y Z sX sY sZ of an object point")
    marks, mark_no, k = _table(text, k, 6, "PHOTO ID X Y sX sY of a marked point")
    if not len(marks):
        raise text.error(min(k, n), "no marked points", hint="the file is truncated")
    return {"path": text.path, "title": lines[0].strip(), "size": size, "camera": np.array(cam),
            "camera_std": np.array(cam_std), "photos": photos, "control": ctrl,
            "control_lines": ctrl_no, "objects": objs, "object_lines": obj_no, "marks": marks,
            "mark_lines": mark_no, "encoding": text.encoding, "text": text}


def _ident(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def _image_size(d: dict, image_size):
    """The image size: given, from line 2, or (as loadpm) from the first
    photo's image file when it is found beside the export."""
    if image_size is not None:
        return tuple(int(v) for v in image_size)
    if d["size"] is not None:
        return d["size"]
    name = d["photos"][0]["name"].replace("\\", "/")
    for cand in (d["path"].parent / name, d["path"].parent / Path(name).name):
        if cand.is_file():
            import cv2
            img = cv2.imread(str(cand), cv2.IMREAD_UNCHANGED)
            if img is not None:
                return int(img.shape[1]), int(img.shape[0])
    raise d["text"].error(2, "the image size is not in the file (WIDTH HEIGHT after TOL "
                             "MAXITER) and the first photo's image file was not found",
                          hint="add the width and height in pixels to line 2, or give "
                               "--image-size W,H")


def _camera(d: dict, size, free):
    from photogram.project.model import Camera, Parameter
    c, xp, yp, xs, ys, K1, K2, K3, P1, P2 = d["camera"]
    W, H = size
    pw, ph = xs / W, ys / H
    if not (pw > 0 and ph > 0):
        raise d["text"].error(4, "the format size xs, ys must be positive")
    values = {"c": c / ph, "x0": xp / pw, "y0": yp / ph, "K1": K1 * ph ** 2, "K2": K2 * ph ** 4,
              "K3": K3 * ph ** 6, "P1": P1 * ph, "P2": P2 * ph, "B1": pw / ph - 1.0, "B2": 0.0}
    if free == "all":
        free = DBAT_CALIBRATION
    free = set(free or ())
    unknown = sorted(free - set(values))
    if unknown:
        from photogram.errors import InputError
        raise InputError(f"unknown camera parameter(s) {', '.join(unknown)} to free",
                         hint="use 'all' or names of " + ", ".join(values))
    return Camera(name="pm", model="brown",
                  parameters={k: Parameter(value=float(v), free=k in free)
                              for k, v in values.items()},
                  image_size=(int(W), int(H)), pixel_size=(pw, ph), source=str(d["path"]))


def _mark_sigmas(d: dict, keep) -> np.ndarray:
    """Observation sigmas (px) by DBAT's rule (module doc)."""
    s = d["marks"][keep][:, 4:6]
    if not len(s) or np.all(s == 0):
        if len(s):
            log.warning("%s: every marked-point sigma is 0: 1 px is used (as DBAT)", d["path"])
        return np.ones(len(s))
    zero = np.any(s == 0, axis=1)
    if zero.any():
        log.warning("%s: %d marked point(s) have sigma 0 among others: they get 1 px "
                    "(DBAT gives them no finite weight)", d["path"], int(zero.sum()))
    return np.where(zero, 1.0, s.mean(axis=1))


def _control(d: dict, control):
    """{id: (xyz, sigma)} of the control points: from the control file if
    given (DBAT's table; sigma 0 or none: fixed), else the export's block."""
    if control is not None:
        from photogram.project.dbat_tables import read_control_points
        cp = read_control_points(control)
        return {pid: (cp.xyz[k], np.nan_to_num(cp.sigma[k], nan=0.0))
                for k, pid in enumerate(cp.ids)}
    return {_ident(r[0]): (r[1:4], r[4:7]) for r in d["control"]}


def pmexport_project(path, name: str | None = None, image_size=None, *, control=None,
                     free=None):
    """Import a PhotoModeler export as a project (module doc).

    Parameters
    ----------
    path : the export
    image_size : (width, height) px, optional (overrides line 2)
    control : path of a DBAT control table (``id,label,x,y,z[,sx,sy,sz]``),
        optional; its points that are object points of the export become
        control points (datum ``control`` if all are fixed, else
        ``weighted``)
    free : "all" or names of the ``brown`` parameters to estimate; default:
        the camera is fixed (as DBAT's prob2dbatstruct)
    """
    from photogram.geometry import to_radians
    d = read_pmexport(path)
    text = d["text"]
    camera = _camera(d, _image_size(d, image_size), free)
    photos = d["photos"]
    names = [str(i + 1) for i in range(len(photos))]
    outer = np.array([p["outer"] for p in photos])
    angles = to_radians(outer[:, [5, 4, 3]], "deg")          # file: kappa phi omega
    ctrl = _control(d, control)
    objs = {_ident(r[0]): r for r in d["objects"]}
    marks = d["marks"]
    obs_st, obs_pt, keep = [], [], []
    seen = set()
    for i, row in enumerate(marks):
        no = d["mark_lines"][i]
        photo = row[0]
        if not (photo.is_integer() and 0 <= photo < len(photos)):
            raise text.error(no, f"marked point on photo {photo:g}, which has no photo block "
                                 f"(photos are numbered 0 to {len(photos) - 1})")
        pid = _ident(row[1])
        if pid not in objs:
            continue                                      # no object point: not used (DBAT)
        if (photo, pid) in seen:
            raise text.error(no, f"point {pid} is marked twice on photo {int(photo)}")
        seen.add((photo, pid))
        obs_st.append(names[int(photo)])
        obs_pt.append(pid)
        keep.append(i)
    keep = np.array(keep, int)
    measured = set(obs_pt)
    unmarked = [p for p in objs if p not in measured]
    if unmarked:
        log.warning("%s: object point(s) %s have no marked points and are left out", d["path"],
                    ", ".join(unmarked[:10]) + (" ..." if len(unmarked) > 10 else ""))
    ids = [p for p in objs if p in measured]
    rays = {p: 0 for p in ids}
    for p in obs_pt:
        rays[p] += 1
    single = [p for p in ids if rays[p] == 1 and p not in ctrl]
    if single:
        log.warning("%s: point(s) %s are marked on one photo only: the project is refused until "
                    "they are marked again or removed (DBAT: structurally rank deficient)",
                    d["path"], ", ".join(single[:10]) + (" ..." if len(single) > 10 else ""))
    control_ids = {p for p in ids if p in ctrl}
    kinds = ["control" if p in control_ids else "tie" for p in ids]
    xyz = np.array([ctrl[p][0] if p in control_ids else objs[p][1:4] for p in ids], float)
    psig = np.array([ctrl[p][1] if p in control_ids else [np.nan] * 3 for p in ids], float)
    weighted = any(np.any(np.asarray(ctrl[p][1]) > 0) for p in control_ids)
    datum = "weighted" if weighted else "control" if control_ids else "free"
    sigma = _mark_sigmas(d, keep)
    return build_project(name or Path(path).stem, {"pm": camera}, stations=names,
                         station_camera=["pm"] * len(names), angles=angles, X0=outer[:, :3],
                         point_ids=ids, kinds=kinds, xyz=xyz.reshape(-1, 3),
                         point_sigma=psig.reshape(-1, 3), obs_station=obs_st, obs_point=obs_pt,
                         obs_xy=marks[keep][:, 2:4], obs_sigma=sigma,
                         datum=datum, sigma_image=float(np.median(sigma)) if len(sigma) else 1.0)
