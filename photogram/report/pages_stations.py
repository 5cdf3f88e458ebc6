"""Exterior orientation of every station with its a-posteriori sigmas."""

from __future__ import annotations

from photogram.report.numbers import pair
from photogram.report.registry import section

_INTRO = ("Exterior orientation: projection centre X0 Y0 Z0 and rotation omega phi kappa "
          "of every image (station), each with its a-posteriori standard deviation. "
          "'points' is the number of image points used in the adjustment.")


def _sigma(st, name, column):
    col = "est_s" + column
    return st.loc[name, col] if col in st.columns else None


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
        n_obs = r[r["used"]].groupby("station").size().to_dict()
    pos, rot = [], []
    for name in st.index:
        row = [name, str(st.loc[name, "camera"])]
        for c in ("X0", "Y0", "Z0"):
            row += pair(st.loc[name, c], _sigma(st, name, c))
        pos.append(row + [str(n_obs.get(name, "-"))])
        row = [name]
        for c in ("omega", "phi", "kappa"):
            row += pair(st.loc[name, c], _sigma(st, name, c))
        rot.append(row)
    doc.table(["station", "camera", f"X0 [{lu}]", "sigma", f"Y0 [{lu}]", "sigma",
               f"Z0 [{lu}]", "sigma", "points"], pos, align="llrrrrrrr",
              title="Projection centres")
    doc.table(["station", f"omega [{au}]", "sigma", f"phi [{au}]", "sigma",
               f"kappa [{au}]", "sigma"], rot, title="Rotations (omega-phi-kappa, "
              f"{data.info.get('rotation_direction', 'world_to_camera')})")
