"""The target-field description: what `photogram measure` looks for.

A small TOML file (example: ``projects/camcal/sheet.toml``)::

    [field]
    name = "PhotoModeler calibration sheet"
    images = "../../../shared/data/dbat/camcal/images"   # folder, relative to this file
    polarity = "dark"          # dark dots on light | bright targets on dark
    channel = "green"          # colour images: green | red | blue | gray
    diameter = 0.0445          # target diameter (object units), for the eccentricity
    min_diameter = 6           # px, smallest target image (major axis)
    max_diameter = 90          # px, largest
    min_contrast = 20          # grey levels above the local background
    sigma_floor = 0.02         # px, added in quadrature to each centre sigma

    [codes]
    kind = "ring"              # ring-coded marks (photogram.measure.codes)
    radii = [2.9, 3.3, 3.7]    # ring sample radii, in dot radii

    [[codes.target]]
    id = "1001"
    bits = "11111000"          # inked sectors, clockwise in the image
    xyz = [0.0, 1.0, 0.0]      # approximate object coordinates

    [grid]                     # the uncoded layout: a regular grid in the plane Z = 0
    cols = 10
    rows = 10
    spacing = 0.142857142857   # object units
    origin = [-0.142857142857, -0.142857142857]   # (X, Y) of column 0, row 0
    id = "D{row}{col}"         # Python format of a dot's id; row 0 at the smallest Y

Grid nodes within a quarter spacing of a coded target are the coded
target's own dot and get no grid id. Every mistake is an
:class:`~photogram.errors.InputError` naming the file, the line (found by
searching for the key) and how to fix it.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.measure.codes import RingCode

__all__ = ["TargetField", "read_field", "CHANNELS"]

CHANNELS = ("green", "red", "blue", "gray")
_FIELD_KEYS = {"name", "images", "polarity", "channel", "diameter", "min_diameter",
               "max_diameter", "min_contrast", "sigma_floor", "shape"}


@dataclass
class TargetField:
    """A parsed target-field description (module doc)."""

    path: Path
    name: str = "field"
    images: Path | None = None
    polarity: str = "dark"
    channel: str = "green"
    diameter: float = 0.0
    shape: str = "circle"       # circle (flat targets) | ball (spheres)
    min_diameter: float = 5.0
    max_diameter: float = 80.0
    min_contrast: float = 20.0
    sigma_floor: float = 0.02
    codes: list[RingCode] = field(default_factory=list)
    code_xyz: dict[str, np.ndarray] = field(default_factory=dict)
    code_radii: tuple = (2.9, 3.3, 3.7)
    grid_ids: list[str] = field(default_factory=list)
    grid_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    spacing: float = 0.0
    aruco_dictionary: str | None = None
    aruco_sigma: float = 0.05
    markers: dict[int, str] = field(default_factory=dict)        # marker id -> point id
    marker_xyz: dict[str, np.ndarray] = field(default_factory=dict)
    target_ids: list[str] = field(default_factory=list)          # 3D field: uncoded targets
    target_xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    target_normal: np.ndarray | None = None     # (m, 3) unit normals, or None (unknown)

    @property
    def spatial(self) -> bool:
        """A 3D field (numbered by DLT from the codes) rather than a plane: a
        table of targets, or no grid and six or more codes not in one plane
        (then the uncoded targets are matched across views,
        :mod:`photogram.measure.epipolar`)."""
        if self.target_ids:
            return True
        if self.grid_ids:
            return False
        _, xyz = self.coded3()
        if len(xyz) < 6:
            return False
        sv = np.linalg.svd(xyz - xyz.mean(axis=0), compute_uv=False)
        return bool(sv[2] > 1e-3 * sv[0])

    def coded3(self) -> tuple[list[str], np.ndarray]:
        """Ids and (X, Y, Z) of the coded targets: ring codes, then ArUco markers."""
        ids = [c.id for c in self.codes] + list(self.markers.values())
        xyz = [self.code_xyz[c.id] for c in self.codes] + \
            [self.marker_xyz[p] for p in self.markers.values()]
        return ids, np.array(xyz, float).reshape(-1, 3)

    def coded(self) -> tuple[list[str], np.ndarray]:
        """Ids and (X, Y) of the coded targets: ring codes, then ArUco markers."""
        ids = [c.id for c in self.codes] + list(self.markers.values())
        xyz = [self.code_xyz[c.id] for c in self.codes] + \
            [self.marker_xyz[p] for p in self.markers.values()]
        return ids, np.array([v[:2] for v in xyz], float).reshape(-1, 2)

    def layout(self, markers: bool = True) -> tuple[list[str], np.ndarray]:
        """Ids and (X, Y) of every target of the plane: ring codes, ArUco
        markers (unless ``markers=False``), then the grid."""
        ids = [c.id for c in self.codes] + (list(self.markers.values()) if markers else [])
        xyz = [self.code_xyz[c.id] for c in self.codes] + \
            ([self.marker_xyz[p] for p in self.markers.values()] if markers else [])
        xy = np.vstack([np.array([v[:2] for v in xyz], float).reshape(-1, 2), self.grid_xy])
        return ids + list(self.grid_ids), xy


def _is_xyz(v) -> bool:
    return (isinstance(v, list) and len(v) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
                    for x in v))


def _line(text: str, key: str) -> int | None:
    for i, raw in enumerate(text.splitlines(), 1):
        if raw.strip().startswith(key):
            return i
    return None


def read_field(path) -> TargetField:
    """Read and validate a target-field description (module doc).

    Raises
    ------
    InputError
        Unreadable file, TOML syntax, unknown keys, values out of range,
        duplicate ids, a code without bits or coordinates.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"cannot read the target-field description: {exc.strerror}",
                         file=path, hint="give the path of the field's .toml file") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"TOML syntax error: {exc}", file=path,
                         hint="see docs/measure.md for an example") from None

    def err(what, key, hint):
        return InputError(what, file=path, line=_line(text, key), hint=hint)

    try:
        return _read(path, doc, err)
    except (TypeError, ValueError, AttributeError, KeyError, IndexError) as exc:
        raise InputError(f"malformed value in the target-field description ({exc})", file=path,
                         hint="compare with projects/camcal/sheet.toml and docs/measure.md") \
            from None


