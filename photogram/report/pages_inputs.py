"""One page of the fixed inputs of a command that estimates none of them
(the intersect step: cameras from a calibration, stations from an
orientation). Their full pages (sigmas, correlations, distortion maps) are
in the reports of the commands that estimated them; repeating them here
would show the same numbers again without sigmas (see
:data:`photogram.report.registry.INPUT_ONLY`)."""

from __future__ import annotations

from collections import Counter

from pathlib import Path

import numpy as np

from photogram.errors import PhotogramError
from photogram.report.numbers import num
from photogram.report.pages_cameras import camera_source, distortion_field
from photogram.report.registry import INPUT_ONLY, section

#: principal distance and principal point (brown, aicon, DBAT: c x0 y0; opencv: fx cx cy)
_HEAD = (("c", "fx"), ("x0", "cx"), ("y0", "cy"))


def _applies(data) -> bool:
    return data.command in INPUT_ONLY and bool(data.results.cameras)


def _largest_distortion(data, name, cam) -> str:
    fmt = data.image_format(name)
    if fmt is None:
        return "-"
    try:
        field = distortion_field(cam, fmt)
    except PhotogramError:
        return "-"
    if field is None:
        return "-"
    mag = float(np.hypot(field[2], field[3]).max())
    return "none" if not mag > 1e-9 * float(np.hypot(*fmt)) else num(mag, 3)


def _short(path) -> str:
    return Path(str(path)).as_posix() if path else "-"


def _camera_rows(data):
    rows = []
    for name, cam in sorted(data.results.cameras.items()):
        par = cam.parameters
        head = [next((num(par[k].value, 6) for k in keys if k in par), "-") for keys in _HEAD]
        rows.append([name, cam.model, *head, _largest_distortion(data, name, cam),
                     _short(camera_source(data, name, cam))])
    return rows


def _station_rows(data):
    st = data.stations
    n_obs = {}
    if data.has_residuals:
        r = data.residuals
        n_obs = Counter(r["station"][r["used"]].astype(str).tolist())
    return [[name, str(st["camera"][i])]
            + [num(st[c][i], 7) for c in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
            + [str(n_obs.get(name, 0))] for i, name in enumerate(st.ids)]


def _intro(data) -> str:
    sources = sorted({_short(camera_source(data, n, c))
                      for n, c in data.results.cameras.items()} - {"-"})
    cov = data.summary.get("orientation_covariance") or []
    text = ("This command estimates neither the cameras nor the stations: it holds them fixed "
            "as they are listed here, once. Their sigmas, correlations and distortion maps "
            "are in the reports of the commands that estimated them"
            + (f" (cameras from {', '.join(sources)})" if sources else "") + ".")
    if cov:
        text += (" The covariance of this orientation (" + ", ".join(_short(c) for c in cov)
                 + ") is propagated into the points and the stick model.")
    else:
        text += " No orientation covariance was propagated: the sigmas are from image noise only."
    return text


@section("inputs", "Input orientation (fixed)", 20, applies=_applies, native=True)
def build(doc, data):
    iu, lu, au = data.image_unit, data.length_unit, data.angle_unit
    doc.start_section("Input orientation (fixed)", intro=_intro(data))
    doc.table(["camera", "model", f"c [{iu}]", f"x0 [{iu}]", f"y0 [{iu}]",
               f"max. distortion [{iu}]", "from"], _camera_rows(data), align="llrrrrl",
              title="Cameras (interior orientation)", size=7.5)
    if len(data.stations):
        doc.table(["station", "camera", f"X0 [{lu}]", f"Y0 [{lu}]", f"Z0 [{lu}]",
                   f"omega [{au}]", f"phi [{au}]", f"kappa [{au}]", "points"],
                  _station_rows(data), align="llrrrrrrr", size=7.5,
                  title="Stations (exterior orientation, "
                        f"{data.info.get('rotation_direction', 'world_to_camera')})")
