"""DBAT XML project scripts (``camcaldemo.xml``, ``sxb.xml``) into a
self-contained photogram project.

What is read (docs/project-files.md, "Mapping a DBAT script to a .prj"):

* ``<input base_dir=...>``: ``$HERE`` (the script's folder), ``$HOME`` and
  ``$DBAT`` (environment variable ``DBAT``) are expanded. A table that is
  not found where the script says is looked for beside the script (DBAT's
  examples are often copied flat) with a warning in the log.
* ``<ctrl_pts><file format=...>`` with ``<filter id="..">remove|keep</filter>``;
  ``<check_pts>`` likewise: the kept points become ``check`` points.
* ``<image_pts><file format=".." sxy="..">``, one or several.
* ``<cameras><camera>``: one camera (``photogram.io.dbat.read_camera_xml``),
  converted to a ``brown`` camera in pixels.
* ``<set_bundle_estimate_params><io>``: which interior parameters are free
  (``all``, ``cc``, ``pp``/``px``/``py``, ``aspect``, ``skew``, ``K``/``K1``..,
  ``P``/``P1``..; ``nK``/``nP`` of the camera limit K and P).
* Datum: ``control`` when the control points are fixed (no sigmas),
  ``weighted`` when they have sigmas.

Not taken over: image file paths, the order of DBAT's operations (photogram's
approximation chain replaces spatial resection / forward intersection),
plots and output file names, control point labels.
"""

from __future__ import annotations

import logging
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from photogram.errors import InputError

__all__ = ["dbat_script_project", "read_dbat_script"]

log = logging.getLogger("photogram")

_IO_KEYS = {"cc": ("c",), "pp": ("x0", "y0"), "px": ("x0",), "py": ("y0",),
            "aspect": ("B1",), "as": ("B1",), "skew": ("B2",), "sk": ("B2",),
            "K": ("K1", "K2", "K3"), "K1": ("K1",), "K2": ("K2",), "K3": ("K3",),
            "P": ("P1", "P2"), "P1": ("P1",), "P2": ("P2",)}


def _parse(path: Path) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        line = exc.position[0] if getattr(exc, "position", None) else None
        raise InputError(f"XML syntax error: {exc.msg if hasattr(exc, 'msg') else exc}",
                         file=path, line=line, hint="the file is damaged or truncated") from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", file=path) from None


def _line_of(path: Path, tag: str, text: str | None = None) -> int | None:
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    for k, ln in enumerate(lines, 1):
        if f"<{tag}" in ln and (text is None or text in ln):
            return k
    return None


def _expand(text: str, here: Path) -> str:
    text = text.strip().replace("$HERE", str(here)).replace("$HOME", str(Path.home()))
    if "$DBAT" in text:
        text = text.replace("$DBAT", os.environ.get("DBAT", str(here)))
    return text


def _file(el: ET.Element, base: Path, script: Path) -> Path:
    name = (el.text or "").strip()
    if not name:
        raise InputError(f"empty <{el.tag}> element", file=script, line=_line_of(script, el.tag))
    p = Path(_expand(name, script.parent))
    p = p if p.is_absolute() else base / p
    if p.is_file():
        return p
    flat = script.parent / Path(name).name
    if flat.is_file():
        log.warning("%s: %s not found, using %s beside the script", script, p, flat)
        return flat
    raise InputError(f"table {name} not found (looked for {p} and {flat})", file=script,
                     line=_line_of(script, "file", name))


def _ids(text: str) -> set[str]:
    from photogram.project.dbat_tables import _ident
    return {_ident(s.strip()) for s in (text or "").split(",") if s.strip()}


def _points_block(el, base, script):
    """[(path, format, filter ids, keep?)] of a <ctrl_pts>/<check_pts> block."""
    if el is None:
        return []
    out = []
    flt = el.find("filter")
    ids = _ids(flt.get("id", "")) if flt is not None else None
    mode = (flt.text or "").strip().lower() if flt is not None else None
    if mode not in (None, "keep", "remove"):
        raise InputError(f"<filter> must say keep or remove, not {mode!r}", file=script,
                         line=_line_of(script, "filter"))
    for f in el.findall("file"):
        out.append((_file(f, base, script), f.get("format"), ids, mode))
    return out


def _free(root: ET.Element, cam) -> list[str]:
    io = None
    for op in root.iter("set_bundle_estimate_params"):
        io = op.find("io")
    if io is None:
        return []
    nk = int(cam.get("nK", 3))
    np_ = int(cam.get("nP", 2))
    allowed = {"c", "x0", "y0", "B1", "B2"} | {f"K{i}" for i in range(1, nk + 1)} \
        | {f"P{i}" for i in range(1, np_ + 1)}

    def flag(t):
        return (t or "").strip().lower() in ("true", "1", "yes")
    free: set[str] = set()
    if len(io) == 0:
        return sorted(allowed) if flag(io.text) else []
    order = ["all"] + [c.tag for c in io if c.tag != "all"]
    for tag in order:
        child = io.find(tag)
        if child is None:
            continue
        names = allowed if tag == "all" else set(_IO_KEYS.get(tag, ()))
        (free.update if flag(child.text) else free.difference_update)(names)
    model = ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1", "B2")
    return [n for n in model if n in free and n in allowed]