def _read(path: Path, doc: dict, err) -> TargetField:

    unknown = set(doc) - {"field", "codes", "grid", "aruco", "targets"}
    if unknown:
        k = sorted(unknown)[0]
        raise err(f"unknown section [{k}]", f"[{k}",
                  "allowed: [field], [codes], [aruco], [grid], [targets]")
    f = doc.get("field", {})
    for sec in ("field", "codes", "grid", "aruco", "targets"):
        if sec in doc and not isinstance(doc[sec], dict):
            raise err(f"{sec} must be a section [{sec}]", sec, "see docs/measure.md")
    bad = set(f) - _FIELD_KEYS
    if bad:
        k = sorted(bad)[0]
        raise err(f"unknown key {k!r} in [field]", k, f"allowed: {', '.join(sorted(_FIELD_KEYS))}")
    out = TargetField(path=path, name=str(f.get("name", path.stem)))
    if "images" in f:
        if not isinstance(f["images"], str) or not f["images"]:
            raise err(f"images = {f['images']!r}", "images", 'a folder, e.g. images = "images"')
        out.images = (path.parent / f["images"])
    out.polarity = str(f.get("polarity", "dark"))
    if out.polarity not in ("dark", "bright"):
        raise err(f"polarity {out.polarity!r}", "polarity", "dark or bright")
    out.shape = str(f.get("shape", "circle"))
    if out.shape not in ("circle", "ball"):
        raise err(f"shape {out.shape!r}", "shape", "circle (flat targets) or ball (spheres)")
    out.channel = str(f.get("channel", "green"))
    if out.channel not in CHANNELS:
        raise err(f"channel {out.channel!r}", "channel", f"one of {', '.join(CHANNELS)}")
    for key in ("diameter", "min_diameter", "max_diameter", "min_contrast", "sigma_floor"):
        if key in f:
            v = f[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) \
                    or v < 0 or (v == 0 and key in ("min_diameter", "max_diameter")):
                raise err(f"{key} = {v!r} is not a positive number", key, "give a number > 0")
            setattr(out, key, float(v))
    if out.min_diameter >= out.max_diameter:
        raise err("min_diameter must be smaller than max_diameter", "min_diameter",
                  "target image diameters in pixels")
    codes = doc.get("codes", {})
    if codes:
        if codes.get("kind", "ring") != "ring":
            raise err(f"codes kind {codes.get('kind')!r}", "kind", "only ring codes so far")
        if "radii" in codes:
            radii = codes["radii"]
            if not isinstance(radii, list) or not radii or not all(
                    isinstance(r, (int, float)) and not isinstance(r, bool) and 1 < r < 20
                    for r in radii):
                raise err(f"radii = {radii!r}", "radii",
                          "a list of ring radii in dot radii, e.g. [2.9, 3.3, 3.7]")
            out.code_radii = tuple(float(r) for r in radii)
        seen = set()
        targets = codes.get("target", [])
        if not isinstance(targets, list) or not all(isinstance(c, dict) for c in targets):
            raise err("[[codes.target]] must be tables", "[[codes.target]",
                      "one [[codes.target]] block per code")
        for i, c in enumerate(targets):
            cid = str(c.get("id", ""))
            bits = str(c.get("bits", ""))
            if not cid or cid in seen:
                raise err(f"code target {i + 1}: missing or duplicate id {cid!r}", "id",
                          "every code needs its own id")
            seen.add(cid)
            if len(bits) < 2 or set(bits) - {"0", "1"} or "1" not in bits or "0" not in bits:
                raise err(f"code {cid}: bits {bits!r} must be a string of 0 and 1 with both",
                          "bits", 'e.g. bits = "11001100"')
            xyz = c.get("xyz")
            if not _is_xyz(xyz):
                raise err(f"code {cid}: xyz must be [X, Y, Z]", "xyz",
                          "approximate object coordinates of the code")
            out.codes.append(RingCode(cid, bits))
            out.code_xyz[cid] = np.array(xyz, float)
    _read_aruco(doc.get("aruco"), out, err)
    g = doc.get("grid")
    if g:
        try:
            cols, rows = int(g["cols"]), int(g["rows"])
            spacing = float(g["spacing"])
            origin = np.array(g.get("origin", [0.0, 0.0]), float)
        except (KeyError, TypeError, ValueError) as exc:
            raise err(f"[grid] needs cols, rows, spacing (and origin): {exc}", "[grid",
                      "e.g. cols = 10, rows = 10, spacing = 0.1") from None
        if cols < 1 or rows < 1 or cols * rows > 100000 or not 0 < spacing < np.inf \
                or origin.shape != (2,) or not np.isfinite(origin).all():
            raise err("[grid]: cols, rows >= 1, spacing > 0, origin = [X, Y]", "[grid",
                      "see docs/measure.md")
        fmt = str(g.get("id", "D{row}{col}"))
        r, c = np.mgrid[0:rows, 0:cols]
        xy = origin + spacing * np.column_stack([c.ravel(), r.ravel()])
        code_xy = np.array([v[:2] for v in list(out.code_xyz.values())
                            + list(out.marker_xyz.values())]).reshape(-1, 2)
        keep = np.ones(len(xy), bool)
        if len(code_xy):
            d = np.linalg.norm(xy[:, None] - code_xy[None], axis=2).min(axis=1)
            keep = d > 0.25 * spacing
        try:
            ids = [fmt.format(row=int(rr), col=int(cc)) for rr, cc in zip(r.ravel(), c.ravel())]
        except (KeyError, IndexError, ValueError) as exc:
            raise err(f"[grid] id format {fmt!r}: {exc}", "id", 'e.g. id = "D{row}{col}"') \
                from None
        ids = [i for i, k in zip(ids, keep) if k]
        if len(set(ids)) != len(ids) or set(ids) & (set(out.code_xyz) | set(out.marker_xyz)):
            raise err(f"[grid] id format {fmt!r} gives duplicate ids", "id",
                      'include row and column, e.g. "D{row:02d}{col:02d}"')
        out.grid_ids = ids
        out.grid_xy = xy[keep]
        out.spacing = spacing
    if "targets" in doc:
        if g:
            raise err("[grid] and [targets] together", "[targets",
                      "a plane's grid or a 3D field's table of targets, not both")
        _read_targets(doc["targets"], out, err)
    if out.shape == "ball" and not out.target_ids:
        raise err("shape = \"ball\" needs a 3D field's table of targets", "shape",
                  "give [targets] file = ... (balls are corrected from each image's DLT)")
    if not out.codes and not out.markers:
        raise err("the field has no coded targets", "[codes",
                  "numbering needs coded targets ([[codes.target]] or [[aruco.marker]])")
    return out


