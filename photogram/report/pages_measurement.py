"""The measurement: a calibrate/orient project whose image points were
written by `photogram measure`.

Applies when the project file named in summary.json can be read and its
``[observations] points`` table lies in a folder whose summary.json says
``"command": "measure"`` (the measurement's own output folder, e.g.
projects/lab/results-measure/). Shows the measurement's counts per image
(targets accepted, numbered, codes, blobs rejected by reason) next to what
the adjustment made of them (observations used, rejected by data snooping,
RMS residual against the measured sigma), and per target (images measured,
used). The measurement's own report.pdf (in its folder) has the drawings.
"""

from __future__ import annotations

from collections import Counter

import json
from pathlib import Path

import numpy as np

from photogram.report.numbers import num
from photogram.report.registry import section

__all__ = ["measurement_of"]

_REJECTIONS = ("size", "border", "shape", "roundness", "edge", "fit", "contrast", "marker")


def measurement_of(data) -> dict | None:
    """The measurement behind the project's image points, or None:
    ``{"folder", "table", "summary", "observations": {(station, point): sigma}}``."""
    if "measurement" in data.extra:
        return data.extra["measurement"]
    out = None
    project = data.project
    table = getattr(project, "sources", {}).get("image_points") if project is not None else None
    if table is not None:
        path = Path(table).parent / "summary.json"
        try:
            summary = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            summary = None
        if isinstance(summary, dict) and summary.get("command") == "measure" \
                and isinstance(summary.get("per_image"), dict):
            out = {"folder": Path(table).parent, "table": Path(table), "summary": summary,
                   "observations": _sigmas(project)}
    data.extra["measurement"] = out
    return out


def _sigmas(project) -> dict:
    ip = project.image_points
    names, ids = project.stations.names, project.points.ids
    sigma = getattr(ip, "sigma", None)
    if sigma is None:
        sigma = np.full(len(ip.station), np.nan)
    return {(names[s], ids[p]): float(v) for s, p, v in zip(ip.station, ip.point, sigma)}


def _relative(path: Path, start: Path) -> str:
    """``path`` relative to the results folder (the report does not depend
    on where the projects are)."""
    import os
    try:
        return Path(os.path.relpath(Path(path).resolve(), Path(start).resolve())).as_posix()
    except ValueError:                      # another drive
        return Path(path).name


def _int(v) -> int:
    try:
        return int(v)
    except (TypeError, ValueError):
        return 0


@section("measurement", "Measurement (photogram measure)", 35,
         applies=lambda d: measurement_of(d) is not None, native=True)
def build(doc, data):
    m = measurement_of(data)
    s = m["summary"]
    unit = data.image_unit
    doc.start_section("Measurement (photogram measure)", intro=(
        "The image points of this adjustment were measured automatically by photogram "
        "measure. Per image: the targets it accepted, numbered (given a point id) and "
        "decoded (codes), and the blobs it rejected with the reason (size, border: touches "
        "the image border, shape, roundness, edge, fit: ellipse residual, contrast, marker: "
        "a dot on an ArUco marker's cells); then what the adjustment made of them: the "
        "observations used, those rejected by data snooping, and the RMS residual against "
        "the median measured sigma (the residual RMS should be about sigma0 times the "
        "sigma). A target seen in few images is weakly determined. The drawings of every "
        "image are in the measurement's own report.pdf."))
    r = data.residuals
    res = r.with_column("station", r["station"].astype(str)).with_column(
        "point", r["point"].astype(str))
    obs = m["observations"]
    adj_keys = set(zip(res["station"], res["point"]))
    same = adj_keys == set(obs)
    doc.pairs([
        ("target field", f"{s.get('name', '')} ({s.get('field', '')})"),
        ("measurement", _relative(m["folder"], data.folder)),
        ("images", str(_int(s.get("images")))),
        ("observations measured", str(_int(s.get("observations")))),
        ("targets measured", str(len(s.get("per_target") or {}))),
        ("in the adjustment", f"{int(res['used'].sum())} used, {int((~res['used']).sum())} "
                              f"rejected (data snooping)"),
        ("consistency", "the adjustment's observations are the measured table" if same else
         "the measured table differs from the adjustment's observations (measured again "
         "after the adjustment?)"),
    ])
    keys = ("accepted", "numbered", "codes", "unnumbered", "code_rejected")
    header = ["image", "accepted", "numbered", "codes", "unnumb.", "ring rej.",
              "blobs rej.", "used", "rejected", f"RMS v [{unit}]", f"med. sigma [{unit}]"]
    rows = []
    for name, c in sorted(s["per_image"].items()):
        c = c if isinstance(c, dict) else {}
        g = res.take(res["station"] == name)
        used = g.take(g["used"])
        v = used.numbers(["vx", "vy"])
        rms = float(np.sqrt(np.mean(np.sum(v ** 2, axis=1)) / 2)) if len(v) else float("nan")
        sig = [obs[k] for k in obs if k[0] == name and np.isfinite(obs[k])]
        rows.append([name] + [str(_int(c.get(k))) for k in keys]
                    + [str(sum(_int(c.get(k)) for k in _REJECTIONS)), str(len(used)),
                       str(len(g) - len(used)), num(rms, 3),
                       num(float(np.median(sig)), 3) if sig else "-"])
    doc.table(header, rows, title="Per image", size=7.5, note=(
        "RMS v: root mean square residual per coordinate of the used observations; med. "
        "sigma: median sigma the measurement gave them."))
    reasons = {k: sum(_int((c or {}).get(k)) for c in s["per_image"].values())
               for k in _REJECTIONS}
    doc.pairs([(k, str(v)) for k, v in reasons.items()], title="Blobs rejected, by reason")
    per_target = s.get("per_target") or {}
    used_per = Counter(res["point"][res["used"]].tolist())
    rejected_per = Counter(res["point"][~res["used"]].tolist())
    rows = [[pid, str(_int(n)), str(int(used_per.get(pid, 0))), str(int(rejected_per.get(pid, 0)))]
            for pid, n in sorted(per_target.items(), key=lambda kv: (_int(kv[1]), kv[0]))]
    half = (len(rows) + 1) // 2
    pairs = [a + ([""] + b if b else []) for a, b in
             zip(rows[:half], rows[half:] + [[]] * (2 * half - len(rows)))]
    doc.table(["target", "images", "used", "rejected"] + ["", "target", "images", "used",
                                                          "rejected"],
              [p + [""] * (9 - len(p)) for p in pairs], align="lrrrllrrr", size=7.5,
              title="Per target (fewest images first)")
    problems = s.get("problems") or []
    doc.subheading("Problems reported by the measurement")
    doc.bullets([str(p) for p in problems[:20]], size=8)