def read_dbat_script(path) -> dict:
    """The parts of a DBAT script photogram uses (paths resolved)."""
    path = Path(path).resolve()
    root = _parse(path)
    if root.tag != "document" or root.find("input") is None:
        raise InputError("not a DBAT script (no <document><input>)", file=path, line=1,
                         hint="for a camera file use [cameras] from_dbat in a .prj")
    inp = root.find("input")
    base = Path(_expand(inp.get("base_dir", "$HERE"), path.parent))
    ctrl = _points_block(inp.find("ctrl_pts"), base, path)
    check = _points_block(inp.find("check_pts"), base, path)
    ip = inp.find("image_pts")
    images = []
    for f in (ip.findall("file") if ip is not None else []):
        sxy = f.get("sxy")
        try:
            sxy = float(sxy) if sxy is not None else None
        except ValueError:
            raise InputError(f"sxy={sxy!r} is not a number", file=path,
                             line=_line_of(path, "file", f.text.strip())) from None
        images.append((_file(f, base, path), f.get("format") or "im,id,x,y,sxy", sxy))
    if not images:
        raise InputError("the script has no <image_pts><file>", file=path,
                         line=_line_of(path, "input"))
    cams = inp.find("cameras")
    cam_els = [] if cams is None else [c for c in cams.findall("camera")]
    if len(cam_els) != 1:
        raise InputError(f"the script has {len(cam_els)} cameras; photogram imports scripts with "
                         f"exactly one", file=path, line=_line_of(path, "cameras"))
    cam = {c.tag: (c.text or "").strip() for c in cam_els[0]}
    name = (root.findtext("meta/name") or path.stem).strip()
    unit = (root.findtext("meta/project_unit") or "m").strip()
    return {"path": path, "name": name, "unit": unit, "ctrl": ctrl, "check": check,
            "images": images, "camera": cam, "free": _free(root, cam)}


def dbat_script_project(path, name: str | None = None):
    """Import a DBAT script as a :class:`~photogram.project.model.Project`
    (tables copied into photogram's CSV tables when written).

    Raises
    ------
    InputError
        Malformed XML (with the line), missing tables, several cameras, and
        every error of the DBAT table readers (file and line).
    """
    from photogram.io.dbat import (_brown_camera, _slug, read_camera_xml, read_control_points,
                                   read_image_points)
    from photogram.io.exchange import build_project
    s = read_dbat_script(path)
    script = s["path"]
    cam = read_camera_xml(script)[0]
    cname = _slug(cam.name)
    camera = _brown_camera(cam, cname, str(script))
    for p in s["free"]:
        camera.parameters[p].free = True
    # points: control (minus removed), check (kept)
    coords: dict[str, tuple] = {}
    kind: dict[str, str] = {}
    fixed = True
    for block, role in ((s["ctrl"], "control"), (s["check"], "check")):
        for file, fmt, ids, mode in block:
            cp = read_control_points(file)
            for k, pid in enumerate(cp.ids):
                inside = ids is not None and pid in ids
                if mode == "remove" and inside or mode == "keep" and not inside:
                    continue
                coords[pid] = (cp.xyz[k], cp.sigma[k])
                kind[pid] = role
                if role == "control" and np.any(cp.sigma[k] > 0):
                    fixed = False
    st_names, obs_st, obs_pt, obs_xy, obs_sig = [], [], [], [], []
    seen = set()
    for file, fmt, sxy in s["images"]:
        ip = read_image_points(file, fmt, sxy)
        for k in range(len(ip.image)):
            key = (ip.image[k], ip.point[k])
            if key in seen:
                raise InputError(f"point {ip.point[k]} is measured twice in image "
                                 f"{ip.image[k]}", file=file, line=int(ip.line[k]))
            seen.add(key)
        st_names += ip.image
        obs_st += ip.image
        obs_pt += ip.point
        obs_xy.append(ip.xy)
        obs_sig.append(ip.sxy)
    st_names = list(dict.fromkeys(st_names))
    measured = list(dict.fromkeys(obs_pt))
    ids = list(coords) + [p for p in measured if p not in coords]
    kinds = [kind.get(p, "tie") for p in ids]
    xyz = np.array([coords[p][0] if p in coords else [np.nan] * 3 for p in ids], float)
    sig = np.array([coords[p][1] if p in coords else [np.nan] * 3 for p in ids], float)
    sigmas = np.concatenate(obs_sig)
    first = s["images"][0]
    sigma_image = first[2] if first[2] is not None else \
        float(np.nanmedian(obs_sig[0])) if np.isfinite(obs_sig[0]).any() else 1.0
    project = build_project(name or script.stem, {cname: camera}, stations=st_names,
                            station_camera=[cname] * len(st_names), point_ids=ids,
                            kinds=kinds, xyz=xyz.reshape(-1, 3), point_sigma=sig.reshape(-1, 3),
                            obs_station=obs_st, obs_point=obs_pt, obs_xy=np.vstack(obs_xy),
                            obs_sigma=sigmas, length_unit=s["unit"] if s["unit"] in
                            ("m", "dm", "cm", "mm") else "m",
                            datum="control" if fixed else "weighted", sigma_image=sigma_image)
    project.adjustment.max_iterations = 20
    return project
