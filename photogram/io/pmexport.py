"""PhotoModeler text exports, in the layout DBAT reads (``loadpm.m`` and
``prob2dbatstruct.m`` of niclasborlin/dbat).

Layout (blank lines end the blocks; numbers separated by blanks)::

    TITLE
    TOL MAXITER [WIDTH HEIGHT]                 image size in px (optional)
    default sigmas (photo coordinates mm, control m, object m, camera ...)
    c xp yp xs ys K1 K2 K3 P1 P2               default camera, mm
    sigmas of the default camera
    N FILE_NAME                                one block of 6 lines per photo,
    N X Y Z KAPPA PHI OMEGA                    N zero-based; angles in degrees
    N sX sY sZ sKAPPA sPHI sOMEGA
    N cXY cXZ cYZ                              (may hold only N)
    N c xp yp xs ys K1 K2 K3 P1 P2             the photo's camera (not used)
    N sigmas of it
    <blank>
    ID X Y Z sX sY sZ                          control points (m)
    <blank>
    ID X Y Z sX sY sZ                          all object points as estimated
    <blank>
    PHOTO ID X Y sX sY                         marked points: x, y in px, sigmas in mm
    [<blank> features ...]                     ignored

Conversion (docs/camera-models.md, 4.1 and 4.2): PhotoModeler's values are
the ``brown`` model's in mm (DBAT flips the signs of py, K and P internally
and back in its report). With pixel width ``pw = xs / WIDTH`` and height
``ph = ys / HEIGHT`` photogram works in pixels of height ``ph``: ``c =
c_mm / ph``, ``x0 = xp / pw``, ``y0 = yp / ph``, ``K_i * ph^(2i)``, ``P_i
* ph`` and, for non-square pixels, ``B1 = pw / ph - 1``. The angles
(world-to-camera omega-phi-kappa, as DBAT's) and positions are stations
with their estimated values as approximations; the object points are
approximations of the tie points, the control points keep their sigmas (0:
fixed). Marked-point sigmas become px (``mean(sx, sy) / ph``); zero sigmas
(smart points) take ``sigma_image``.

Lost: the per-photo cameras (the default camera is used for all photos, as
DBAT does by default), the a-priori default sigmas of stations and points,
the station covariances, features.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.io.exchange import LineText, build_project

__all__ = ["read_pmexport", "pmexport_project"]


def _fields(s: str) -> list[str]:
    return s.replace(",", " ").split()


def read_pmexport(path) -> dict:
    """Parse a PhotoModeler export (see the module doc) into plain arrays.

    Raises
    ------
    InputError
        Missing header lines, a truncated photo block, bad numbers: with the
        line.
    """
    text = LineText(path, "PhotoModeler export")
    lines = text.lines
    n = len(lines)
    if n < 5:
        raise text.error(n or 1, "the header needs 5 lines (title, tolerance, default "
                                 "sigmas, default camera, its sigmas)",
                         hint="the file is truncated or not a PhotoModeler export")
    tol = text.numbers(2, _fields(lines[1]), what="TOL MAXITER [WIDTH HEIGHT]", minimum=2)
    size = (int(tol[2]), int(tol[3])) if len(tol) >= 4 else None
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
            raise text.error(k + 1, f"expected a photo block 'N FILE_NAME', found {f[0]!r}") \
                from None
        if k + 5 >= n:
            raise text.error(n, f"photo {number}: its block of 6 lines is truncated")
        block = []
        for j, (what, count) in enumerate((("X Y Z KAPPA PHI OMEGA", 6),
                                          ("their sigmas", 6), ("covariances", None),
                                          ("camera", 10), ("camera sigmas", None)), start=1):
            vals = text.numbers(k + j + 1, _fields(lines[k + j]), what=what)
            if not vals or int(vals[0]) != number:
                raise text.error(k + j + 1, f"photo {number}: expected a line starting with "
                                            f"{number} ({what})")
            if count is not None and len(vals) - 1 != count:
                raise text.error(k + j + 1, f"photo {number}: expected {count} values "
                                            f"({what}), found {len(vals) - 1}")
            block.append(vals[1:])
        photos.append({"number": number, "name": f[1].strip() if len(f) > 1 else str(number),
                       "outer": np.array(block[0]), "outer_std": np.array(block[1]),
                       "line": k + 1})
        k += 6
    if not photos:
        raise text.error(min(k + 1, n), "no photo blocks after the header")

    def table(start, width, what):
        rows, nos = [], []
        i = start
        while i < n and lines[i].strip():
            vals = text.numbers(i + 1, _fields(lines[i]), width, what=what)
            rows.append(vals)
            nos.append(i + 1)
            i += 1
        return np.array(rows, float).reshape(-1, width), nos, i + 1

    ctrl, ctrl_no, k = table(k + 1, 7, "ID X Y Z sX sY sZ of a control point")
    objs, obj_no, k = table(k, 7, "ID X Y Z sX sY sZ of an object point")
    marks, mark_no, k = table(k, 6, "PHOTO ID X Y sX sY of a marked point")
    if not len(marks):
        raise text.error(min(k, n), "no marked points", hint="the file is truncated")
    return {"path": text.path, "title": lines[0].strip(), "size": size, "camera": np.array(cam),
            "camera_std": np.array(cam_std), "photos": photos, "control": ctrl,
            "control_lines": ctrl_no, "objects": objs, "marks": marks, "mark_lines": mark_no,
            "text": text}


def _ident(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def pmexport_project(path, name: str | None = None, image_size=None):
    """Import a PhotoModeler export as a project (image unit px, one
    ``brown`` camera with c, x0, y0, K1-K3, P1-P2 free; datum ``control`` if
    all control points are fixed, else ``weighted``)."""
    from photogram.geometry import to_radians
    from photogram.project.model import Camera, Parameter
    d = read_pmexport(path)
    text = d["text"]
    size = image_size or d["size"]
    if size is None:
        raise text.error(2, "the image size is not in the file (WIDTH HEIGHT after TOL "
                            "MAXITER)", hint="give it with image_size=(w, h)")
    c, xp, yp, xs, ys, K1, K2, K3, P1, P2 = d["camera"]
    W, H = size
    pw, ph = xs / W, ys / H
    if not (pw > 0 and ph > 0):
        raise text.error(4, "the format size xs, ys must be positive")
    values = {"c": c / ph, "x0": xp / pw, "y0": yp / ph, "K1": K1 * ph ** 2, "K2": K2 * ph ** 4,
              "K3": K3 * ph ** 6, "P1": P1 * ph, "P2": P2 * ph, "B1": pw / ph - 1.0, "B2": 0.0}
    free = {"c", "x0", "y0", "K1", "K2", "K3", "P1", "P2"}
    camera = Camera(name="pm", model="brown",
                    parameters={k: Parameter(value=float(v), free=k in free)
                                for k, v in values.items()},
                    image_size=(int(W), int(H)), pixel_size=(pw, ph), source=str(d["path"]))
    photos = d["photos"]
    numbers = [p["number"] for p in photos]
    if len(set(numbers)) != len(numbers):
        raise text.error(photos[-1]["line"], "photo numbers repeat")
    names = [str(p["number"]) for p in photos]
    outer = np.array([p["outer"] for p in photos])
    X0 = outer[:, :3]
    angles = to_radians(outer[:, [5, 4, 3]], "deg")          # file: kappa phi omega
    ctrl = {_ident(r[0]): r for r in d["control"]}
    objs = {_ident(r[0]): r for r in d["objects"]}
    marks = d["marks"]
    by_number = {p: names[i] for i, p in enumerate(numbers)}
    obs_st, obs_pt, keep = [], [], []
    seen = set()
    for i, row in enumerate(marks):
        no = d["mark_lines"][i]
        photo = int(row[0])
        if photo not in by_number:
            raise text.error(no, f"marked point on photo {photo}, which has no photo block")
        pid = _ident(row[1])
        if pid not in objs and pid not in ctrl:
            continue                                      # no object point: not used (DBAT)
        if (photo, pid) in seen:
            raise text.error(no, f"point {pid} is marked twice on photo {photo}")
        seen.add((photo, pid))
        obs_st.append(by_number[photo])
        obs_pt.append(pid)
        keep.append(i)
    keep = np.array(keep, int)
    sig_mm = marks[keep][:, 4:6].mean(axis=1)
    sigma = np.where(sig_mm > 0, sig_mm / ph, np.nan)
    ids = list(dict.fromkeys(list(ctrl) + list(objs)))
    measured = set(obs_pt)
    ids = [p for p in ids if p in measured or p in ctrl]
    kinds = ["control" if p in ctrl else "tie" for p in ids]
    xyz = np.array([ctrl[p][1:4] if p in ctrl else objs[p][1:4] for p in ids], float)
    psig = np.array([ctrl[p][4:7] if p in ctrl else [np.nan] * 3 for p in ids], float)
    weighted = any(np.any(ctrl[p][4:7] > 0) for p in ctrl)
    finite = sigma[np.isfinite(sigma)]
    return build_project(name or Path(path).stem, {"pm": camera}, stations=names,
                         station_camera=["pm"] * len(names), angles=angles, X0=X0,
                         point_ids=ids, kinds=kinds, xyz=xyz.reshape(-1, 3),
                         point_sigma=psig.reshape(-1, 3), obs_station=obs_st, obs_point=obs_pt,
                         obs_xy=marks[keep][:, 2:4], obs_sigma=sigma,
                         datum="weighted" if weighted else "control",
                         sigma_image=float(np.median(finite)) if len(finite) else 1.0)
