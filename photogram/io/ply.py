"""PLY point clouds of object points with their precision (ASCII PLY 1.0).

Each vertex: ``x y z`` (project axes and length unit) and the a-posteriori
standard deviations ``sigma_x sigma_y sigma_z`` as extra properties (``nan``
where not estimated), plus ``kind`` (0 tie, 1 control, 2 check) and, when
every point id is an integer, ``id``; other ids are lost (PLY has no text
properties) and listed in the header comments instead. Floats are written
with ``repr``, so the numbers read back exactly. Points without coordinates
are left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


__all__ = ["format_ply", "write_ply", "read_ply"]

KIND_CODES = {"tie": 0, "control": 1, "check": 2}


def _integer_ids(ids) -> bool:
    try:
        return all(str(int(i)) == str(i) and abs(int(i)) < 2 ** 31 for i in ids)
    except ValueError:
        return False


def format_ply(ids, xyz, sigma, kinds=None, *, unit: str = "m", comment: str = "") -> str:
    """The text of an ASCII PLY file (see the module doc)."""
    ids = [str(i) for i in ids]
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    sigma = np.full_like(xyz, np.nan) if sigma is None else np.asarray(sigma, float)
    kinds = ["tie"] * len(ids) if kinds is None else [str(k) for k in kinds]
    keep = np.all(np.isfinite(xyz), axis=1)
    ids = [i for i, k in zip(ids, keep) if k]
    kinds = [c for c, k in zip(kinds, keep) if k]
    xyz, sigma = xyz[keep], sigma[keep]
    with_id = _integer_ids(ids)
    head = ["ply", "format ascii 1.0", "comment written by photogram",
            f"comment length unit: {unit}; sigma_*: a-posteriori standard deviations "
            f"(nan: not estimated); kind: 0 tie, 1 control, 2 check"]
    head += [f"comment {c}" for c in comment.splitlines() if c.strip()]
    if not with_id:
        head += [f"comment point {k} is {i}" for k, i in enumerate(ids)]
    head += [f"element vertex {len(ids)}"]
    head += [f"property double {c}" for c in ("x", "y", "z", "sigma_x", "sigma_y", "sigma_z")]
    head += ["property uchar kind"] + (["property int id"] if with_id else []) + ["end_header"]
    rows = []
    for k in range(len(ids)):
        vals = [repr(float(v)) if np.isfinite(v) else "nan" for v in (*xyz[k], *sigma[k])]
        vals.append(str(KIND_CODES.get(kinds[k], 0)))
        if with_id:
            vals.append(ids[k])
        rows.append(" ".join(vals))
    return "\n".join(head + rows) + "\n"


def write_ply(path, ids, xyz, sigma, kinds=None, *, unit: str = "m", force: bool = False,
              comment: str = "") -> Path:
    from photogram.io.exchange import write_new_text
    return write_new_text(path, format_ply(ids, xyz, sigma, kinds, unit=unit, comment=comment),
                          force)


def read_ply(path) -> dict:
    """An ASCII PLY file's vertices as ``{property: array}`` (any properties)."""
    from photogram.io.exchange import LineText
    text = LineText(path, "PLY file")
    lines = text.lines
    if not lines or lines[0].strip() != "ply":
        raise text.error(1, "not a PLY file (first line is not 'ply')")
    props, count, k = [], None, 1
    while k < len(lines) and lines[k].strip() != "end_header":
        f = lines[k].split()
        if f[:1] == ["format"] and f[1:2] != ["ascii"]:
            raise text.error(k + 1, f"only ASCII PLY is read, not {f[1]}")
        if f[:2] == ["element", "vertex"]:
            count = int(f[2])
        elif f[:1] == ["property"] and count is not None and len(f) == 3:
            props.append(f[2])
        k += 1
    if k >= len(lines) or count is None:
        raise text.error(len(lines), "no end_header or no vertex element",
                         hint="the file is truncated")
    rows = []
    for j in range(count):
        no = k + 2 + j
        if no > len(lines):
            raise text.error(len(lines), f"{count} vertices announced, {j} found",
                             hint="the file is truncated")
        rows.append(text.numbers(no, lines[no - 1].split(), len(props), what="vertex values",
                                 allow_nan=True))
    data = np.array(rows, float).reshape(-1, len(props))
    return {p: data[:, j] for j, p in enumerate(props)}
