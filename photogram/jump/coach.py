"""Units a coach reads, and the height above a landing-slope profile.

``[report] units = "coach"`` (or ``--units coach`` on intersect and report)
shows the stick model in degrees, metres and km/h: the report's tables and
figures, ``stick.png``, ``timeseries.png`` and the companion table
``coach.csv`` that intersect writes beside ``exposures.csv`` (which keeps
the project's units, so that every reader of it stays as it was).

A landing-slope profile (``[intersect] landing_profile = "profile.csv"``)
is a CSV with the columns ``distance,height``: the slope's surface along
the jump axis, which is world X (``distance`` = world X, ``height`` =
world Z of the surface, both in the project's length unit, ``distance``
increasing), linear in between. The height of O above it, ``H = O_z -
z(O_x)`` (vertical, NaN outside the profile), goes into exposures.csv as
``H`` and ``sigma_H`` beside ``Z0`` (world Z), propagated like every other
parameter (:class:`photogram.jump.stick.ProfileGround`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.jump import definitions as defs
from photogram.jump.stick import ANGLE_FACTORS, ProfileGround
from photogram.project.model import LENGTH_UNITS, REPORT_UNITS

__all__ = ["COACH", "HEIGHT", "check_units", "unit_of", "to_coach", "coach_table",
           "read_landing_profile", "KMH_PER_MS"]

#: the coach's units of angles, lengths and speeds
COACH = {"angle": "deg", "length": "m", "speed": "km/h"}
#: exposures.csv's column of the height of O above the landing-slope profile
HEIGHT = "H"
#: km/h per m/s
KMH_PER_MS = 3.6
_LENGTHS = ("Z0", HEIGHT, "O_x", "O_y", "O_z")


def check_units(value, source: str = "--units") -> str:
    """``value`` if it is one of :data:`photogram.project.model.REPORT_UNITS`,
    else a one-line :class:`InputError`."""
    if value not in REPORT_UNITS:
        raise InputError(f"{source}: unknown units {value!r}",
                         hint=f"use one of {', '.join(REPORT_UNITS)}")
    return value


def unit_of(name: str, angle_unit: str, length_unit: str, units: str = "project") -> str:
    """Unit of the stick-model column ``name`` (``sigma_`` prefix allowed)."""
    base = name[6:] if name.startswith("sigma_") else name
    coach = units == "coach"
    if base in defs.ANGLE_PARAMETERS:
        return COACH["angle"] if coach else angle_unit
    if base == "v":
        return COACH["speed"] if coach else f"{length_unit}/s"
    if base in _LENGTHS:
        return COACH["length"] if coach else length_unit
    return ""


def to_coach(frame, angle_unit: str, length_unit: str):
    """A copy of an exposures.csv table (project units) in deg, m and km/h;
    column names unchanged."""
    if angle_unit not in ANGLE_FACTORS:
        raise InputError(f"unknown angle unit {angle_unit!r}")
    if length_unit not in LENGTH_UNITS:
        raise InputError(f"unknown length unit {length_unit!r}")
    to_deg = ANGLE_FACTORS["deg"] / ANGLE_FACTORS[angle_unit]
    to_m = LENGTH_UNITS[length_unit]
    out = frame.copy()
    for c in out.columns:
        base = c[6:] if c.startswith("sigma_") else c
        if base in defs.ANGLE_PARAMETERS:
            out[c] = out[c].astype(float) * to_deg
        elif base == "v":
            out[c] = out[c].astype(float) * to_m * KMH_PER_MS
        elif base in _LENGTHS:
            out[c] = out[c].astype(float) * to_m
    return out


def coach_table(frame, angle_unit: str, length_unit: str):
    """coach.csv: exposure, time and every parameter with its sigma in deg,
    m and km/h; the unit is part of each column name (``alpha_deg``,
    ``Z0_m``, ``H_m``, ``v_kmh``, ...)."""
    c = to_coach(frame, angle_unit, length_unit)
    suffix = {"deg": "deg", "m": "m", "km/h": "kmh"}
    names = [n for n in (*defs.PARAMETERS, HEIGHT) if n in c.columns]
    cols = {"exposure": c["exposure"], "time_s": c["time"]}
    for n in names:
        s = suffix[unit_of(n, angle_unit, length_unit, "coach")]
        cols[f"{n}_{s}"] = c[n]
        if f"sigma_{n}" in c.columns:
            cols[f"sigma_{n}_{s}"] = c[f"sigma_{n}"]
    import pandas as pd
    return pd.DataFrame(cols)


def read_landing_profile(path) -> ProfileGround:
    """The landing-slope profile CSV (``distance,height``, see the module).

    Raises
    ------
    InputError
        Unreadable file, missing columns, bad numbers, fewer than 2 rows or
        distances not increasing (one line with file and line).
    """
    import pandas as pd

    path = Path(path)
    hint = "a CSV with a header distance,height and distance increasing (world X)"
    try:
        table = pd.read_csv(path, comment="#", skipinitialspace=True)
    except (OSError, UnicodeDecodeError, ValueError, pd.errors.ParserError) as exc:
        raise InputError(f"cannot read the landing profile: {str(exc).splitlines()[0]}",
                         file=path, hint=hint) from None
    missing = [c for c in ("distance", "height") if c not in table.columns]
    if missing:
        raise InputError(f"landing profile: column {missing[0]} is missing", file=path,
                         hint=hint)
    values = table[["distance", "height"]].apply(pd.to_numeric, errors="coerce")
    bad = ~np.all(np.isfinite(values.to_numpy(float)), axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InputError(f"landing profile: row {row + 1} is not two finite numbers", file=path,
                         hint=hint)
    x, z = values["distance"].to_numpy(float), values["height"].to_numpy(float)
    if len(x) < 2:
        raise InputError("landing profile: at least 2 rows are needed", file=path, hint=hint)
    if np.any(np.diff(x) <= 0):
        row = int(np.flatnonzero(np.diff(x) <= 0)[0]) + 2
        raise InputError(f"landing profile: distance does not increase at row {row}",
                         file=path, hint=hint)
    return ProfileGround(x=x, z=z)