def _read_targets(t, out: TargetField, err) -> None:
    """[targets] file = "points.csv": the uncoded targets of a 3D field
    (columns id, X, Y, Z, optionally their normals nX, nY, nZ; others, e.g. a
    project's kind or sigmas, ignored; rows without coordinates skipped);
    ``normal = [..]`` gives one normal for all."""
    import csv
    bad = set(t) - {"file", "normal"}
    if bad or "file" not in t:
        raise err("[targets] takes the keys file and normal", "[targets",
                  'e.g. file = "points.csv" with columns id, X, Y, Z')
    normal = t.get("normal")
    if normal is not None:
        if not _is_xyz(normal) or not np.linalg.norm(normal) > 0:
            raise err(f"normal = {normal!r}", "normal",
                      "the targets' common normal, e.g. normal = [0, 0, 1]")
    path = out.path.parent / str(t["file"])
    try:
        lines = [ln for ln in path.read_text(encoding="utf-8-sig").splitlines()
                 if ln.strip() and not ln.lstrip().startswith("#")]
    except OSError as exc:
        raise InputError(f"cannot read the targets table: {exc.strerror}", file=path,
                         hint="[targets] file is relative to the field description") from None
    rows = list(csv.reader(lines))
    head = [h.strip() for h in rows[0]] if rows else []
    if not {"id", "X", "Y", "Z"} <= set(head):
        raise InputError(f"the targets table needs columns id, X, Y, Z (has {head})",
                         file=path, line=1, hint="a header line id,X,Y,Z")
    k = [head.index(c) for c in ("id", "X", "Y", "Z")]
    kn = [head.index(c) for c in ("nX", "nY", "nZ")] if {"nX", "nY", "nZ"} <= set(head) else []
    ids, xyz, normals = [], [], []
    known = set(out.code_xyz) | set(out.marker_xyz)
    for n, r in enumerate(rows[1:], 2):
        cells = [r[i].strip() if i < len(r) else "" for i in k]
        if not all(cells[1:]):
            continue
        try:
            v = [float(c) for c in cells[1:]]
        except ValueError:
            raise InputError(f"coordinates of {cells[0]} are not numbers", file=path, line=n,
                             hint="X, Y, Z as numbers") from None
        if cells[0] in known or cells[0] in ids:
            continue                          # a coded target's own row, or a duplicate
        if kn:
            try:
                nv = np.array([float(r[i]) for i in kn])
            except (ValueError, IndexError):
                raise InputError(f"normal of {cells[0]} is not three numbers", file=path,
                                 line=n, hint="nX, nY, nZ as numbers") from None
            if not np.linalg.norm(nv) > 0 or not np.isfinite(nv).all():
                raise InputError(f"normal of {cells[0]} is zero", file=path, line=n,
                                 hint="the direction the target faces")
            normals.append(nv / np.linalg.norm(nv))
        ids.append(cells[0])
        xyz.append(v)
    if not ids:
        raise InputError("the targets table has no target with coordinates", file=path,
                         hint="rows id,X,Y,Z")
    out.target_ids = ids
    out.target_xyz = np.array(xyz, float)
    if kn:
        out.target_normal = np.array(normals)
    elif normal is not None:
        n = np.array(normal, float) / np.linalg.norm(normal)
        out.target_normal = np.tile(n, (len(ids), 1))


