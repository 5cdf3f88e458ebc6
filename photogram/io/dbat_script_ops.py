"""The ``<operations>`` of a DBAT XML script and its ``<prior_eo>`` table,
as :mod:`photogram.io.dbat_script` takes them over (DBAT's
``code/script/parseops.m``, ``parsesetinitialvalues.m``,
``parsesetbundleest.m``, ``parsesetdatum.m``, ``parseprioreo.m`` and
``loadeotable.m``; docs/project-files.md, "Mapping a DBAT script to a
.prj").

DBAT runs the operations in order on one state; so does :func:`run_operations`
on a small :class:`ScriptState`: the interior values (``set_initial_values
<io>``), whether the prior exterior orientation is the start
(``<eo>loaded``), which interior and exterior parameters are estimated
(``set_bundle_estimate_params``) and the datum (``set_datum``). DBAT's
numerical operations (``spatial_resection``, ``forward_intersection``,
``bundle_adjustment``, ``check_ray_count``) are photogram's approximation
chain and adjustment: they are accepted and not repeated here.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError

__all__ = ["ScriptState", "run_operations", "read_prior_eo", "TEXT_OPERATIONS"]

#: operations without structure (DBAT's parseops)
TEXT_OPERATIONS = ("check_ray_count", "spatial_resection", "forward_intersection",
                   "bundle_adjustment")
STRUCTURED_OPERATIONS = ("set_initial_values", "set_bundle_estimate_params", "set_datum")

_IO_KEYS = {"cc": ("c",), "pp": ("x0", "y0"), "px": ("x0",), "py": ("y0",),
            "aspect": ("B1",), "skew": ("B2",),
            "K": ("K1", "K2", "K3"), "K1": ("K1",), "K2": ("K2",), "K3": ("K3",),
            "P": ("P1", "P2"), "P1": ("P1",), "P2": ("P2",)}
_EO_KEYS = {"all": range(6), "pos": range(3), "angles": range(3, 6), "x": (0,), "y": (1,),
            "z": (2,)}
_EO_FORMAT = ("id", "ignored", "label", "x", "y", "z", "sx", "sy", "sz", "sxy", "sxyz",
              "omega", "phi", "kappa", "so", "sp", "sk", "sang")
_ANGLE_UNITS = {"radian": 1.0, "degrees": math.pi / 180.0, "gon": math.pi / 200.0}


@dataclass
class ScriptState:
    """What the operations set (DBAT's ``s.IO.val``, ``s.bundle.est`` ...)."""

    camera: object                      # DbatCamera (camera units)
    n_stations: int
    free: set = field(default_factory=set)            # brown parameter names
    eo_free: np.ndarray = None          # (n, 6) bool: X0 Y0 Z0 omega phi kappa
    eo_loaded: bool = False             # <set_initial_values><eo>loaded
    dependent: tuple | None = None      # (ref_cam, ref_base) of <set_datum>
    notes: list = field(default_factory=list)

    def __post_init__(self):
        if self.eo_free is None:
            self.eo_free = np.ones((self.n_stations, 6), dtype=bool)


class _Where:
    """Error positions inside the script (element -> line)."""

    def __init__(self, script: Path, lines: dict):
        self.script, self.lines = script, lines

    def error(self, el, what: str, hint: str | None = None) -> InputError:
        return InputError(what, file=self.script, line=self.lines.get(el), hint=hint)

    def check(self, el, allowed, where: str):
        """Refuse a child element DBAT does not know (DBAT's checkxmlfields)."""
        for child in el:
            if child.tag not in allowed and child.tag != "c":
                raise self.error(child, f"unknown element <{child.tag}> in <{where}>",
                                 hint=f"DBAT knows {', '.join(allowed)} there (and <c> "
                                      f"comments)")


def _text(el) -> str:
    return (el.text or "").strip()


def _values(where: _Where, el, what: str) -> list[float]:
    try:
        out = [float(v) for v in _text(el).split(",") if v.strip()]
    except ValueError:
        out = []
    if not out or not all(math.isfinite(v) for v in out):
        raise where.error(el, f"<{what}> must be 'default', 'loaded' or numbers, not "
                              f"{_text(el)!r}")
    return out


# --------------------------------------------------------------------------
# set_initial_values


def _initial_io(where: _Where, el, state: ScriptState):
    """``<io>``: 'loaded' keeps the camera's values, 'default' sets cc to
    the focal length, pp to the sensor centre and aspect, skew, K, P to
    their null values (DBAT's parsesetinitialiovalues)."""
    cam = state.camera
    fields = [("all", el)] if len(el) == 0 else [(c.tag, c) for c in el if c.tag != "c"]
    where.check(el, ("all", "cc", "pp", "K", "P", "aspect", "skew"), "set_initial_values/io")
    centre = (cam.sensor[0] / 2.0, cam.sensor[1] / 2.0)
    for tag, sub in fields:
        word = _text(sub)
        if word == "loaded":
            continue
        if tag == "all":
            if word != "default":
                raise where.error(sub, f"<{tag}> must be 'default' or 'loaded', not {word!r}")
            cam = dataclasses.replace(cam, cc=cam.focal, pp=centre, K=(0.0,) * len(cam.K),
                                      P=(0.0,) * len(cam.P))
            state.notes.append("aspect and skew start at their defaults")
        elif tag == "cc":
            cc = cam.focal if word in ("focal", "default") else _values(where, sub, "cc")[0]
            cam = dataclasses.replace(cam, cc=cc)
        elif tag == "pp":
            pp = centre if word == "default" else tuple(_values(where, sub, "pp"))
            if len(pp) != 2:
                raise where.error(sub, "<pp> needs two values x,y")
            cam = dataclasses.replace(cam, pp=pp)
        elif tag in ("K", "P"):
            old = getattr(cam, tag)
            new = (0.0,) * len(old) if word == "default" else tuple(_values(where, sub, tag))
            cam = dataclasses.replace(cam, **{tag: new})
        elif word != "default":                   # aspect, skew
            raise where.error(sub, f"<{tag}> {word!r}: photogram takes over 'default' and "
                                   f"'loaded' only for {tag}",
                              hint="start from 'default' (the adjustment estimates it)")
    state.camera = cam


def _initial_values(where: _Where, el, state: ScriptState):
    where.check(el, ("io", "eo", "op"), "set_initial_values")
    for sub in el:
        word = _text(sub) if len(sub) == 0 else _text(sub.find("all")) \
            if sub.find("all") is not None else ""
        if sub.tag == "io":
            _initial_io(where, sub, state)
        elif sub.tag == "eo":
            if word != "loaded":
                raise where.error(sub, f"<eo> must be 'loaded' (or <all>loaded</all>), not "
                                       f"{word!r}")
            state.eo_loaded = True
        elif sub.tag == "op" and word != "loaded":
            raise where.error(sub, f"<op> must be 'loaded' (or <all>loaded</all>), not {word!r}")


# --------------------------------------------------------------------------
# set_bundle_estimate_params


def _flag(where, el, allowed=("true", "false")) -> str:
    word = _text(el)
    if word not in allowed:
        raise where.error(el, f"<{el.tag}> must be {' or '.join(allowed)}, not {word!r}")
    return word


def _estimate_io(where: _Where, el, state: ScriptState):
    nk, np_ = len(state.camera.K) or 3, len(state.camera.P) or 2
    allowed = {"c", "x0", "y0", "B1", "B2"} | {f"K{i}" for i in range(1, min(nk, 3) + 1)} \
        | {f"P{i}" for i in range(1, min(np_, 2) + 1)}
    fields = [("all", el)] if len(el) == 0 else [(c.tag, c) for c in el if c.tag != "c"]
    where.check(el, ("all",) + tuple(_IO_KEYS), "set_bundle_estimate_params/io")
    for tag, sub in fields:
        names = allowed if tag == "all" else set(_IO_KEYS[tag]) & allowed
        if _flag(where, sub) == "true":
            state.free |= names
        else:
            state.free -= names


def _estimate_eo(where: _Where, el, state: ScriptState, prior_std):
    fields = [("all", el)] if len(el) == 0 else [(c.tag, c) for c in el if c.tag != "c"]
    where.check(el, tuple(_EO_KEYS), "set_bundle_estimate_params/eo")
    for tag, sub in fields:
        ix = list(_EO_KEYS[tag])
        word = _flag(where, sub, ("true", "false", "default"))
        if word == "default":             # estimate what the prior does not fix
            std = prior_std if prior_std is not None else \
                np.full((state.n_stations, 6), np.nan)
            state.eo_free[:, ix] = std[:, ix] != 0
        else:
            state.eo_free[:, ix] = word == "true"


def _estimate(where: _Where, el, state: ScriptState, prior_std):
    where.check(el, ("io", "eo", "op"), "set_bundle_estimate_params")
    for sub in el:
        if sub.tag == "io":
            _estimate_io(where, sub, state)
        elif sub.tag == "eo":
            _estimate_eo(where, sub, state, prior_std)
        elif sub.tag == "op":
            word = _text(sub) if len(sub) == 0 else _text(sub.find("all")) \
                if sub.find("all") is not None else ""
            if word != "default":
                raise where.error(sub, f"<op> {word!r}: photogram takes over only 'default' "
                                       f"(tie points and weighted control estimated, fixed "
                                       f"control fixed)",
                                  hint="use <op>default</op>; fix or weight control points "
                                       "in the control table")


# --------------------------------------------------------------------------
# set_datum


def _datum(where: _Where, el, state: ScriptState):
    if _text(el) != "depend":
        raise where.error(el, f"<set_datum> {_text(el)!r}: DBAT knows only 'depend'")
    unknown = sorted(set(el.attrib) - {"ref_cam", "ref_base"})
    if unknown:
        raise where.error(el, f"<set_datum> has unknown attribute(s) {', '.join(unknown)}",
                          hint="DBAT's attributes are ref_cam and ref_base")
    try:
        ref = int(el.get("ref_cam", "1"))
    except ValueError:
        raise where.error(el, f"ref_cam={el.get('ref_cam')!r} is not an image number") \
            from None
    base = el.get("ref_base", "longest")
    if base not in ("longest", "x", "y", "z"):
        raise where.error(el, f"ref_base={base!r}: DBAT knows longest, x, y, z")
    if not 1 <= ref <= state.n_stations:
        raise where.error(el, f"ref_cam={ref} is not an image number (1 to "
                              f"{state.n_stations})")
    state.dependent = (ref, base)
    state.eo_free[:] = True               # DBAT: 'depend' estimates all others


def run_operations(root, state: ScriptState, where: _Where, prior_std=None) -> ScriptState:
    """Apply the script's ``<operations>`` in order (module doc)."""
    ops = root.find("operations")
    if ops is None:
        return state
    where.check(ops, ("operation",), "operations")
    for op in ops.findall("operation"):
        children = [c for c in op if c.tag != "c"]
        if not children:
            if _text(op) not in TEXT_OPERATIONS:
                raise where.error(op, f"unknown operation {_text(op)!r}",
                                  hint="DBAT knows " + ", ".join(TEXT_OPERATIONS
                                                                 + STRUCTURED_OPERATIONS))
            continue
        if len(children) > 1:
            raise where.error(op, "one <operation> holds one operation, found "
                                  + ", ".join(f"<{c.tag}>" for c in children))
        el = children[0]
        if el.tag == "set_initial_values":
            _initial_values(where, el, state)
        elif el.tag == "set_bundle_estimate_params":
            _estimate(where, el, state, prior_std)
        elif el.tag == "set_datum":
            _datum(where, el, state)
        else:
            raise where.error(el, f"unknown operation <{el.tag}>",
                              hint="DBAT knows " + ", ".join(TEXT_OPERATIONS
                                                             + STRUCTURED_OPERATIONS))
    return state


# --------------------------------------------------------------------------
# prior_eo


def read_prior_eo(path: Path, fmt: str, units: str | None, where: _Where, el) -> dict:
    """DBAT's EO table (``loadeotable``): comma-separated, ``#`` comments,
    columns named by ``fmt``. Returns ``ids`` (or None), ``position`` (n,
    3), ``angles`` (n, 3) rad (NaN if absent), ``std`` (n, 6) (position
    sigmas 0 when absent: fixed, as DBAT; angle sigmas NaN when absent)."""
    from photogram.project.dbat_tables import _float, _ident, _rows
    cols = [c.strip() for c in fmt.split(",")]
    bad = [c for c in cols if c not in _EO_FORMAT]
    if bad:
        raise where.error(el, f"prior_eo format has unknown column(s) {', '.join(bad)}",
                          hint="DBAT's columns: " + ", ".join(_EO_FORMAT))
    ids, pos, ang, std = [], [], [], []
    for no, f in _rows(path):
        if len(f) != len(cols):
            raise InputError(f"expected {len(cols)} columns ({fmt}), got {len(f)}", file=path,
                             line=no)
        p, a = [np.nan] * 3, [np.nan] * 3
        s, sa = [0.0] * 3, [np.nan] * 3
        for c, v in zip(cols, f):
            if c == "id":
                ids.append(_ident(v))
            elif c in ("x", "y", "z"):
                p["xyz".index(c)] = _float(v, path, no, c)
            elif c in ("sx", "sy", "sz"):
                s["xyz".index(c[1])] = _float(v, path, no, c)
            elif c in ("sxy", "sxyz"):
                s[:len(c) - 1] = [_float(v, path, no, c)] * (len(c) - 1)
            elif c in ("omega", "phi", "kappa"):
                a[("omega", "phi", "kappa").index(c)] = _float(v, path, no, c)
            elif c in ("so", "sp", "sk"):
                sa["opk".index(c[1])] = _float(v, path, no, c)
            elif c == "sang":
                sa = [_float(v, path, no, c)] * 3
        pos.append(p), ang.append(a), std.append(s + sa)
    ang = np.array(ang, float).reshape(-1, 3)
    std = np.array(std, float).reshape(-1, 6)
    if np.isfinite(ang).any():
        if units not in _ANGLE_UNITS:
            raise where.error(el, "the prior_eo table has angles but no units attribute"
                              if units is None else f"units={units!r}: DBAT knows "
                              + ", ".join(_ANGLE_UNITS),
                              hint='add units="degrees" (or radian, gon) to the <file>')
        ang = ang * _ANGLE_UNITS[units]
        std[:, 3:] = std[:, 3:] * _ANGLE_UNITS[units]
    return {"ids": ids if "id" in cols else None, "position": np.array(pos, float).reshape(-1, 3),
            "angles": ang, "std": std, "path": path}
