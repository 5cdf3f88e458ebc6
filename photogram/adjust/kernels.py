"""Optional compiled kernels (numba) for the hot loops of the engine.

``pip install photogram[fast]`` installs numba. The kernels are used for
problems with at least ``min_rows`` E-rows (20,000 by default, environment
variable ``PHOTOGRAM_NUMBA_MIN_ROWS``): below that the pure-numpy path is as
fast as the one-time cost of importing numba and loading its cached code
(about a second). Without numba, with ``PHOTOGRAM_NUMBA=0`` or after
``use_numba(False)`` the engine runs its pure-numpy path, which gives the
same results (to rounding) and stays the tested default.

The kernels (:mod:`photogram.adjust._numba_kernels`) work on the per-row
representation of :mod:`normal`: for every row of a residual block that
touches one eliminated point ("E-row"), the Jacobian of its reduced columns
``Jc`` (d x s, padded with zeros), of its point ``Je`` (d x 3), the reduced
column numbers ``rcols`` (s; padding points at the dummy column ``n_r``)
and the point number.
"""

from __future__ import annotations

import importlib.util
import os

_OFF = ("0", "false", "no", "off")

HAVE_NUMBA = (os.environ.get("PHOTOGRAM_NUMBA", "1").strip().lower() not in _OFF
              and importlib.util.find_spec("numba") is not None)

_state = {"enabled": HAVE_NUMBA,
          "min_rows": int(os.environ.get("PHOTOGRAM_NUMBA_MIN_ROWS", "20000")),
          "module": None}


def use_numba(flag: bool | None = None, min_rows: int | None = None) -> bool:
    """Switch the compiled kernels on or off (when numba is installed) and
    set the problem size from which they are used; returns whether they are
    switched on. ``use_numba()`` only queries."""
    if flag is not None:
        _state["enabled"] = bool(flag) and HAVE_NUMBA
    if min_rows is not None:
        _state["min_rows"] = int(min_rows)
    return _state["enabled"]


def min_rows() -> int:
    return _state["min_rows"]


def enabled() -> bool:
    return _state["enabled"]


def active(n_rows: int) -> bool:
    """Use the kernels for a problem with ``n_rows`` E-rows?"""
    if not _state["enabled"] or n_rows < _state["min_rows"]:
        return False
    return compiled() is not None


def compiled():
    """The compiled kernel module (imported on first use), or None when
    numba cannot be imported (the numpy path is used then)."""
    if _state["module"] is None:
        try:
            from photogram.adjust import _numba_kernels
        except Exception:   # pragma: no cover - broken numba installation
            _state["enabled"] = False
            return None
        _state["module"] = _numba_kernels
    return _state["module"]