def _read_aruco(a, out: TargetField, err) -> None:
    """The [aruco] section (photogram.measure.aruco)."""
    if not a:
        return
    import cv2
    bad = set(a) - {"dictionary", "sigma", "marker"}
    if bad:
        k = sorted(bad)[0]
        raise err(f"unknown key {k!r} in [aruco]", k, "allowed: dictionary, sigma, marker")
    name = str(a.get("dictionary", "DICT_4X4_50"))
    if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise err(f"unknown ArUco dictionary {name!r}", "dictionary",
                  "e.g. DICT_4X4_50, DICT_5X5_100, DICT_6X6_250, DICT_APRILTAG_36h11")
    out.aruco_dictionary = name
    sigma = a.get("sigma", 0.05)
    if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not sigma > 0:
        raise err(f"[aruco] sigma = {sigma!r}", "sigma", "a positive number of pixels")
    out.aruco_sigma = float(sigma)
    for m in a.get("marker", []):
        mid = m.get("id")
        if isinstance(mid, bool) or not isinstance(mid, int) or mid < 0 or mid in out.markers:
            raise err(f"[[aruco.marker]] id {mid!r}: a new integer >= 0", "id",
                      "the marker's id in its dictionary")
        point = str(m.get("point", f"M{mid}"))
        xyz = m.get("xyz")
        if not _is_xyz(xyz):
            raise err(f"marker {mid}: xyz must be [X, Y, Z]", "xyz",
                      "object coordinates of the marker's centre")
        if point in out.code_xyz or point in out.marker_xyz:
            raise err(f"marker {mid}: point id {point!r} is used twice", "point",
                      "give every marker its own point id")
        out.markers[mid] = point
        out.marker_xyz[point] = np.array(xyz, float)
