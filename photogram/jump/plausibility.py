"""Is the intersected jumper a person? Plausibility of the stick model.

A wrong ``length_unit`` (dm data declared as ``"m"``), a wrong frame rate
or a scale error of the orientation give a stick model that is internally
consistent, with small sigmas, and physically impossible: a jumper 16 m
tall flying at 208 m/s. :func:`plausibility_warnings` compares, in metres
and seconds, what the intersect step measured with what a ski jumper can
do and returns one warning per violated limit (empty when plausible):

* **speed** of O above :data:`MAX_SPEED` (45 m/s; jumpers take off at
  23-27 m/s and fly at most ~35 m/s);
* **size**: the median distance from the helmet P1 to the midpoint O of the
  bindings outside :data:`BODY_SIZE` (0.5-3 m; a crouched to stretched
  jumper measures 0.9-2 m), and the median distance between the bindings
  P3-P4 above :data:`MAX_BINDING_GAP` (1.5 m);
* **height**: the vertical acceleration of O (a parabola fitted to its
  height over time; free flight with lift gives -10 to -5 m/s^2) beyond
  :data:`MAX_VERTICAL_ACCELERATION` (25 m/s^2) by more than 3 sigma of the
  fit.

Each warning names the measured value, the limit and, where one exists,
the length unit that would make the jumper plausible.
"""

from __future__ import annotations

import numpy as np

from photogram.project.model import LENGTH_UNITS

__all__ = ["plausibility_warnings", "MAX_SPEED", "BODY_SIZE", "MAX_BINDING_GAP",
           "MAX_VERTICAL_ACCELERATION"]

#: m/s: no ski jumper is faster (inrun ~25 m/s, flight at most ~35 m/s)
MAX_SPEED = 45.0
#: m: helmet P1 to the midpoint of the bindings, crouched to stretched
BODY_SIZE = (0.5, 3.0)
#: m: distance between the bindings P3 and P4
MAX_BINDING_GAP = 1.5
#: m/s^2: |vertical acceleration| of O (free fall is 9.81)
MAX_VERTICAL_ACCELERATION = 25.0


def _median_distance(a, b) -> float:
    d = np.linalg.norm(np.asarray(a, float) - np.asarray(b, float), axis=1)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else float("nan")


def _vertical_acceleration(times, z) -> tuple[float, float]:
    """(a, sigma_a) of a parabola fitted to ``z(t)``; NaN with fewer than 6
    exposures (4 distinct times) or a span below 0.15 s."""
    ok = np.isfinite(times) & np.isfinite(z)
    t, z = np.asarray(times, float)[ok], np.asarray(z, float)[ok]
    if t.size < 6 or np.ptp(t) < 0.15 or np.unique(t).size < 4:
        return float("nan"), float("nan")
    t0 = t - t.mean()
    A = np.column_stack([t0 ** 2, t0, np.ones_like(t0)])
    coef, *_ = np.linalg.lstsq(A, z, rcond=None)
    r = z - A @ coef
    s2 = float(r @ r) / (t.size - 3)
    cov = s2 * np.linalg.inv(A.T @ A)
    return 2.0 * float(coef[0]), 2.0 * float(np.sqrt(cov[0, 0]))


def _unit_hint(size_m: float, unit: str) -> str:
    """' (are the coordinates in dm? ...)' when another unit makes the body
    size plausible, else ''."""
    if not np.isfinite(size_m) or size_m <= 0:
        return ""
    raw = size_m / LENGTH_UNITS[unit]                 # the size in the project's unit
    lo, hi = BODY_SIZE
    fits = [u for u, f in LENGTH_UNITS.items() if u != unit and lo <= raw * f <= hi]
    if not fits:
        return ""
    return (f"; are the coordinates in {fits[0]}? then set length_unit = \"{fits[0]}\" in "
            f"[project]")


def plausibility_warnings(model, length_unit: str) -> list[str]:
    """Warnings for a stick model that no ski jumper can have (module doc).

    Parameters
    ----------
    model : StickModel
        Of the intersect step (``P``, ``O``, ``times``, ``values["v"]``, in
        the project's length unit).
    length_unit : str
        The project's length unit (m, dm, cm, mm).

    Returns
    -------
    list of str
        One sentence per violated limit, empty when all is plausible.
    """
    to_m = LENGTH_UNITS[length_unit]
    out = []
    size = _median_distance(model.P[:, 0], model.O) * to_m
    hint = _unit_hint(size, length_unit)
    lo, hi = BODY_SIZE
    if np.isfinite(size) and not lo <= size <= hi:
        out.append(f"implausible jumper size: helmet to the middle of the bindings "
                   f"measures {size:.3g} m (median over the exposures; a jumper measures "
                   f"{lo:g}-{hi:g} m){hint}")
    gap = _median_distance(model.P[:, 2], model.P[:, 3]) * to_m
    if np.isfinite(gap) and gap > MAX_BINDING_GAP:
        out.append(f"implausible jumper size: the bindings are {gap:.3g} m apart (median; "
                   f"at most {MAX_BINDING_GAP:g} m){hint}")
    v = np.asarray(model.values["v"], float) * to_m
    fast = np.isfinite(v) & (v > MAX_SPEED)
    if np.any(fast):
        out.append(f"implausible speed: v reaches {np.nanmax(v):.3g} m/s at {int(fast.sum())} "
                   f"of {int(np.isfinite(v).sum())} exposures (ski jumpers fly at most "
                   f"~35 m/s; limit {MAX_SPEED:g} m/s){hint or '; check length_unit and fps'}")
    a, sa = _vertical_acceleration(model.times, model.O[:, 2] * to_m)
    if np.isfinite(a) and abs(a) - 3.0 * sa > MAX_VERTICAL_ACCELERATION:
        out.append(f"implausible height change: the bindings accelerate vertically at "
                   f"{a:.3g} +- {sa:.2g} m/s^2 (free fall is -9.81; limit "
                   f"{MAX_VERTICAL_ACCELERATION:g} m/s^2){hint or '; check length_unit and fps'}")
    return out
