"""Exterior orientation of every station with its a-posteriori sigmas."""

from __future__ import annotations

import numpy as np

from photogram.report.numbers import pair
from photogram.report.registry import section

_INTRO = ("Exterior orientation: projection centre X0 Y0 Z0 and rotation omega phi kappa "
          "of every image (station), each with its a-posteriori standard deviation. "
          "'points' is the number of image points used in the adjustment.")


def _sigma(st, i, column):
    col = "est_s" + column
    return st[col][i] if col in st else None


@section("stations", "Stations (exterior orientation)", 30,
         applies=lambda d: len(d.results.stations) > 0, native=True)
def build(doc, data):
    st = data.stations
    lu, au = data.length_unit, data.angle_unit
    fixed = not any(c.startswith("est_s") for c in st.columns)
    doc.start_section("Stations (exterior orientation)", intro=_INTRO + (
        " Here the stations were not estimated: they are the fixed orientation the "
        "command used." if fixed else ""))
    n_obs = {}
    if data.has_residuals:
        r = data.residuals
        code, names = r.groups("station")
        counts = np.bincount(code[r["used"]], minlength=len(names))
        n_obs = {n: int(k) for n, k in zip(names, counts) if k}
    pos, rot = [], []
    for i, name in enumerate(st.ids):
        row = [name, str(st["camera"][i])]
        for c in ("X0", "Y0", "Z0"):
            row += pair(st[c][i], _sigma(st, i, c))
        pos.append(row + [str(n_obs.get(name, "-"))])
        row = [name]
        for c in ("omega", "phi", "kappa"):
            row += pair(st[c][i], _sigma(st, i, c))
        rot.append(row)
    doc.table(["station", "camera", f"X0 [{lu}]", "sigma", f"Y0 [{lu}]", "sigma",
               f"Z0 [{lu}]", "sigma", "points"], pos, align="llrrrrrrr",
              title="Projection centres")
    doc.table(["station", f"omega [{au}]", "sigma", f"phi [{au}]", "sigma",
               f"kappa [{au}]", "sigma"], rot, title="Rotations (omega-phi-kappa, "
              f"{data.info.get('rotation_direction', 'world_to_camera')})")
