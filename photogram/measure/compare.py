"""A measured observation table against a reference table of the same
targets (typed by hand, another program's measurement, or the truth of a
simulation).

Rows are matched by (station, point). For every match the difference is
normalised by the combined sigma, ``z = d / sqrt(sigma_m^2 + sigma_r^2)``
per coordinate (``sigma_m`` the measured table's sigma column, ``sigma_r``
the reference's sigma column or ``sigma_reference``); a match with
``|z| > gate`` in either coordinate is counted as **beyond the gate** (a
sigma too optimistic, a partly hidden target), and a match more than
``wrong_px`` pixels off as a **wrong label** (a target numbered as another
one is at least the distance between two targets off).
Used by ``photogram demo`` (the lab's measurement against its typed table)
and the tests (against the true image points).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photogram.errors import InputError

__all__ = ["Comparison", "compare_tables", "read_points_table"]


def read_points_table(path) -> dict:
    """``(station, point) -> (x, y, sigma)`` of an image points CSV (``#``
    comment lines skipped; sigma NaN when the table has none)."""
    path = Path(path)
    try:
        lines = [ln for ln in path.read_text(encoding="utf-8").splitlines()
                 if ln.strip() and not ln.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the image points table: {exc}", file=path) from None
    rows = list(csv.DictReader(lines))
    if not rows or not {"station", "point", "x", "y"} <= set(rows[0]):
        raise InputError("not an image points table (columns station, point, x, y)", file=path)
    out = {}
    for r in rows:
        try:
            s = float(r["sigma"]) if r.get("sigma") not in (None, "") else float("nan")
            out[(r["station"], r["point"])] = (float(r["x"]), float(r["y"]), s)
        except ValueError:
            raise InputError(f"a row that is not numbers: {r}", file=path) from None
    return out


@dataclass
class Comparison:
    n_measured: int
    n_reference: int
    matched: int
    extra: list = field(default_factory=list)      # measured, not in the reference
    missing: list = field(default_factory=list)    # in the reference, not measured
    rms: float = float("nan")                      # 2D RMS of the differences, px
    largest: float = float("nan")                  # largest 2D difference, px
    mean_z2: float = float("nan")                  # mean of z^2 over both coordinates
    max_z: float = float("nan")
    beyond: list = field(default_factory=list)     # (station, point, dx, dy) with |z| > gate
    wrong: list = field(default_factory=list)      # (station, point, dx, dy) > wrong_px off
    fraction_within_3: float = float("nan")        # of the coordinates with |z| <= 3
    gate: float = 5.0
    wrong_px: float = 3.0

    def line(self) -> str:
        return (f"{self.matched} of {self.n_reference} found "
                f"({100 * self.matched / max(self.n_reference, 1):.1f} %), "
                f"{len(self.extra)} not in it, difference RMS {self.rms:.3f} px "
                f"(largest {self.largest:.3f}), mean z^2 {self.mean_z2:.2f} "
                f"(1 when the sigmas are right), {len(self.beyond)} beyond {self.gate:g} sigma, "
                f"{len(self.wrong)} more than {self.wrong_px:g} px off (wrong labels)")


def compare_tables(measured, reference, *, sigma_reference: float = 0.0,
                   gate: float = 5.0, wrong_px: float = 3.0) -> Comparison:
    """Compare two image points tables (module doc)."""
    m = read_points_table(measured) if not isinstance(measured, dict) else measured
    r = read_points_table(reference) if not isinstance(reference, dict) else reference
    keys = [k for k in m if k in r]
    out = Comparison(n_measured=len(m), n_reference=len(r), matched=len(keys),
                     extra=sorted(k for k in m if k not in r),
                     missing=sorted(k for k in r if k not in m), gate=gate,
                     wrong_px=wrong_px)
    if not keys:
        return out
    d = np.array([[m[k][0] - r[k][0], m[k][1] - r[k][1]] for k in keys])
    sm = np.array([m[k][2] for k in keys])
    sr = np.array([r[k][2] for k in keys])
    sm = np.where(np.isfinite(sm), sm, 0.0)
    sr = np.where(np.isfinite(sr), sr, sigma_reference)
    s = np.sqrt(sm ** 2 + sr ** 2)
    s = np.where(s > 0, s, np.nan)
    z = d / s[:, None]
    dist = np.hypot(d[:, 0], d[:, 1])
    out.rms = float(np.sqrt(np.mean(dist ** 2)))
    out.largest = float(dist.max())
    out.mean_z2 = float(np.nanmean(z ** 2))
    out.max_z = float(np.nanmax(np.abs(z)))
    out.fraction_within_3 = float(np.mean(np.abs(z[np.isfinite(z)]) <= 3))

    def rows(mask):
        return [(keys[i][0], keys[i][1], float(d[i, 0]), float(d[i, 1]))
                for i in np.flatnonzero(mask)]
    out.beyond = rows(np.nanmax(np.abs(z), axis=1) > gate)
    out.wrong = rows(dist > wrong_px)
    return out
