"""DBAT XML project scripts (``camcaldemo.xml``, ``sxb.xml``) into a
self-contained photogram project (docs/project-files.md, "Mapping a DBAT
script to a .prj"; DBAT's parser: ``code/script/*.m`` of niclasborlin/dbat).

What is read:

* ``<input base_dir=...>``: ``$HERE`` (the script's folder), ``$HOME`` and
  ``$DBAT`` (environment variable ``DBAT``) are expanded. A table that is
  not found where the script says is looked for beside the script (DBAT's
  examples are often copied flat) with a warning in the log.
* ``<ctrl_pts><file format=...>`` with ``<filter id="..">remove|keep</filter>``;
  ``<check_pts>`` likewise: the kept points become ``check`` points.
* ``<images><file format="id,path">``: the image ids give the order of the
  stations (DBAT's image numbers, ``ref_cam``); the image paths are not used.
* ``<image_pts><file format=".." sxy="..">``, one or several.
* ``<cameras>``: one ``<camera>`` in the script, or ``<file>`` naming a DBAT
  camera file (``<document><cameras><camera>``) beside it; converted to a
  ``brown`` camera in pixels (:func:`photogram.io.dbat.read_camera_xml`).
* ``<prior_eo><file format=".." units="..">``: DBAT's EO table
  (:func:`photogram.io.dbat_script_ops.read_prior_eo`), matched to the
  images by ``id`` (else in order); its values are the stations'
  approximate values when ``<set_initial_values><eo>loaded``; a sigma of 0
  fixes the parameter when ``<set_bundle_estimate_params><eo>default``. As
  in DBAT's scripts the prior is not a weighted observation.
* ``<operations>`` (:mod:`photogram.io.dbat_script_ops`):
  ``set_initial_values`` (the interior start values, ``default`` or
  ``loaded``), ``set_bundle_estimate_params`` (free interior parameters;
  exterior ``true``/``false``/``default``), ``set_datum ... depend``
  (``datum = "dependent"``, ``dependent_station`` = the ``ref_cam``-th
  image, ``dependent_coordinate`` = ``ref_base``).
* Datum otherwise: ``control`` when the control points are fixed (no
  sigmas), ``weighted`` when they have sigmas, ``free`` without control.

Unknown elements (DBAT refuses them too), missing files and bad values are
one-line errors with the script's line.

Not taken over: image file paths, the order of DBAT's numerical operations
(photogram's approximation chain replaces spatial resection / forward
intersection), ``<meta>``, ``<output>`` (plots and output file names),
control point labels, numeric start values for aspect and skew, ``<op>``
other than ``default``, several cameras.
"""

from __future__ import annotations

import logging
import os
import xml.etree.ElementTree as ET
import xml.parsers.expat
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.dbat_script_ops import ScriptState, _Where, read_prior_eo, run_operations

__all__ = ["dbat_script_project", "read_dbat_script"]

log = logging.getLogger("photogram")

_DOCUMENT = ("meta", "input", "operations", "output")
_INPUT = ("ctrl_pts", "check_pts", "images", "prior_eo", "image_pts", "cameras")
_CAMERA = ("id", "name", "unit", "sensor", "image", "aspect", "nK", "nP", "focal", "model",
           "cc", "pp", "K", "P", "skew", "all", "calibrated", "calibration_info")


def _parse(path: Path):
    """(root element, {element: line}) of an XML file (expat, for lines)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", file=path) from None
    builder, lines = ET.TreeBuilder(), {}
    parser = xml.parsers.expat.ParserCreate()

    def start(tag, attrs):
        lines[builder.start(tag, attrs)] = parser.CurrentLineNumber
    parser.StartElementHandler = start
    parser.EndElementHandler = builder.end
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as exc:
        raise InputError(f"XML syntax error: {xml.parsers.expat.ErrorString(exc.code)}",
                         file=path, line=exc.lineno,
                         hint="the file is damaged or truncated") from None
    return builder.close(), lines


def _expand(text: str, here: Path) -> str:
    text = text.strip().replace("$HERE", str(here)).replace("$HOME", str(Path.home()))
    if "$DBAT" in text:
        text = text.replace("$DBAT", os.environ.get("DBAT", str(here)))
    return text


def _file(where: _Where, el: ET.Element, base: Path) -> Path:
    script = where.script
    name = (el.text or "").strip()
    if not name:
        raise where.error(el, f"empty <{el.tag}> element", hint="name a file")
    p = Path(_expand(name, script.parent))
    p = p if p.is_absolute() else base / p
    if p.is_file():
        return p
    flat = script.parent / Path(name).name
    if flat.is_file():
        log.warning("%s: %s not found, using %s beside the script", script, p, flat)
        return flat
    looked = f"{p}" if p == flat else f"{p} and {flat}"
    raise where.error(el, f"file {name} not found (looked for {looked})",
                      hint="correct the path (relative to base_dir) or copy the file there")


def _ids(text: str) -> set[str]:
    from photogram.project.dbat_tables import _ident
    return {_ident(s.strip()) for s in (text or "").split(",") if s.strip()}


def _points_block(where: _Where, el, base):
    """[(path, format, filter ids, keep?)] of a <ctrl_pts>/<check_pts> block."""
    if el is None:
        return []
    where.check(el, ("file", "filter"), el.tag)
    out = []
    flt = el.find("filter")
    ids = _ids(flt.get("id", "")) if flt is not None else None
    mode = (flt.text or "").strip().lower() if flt is not None else None
    if mode not in (None, "keep", "remove"):
        raise where.error(flt, f"<filter> must say keep or remove, not {mode!r}")
    for f in el.findall("file"):
        out.append((_file(where, f, base), f.get("format"), ids, mode))
    return out


def _camera(where: _Where, cams, base):
    """The one DbatCamera of <cameras> (inline or from a camera file)."""
    from photogram.io.dbat import read_camera_xml
    where.check(cams, ("file", "camera"), "cameras")
    files, inline = cams.findall("file"), cams.findall("camera")
    if len(files) + len(inline) != 1:
        raise where.error(cams, f"the script has {len(files) + len(inline)} cameras; photogram "
                                f"imports scripts with exactly one")
    if inline:
        where.check(inline[0], _CAMERA, "camera")
        return read_camera_xml(where.script)[0], where.script
    path = _file(where, files[0], base)
    root, lines = _parse(path)
    inner = _Where(path, lines)
    if root.tag != "document" or root.find("cameras") is None:
        raise inner.error(root, "not a DBAT camera file (no <document><cameras>)",
                          hint="the camera file holds <document><cameras><camera>...")
    found = root.find("cameras").findall("camera")
    if len(found) != 1:
        raise inner.error(root.find("cameras"), f"the camera file has {len(found)} cameras; "
                                                f"photogram imports scripts with exactly one")
    inner.check(found[0], _CAMERA, "camera")
    return read_camera_xml(path)[0], path


def _image_ids(where: _Where, el, base) -> list[str] | None:
    """Image ids in the order of the <images> table (format 'id,path')."""
    if el is None:
        return None
    where.check(el, ("file",), "images")
    from photogram.project.dbat_tables import _ident, _rows
    out = []
    for f in el.findall("file"):
        path = _file(where, f, base)
        cols = [c.strip() for c in (f.get("format") or "id,path").split(",")]
        if "id" not in cols:
            raise where.error(f, f"<images> format {f.get('format')!r} has no id column")
        for _, row in _rows(path):
            out.append(_ident(row[cols.index("id")]))
    return out


def read_dbat_script(path) -> dict:
    """The parts of a DBAT script photogram uses (paths resolved, the
    operations applied: :class:`~photogram.io.dbat_script_ops.ScriptState`)."""
    path = Path(path).resolve()
    root, lines = _parse(path)
    where = _Where(path, lines)
    if root.tag != "document" or root.find("input") is None:
        raise InputError("not a DBAT script (no <document><input>)", file=path, line=1,
                         hint="for a camera file use [cameras] from_dbat in a .prj")
    where.check(root, _DOCUMENT, "document")
    inp = root.find("input")
    where.check(inp, _INPUT, "input")
    base = Path(_expand(inp.get("base_dir", "$HERE"), path.parent))
    ctrl = _points_block(where, inp.find("ctrl_pts"), base)
    check = _points_block(where, inp.find("check_pts"), base)
    ip = inp.find("image_pts")
    images = []
    if ip is not None:
        where.check(ip, ("file",), "image_pts")
    for f in (ip.findall("file") if ip is not None else []):
        sxy = f.get("sxy")
        try:
            sxy = float(sxy) if sxy is not None else None
        except ValueError:
            raise where.error(f, f"sxy={sxy!r} is not a number") from None
        images.append((_file(where, f, base), f.get("format") or "im,id,x,y,sxy", sxy))
    if not images:
        raise where.error(inp, "the script has no <image_pts><file>")
    cams = inp.find("cameras")
    if cams is None:
        raise where.error(inp, "the script has no <cameras>",
                          hint="add <cameras><camera>...</camera></cameras> or "
                               "<cameras><file>camera.xml</file></cameras>")
    camera, camera_file = _camera(where, cams, base)
    prior = None
    pe = inp.find("prior_eo")
    if pe is not None:
        where.check(pe, ("file",), "prior_eo")
        f = pe.find("file")
        if f is None:
            raise where.error(pe, "<prior_eo> has no <file>")
        if not f.get("format"):
            raise where.error(f, "<prior_eo><file> has no format attribute",
                              hint='e.g. format="id,x,y,z,omega,phi,kappa" units="degrees"')
        prior = read_prior_eo(_file(where, f, base), f.get("format"), f.get("units"), where, f)
    name = (root.findtext("meta/name") or path.stem).strip()
    unit = (root.findtext("meta/project_unit") or "m").strip()
    return {"path": path, "name": name, "unit": unit, "ctrl": ctrl, "check": check,
            "images": images, "camera": camera, "camera_file": camera_file,
            "image_ids": _image_ids(where, inp.find("images"), base), "prior_eo": prior,
            "root": root, "where": where}


def _stations(s, measured_images):
    """Station names: the <images> ids (DBAT's image numbers), else the
    measured image ids in order of appearance."""
    ids = s["image_ids"]
    if ids is None:
        return list(dict.fromkeys(measured_images))
    missing = [i for i in dict.fromkeys(measured_images) if i not in ids]
    if missing:
        raise InputError(f"image(s) {', '.join(missing[:5])} have measurements but are not in "
                         f"the <images> table", file=s["path"],
                         hint="add them to the images table")
    return list(dict.fromkeys(ids))


def _prior_rows(s, names):
    """(n, 3) positions, (n, 3) angles, (n, 6) sigmas of the stations from
    <prior_eo> (NaN where none)."""
    n = len(names)
    pos, ang, std = np.full((n, 3), np.nan), np.full((n, 3), np.nan), np.full((n, 6), np.nan)
    pe = s["prior_eo"]
    if pe is None:
        return pos, ang, std
    if pe["ids"] is not None:
        index = {k: i for i, k in enumerate(names)}
        bad = [k for k in pe["ids"] if k not in index]
        if bad:
            raise InputError(f"prior_eo names image(s) {', '.join(bad[:5])} that are not "
                             f"stations", file=pe["path"], hint="use the ids of the images")
        rows = [index[k] for k in pe["ids"]]
    else:
        if len(pe["position"]) != n:
            raise InputError(f"prior_eo has {len(pe['position'])} rows for {n} images (no id "
                             f"column: the rows are the images in order)", file=pe["path"],
                             hint="add an id column to the format")
        rows = list(range(n))
    pos[rows], ang[rows], std[rows] = pe["position"], pe["angles"], pe["std"]
    return pos, ang, std


def _station_tables(s, state, names):
    """Approximate values and sigmas (0: fixed, NaN: free) of the stations."""
    pos, ang, std = _prior_rows(s, names)
    if not state.eo_loaded:
        pos[:], ang[:] = np.nan, np.nan
    rot = state.eo_free[:, 3:]
    partial = np.flatnonzero(rot.any(1) & ~rot.all(1))
    if len(partial):
        raise InputError(f"the script fixes only some rotation angles of image "
                         f"{names[int(partial[0])]}; photogram fixes a rotation as a whole",
                         file=s["path"], hint="estimate or fix omega, phi and kappa together")
    sig = np.where(state.eo_free, np.nan, 0.0)
    return pos, ang, sig[:, :3], sig[:, 3:]


def _lens_camera(cam, name: str, source: str, free):
    """The script's camera in the photogram model of its DBAT lens model
    (``<model>`` of the camera file, 3 when absent; docs/camera-models.md
    4.5), and the parameters to free: DBAT's models 1, 2 and -1 have no
    aspect and skew, so ``<all>true</all>`` frees neither (as in DBAT)."""
    from photogram.project.dbat_tables import (DBAT_LENS_MODELS, DBAT_NO_AFFINITY,
                                               dbat_lens_camera)
    lens = 3 if cam.model is None else int(cam.model)
    if lens not in DBAT_LENS_MODELS:
        log.warning("%s: DBAT lens model %d is not known to photogram; read as model 3 "
                    "(brown)", source, lens)
        lens = 3
    camera = dbat_lens_camera(cam, name, source, DBAT_LENS_MODELS[lens])
    if lens in DBAT_NO_AFFINITY:
        free = [p for p in free if p not in ("B1", "B2")]
    return camera, [p for p in free if p in camera.parameters]


def dbat_script_project(path, name: str | None = None):
    """Import a DBAT script as a :class:`~photogram.project.model.Project`
    (tables copied into photogram's CSV tables when written).

    Raises
    ------
    InputError
        Malformed XML, unknown elements, missing files (with the script's
        line), several cameras, and every error of the DBAT table readers
        (file and line).
    """
    from photogram.io.dbat import _slug, read_control_points, read_image_points
    from photogram.io.exchange import build_project
    s = read_dbat_script(path)
    script = s["path"]
    obs_st, obs_pt, obs_xy, obs_sig = [], [], [], []
    seen = set()
    for file, fmt, sxy in s["images"]:
        ip = read_image_points(file, fmt, sxy)
        for k in range(len(ip.image)):
            key = (ip.image[k], ip.point[k])
            if key in seen:
                raise InputError(f"point {ip.point[k]} is measured twice in image "
                                 f"{ip.image[k]}", file=file, line=int(ip.line[k]))
            seen.add(key)
        obs_st += ip.image
        obs_pt += ip.point
        obs_xy.append(ip.xy)
        obs_sig.append(ip.sxy)
    st_names = _stations(s, obs_st)
    state = run_operations(s["root"], ScriptState(s["camera"], len(st_names)), s["where"],
                           prior_std=_prior_rows(s, st_names)[2])
    cam = state.camera
    cname = _slug(cam.name)
    camera, free = _lens_camera(cam, cname, str(s["camera_file"]), state.free)
    for p in free:
        camera.parameters[p].free = True
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
    measured = list(dict.fromkeys(obs_pt))
    ids = list(coords) + [p for p in measured if p not in coords]
    xyz = np.array([coords[p][0] if p in coords else [np.nan] * 3 for p in ids], float)
    sig = np.array([coords[p][1] if p in coords else [np.nan] * 3 for p in ids], float)
    first = s["images"][0]
    sigma_image = first[2] if first[2] is not None else \
        float(np.nanmedian(obs_sig[0])) if np.isfinite(obs_sig[0]).any() else 1.0
    has_control = "control" in kind.values()
    datum = "dependent" if state.dependent else \
        ("control" if fixed else "weighted") if has_control else "free"
    pos, ang, pos_sig, ang_sig = _station_tables(s, state, st_names)
    project = build_project(name or script.stem, {cname: camera}, stations=st_names,
                            station_camera=[cname] * len(st_names), angles=ang, X0=pos,
                            point_ids=ids, kinds=[kind.get(p, "tie") for p in ids],
                            xyz=xyz.reshape(-1, 3), point_sigma=sig.reshape(-1, 3),
                            obs_station=obs_st, obs_point=obs_pt, obs_xy=np.vstack(obs_xy),
                            obs_sigma=np.concatenate(obs_sig), length_unit=s["unit"] if
                            s["unit"] in ("m", "dm", "cm", "mm") else "m",
                            datum=datum, sigma_image=sigma_image)
    project.stations.position_sigma[:] = pos_sig
    project.stations.angle_sigma[:] = ang_sig
    if state.dependent:
        ref, base = state.dependent
        project.adjustment.dependent_station = st_names[ref - 1]
        project.adjustment.dependent_coordinate = base
    project.adjustment.max_iterations = 20
    return project
